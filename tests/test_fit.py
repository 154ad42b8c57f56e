"""RANSAC fitting: accuracy with noise and outliers, determinism, model choice, errors."""
import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.part.fit import fit_surface
from camtool.part.surface import PlaneSurface, SpherePatch
from camtool.part.workpiece import Workpiece
from camtool.settings import FitSettings

CENTER = np.array([1000.0, 0.0, 100.0])


def _with_outliers(pts, normals, rng, ratio=0.3, pad=0.0):
    n_out = int(round(len(pts) * ratio / (1 - ratio)))
    lo, hi = pts.min(axis=0) - pad, pts.max(axis=0) + pad
    out = rng.uniform(lo, hi, (n_out, 3))
    order = rng.permutation(len(pts) + n_out)
    return Workpiece(np.vstack([pts, out])[order], np.vstack([normals, np.tile(normals[:1], (n_out, 1))])[order])


def sphere_patch_points(n, rng, sigma=0.1, R=600.0):
    az = rng.uniform(*np.radians([-40, 40]), n)
    el = np.arcsin(rng.uniform(*np.sin(np.radians([-10, 60])), n))
    d = np.stack([-np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], 1)
    return CENTER + d * (R + rng.normal(0, sigma, n))[:, None], d


def plane_points(n, rng, normal, offset, sigma=0.1):
    normal = normal / np.linalg.norm(normal)
    a = np.cross(normal, [0.3, 0.5, 0.8]); a /= np.linalg.norm(a)
    b = np.cross(normal, a)
    uv = rng.uniform(-400, 400, (n, 2))
    pts = offset * normal + uv[:, :1] * a + uv[:, 1:] * b + rng.normal(0, sigma, (n, 1)) * normal
    return pts, np.tile(normal, (n, 1))


@pytest.fixture(scope="module")
def sphere_wp():
    rng = np.random.default_rng(11)
    pts, d = sphere_patch_points(70_000, rng)
    return _with_outliers(pts, d, rng)  # 100k points, 30 % outliers in the bounding box


@pytest.fixture(scope="module")
def plane_wp():
    rng = np.random.default_rng(12)
    pts, nrm = plane_points(70_000, rng, np.array([0.2, -1.0, 0.3]), -550.0)
    return _with_outliers(pts, nrm, rng, pad=100.0)  # box padded off the plane: real outliers


def test_sphere_accuracy(sphere_wp):
    s = fit_surface(sphere_wp, FitSettings.make(model="sphere"))
    assert isinstance(s, SpherePatch)
    assert abs(s.radius_mm - 600.0) <= 0.05
    assert np.linalg.norm(s.center_mm - CENTER) <= 0.1
    assert 0.69 < s.stats.inlier_ratio < 0.72 and s.stats.n_points == 100_000
    assert 0.08 < s.stats.rms_mm < 0.13 and s.stats.max_residual_mm < 0.5
    # frame: e3 is world up, e1 the horizontal mean direction (-x): rows stay horizontal
    assert np.allclose(s.frame[:, 2], [0, 0, 1]) and np.allclose(s.frame[:, 0], [-1, 0, 0], atol=1e-3)
    lo, hi = np.degrees(s.boundary.bounds())
    assert np.allclose([lo[0], hi[0]], [-40, 40], atol=0.8) and np.allclose([lo[1], hi[1]], [-10, 60], atol=0.8)
    assert s.boundary.holes_uv == ()


def test_plane_accuracy_and_orientation(plane_wp):
    true_n = np.array([0.2, -1.0, 0.3]) / np.linalg.norm([0.2, -1.0, 0.3])
    s = fit_surface(plane_wp, FitSettings.make(model="plane"))
    assert isinstance(s, PlaneSurface)
    angle_deg = np.degrees(np.arccos(np.clip(s.normal @ true_n, -1, 1)))
    assert angle_deg <= 0.01  # also checks the sign: towards the workpiece normals
    assert abs(s.offset_mm - (-550.0)) <= 0.05
    assert np.isclose(np.cross(s.u_axis, s.v_axis) @ s.normal, 1.0)
    assert s.v_axis[2] > 0.9  # tilted plane: v follows world up


def test_auto_picks_plane_for_plane_and_sphere_for_sphere(plane_wp, sphere_wp):
    assert fit_surface(plane_wp, FitSettings.make()).model == "plane"
    assert fit_surface(sphere_wp, FitSettings.make()).model == "sphere"


def test_auto_takes_plane_for_a_flat_cloud_without_outliers():
    rng = np.random.default_rng(3)
    pts, nrm = plane_points(5000, rng, np.array([0.0, 0.0, 1.0]), 10.0)
    s = fit_surface(Workpiece(pts, nrm), FitSettings.make())
    assert s.model == "plane" and np.allclose(s.normal, [0, 0, 1], atol=1e-3)


def test_same_seed_same_result(sphere_wp):
    a = fit_surface(sphere_wp, FitSettings.make(seed=7, iterations=200))
    b = fit_surface(sphere_wp, FitSettings.make(seed=7, iterations=200))
    assert a.radius_mm == b.radius_mm and np.array_equal(a.center_mm, b.center_mm)
    assert np.array_equal(a.boundary.outer_uv, b.boundary.outer_uv)


def test_no_model_reaches_min_inlier_ratio():
    rng = np.random.default_rng(4)
    wp = Workpiece(rng.uniform(0, 500, (3000, 3)), np.tile([0, 0, 1.0], (3000, 1)), source="noise.xyz")
    with pytest.raises(BadInput, match="min_inlier_ratio"):
        fit_surface(wp, FitSettings.make())


def test_degenerate_inputs():
    z = np.tile([0, 0, 1.0], (10, 1))
    with pytest.raises(BadInput, match="needs at least 3"):
        fit_surface(Workpiece(np.zeros((2, 3)) + [[0, 0, 0], [1, 0, 0]], z[:2], source="two.xyz"), FitSettings.make())
    line = np.outer(np.arange(10.0), [1, 2, 3])
    with pytest.raises(BadInput, match="line"):
        fit_surface(Workpiece(line, z, source="line.xyz"), FitSettings.make())
    rng = np.random.default_rng(0)
    flat = np.column_stack([rng.uniform(0, 100, (50, 2)), np.zeros(50)])
    with pytest.raises(BadInput, match="plane"):
        fit_surface(Workpiece(flat, np.tile([0, 0, 1.0], (50, 1))), FitSettings.make(model="sphere"))
    with pytest.raises(BadInput, match="fit.model"):
        fit_surface(Workpiece(flat, np.tile([0, 0, 1.0], (50, 1))), FitSettings.make(model="cone"))


def test_a_bowl_is_worked_from_inside():
    """A concave sphere patch (normals to the centre): the material side comes from the data's normals."""
    from camtool.path.raster import raster_path
    from camtool.settings import RasterSettings

    rng = np.random.default_rng(5)
    az, el = rng.uniform(-0.6, 0.6, 6000), rng.uniform(-0.4, 0.4, 6000)
    d = np.stack([-np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=1)
    centre = np.array([1200.0, 0.0, 500.0])
    bowl = Workpiece(centre + 400.0 * d, -d)  # normals point to the centre: a bowl
    s = fit_surface(bowl, FitSettings.make(model="sphere"))
    assert s.concave
    uv = s.uv_from_points(bowl.points_mm[:50])
    assert np.all(np.sum(s.normal_at(uv[:, 0], uv[:, 1]) * bowl.normals[:50], axis=1) > 0.99)
    path = raster_path(s, RasterSettings.make(step_over_mm=40, pitch_mm=20))
    work = path.poses_mm[path.is_work]
    radial = (work[:, :3, 3] - s.center_mm) / s.radius_mm
    assert np.all(np.sum(work[:, :3, 2] * radial, axis=1) > 0.99)  # tool z into the material, away from the centre
    convex = fit_surface(Workpiece(bowl.points_mm, d), FitSettings.make(model="sphere"))
    assert not convex.concave


def cylinder_points(n, rng, sigma=0.1, R=150.0, inside=False):
    """Points on a third of a cylinder R about the axis through (1000, 0, 100) along (0, 1, 1)/sqrt 2."""
    a = np.array([0.0, 1, 1]) / np.sqrt(2)
    e1 = np.array([1.0, 0, 0])
    e2 = np.cross(a, e1)
    u = rng.uniform(-1.0, 1.0, n)
    v = rng.uniform(-200, 200, n)
    radial = np.cos(u)[:, None] * e1 + np.sin(u)[:, None] * e2
    pts = CENTER + (R + rng.normal(0, sigma, n))[:, None] * radial + v[:, None] * a
    return pts, (-radial if inside else radial), a


@pytest.mark.parametrize("inside", [False, True])
def test_cylinder_fit_explicit_and_auto(inside):
    rng = np.random.default_rng(5)
    pts, normals, a = cylinder_points(20000, rng, inside=inside)
    wp = _with_outliers(pts, normals, rng, ratio=0.2)
    for model in ("cylinder", "auto"):
        s = fit_surface(wp, FitSettings.make(model=model))
        assert s.model == "cylinder" and s.concave == inside
        assert abs(s.radius_mm - 150.0) < 0.1
        assert np.degrees(np.arccos(min(1.0, abs(float(s.axis @ a))))) < 0.1
        d = s.center_mm - CENTER
        assert np.linalg.norm(d - (d @ a) * a) < 0.1
        assert 0.75 < s.stats.inlier_ratio < 0.85


def test_auto_keeps_plane_and_sphere_over_cylinder(sphere_wp):
    s = fit_surface(sphere_wp, FitSettings.make(model="auto"))
    assert s.model == "sphere"
    rng = np.random.default_rng(2)
    pts, normals = plane_points(5000, rng, np.array([0.2, 0.3, 1.0]), 50.0)
    assert fit_surface(Workpiece(pts, normals), FitSettings.make(model="auto")).model == "plane"
    with pytest.raises(BadInput, match="no cylinder"):
        fit_surface(Workpiece(pts, normals), FitSettings.make(model="cylinder"))
