"""Boundary extraction: outer polygon and holes that hug the material."""
import numpy as np
import pytest

from camtool.part.boundary import boundary_from_uv
from camtool.part.fit import fit_surface
from camtool.part.workpiece import load_workpiece
from camtool.settings import FitSettings

ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]


def _plate_uv(n=60_000, seed=0):
    rng = np.random.default_rng(seed)
    uv = rng.uniform([-200, -150], [200, 150], (n, 2))
    in_hole = np.hypot(uv[:, 0] - 60, uv[:, 1] - 30) < 40  # 80 mm round hole
    return uv[~in_hole]


def test_plate_with_round_hole_gives_outer_and_one_hole():
    b = boundary_from_uv(_plate_uv(), None, cell_mm=2.0, close_gaps_mm=6.0, simplify_mm=0.5)
    assert len(b.holes_uv) == 1
    assert not b.contains(np.array([[60.0, 30.0]]))[0]
    assert b.contains(np.array([[0.0, 0.0], [-150.0, -100.0], [60.0, 80.0]])).all()
    lo, hi = b.bounds()
    assert np.allclose(lo, [-200, -150], atol=3.0) and np.allclose(hi, [200, 150], atol=3.0)
    r = np.hypot(b.holes_uv[0][:, 0] - 60, b.holes_uv[0][:, 1] - 30)
    assert np.all(np.abs(r - 40) < 3.0)  # hugs the hole edge within about one cell
    # orientation convention: outer counter-clockwise, hole clockwise
    def area(p):
        return 0.5 * np.sum(p[:, 0] * np.roll(p[:, 1], -1) - p[:, 1] * np.roll(p[:, 0], -1))
    assert area(b.outer_uv) > 0 > area(b.holes_uv[0])


def test_small_gaps_are_closed_and_largest_component_kept():
    uv = _plate_uv()
    uv = uv[~((uv[:, 0] > -105) & (uv[:, 0] < -95))]  # a 10 mm slot across the plate
    island = np.random.default_rng(1).uniform([400, 0], [420, 20], (2000, 2))  # a separate chip
    b = boundary_from_uv(np.vstack([uv, island]), None, cell_mm=2.0, close_gaps_mm=12.0)
    assert len(b.holes_uv) == 1 and b.bounds()[1][0] < 210  # slot closed, chip left out
    b_open = boundary_from_uv(uv, None, cell_mm=2.0, close_gaps_mm=0.0)
    assert b_open.bounds()[0][0] > -100  # without closing the slot splits the plate


def test_sample_plate_hole_stl():
    s = fit_surface(load_workpiece(ROOT / "samples" / "plate_hole.stl"), FitSettings.make())
    assert s.model == "plane" and np.allclose(s.normal, [0, 0, 1])
    assert len(s.boundary.holes_uv) == 1
    hole_centre_uv = s.uv_from_points(np.array([[60.0, 30.0, 0.0]]))
    assert not s.boundary.contains(hole_centre_uv)[0]
    assert s.boundary.contains(s.uv_from_points(np.array([[-150.0, -100.0, 0.0]])))[0]


def test_sphere_band_boundary_in_radians():
    rng = np.random.default_rng(2)
    uv = np.column_stack([rng.uniform(*np.radians([-40, 40]), 80_000),
                          np.arcsin(rng.uniform(*np.sin(np.radians([-10, 60])), 80_000))])
    b = boundary_from_uv(uv, 600.0, cell_mm=2.0)
    lo, hi = np.degrees(b.bounds())
    assert np.allclose(lo, [-40, -10], atol=0.6) and np.allclose(hi, [40, 60], atol=0.6)
    assert b.holes_uv == ()
    # the edge at u = 40 deg is hugged at every elevation (sinusoidal raster is equal-area)
    v = np.radians(np.linspace(-5, 55, 13))
    assert b.contains(np.column_stack([np.full(13, np.radians(39.0)), v])).all()
    assert not b.contains(np.column_stack([np.full(13, np.radians(41.5)), v])).any()


def test_too_few_points():
    from camtool.errors import BadInput
    with pytest.raises(BadInput):
        boundary_from_uv(np.zeros((2, 2)), None)


def test_a_sparse_scan_ends_within_half_a_step_of_its_points():
    """A plate scanned every 20 mm: the boundary (and the work rows) stay within 10 mm of the points."""
    from camtool.path.raster import raster_path
    from camtool.settings import RasterSettings
    from camtool.part.surface import PlaneSurface

    xs, ys = np.meshgrid(np.arange(0.0, 401.0, 20.0), np.arange(0.0, 301.0, 20.0))
    uv = np.column_stack([xs.ravel(), ys.ravel()])
    b = boundary_from_uv(uv)
    lo, hi = b.bounds()
    assert np.all(lo >= -10.0 - 1e-6) and np.all(hi <= [410.0 + 1e-6, 310.0 + 1e-6])
    surface = PlaneSurface(np.zeros(3), np.array([0, 0, 1.0]), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), b)
    path = raster_path(surface, RasterSettings.make(step_over_mm=20, pitch_mm=5, lead_mm=0))
    work = path.poses_mm[path.is_work][:, :3, 3]
    assert work[:, 0].min() >= -10.0 and work[:, 0].max() <= 410.0
    assert work[:, 1].min() >= -10.0 and work[:, 1].max() <= 310.0
