"""camtool.part.surface: plane and sphere parameterisations, the boundary, and the surface file."""
import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from camtool.errors import BadInput
from camtool.part.surface import (
    SURFACE_FORMAT,
    SURFACE_VERSION,
    Boundary,
    FitStats,
    PlaneSurface,
    SpherePatch,
    load_surface,
    save_surface,
    surface_from_dict,
)


def rect(u0, u1, v0, v1):
    return np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]], float)


def tilted_plane(stats=None):
    """A plane through (100, -50, 30) with a frame rotated off the world axes."""
    R = Rotation.from_euler("xyz", [20, -35, 50], degrees=True).as_matrix()
    hole = rect(40, 60, 40, 60)
    return PlaneSurface(np.array([100.0, -50.0, 30.0]), R[:, 2], R[:, 0], R[:, 1],
                        Boundary(rect(0, 200, 0, 100), (hole,)), stats)


def sphere_patch(stats=None):
    frame = Rotation.from_euler("zyx", [30, 10, -5], degrees=True).as_matrix()
    return SpherePatch(np.array([1000.0, 20.0, 100.0]), 600.0, frame,
                       Boundary(np.radians(rect(-40, 40, -10, 60))), stats)


# -- Boundary ------------------------------------------------------------------
def test_boundary_contains_outer_minus_holes():
    b = Boundary(rect(0, 10, 0, 10), (rect(2, 4, 2, 4), rect(6, 8, 6, 8)))
    uv = np.array([[1, 1], [3, 3], [7, 7], [5, 5], [11, 5], [-1, 5], [9, 9.5], [3, 7]])
    assert b.contains(uv).tolist() == [True, False, False, True, False, False, True, True]
    assert b.contains(np.array([5.0, 5.0])).tolist() == [True]  # a single (u, v) is one row
    lo, hi = b.bounds()
    assert np.array_equal(lo, [0, 0]) and np.array_equal(hi, [10, 10])


def test_boundary_dict_round_trip():
    b = Boundary(rect(-0.5, 0.25, 0.1, 0.7), (rect(0, 0.1, 0.2, 0.3),))
    d = json.loads(json.dumps(b.to_dict()))
    b2 = Boundary.from_dict(d)
    assert np.allclose(b2.outer_uv, b.outer_uv, atol=1e-9)
    assert len(b2.holes_uv) == 1 and np.allclose(b2.holes_uv[0], b.holes_uv[0], atol=1e-9)
    assert Boundary.from_dict({"outer_uv": rect(0, 1, 0, 1).tolist()}).holes_uv == ()


# -- PlaneSurface -----------------------------------------------------------------
def test_plane_points_lie_on_the_plane_at_the_right_place():
    s = tilted_plane()
    u = np.array([0.0, 10.0, -25.0, 130.0])
    v = np.array([0.0, 3.0, 70.0, -8.0])
    p = s.point_mm(u, v)
    assert p.shape == (4, 3)
    assert np.allclose(p @ s.normal, s.offset_mm, atol=1e-9)
    for k in range(4):  # p = origin + u * u_axis + v * v_axis, written out
        assert np.allclose(p[k], s.origin_mm + u[k] * s.u_axis + v[k] * s.v_axis, atol=1e-12)
    assert np.linalg.norm(p[1] - p[0]) == pytest.approx(np.hypot(10.0, 3.0))  # u, v are mm
    assert s.offset_mm == pytest.approx(float(s.normal @ [100.0, -50.0, 30.0]))


def test_plane_uv_round_trip_and_projection():
    s = tilted_plane()
    rng = np.random.default_rng(0)
    uv = rng.uniform(-300, 300, (50, 2))
    p = s.point_mm(uv[:, 0], uv[:, 1])
    assert np.allclose(s.uv_from_points(p), uv, atol=1e-9)
    lifted = p + 12.5 * s.normal  # off the plane: uv is the foot of the perpendicular
    assert np.allclose(s.uv_from_points(lifted), uv, atol=1e-9)


def test_plane_normal_and_metric_scale_shapes():
    s = tilted_plane()
    n = s.normal_at(np.zeros((2, 3)), 1.0)
    assert n.shape == (2, 3, 3) and np.allclose(n, s.normal)
    n[0, 0] = 0  # a copy: the surface keeps its normal
    assert np.linalg.norm(s.normal) == pytest.approx(1.0)
    assert np.array_equal(s.metric_scale(np.zeros((5, 2))), np.ones((5, 2)))
    assert s.model == "plane" and s.uv_unit == "mm"


# -- SpherePatch ------------------------------------------------------------------
def test_sphere_points_on_the_sphere_with_radial_normals():
    s = sphere_patch()
    rng = np.random.default_rng(1)
    u = rng.uniform(-1, 1, 40)
    v = rng.uniform(-1.2, 1.2, 40)
    p = s.point_mm(u, v)
    assert np.allclose(np.linalg.norm(p - s.center_mm, axis=1), s.radius_mm, atol=1e-9)
    n = s.normal_at(u, v)
    assert np.allclose(n, (p - s.center_mm) / s.radius_mm, atol=1e-12)
    e1, e2, e3 = s.frame.T
    k = 7  # the formula of the module doc, for one point
    expected = s.center_mm + s.radius_mm * (np.cos(v[k]) * np.cos(u[k]) * e1 + np.cos(v[k]) * np.sin(u[k]) * e2
                                            + np.sin(v[k]) * e3)
    assert np.allclose(p[k], expected, atol=1e-9)


def test_sphere_landmarks():
    s = sphere_patch()
    e1, e2, e3 = s.frame.T
    assert np.allclose(s.point_mm(0.0, 0.0), s.center_mm + 600 * e1, atol=1e-9)
    assert np.allclose(s.point_mm(np.pi / 2, 0.0), s.center_mm + 600 * e2, atol=1e-9)
    assert np.allclose(s.point_mm(0.3, np.pi / 2), s.center_mm + 600 * e3, atol=1e-9)
    assert np.allclose(s.normal_at(np.pi, 0.0), -e1, atol=1e-12)


def test_sphere_uv_round_trip_at_any_distance_from_the_centre():
    s = sphere_patch()
    rng = np.random.default_rng(2)
    uv = np.column_stack([rng.uniform(-3.0, 3.0, 60), rng.uniform(-1.4, 1.4, 60)])
    p = s.point_mm(uv[:, 0], uv[:, 1])
    assert np.allclose(s.uv_from_points(p), uv, atol=1e-10)
    # a point 30 mm outside along the normal has the same (u, v)
    assert np.allclose(s.uv_from_points(p + 30 * s.normal_at(uv[:, 0], uv[:, 1])), uv, atol=1e-10)


def test_sphere_metric_scale_is_the_length_of_the_tangents():
    s = sphere_patch()
    uv = np.array([[0.1, -0.2], [-0.5, 0.9], [0.0, 1.3]])
    h = 1e-6
    du = (s.point_mm(uv[:, 0] + h, uv[:, 1]) - s.point_mm(uv[:, 0] - h, uv[:, 1])) / (2 * h)
    dv = (s.point_mm(uv[:, 0], uv[:, 1] + h) - s.point_mm(uv[:, 0], uv[:, 1] - h)) / (2 * h)
    fd = np.column_stack([np.linalg.norm(du, axis=1), np.linalg.norm(dv, axis=1)])
    assert np.allclose(s.metric_scale(uv), fd, rtol=1e-6)
    assert np.allclose(s.metric_scale(uv)[:, 0], 600 * np.cos(uv[:, 1]))
    assert s.model == "sphere" and s.uv_unit == "rad"


# -- dicts and files --------------------------------------------------------------
def assert_same_surface(a, b):
    assert type(a) is type(b)
    if isinstance(a, PlaneSurface):
        for f in ("origin_mm", "normal", "u_axis", "v_axis"):
            assert np.array_equal(getattr(a, f), getattr(b, f)), f
    else:
        assert np.array_equal(a.center_mm, b.center_mm) and a.radius_mm == b.radius_mm
        assert np.array_equal(a.frame, b.frame)
    assert np.allclose(a.boundary.outer_uv, b.boundary.outer_uv, atol=1e-9)
    assert len(a.boundary.holes_uv) == len(b.boundary.holes_uv)
    for ha, hb in zip(a.boundary.holes_uv, b.boundary.holes_uv):
        assert np.allclose(ha, hb, atol=1e-9)
    assert a.stats == b.stats


STATS = FitStats(0.875, 0.12, 0.49, 20000, 17500)


@pytest.mark.parametrize("make", [tilted_plane, sphere_patch])
@pytest.mark.parametrize("stats", [None, STATS])
def test_dict_round_trip(make, stats):
    s = make(stats)
    d = json.loads(json.dumps(s.to_dict()))
    assert d["model"] == s.model and d["uv_unit"] == s.uv_unit
    assert ("inlier_ratio" in d) == (stats is not None)
    assert_same_surface(surface_from_dict(d), s)


def test_plane_dict_offset_is_consistent():
    d = tilted_plane().to_dict()
    assert d["offset_mm"] == pytest.approx(np.dot(d["normal"], d["origin_mm"]))


@pytest.mark.parametrize("make", [tilted_plane, sphere_patch])
def test_save_and_load_surface(tmp_path, make):
    s = make(STATS)
    f = tmp_path / "deep" / "er" / "surface.json"  # the folder is created
    save_surface(s, f)
    d = json.loads(f.read_text())
    assert d["format"] == SURFACE_FORMAT and d["version"] == SURFACE_VERSION
    loaded = load_surface(f)
    assert_same_surface(loaded, s)
    # the loaded surface evaluates like the original
    uv = np.array([[10.0, 20.0]]) if s.model == "plane" else np.array([[0.2, 0.3]])
    assert np.allclose(loaded.point_mm(uv[:, 0], uv[:, 1]), s.point_mm(uv[:, 0], uv[:, 1]), atol=1e-9)


def test_load_surface_without_version_key(tmp_path):
    f = tmp_path / "old.json"
    f.write_text(json.dumps(tilted_plane().to_dict()))
    assert_same_surface(load_surface(f), tilted_plane())


def test_load_surface_errors_are_bad_input(tmp_path):
    with pytest.raises(BadInput, match="not found"):
        load_surface(tmp_path / "missing.json")
    newer = tmp_path / "newer.json"
    newer.write_text(json.dumps({"format": SURFACE_FORMAT, "version": SURFACE_VERSION + 1,
                                 **tilted_plane().to_dict()}))
    with pytest.raises(BadInput, match="version"):
        load_surface(newer)
    junk = tmp_path / "junk.json"
    junk.write_text("{not json")
    with pytest.raises(BadInput, match="not a camtool surface file"):
        load_surface(junk)
    array = tmp_path / "array.json"
    array.write_text("[1, 2, 3]")
    with pytest.raises(BadInput):
        load_surface(array)
    missing_key = tmp_path / "nokey.json"
    d = tilted_plane().to_dict()
    del d["u_axis"]
    missing_key.write_text(json.dumps(d))
    with pytest.raises(BadInput, match="not a camtool surface file"):
        load_surface(missing_key)
    with pytest.raises(BadInput):
        load_surface(tmp_path)  # a folder


def test_unknown_model_is_bad_input():
    d = tilted_plane().to_dict()
    d["model"] = "cone"
    with pytest.raises(BadInput, match="cone"):
        surface_from_dict(d)


def test_save_surface_onto_a_folder_is_bad_input(tmp_path):
    with pytest.raises(BadInput):
        save_surface(tilted_plane(), tmp_path)


def _cylinder():
    from camtool.part.surface import Cylinder

    frame = np.array([[0.0, 0, 1], [0, -1.0, 0], [1.0, 0, 0]]).T
    return Cylinder(np.array([10.0, 20, 30]), 120.0, frame,
                    Boundary(np.array([[-1.5, -150], [1.5, -150], [1.5, 150], [-1.5, 150]])), None, True)


def test_cylinder_points_normals_uv_and_metric():
    c = _cylinder()
    assert c.model == "cylinder" and c.uv_unit == "rad,mm" and np.allclose(c.axis, [1, 0, 0])
    uv = np.array([[0.3, -20.0], [-1.2, 140.0]])
    p = c.point_mm(uv[:, 0], uv[:, 1])
    d = p - c.center_mm
    assert np.allclose(np.hypot(d[:, 1], d[:, 2]), 120.0) and np.allclose(d[:, 0], uv[:, 1])
    assert np.allclose(c.uv_from_points(p), uv)
    n = c.normal_at(uv[:, 0], uv[:, 1])
    radial = d.copy()
    radial[:, 0] = 0
    assert np.allclose(n, -radial / 120.0)  # concave: towards the axis
    assert np.allclose(c.metric_scale(uv), [[120.0, 1.0], [120.0, 1.0]])


def test_cylinder_round_trip_and_bad_frame(tmp_path):
    c = _cylinder()
    save_surface(c, tmp_path / "c.json")
    back = load_surface(tmp_path / "c.json")
    assert back.to_dict() == c.to_dict() and back.concave
    d = c.to_dict()
    d["frame"] = [[1, 0, 0], [1, 0, 0], [0, 0, 1]]
    with pytest.raises(ValueError):
        surface_from_dict(d)


def test_a_surface_file_that_is_a_fifo_or_a_bad_face_set_is_refused_without_blocking(tmp_path):
    import os

    fifo = tmp_path / "surface.json"
    os.mkfifo(fifo)
    with pytest.raises(BadInput, match="FIFO"):
        load_surface(fifo)  # no writer: reading it would block for ever
    bad = tmp_path / "faces.json"
    bad.write_text('{"model": "faces", "indices": [0, 1], "raster_changes": [{}, {"bogus": 1}], "faces": []}')
    with pytest.raises(BadInput, match="not a camtool surface file"):
        load_surface(bad)
