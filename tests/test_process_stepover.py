"""camtool.process.stepover: the auto step-over from the predicted map."""
import pytest

from camtool.errors import BadInput
from camtool.process.footprint import Footprint
from camtool.process.stepover import choose_step_over, predicted_map, ripple_limit_mm, ripple_share
from camtool.path.raster import raster_path
from camtool.settings import ProcessSettings, RasterSettings
from tests.test_process_integrate import plate


def test_ripple_share_falls_with_the_step_over_and_the_limit_meets_the_target():
    fp = Footprint("parabolic", 25.0)
    assert ripple_share(fp, 10.0, 0.05) == 1.0
    assert ripple_share(fp, 50.0, 0.05) < 0.5
    s = ripple_limit_mm(fp, 0.95, 0.05)
    assert ripple_share(fp, s, 0.05) >= 0.95 and ripple_share(fp, s + 3.0, 0.05) < 0.95


def test_auto_step_over_meets_the_target_on_a_large_plate():
    surface = plate(600, 400)
    process = ProcessSettings.make(kind="polish", profile="parabolic", diameter_mm=30, grid_mm=2.0)
    raster = RasterSettings.make(step_over_mm="auto", pitch_mm=10, lead_mm=20)
    assert raster.step_over_auto
    chosen, record = choose_step_over(surface, raster, process, 100.0)
    assert record["met"] and record["predicted_share_within_band"] >= 0.95
    assert chosen.step_over_mm == record["step_over_mm"] and not chosen.step_over_auto
    assert record["limited_by"] in ("ripple", "edges") and 0 <= record["candidates"][0]["interior_share_within_band"] <= 1
    # the prediction of the chosen raster is what the record says
    _, pmap = predicted_map(surface, chosen, process, 100.0)
    assert pmap.values.max() > 0


def test_auto_needs_a_process_and_other_commands_need_a_number():
    raster = RasterSettings.make(step_over_mm="auto")
    with pytest.raises(BadInput, match="process.kind"):
        choose_step_over(plate(), raster, ProcessSettings.make(), 100.0)
    with pytest.raises(BadInput, match="auto"):
        raster_path(plate(), raster)
    with pytest.raises(BadInput, match="step_over_mm"):
        RasterSettings.make(step_over_mm="automatic")


def test_auto_step_over_on_a_cylinder_predicts_on_its_own_mesh():
    """A cylinder's map lies on its own (u, v) mesh (camtool.process.mesh_map): "auto" chooses there too."""
    import numpy as np

    from camtool.part.surface import Boundary, Cylinder

    cyl = Cylinder(np.zeros(3), 150.0, np.eye(3), Boundary(np.array([[-1.0, -150], [1.0, -150], [1.0, 150],
                                                                     [-1.0, 150]])))
    process = ProcessSettings.make(kind="polish", profile="parabolic", diameter_mm=30, grid_mm=2.0)
    chosen, record = choose_step_over(cyl, RasterSettings.make(step_over_mm="auto", pitch_mm=10, lead_mm=20),
                                      process, 100.0)
    assert record["surface"] == "cylinder" and record["met"] and chosen.step_over_mm == record["step_over_mm"]
    _, pmap = predicted_map(cyl, chosen, process, 100.0)
    assert pmap.method == "mesh-direct" and pmap.values.max() > 0
