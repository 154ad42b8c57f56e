"""camtool.process.figures: figures of known maps, the npz and PNG files."""
import numpy as np
import pytest

from camtool.process.figures import map_figures, plot_map_png, save_map_npz
from camtool.process.grid import map_grid
from camtool.process.integrate import ProcessMap
from tests.test_process_integrate import plate


def known_map(values_fn, kind="polish"):
    grid = map_grid(plate(100, 60), 1.0, 5.0)
    U, V = np.meshgrid(grid.u, grid.v)
    return ProcessMap(grid, values_fn(U, V), kind, "removal depth", "um", "convolution", 1.0, 1.0, 10)


def test_uniform_map():
    f = map_figures(known_map(lambda U, V: np.full(U.shape, 2.0)))
    assert f["mean"] == pytest.approx(2.0) and f["pv"] == 0 and f["rms"] == 0
    assert f["uniformity_within_5pct"] == 1.0 and f["edge_rolloff_width_mm"] == 0.0
    assert f["uncovered_area_mm2"] == 0.0
    assert f["worked_area_mm2"] == pytest.approx(100 * 60, rel=0.05)


def test_rolloff_and_uncovered():
    # 1 in the middle, falling linearly to 0 over the outer 10 mm in u, and a strip at v > 20 never reached
    def fn(U, V):
        val = np.clip((50 - np.abs(U)) / 10.0, 0, 1)
        return np.where(V > 20, 0.0, val)
    f = map_figures(known_map(fn))
    assert 4.0 <= f["edge_rolloff_width_mm"] <= 12.0
    assert f["uncovered_share"] == pytest.approx(10 / 60, abs=0.03)
    assert f["uniformity_within_5pct"] < 0.8


def test_files(tmp_path):
    pm = known_map(lambda U, V: 1.0 + 0.01 * U)
    f = map_figures(pm)
    npz = save_map_npz(pm, tmp_path / "process_map.npz")
    d = np.load(npz)
    assert d["values"].shape == (len(d["v"]), len(d["u"])) and str(d["units"]) == "um"
    assert np.array_equal(d["values"], pm.values) and str(d["uv_unit"]) == "mm"
    again = save_map_npz(pm, tmp_path / "again.npz")
    assert again.read_bytes() == npz.read_bytes()  # the same map, the same bytes
    png = plot_map_png(pm, f, tmp_path / "plots" / "process_map.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(tmp_path.glob(".tmp-*")) and not list((tmp_path / "plots").glob(".tmp-*"))
