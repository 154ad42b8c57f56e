"""camtool.process.dwell: a target removal map met by feed factors along the rows."""
import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.process.dwell import load_target, plan_dwell
from camtool.process.grid import map_grid
from camtool.path.raster import raster_path
from camtool.settings import ProcessSettings, RasterSettings
from tests.test_process_integrate import plate


def setup():
    surface = plate(400, 300)
    process = ProcessSettings.make(kind="polish", profile="gaussian", diameter_mm=40, relative_speed_m_s=5.0,
                                   grid_mm=2.0, dwell_iterations=40, feed_factor_min=0.2)
    path = raster_path(surface, RasterSettings.make(step_over_mm=8, pitch_mm=4, lead_mm=10, clearance_mm=5))
    return surface, process, path


def test_a_target_is_met_within_the_feed_bounds(tmp_path):
    surface, process, path = setup()
    grid = map_grid(surface, process.grid_mm, 24.0)
    flat = plan_dwell(surface, path, process, 100.0, target=np.zeros(grid.shape), grid=grid).before.values
    base = float(np.median(flat[grid.material]))
    U, V = np.meshgrid(grid.u, grid.v)
    target = base * (1.6 + 0.4 * np.sin(2 * np.pi * U / 200.0) * np.cos(2 * np.pi * V / 300.0))
    f = tmp_path / "target.npz"
    np.savez(f, u=grid.u, v=grid.v, values_um=target)
    plan = plan_dwell(surface, path, process, 100.0, target_file=f, grid=grid)
    fig = plan.figures
    assert fig["residual_rms_after_pct"] <= 10.0 < fig["residual_rms_before_pct"]
    assert fig["convergence_rms_um"][-1] < fig["convergence_rms_um"][0]
    work = path.zone == 0
    assert np.all(plan.feed_factor[work] >= 0.2 - 1e-9) and np.all(plan.feed_factor <= 1.0 + 1e-9)
    assert np.all(plan.feed_factor[~work] == 1.0)
    assert np.allclose(load_target(f, grid), target)


def test_refusals(tmp_path):
    surface, process, path = setup()
    with pytest.raises(BadInput, match="relative_speed_m_s"):
        plan_dwell(surface, path, ProcessSettings.make(kind="polish"), 100.0, target=np.zeros((2, 2)))
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(BadInput, match="bad.npz"):
        plan_dwell(surface, path, process, 100.0, target_file=bad)
    np.savez(tmp_path / "neg.npz", u=[0.0, 1.0], v=[0.0, 1.0], values_um=-np.ones((2, 2)))
    with pytest.raises(BadInput, match="negative"):
        plan_dwell(surface, path, process, 100.0, target_file=tmp_path / "neg.npz")
