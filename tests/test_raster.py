"""Tests of camtool.path.raster: rows, pitch, segments, zones, orientation, coverage, bad input."""
import math

import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.path.raster import (
    APPROACH_POINTS,
    _row_offsets,
    coverage,
    count_rows,
    coverage_radius_mm,
    raster_path,
    raster_summary,
)
from camtool.part.surface import Boundary, PlaneSurface, SpherePatch
from camtool.run.stage_files import load_stage as load_path, save_stage as save_path
from camtool.path.toolpath import ZONE_CODE, Path
from camtool.settings import RasterSettings

WORK, SELF = ZONE_CODE["work"], ZONE_CODE["self_motion"]
LEAD_IN, LEAD_OUT = ZONE_CODE["lead_in"], ZONE_CODE["lead_out"]


def rect(u0, u1, v0, v1):
    return np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]], float)


@pytest.fixture(scope="module")
def sphere():
    """The seed patch: R 600 at (1000, 0, 100), az -40..40, el -10..60 deg, facing -x."""
    frame = np.array([[-1.0, 0, 0], [0, -1.0, 0], [0, 0, 1.0]]).T  # columns e1, e2, e3
    assert np.isclose(np.linalg.det(frame), 1.0)
    return SpherePatch(np.array([1000.0, 0, 100]), 600.0, frame, Boundary(np.radians(rect(-40, 40, -10, 60))))


@pytest.fixture(scope="module")
def plate():
    """A 400 x 300 mm plate (normal +z) with a 60 x 60 mm square hole."""
    return PlaneSurface(np.zeros(3), np.array([0, 0, 1.0]), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]),
                        Boundary(rect(0, 400, 0, 300), (rect(170, 230, 120, 180),)))


@pytest.fixture(scope="module")
def sphere_path(sphere):
    return raster_path(sphere, RasterSettings.make(edge_margin=0.0))   # the seed paper's raster


def work_segments(path):
    """List of (N_i x 3) work positions per segment, in path order."""
    w = path.is_work
    p = path.poses_mm[:, :3, 3]
    return [p[w & (path.segment == i)] for i in np.unique(path.segment[w])]


def spacings(path):
    return np.concatenate([np.linalg.norm(np.diff(s, axis=0), axis=1) for s in work_segments(path)])


# ------------------------------------------------------------------ rows, pitch, step-over


def test_pitch_within_5_percent_on_sphere_and_plane(sphere, plate):
    for surf, kw in ((sphere, {}), (sphere, {"angle_deg": 30}), (plate, {}), (plate, {"pitch_mm": 3.7})):
        path = raster_path(surf, RasterSettings.make(**kw))
        d = spacings(path)
        pitch = kw.get("pitch_mm", 5.0)
        assert np.all(np.abs(d - pitch) <= 0.05 * pitch), (kw, d.min(), d.max())


def test_sphere_rows_are_constant_elevation_and_geodesic_step(sphere, sphere_path):
    elev = []
    for seg in work_segments(sphere_path):
        v = sphere.uv_from_points(seg)[:, 1]
        assert np.ptp(v) < 1e-9  # angle 0: one row = one elevation
        elev.append(v[0])
    gaps_mm = np.diff(elev) * sphere.radius_mm  # geodesic distance between rows
    assert np.allclose(gaps_mm, 10.0, atol=1e-6)
    # centred: the first and last rows are at most half a step-over inside the edge
    lo, hi = np.radians([-10, 60])
    assert 0 < (elev[0] - lo) * 600 <= 5.0 + 1e-9 and 0 < (hi - elev[-1]) * 600 <= 5.0 + 1e-9
    assert abs((elev[0] - lo) - (hi - elev[-1])) < 1e-9


@pytest.mark.parametrize("width_mm, rows, gap_mm, margin_mm", [
    (150.0, 15, 10.0, 5.0),           # whole steps: centred, half a step from each edge
    (151.4, 16, 146.4 / 15, 2.5),     # 0.7 mm margins centred: drawn closer, a quarter step kept
    (156.0, 16, 10.0, 3.0),           # 3 mm margins: enough, centred
])
def test_rows_keep_a_margin_from_the_edges(width_mm, rows, gap_mm, margin_mm):
    """``raster.edge_margin`` (a quarter step by default): rows centred step_over_mm apart that would come
    nearer an edge are drawn closer together, never farther apart; the paper's raster (0) keeps 10 mm."""
    offsets = _row_offsets(0.0, width_mm, 10.0, 0.25)
    assert len(offsets) == rows
    assert np.allclose(np.diff(offsets), gap_mm) and np.diff(offsets).max() <= 10.0 + 1e-9
    assert np.isclose(offsets[0], margin_mm) and np.isclose(width_mm - offsets[-1], margin_mm)
    assert np.allclose(np.diff(_row_offsets(0.0, width_mm, 10.0, 0.0)), 10.0)


def test_plane_step_over_at_an_angle(plate):
    path = raster_path(plate, RasterSettings.make(angle_deg=30))
    across = np.array([-math.sin(math.radians(30)), math.cos(math.radians(30)), 0])
    t = np.unique(np.round(path.poses_mm[path.is_work, :3, 3] @ across, 6))
    assert np.allclose(np.diff(t), 10.0, atol=1e-6)


def test_seed_sphere_gives_about_10k_points(sphere_path):
    s = raster_summary(sphere_path)
    assert 9000 <= s["work_points"] <= 11500
    assert s["rows"] == s["segments"] == math.ceil(600 * math.radians(70) / 10)


def test_boustrophedon_order(sphere, sphere_path):
    segs = work_segments(sphere_path)
    for k, seg in enumerate(segs):
        u = sphere.uv_from_points(seg)[:, 0]
        du = np.diff(u)
        assert np.all(du > 0) if k % 2 == 0 else np.all(du < 0)
    # consecutive rows end and start on the same side of the patch
    for a, b in zip(segs[:-1], segs[1:]):
        assert np.linalg.norm(a[-1] - b[0]) < 30


def test_hole_splits_rows_and_has_no_work_points(plate):
    path = raster_path(plate, RasterSettings.make())
    w = path.poses_mm[path.is_work, :3, 3]
    uv = plate.uv_from_points(w)
    assert np.all(plate.boundary.contains(uv))
    in_hole = (uv[:, 0] > 170) & (uv[:, 0] < 230) & (uv[:, 1] > 120) & (uv[:, 1] < 180)
    assert not in_hole.any()
    s = raster_summary(path)
    rows_through_hole = np.count_nonzero((np.arange(30) * 10 + 5 > 120) & (np.arange(30) * 10 + 5 < 180))
    assert s["rows"] == 30 and s["segments"] == 30 + rows_through_hole
    # a split row: both segments travel the same way, separated by the hole
    segs = work_segments(path)
    ys = [seg[0, 1] for seg in segs]
    split = [i for i in range(len(ys) - 1) if ys[i] == ys[i + 1]]
    assert len(split) == rows_through_hole
    a, b = segs[split[0]], segs[split[0] + 1]
    assert (a[-1, 0] - 170) * (b[0, 0] - 230) < 0 or (a[-1, 0] - 230) * (b[0, 0] - 170) < 0
    assert np.sign(a[1, 0] - a[0, 0]) == np.sign(b[1, 0] - b[0, 0])


# ------------------------------------------------------------------ zones and indices


def test_zone_labels_and_indices(sphere_path):
    p = sphere_path
    n = len(p)
    assert p.segment.shape == p.point.shape == p.zone.shape == (n,)
    names = p.zone_names()
    assert names[:APPROACH_POINTS] == ["approach"] * APPROACH_POINTS
    assert names[-APPROACH_POINTS:] == ["depart"] * APPROACH_POINTS
    assert np.all(p.segment[:APPROACH_POINTS] == 0)
    assert np.all(p.segment[-APPROACH_POINTS:] == p.segment.max())
    assert np.all(np.diff(p.segment) >= 0)  # segments in path order
    assert np.all(p.point[~p.is_work] == 0)
    n_seg = p.segment.max() + 1
    for i in range(n_seg):
        sel = p.segment == i
        z = p.zone[sel]
        j = p.point[sel & p.is_work]
        assert np.array_equal(j, np.arange(1, len(j) + 1))  # j = 1..c_i
        seq = [ZONE_CODE[k] for k in ("lead_in", "work", "lead_out")]
        core = z[np.isin(z, seq)]
        # lead-in poses, then work, then lead-out, 4 each (20 mm / 5 mm)
        assert np.array_equal(core, np.repeat(seq, [4, len(j), 4]))
        if i > 0:  # the transition into segment i carries index i and comes first
            assert np.array_equal(z[:5], [SELF] * 5)
    assert np.count_nonzero(p.zone == SELF) == 5 * (n_seg - 1)


def test_leads_continue_along_the_surface_and_lift(sphere):
    path = raster_path(sphere, RasterSettings.make(lead_mm=20, clearance_mm=8, transition_points=4))
    p = path.poses_mm[:, :3, 3]
    dist = np.linalg.norm(p - sphere.center_mm, axis=1) - sphere.radius_mm  # height over the sphere
    assert np.allclose(dist[path.is_work], 0, atol=1e-6)
    i = 3
    sel = np.flatnonzero(path.segment == i)
    lo = sel[path.zone[sel] == LEAD_OUT]
    work = sel[path.zone[sel] == WORK]
    # rise to the clearance as the cube of the distance from the work: tangent to the surface at the work
    assert np.allclose(dist[lo], 8 * (np.arange(1, 5) / 4) ** 3, atol=1e-6)
    # along the row: the last lead-out is 20 mm of arc beyond the last work point, same elevation
    uv = sphere.uv_from_points(p[[work[-1], lo[-1]]])
    assert abs(uv[0, 1] - uv[1, 1]) < 1e-9
    arc = abs(uv[1, 0] - uv[0, 0]) * 600 * math.cos(uv[0, 1])
    assert arc == pytest.approx(20.0, rel=1e-3)
    # the self-motion zone keeps the clearance and is interpolated by slerp
    tr = np.flatnonzero((path.zone == SELF) & (path.segment == i + 1))
    assert len(tr) == 4 and np.allclose(dist[tr], 8, atol=1e-6)
    from camtool.transforms import rotation_angle_rad
    Ra, Rb = path.poses_mm[tr[0] - 1, :3, :3], path.poses_mm[tr[-1] + 1, :3, :3]
    total = rotation_angle_rad(Ra, Rb)
    for k, idx in enumerate(tr, start=1):
        assert rotation_angle_rad(Ra, path.poses_mm[idx, :3, :3]) == pytest.approx(total * k / 5, abs=1e-9)


def _leads_and_ends(path):
    """(lead pose indices, the work pose each lead leaves from) of a path, rows' blocks in path order."""
    leads, ends = [], []
    for i in np.unique(path.segment):
        sel = np.flatnonzero((path.segment == i) & np.isin(path.zone, (LEAD_IN, WORK, LEAD_OUT)))
        work = sel[path.zone[sel] == WORK]
        for zone, end in ((LEAD_IN, work[0]), (LEAD_OUT, work[-1])):
            k = sel[path.zone[sel] == zone]
            leads.append(k)
            ends.append(np.full(len(k), end))
    return np.concatenate(leads), np.concatenate(ends)


def test_tangent_leads_rise_off_a_convex_face_to_clear_the_rows_tangent(sphere):
    """raster.lead_path = "tangent": each lead of a face convex along its row rises off the surface continued, as
    the cube of its distance from the work (no jump in curvature at the work's end), just enough that no lead pose
    is below the row's tangent plane at the work's end (a neighbour going on tangentially); work, orientation and
    the zones are as with "surface"."""
    keys = dict(lead_mm=20, transition_points=4)
    surf = raster_path(sphere, RasterSettings.make(**keys, lead_path="surface"))
    tan = raster_path(sphere, RasterSettings.make(**keys, lead_path="tangent"))
    assert np.array_equal(surf.zone, tan.zone) and np.array_equal(surf.poses_mm[:, :3, :3], tan.poses_mm[:, :3, :3])
    w = tan.is_work
    assert np.array_equal(tan.poses_mm[w], surf.poses_mm[w])
    leads, ends = _leads_and_ends(tan)
    P, E = tan.poses_mm[leads, :3, 3], tan.poses_mm[ends]
    above = np.einsum("ij,ij->i", P - E[:, :3, 3], -E[:, :3, 2])      # over the work end's tangent plane (z = -n)
    assert above.min() > -1e-5 and np.isclose(above, 0.0, atol=1e-5).any()   # (the lift is along the pose's normal)
    height = np.linalg.norm(P - sphere.center_mm, axis=1) - sphere.radius_mm   # the lift over the sphere
    h_surf = np.linalg.norm(surf.poses_mm[leads, :3, 3] - sphere.center_mm, axis=1) - sphere.radius_mm
    assert np.allclose(h_surf, 0.0, atol=1e-6) and height.max() > 1.0
    # a cubic ramp: along one lead-out, lift / (k / n)^3 is one constant
    sel = np.flatnonzero((tan.segment == 3) & (tan.zone == LEAD_OUT))
    ramp = height[np.searchsorted(leads, sel)] / (np.arange(1, len(sel) + 1) / len(sel)) ** 3
    assert np.allclose(ramp, ramp[0], rtol=1e-6)


def test_tangent_leads_stay_on_a_plane_and_a_concave_face(plate, sphere):
    """On a plane the tangent is the surface; on a concave face the tangent runs into the face's own material,
    and its leads stay on the surface continued."""
    keys = dict(lead_mm=20, transition_points=4)
    for surface in (plate, SpherePatch(sphere.center_mm, sphere.radius_mm, sphere.frame, sphere.boundary,
                                       concave=True)):
        a = raster_path(surface, RasterSettings.make(**keys, lead_path="surface"))
        b = raster_path(surface, RasterSettings.make(**keys, lead_path="tangent"))
        assert np.array_equal(a.poses_mm, b.poses_mm)


def test_approach_and_depart_back_off_along_normal(sphere):
    path = raster_path(sphere, RasterSettings.make(clearance_mm=4))
    p = path.poses_mm[:, :3, 3]
    first = APPROACH_POINTS
    n0 = -path.poses_mm[first, :3, 2]
    assert np.allclose(p[:first] - p[first], np.outer([10, 20 / 3, 10 / 3], n0), atol=1e-9)
    assert np.linalg.norm(p[-1] - p[-1 - APPROACH_POINTS]) == pytest.approx(10.0)


def test_no_leads_when_lead_is_zero(plate):
    path = raster_path(plate, RasterSettings.make(lead_mm=0))
    assert not np.isin(path.zone, [LEAD_IN, LEAD_OUT]).any()
    assert np.count_nonzero(path.zone == SELF) == 5 * path.segment.max()


# ------------------------------------------------------------------ orientation


def test_tool_z_is_minus_normal(sphere, sphere_path):
    w = sphere_path.is_work
    pos = sphere_path.poses_mm[w, :3, 3]
    n = (pos - sphere.center_mm) / sphere.radius_mm
    assert np.allclose(sphere_path.poses_mm[w, :3, 2], -n, atol=1e-9)
    R = sphere_path.poses_mm[:, :3, :3]
    assert np.allclose(np.einsum("nji,njk->nik", R, R), np.eye(3), atol=1e-9)
    assert np.allclose(np.linalg.det(R), 1.0)


def test_fixed_tool_x_does_not_flip_between_rows(sphere, sphere_path):
    x = sphere_path.poses_mm[sphere_path.is_work, :3, 0]
    assert np.all(x[:, 2] > 0)  # follows world +z projected onto the surface
    assert np.min(np.sum(x[1:] * x[:-1], axis=1)) > 0.9  # no 180 deg spin anywhere
    travel = raster_path(sphere, RasterSettings.make(tool_x="travel"))
    segs = [travel.poses_mm[travel.is_work & (travel.segment == i), :3, 0] for i in (0, 1)]
    assert np.dot(segs[0][-1], segs[1][0]) < -0.9  # travel-following x reverses with the row
    d = np.diff(travel.poses_mm[travel.is_work & (travel.segment == 0), :3, 3], axis=0)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    assert np.all(np.sum(d * segs[0][:-1], axis=1) > 0.999)


def test_fixed_tool_x_parallel_to_normal_falls_back(plate):
    path = raster_path(plate, RasterSettings.make(tool_x_world=(0, 0, 1)))  # the plate normal is +z
    x = path.poses_mm[:, :3, 0]
    assert np.allclose(x, x[0]) and abs(x[0, 2]) < 1e-12
    assert np.allclose(path.poses_mm[:, :3, 2], [0, 0, -1])


def test_lead_and_tilt_angles(plate):
    base = raster_path(plate, RasterSettings.make(tool_x="travel"))
    for lead, tilt in ((15.0, 0.0), (0.0, -20.0), (10.0, 5.0)):
        p = raster_path(plate, RasterSettings.make(tool_x="travel", lead_deg=lead, tilt_deg=tilt))
        w = p.is_work
        assert np.allclose(p.poses_mm[:, :3, 3], base.poses_mm[:, :3, 3])  # the TCP stays put
        d = base.poses_mm[w, :3, 0]  # travel direction
        side = np.cross(d, [0, 0, 1])
        z = p.poses_mm[w, :3, 2]
        assert np.allclose(z @ [0, 0, -1], math.cos(math.radians(lead)) * math.cos(math.radians(tilt)))
        assert np.allclose(np.sum(z * d, axis=1), math.sin(math.radians(lead)))
        assert np.allclose(np.sum(z * side, axis=1), -math.sin(math.radians(tilt)) * math.cos(math.radians(lead)))


def test_free_spin_flag_and_npz_round_trip(sphere, tmp_path):
    path = raster_path(sphere, RasterSettings.make(step_over_mm=20, free_spin=True, lead_deg=5))
    assert path.free_spin and not raster_path(sphere, RasterSettings.make(step_over_mm=20)).free_spin
    f = tmp_path / "p.npz"
    save_path(path, f)
    back = load_path(f)
    assert isinstance(back, Path) and back.free_spin
    for name in ("poses_mm", "segment", "point", "zone"):
        assert np.array_equal(getattr(back, name), getattr(path, name))
    assert back.step_over_mm == 20 and back.pitch_mm == 5


def test_deterministic(sphere):
    a, b = raster_path(sphere, RasterSettings.make(angle_deg=17)), raster_path(sphere, RasterSettings.make(angle_deg=17))
    assert np.array_equal(a.poses_mm, b.poses_mm)


# ------------------------------------------------------------------ coverage


def test_coverage_seed_patch_and_plate(sphere, sphere_path, plate):
    assert coverage(sphere, sphere_path, 10.0) >= 0.995
    assert coverage(sphere, raster_path(sphere, RasterSettings.make(angle_deg=45)), 10.0) >= 0.995
    assert coverage(plate, raster_path(plate, RasterSettings.make()), 10.0) >= 0.995
    assert coverage(plate, raster_path(plate, RasterSettings.make(angle_deg=30, pitch_mm=4)), 10.0) >= 0.995


def test_coverage_detects_a_missing_row(plate):
    path = raster_path(plate, RasterSettings.make(lead_mm=0))
    keep = path.segment != 10  # drop one segment (a whole row below the hole)
    holed = Path(path.poses_mm[keep], path.segment[keep], path.point[keep], path.zone[keep],
                 path.free_spin, path.step_over_mm, path.pitch_mm)
    full, gap = coverage(plate, path, 10.0), coverage(plate, holed, 10.0)
    assert full >= 0.995 and gap < 0.995
    # a too-wide step-over, measured against the nominal one, loses coverage too
    assert coverage(plate, raster_path(plate, RasterSettings.make(step_over_mm=14)), 10.0) < 0.99


def test_coverage_radius():
    assert coverage_radius_mm(10, 5) == pytest.approx(0.5 * math.hypot(10, 5) + 0.2)


def test_summary(sphere, sphere_path):
    s = raster_summary(sphere_path, sphere, grid=200)
    assert s["work_points"] + s["zone_points"] == len(sphere_path)
    assert s["path_length_mm"] == pytest.approx(sphere_path.length_mm(), abs=1e-3)
    assert s["coverage"] >= 0.995 and s["rows"] == count_rows(sphere_path)
    assert s["zone_counts"]["approach"] == APPROACH_POINTS


def test_dense_variant_size(sphere):
    path = raster_path(sphere, RasterSettings.make(step_over_mm=2, pitch_mm=2))
    assert 120_000 <= np.count_nonzero(path.is_work) <= 140_000


# ------------------------------------------------------------------ bad input


@pytest.mark.parametrize("kw, words", [
    ({"step_over_mm": 0}, "step_over_mm"),
    ({"step_over_mm": -5}, "step_over_mm"),
    ({"step_over_mm": 2000}, "larger than the patch"),
    ({"pitch_mm": 0}, "pitch_mm"),
    ({"pitch_mm": -1}, "pitch_mm"),
    ({"lead_mm": -1}, "lead_mm"),
    ({"tilt_deg": 90}, "tilt_deg"),
    ({"tilt_deg": -89.5}, "tilt_deg"),
    ({"lead_deg": 95}, "lead_deg"),
    ({"clearance_mm": -2}, "clearance_mm"),
    ({"transition_points": 1}, "transition_points"),
    ({"tool_x": "sideways"}, "tool_x"),
    ({"tool_x_world": (0, 0, 0)}, "tool_x_world"),
    ({"pitch_mm": float("nan")}, "pitch_mm"),
    ({"step_over_mm": 0.01, "pitch_mm": 0.01}, "0.1..10000"),
    ({"step_over_mm": 0.1, "pitch_mm": 0.1}, "coarser"),
])
def test_bad_arguments(sphere, kw, words):
    with pytest.raises(BadInput, match=words) as exc:
        raster_path(sphere, RasterSettings.make(**kw))
    assert "\n" not in str(exc.value)


def test_empty_boundary(sphere):
    for outer in (np.zeros((0, 2)), rect(0, 1, 0, 1)[:2], np.array([[0, 0], [1, 1], [2, 2.0]])):
        surf = SpherePatch(sphere.center_mm, 600.0, sphere.frame, Boundary(outer))
        with pytest.raises(BadInput, match="empty"):
            raster_path(surf, RasterSettings.make())


def test_hole_covering_everything_is_empty(plate):
    surf = PlaneSurface(plate.origin_mm, plate.normal, plate.u_axis, plate.v_axis,
                        Boundary(rect(0, 100, 0, 100), (rect(-10, 110, -10, 110),)))
    with pytest.raises(BadInput, match="no material"):
        raster_path(surf, RasterSettings.make())


# ------------------------------------------------------------------ cylinders


@pytest.fixture(scope="module")
def pipe():
    """The outside of half a pipe: R 120 mm, axis along world x, u -90..90 deg about +z, v -150..150 mm."""
    from camtool.part.surface import Cylinder

    frame = np.array([[0.0, 0, 1], [0, -1.0, 0], [1.0, 0, 0]]).T  # e1 = +z (the middle), e2 = -y, e3 = +x
    return Cylinder(np.zeros(3), 120.0, frame, Boundary(np.array([[-math.pi / 2, -150], [math.pi / 2, -150],
                                                                  [math.pi / 2, 150], [-math.pi / 2, 150]])))


@pytest.mark.parametrize("rows", ["around", "along"])
def test_cylinder_rows_around_or_along_the_axis_geodesic_step(pipe, rows):
    path = raster_path(pipe, RasterSettings.make(step_over_mm=15, pitch_mm=5, lead_mm=0, cylinder_rows=rows,
                                                 edge_margin=0.0))
    segs = work_segments(path)
    for s in segs:
        r = np.hypot(s[:, 1], s[:, 2])
        assert np.allclose(r, 120.0, atol=1e-6)  # on the surface
        if rows == "around":
            assert np.ptp(s[:, 0]) < 1e-6  # a circle round the axis: constant x
        else:
            assert np.ptp(np.arctan2(s[:, 1], s[:, 2])) < 1e-9  # a line along the axis: constant angle
    # neighbouring rows are exactly one step-over apart on the surface (arc length round the axis, or along it)
    firsts = np.array([s[0] for s in segs])
    if rows == "around":
        gaps = np.diff(np.sort(firsts[:, 0]))
    else:
        ang = np.sort(np.arctan2(firsts[:, 1], firsts[:, 2]))
        gaps = 120.0 * np.diff(ang)
    assert np.allclose(gaps, 15.0, atol=1e-6)
    assert np.allclose(spacings(path), 5.0, rtol=0.05)
    assert coverage(pipe, path, 15.0) >= 0.995


def test_cylinder_tool_axis_radial_outside_and_inside(pipe):
    from camtool.part.surface import Cylinder

    for concave in (False, True):
        cyl = Cylinder(pipe.center_mm, pipe.radius_mm, pipe.frame, pipe.boundary, None, concave)
        path = raster_path(cyl, RasterSettings.make(step_over_mm=20, pitch_mm=10))
        w = path.poses_mm[path.is_work]
        radial = w[:, :3, 3].copy()
        radial[:, 0] = 0.0
        radial /= np.linalg.norm(radial, axis=1)[:, None]
        # tool z = -normal: into the material, towards the axis outside, away from it inside
        expect = -radial if not concave else radial
        assert np.allclose(w[:, :3, 2], expect, atol=1e-9)
