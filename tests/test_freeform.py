"""Free-form faces (camtool.part.freeform): a saddle mesh, a noisy scanned cap, holes, stage files, rows on the
surface. Small generated parts: each test runs in about a second."""
import json
from dataclasses import replace

import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.part.fit import fit_surface
from camtool.part.freeform import FreeformSurface, freeform_surface
from camtool.part.surface import surface_from_dict
from camtool.part.workpiece import Workpiece
from camtool.path.raster import coverage, raster_path
from camtool.settings import FitSettings, RasterSettings

FIT = FitSettings.make(model="freeform")


def grid_mesh(x, y, z_of):
    X, Y = np.meshgrid(x, y)
    Z = z_of(X, Y)
    ny, nx = X.shape
    idx = np.arange(nx * ny).reshape(ny, nx)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    F = np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    return np.stack([X, Y, Z], -1).reshape(-1, 3), F


def mesh_workpiece(V, F, n=40000, seed=0, keep=None):
    import trimesh

    m = trimesh.Trimesh(V, F, process=False)
    if keep is not None:
        m.update_faces(keep(m.triangles_center))
        m.remove_unreferenced_vertices()
    pts, fi = trimesh.sample.sample_surface(m, n, seed=seed)
    return Workpiece(np.asarray(pts), np.asarray(m.face_normals)[fi], np.asarray(m.faces), "mesh.stl", "mm", (),
                     np.asarray(m.vertices)), m


def saddle(X, Y):
    return (X ** 2 - Y ** 2) / 600.0


@pytest.fixture(scope="module")
def saddle_part():
    V, F = grid_mesh(np.linspace(-100, 100, 81), np.linspace(-75, 75, 61), saddle)
    wp, mesh = mesh_workpiece(V, F)
    return wp, mesh, fit_surface(wp, FIT)


def work(path):
    W = path.poses_mm[path.is_work]
    return W[:, :3, 3], W[:, :3, 2]


def row_gaps_mm(surface, path, step):
    """Distance on the part from each work point of row k to row k+1's polyline (rows told apart by v)."""
    from scipy.spatial import cKDTree

    cont = path.contour if path.contour is not None else np.zeros(len(path), bool)
    P = path.poses_mm[path.is_work & ~cont, :3, 3]
    v = surface.uv_from_points(P)[:, 1]
    lab = np.rint((v - v.min()) / step).astype(int)
    gaps = []
    for r in range(lab.max()):
        a, b = P[lab == r], P[lab == r + 1]
        if len(a) == 0 or len(b) < 2:
            continue
        _, ii = cKDTree(b).query(a, k=2)
        p1, p2 = b[ii[:, 0]], b[ii[:, 1]]
        e = p2 - p1
        t = np.clip(np.sum((a - p1) * e, 1) / np.maximum(np.sum(e * e, 1), 1e-12), 0, 1)
        d = np.linalg.norm(a - (p1 + t[:, None] * e), axis=1)
        gaps.append(d[d < 2 * step])
    return np.concatenate(gaps)


def test_saddle_mesh_rows_on_the_surface(saddle_part):
    wp, mesh, s = saddle_part
    assert isinstance(s, FreeformSurface) and s.model == "freeform" and s.source_kind == "mesh"
    path = raster_path(s, RasterSettings.make(step_over_mm=10.0, pitch_mm=5.0))
    tcp, z = work(path)
    # work TCPs on the mesh
    import trimesh

    _, dist, _ = trimesh.proximity.closest_point(mesh, tcp)
    assert np.percentile(dist, 99) < 0.1
    # the step-over measured on the surface, p5..p95 within 10 %
    gaps = row_gaps_mm(s, path, 10.0)
    assert 9.0 <= np.percentile(gaps, 5) and np.percentile(gaps, 95) <= 11.0
    # the tool axis along the true normal, no flip or turn over 5 deg between neighbours
    n = np.stack([-2 * tcp[:, 0] / 600, 2 * tcp[:, 1] / 600, np.ones(len(tcp))], 1)
    n /= np.linalg.norm(n, axis=1)[:, None]
    ang = np.degrees(np.arccos(np.clip(np.sum(-z * n, 1), -1, 1)))
    assert np.percentile(ang, 95) < 3.0
    seg = path.segment[path.is_work]
    turn = np.degrees(np.arccos(np.clip(np.sum(z[1:] * z[:-1], 1), -1, 1)))[seg[1:] == seg[:-1]]
    assert turn.max() < 5.0
    assert coverage(s, path, 10.0) > 0.99


def test_rows_turned_keep_their_step(saddle_part):
    _, _, s = saddle_part
    turned = s.rows_at(np.radians(30.0))
    assert turned is not s and np.allclose(turned.frame[:, 2], s.frame[:, 2])
    path = raster_path(s, RasterSettings.make(step_over_mm=8.0, pitch_mm=4.0, angle_deg=30.0))
    gaps = row_gaps_mm(turned, path, 8.0)
    assert 7.2 <= np.percentile(gaps, 5) and np.percentile(gaps, 95) <= 8.8


def test_steeper_than_a_plane_slicer():
    """A trough 40 deg steep: planes 10 mm apart would put the rows 13 mm apart on its walls; these are 10."""
    V, F = grid_mesh(np.linspace(-80, 80, 65), np.linspace(-60, 60, 49), lambda X, Y: 0.012 * Y ** 2)
    wp, _ = mesh_workpiece(V, F)
    s = fit_surface(wp, FIT)
    path = raster_path(s, RasterSettings.make(step_over_mm=10.0, pitch_mm=5.0))
    gaps = row_gaps_mm(s, path, 10.0)
    assert 9.0 <= np.percentile(gaps, 5) and np.percentile(gaps, 95) <= 11.0
    assert s.curvature_range()[0] < 0  # concave towards the tool: a trough, worked from inside


def test_noisy_scan_smoothed_and_outliers_dropped():
    rng = np.random.default_rng(2)
    R, n = 200.0, 60000
    xy = rng.uniform(-70, 70, (n, 2))
    z = np.sqrt(R ** 2 - (xy ** 2).sum(1)) - R
    P = np.column_stack([xy, z])
    c = np.array([0.0, 0.0, -R])
    N = (P - c) / R
    P = P + N * rng.normal(0, 1.0, n)[:, None]
    out = rng.random(n) < 0.005
    P[out] += N[out] * 20.0
    s = freeform_surface(Workpiece(P, N, source="scan.xyz"), FIT)
    assert s.source_kind == "scan" and s.smoothing_mm >= 2.0
    assert any("outliers" in w for w in s.warnings)
    path = raster_path(s, RasterSettings.make(step_over_mm=10.0, pitch_mm=5.0))
    tcp, z = work(path)
    err = np.abs(np.linalg.norm(tcp - c, axis=1) - R)
    assert np.median(err) < 0.5 and np.percentile(err, 99) < 3.0
    ang = np.degrees(np.arccos(np.clip(np.sum(-z * (tcp - c) / np.linalg.norm(tcp - c, axis=1)[:, None], 1), -1, 1)))
    assert np.percentile(ang, 95) < 3.0
    assert 0.5 < s.stats.rms_mm < 1.5   # the scan's noise, for the motion check's tolerance


def test_holes_split_rows_and_stay_holes():
    V, F = grid_mesh(np.linspace(-100, 100, 81), np.linspace(-80, 80, 65), lambda X, Y: -X ** 2 / 2000.0)
    wp, _ = mesh_workpiece(V, F, keep=lambda c: np.hypot(c[:, 0] - 20, c[:, 1]) > 25)
    s = fit_surface(wp, FIT)
    assert len(s.boundary.holes_uv) == 1
    path = raster_path(s, RasterSettings.make(step_over_mm=10.0, pitch_mm=5.0))
    tcp, _ = work(path)
    assert np.hypot(tcp[:, 0] - 20, tcp[:, 1]).min() > 24.0     # no work point in the hole
    cont = path.contour if path.contour is not None else np.zeros(len(path), bool)
    assert len(np.unique(path.segment[path.is_work & ~cont])) > 17   # rows split at the hole


def test_stage_file_round_trip_rasters_the_same(saddle_part):
    _, _, s = saddle_part
    d = json.loads(json.dumps(s.to_dict()))
    back = surface_from_dict(d)
    assert isinstance(back, FreeformSurface)
    st = RasterSettings.make(step_over_mm=10.0, pitch_mm=5.0)
    a, b = raster_path(s, st), raster_path(back, st)
    assert np.array_equal(a.poses_mm, b.poses_mm)
    d["height"]["data"] = d["height"]["data"][:-8]
    with pytest.raises(ValueError):
        surface_from_dict(d)


def test_a_faces_scan_verdict_is_kept_by_its_stage_file_and_its_turned_rows():
    """``FreeformSurface.from_scan`` (issue #46: one verdict, made with the face) round-trips through the stage file
    and ``rows_at``; a file written before it was kept reads a cloud's face as a scan's, a mesh's as CAD."""
    from test_roughness import _triangulated, sheet

    V = sheet(0.05)
    s = freeform_surface(Workpiece(V, np.tile([0.0, 0, 1], (len(V), 1)), _triangulated(V), "scan.ply", "mm", (), V),
                         FIT)
    assert s.from_scan and s.source_kind == "mesh"
    d = json.loads(json.dumps(s.to_dict()))
    assert surface_from_dict(d).from_scan and s.rows_at(0.3).from_scan
    del d["from_scan"]
    assert not surface_from_dict(d).from_scan
    assert surface_from_dict({**d, "source_kind": "scan"}).from_scan
    with pytest.raises(ValueError):
        surface_from_dict({**d, "from_scan": "yes"})


def test_soup_of_flipped_triangles_warns_and_works():
    V, F = grid_mesh(np.linspace(-60, 60, 31), np.linspace(-50, 50, 26), lambda X, Y: (X ** 2 + Y ** 2) / 800.0)
    F = F.copy()
    F[::2] = F[::2, ::-1]                        # every other triangle wound the other way
    wp, _ = mesh_workpiece(V, F, n=20000)
    s = fit_surface(wp, FIT)
    assert len(s.warnings) == 1 and "do not agree on a side" in s.warnings[0]
    assert s.mean_normal()[2] > 0.99            # worked from world up, normals all on that side
    assert (s.normals[s.material] @ s.frame[:, 2]).min() > 0


def test_points_on_a_line_are_refused():
    P = np.column_stack([np.linspace(0, 100, 500), np.zeros(500), np.zeros(500)])
    with pytest.raises(BadInput, match="line"):
        freeform_surface(Workpiece(P, np.tile([0.0, 0, 1], (500, 1)), source="line.xyz"), FIT)


def _uv_on_face(s, n, rng):
    """Up to ``n`` uniform random parameters inside the face's boundary."""
    lo, hi = s.boundary.bounds()
    uv = rng.uniform(lo, hi, (n, 2))
    return uv[s.boundary.contains(uv)]


def test_uv_round_trip(saddle_part):
    _, _, s = saddle_part
    uv = _uv_on_face(s, 500, np.random.default_rng(0))
    back = s.uv_from_points(s.point_mm(uv[:, 0], uv[:, 1]))
    assert np.abs(back - uv).max() < 0.05
    assert np.allclose(np.linalg.norm(s.normal_at(uv[:, 0], uv[:, 1]), axis=1), 1.0)


def test_points_taken_onto_the_face_lie_on_the_part(saddle_part):
    """project_mm: points off the face come onto it along the chart's normal; against the saddle's own formula."""
    _, mesh, s = saddle_part
    rng = np.random.default_rng(1)
    uv = _uv_on_face(s, 300, rng)
    on = s.point_mm(uv[:, 0], uv[:, 1])
    off = on + rng.uniform(-2.0, 2.0, (len(on), 1)) * s.frame[:, 2]
    got = s.project_mm(off)
    assert np.allclose(got, on, atol=1e-9)       # moved along e3 only, back onto the same height field
    assert np.abs(got[:, 2] - saddle(got[:, 0], got[:, 1])).max() < 0.01


def test_fit_summary_lists_the_face(saddle_part):
    from camtool.commands.fit import surface_summary

    _, _, s = saddle_part
    d = surface_summary(s)
    assert d["model"] == "freeform" and d["holes"] == 0 and d["source"] == "mesh"
    assert 30000 < d["area_mm2"] < 32500                   # 200 x 150 mm, a little more for the saddle's slope
    assert d["rms_mm"] < 0.01 and d["inlier_ratio"] > 0.99  # the mesh's own points lie on it
    lo, hi = d["curvature_range"]
    assert lo < 0 < hi                                       # a saddle curves both ways


def test_leads_run_straight_on_with_the_work_ends_orientation(saddle_part):
    """Issue #46: past a free-form face's edge a lead runs straight along the row's tangent at the work's end (the
    tool's orientation kept), rising along that end's normal by the lead lift (smootherstep, 0 at the work)."""
    from camtool.part.freeform import LEAD_LIFT_MIN_MM
    from camtool.path.toolpath import ZONE_CODE

    _, _, s = saddle_part
    path = raster_path(s, RasterSettings.make(step_over_mm=20.0, pitch_mm=5.0, lead_mm=20.0))
    assert s.lead_band_mm == LEAD_LIFT_MIN_MM   # a mesh: no noise, the least lift
    P = path.poses_mm
    for seg in np.unique(path.segment)[:6]:
        k = np.flatnonzero(path.segment == seg)
        out = k[path.zone[k] == ZONE_CODE["lead_out"]]
        end = k[path.zone[k] == ZONE_CODE["work"]][-1]
        n = -P[end][:3, 2]                                          # the work end's normal
        assert np.abs(P[out][:, :3, :3] - P[end][:3, :3]).max() < 1e-12
        off = P[out][:, :3, 3] - P[end][:3, 3]
        lift = off @ n
        flat = off - lift[:, None] * n                             # in the tangent plane: one straight line
        d = flat / np.linalg.norm(flat, axis=1, keepdims=True)
        assert np.abs(d - d[0]).max() < 1e-9
        assert lift[0] > 0 and np.all(np.diff(lift) > -1e-9) and lift[-1] == pytest.approx(LEAD_LIFT_MIN_MM, abs=1e-9)


def test_transitions_start_and_end_where_the_straight_leads_do():
    """The self-motion between two rows of a free-form face runs from the lead-out's end to the next lead-in's
    start (the leads run straight off the surface: a transition laid between their (u, v) on the surface began
    beside the lead-out and jumped back to the lead-in, a zig-zag the time law's spline cut into the part): its
    first and last steps are one share of the straight span between the leads' ends, lifted by the sine arc."""
    from camtool.path.toolpath import ZONE_CODE

    V, F = grid_mesh(np.linspace(-60, 60, 61), np.linspace(-45, 45, 46), lambda X, Y: (X ** 2 + Y ** 2) / 160.0)
    s = fit_surface(mesh_workpiece(V, F)[0], FIT)               # a bowl curved at R 80 mm: leads 30 mm long
    settings = RasterSettings.make(step_over_mm=15.0, pitch_mm=5.0, lead_mm=30.0)
    path = raster_path(s, settings)
    P = path.poses_mm[:, :3, 3]
    zone = np.asarray(path.zone)
    runs = np.split(np.flatnonzero(zone == ZONE_CODE["self_motion"]),
                    np.flatnonzero(np.diff(np.flatnonzero(zone == ZONE_CODE["self_motion"])) > 1) + 1)
    assert len(runs) > 3
    m = settings.transition_points
    lift = max(settings.clearance_mm, settings.self_motion_lift_mm)
    for k in runs:
        a, b = k[0] - 1, k[-1] + 1
        assert zone[a] == ZONE_CODE["lead_out"] and zone[b] == ZONE_CODE["lead_in"]
        chain = P[np.concatenate([[a], k, [b]])]
        steps = np.linalg.norm(np.diff(chain, axis=0), axis=1)
        first = np.hypot(np.linalg.norm(P[b] - P[a]) / (m + 1), lift * np.sin(np.pi / (m + 1)))
        assert max(steps[0], steps[-1]) <= first + 0.3     # off the leads' ends: one share of the span, lifted


def test_a_scans_leads_rise_by_its_noise_band():
    """The noisy cap (1 mm): past the face's edge the leads' last quarter is at least the noise band (3 RMS
    residuals) off the true sphere, on its tool side; the work poses stay on it."""
    rng = np.random.default_rng(5)
    R, n = 200.0, 40000
    xy = rng.uniform(-60, 60, (n, 2))
    P = np.column_stack([xy, np.sqrt(R ** 2 - (xy ** 2).sum(1)) - R])
    c = np.array([0.0, 0.0, -R])
    N = (P - c) / R
    P = P + N * rng.normal(0, 1.0, n)[:, None]
    s = freeform_surface(Workpiece(P, N, source="scan.xyz"), FIT)
    band = s.lead_band_mm
    assert band == pytest.approx(3.0 * s.stats.rms_mm) and 2.4 < band < 4.0
    path = raster_path(s, RasterSettings.make(step_over_mm=15.0, pitch_mm=5.0, lead_mm=20.0))
    from camtool.path.toolpath import ZONE_CODE

    pos = path.poses_mm[:, :3, 3]
    above = np.linalg.norm(pos - c, axis=1) - R
    lead = np.isin(path.zone, [ZONE_CODE["lead_in"], ZONE_CODE["lead_out"]])
    far = np.zeros(len(pos), bool)
    for seg in np.unique(path.segment):               # each lead's pose farthest from the work
        k = np.flatnonzero((path.segment == seg) & lead)
        if len(k):
            far[[k[0], k[-1]]] = True
    assert above[far].min() > band - 0.3
    assert np.percentile(np.abs(above[path.is_work]), 50) < 0.5


def _noisy_cap(noise_mm, n=60000, R=200.0, seed=2):
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-70, 70, (n, 2))
    P = np.column_stack([xy, np.sqrt(R ** 2 - (xy ** 2).sum(1)) - R])
    c = np.array([0.0, 0.0, -R])
    N = (P - c) / R
    return P + N * rng.normal(0, noise_mm, n)[:, None], N, c


def _normal_noise_deg(s, c, radius_mm=45.0):
    """Per-axis RMS tilt (deg) of the surface's normals from the true sphere's inside ``radius_mm``."""
    g = s.grid
    X, Y = np.meshgrid(g.x0 + np.arange(g.nx) * g.g, g.y0 + np.arange(g.ny) * g.g)
    inside = np.hypot(X, Y) < radius_mm
    pts = s.origin_mm + X[..., None] * s.frame[:, 0] + Y[..., None] * s.frame[:, 1] + s.height[..., None] * s.frame[:, 2]
    true = (pts - c) / np.linalg.norm(pts - c, axis=-1, keepdims=True)
    d = (s.normals - true)[inside]
    return np.degrees(np.sqrt(np.mean(np.stack([d @ s.frame[:, 0], d @ s.frame[:, 1]], 1) ** 2, axis=0)))


@pytest.mark.parametrize("noise_mm", [1.0, 0.3])
def test_a_scans_normals_are_smoothed_until_the_noise_no_longer_tilts_them(noise_mm):
    """The normals' sigma grows with the scan's noise until its closed-form tilt (RMS r / (L^2 sqrt(8 pi rho)))
    is SCAN_NORMAL_NOISE_DEG; the tilt measured against the true sphere agrees. A quiet scan keeps the tool's
    footprint (6 mm)."""
    from camtool.part.freeform import NORMAL_SMOOTHING_MM, SCAN_NORMAL_NOISE_DEG, SCAN_NORMAL_SMOOTHING_MAX_MM

    P, N, c = _noisy_cap(noise_mm)
    s = freeform_surface(Workpiece(P, N, source="scan.xyz"), FIT)
    tilt = _normal_noise_deg(s, c)
    if noise_mm >= 1.0:
        assert NORMAL_SMOOTHING_MM < s.normal_smoothing_mm <= SCAN_NORMAL_SMOOTHING_MAX_MM
        assert (tilt <= 1.2 * SCAN_NORMAL_NOISE_DEG).all() and (tilt >= 0.7 * SCAN_NORMAL_NOISE_DEG).all()
    else:
        assert s.normal_smoothing_mm == NORMAL_SMOOTHING_MM
        assert (tilt < SCAN_NORMAL_NOISE_DEG).all()
    # the stage file keeps the sigma the normals were made with
    again = surface_from_dict(json.loads(json.dumps(s.to_dict())))
    assert again.normal_smoothing_mm == s.normal_smoothing_mm


def test_scan_normal_smoothing_grows_with_noise_and_stops_at_its_cap():
    from camtool.part.freeform import SCAN_NORMAL_SMOOTHING_MAX_MM, scan_normal_smoothing_mm

    sig = [scan_normal_smoothing_mm(r, 4.0, 2.0, 6.0) for r in (0.01, 0.3, 1.0, 1.5, 50.0)]
    assert sig[0] == sig[1] == 6.0 and 6.0 < sig[2] < sig[3] < SCAN_NORMAL_SMOOTHING_MAX_MM == sig[4]
    # a denser scan averages more points in the same window: less smoothing for the same noise
    assert scan_normal_smoothing_mm(1.0, 8.0, 2.0, 6.0) < scan_normal_smoothing_mm(1.0, 4.0, 2.0, 6.0)


def test_the_sag_takes_its_midposes_onto_a_cad_meshs_face_only(saddle_part):
    """run.stages.face_projector reads the face's own verdict (``FreeformSurface.from_scan``): a CAD mesh's free-form
    face projects; a face of the same mesh called a scan (workpiece.scan = "yes"), a face of a scan's own vertices
    (noise) and no surface do not (their midposes stay on the arc)."""
    from camtool.run.stages import face_projector
    wp, _, s = saddle_part
    assert face_projector(s, wp) == s.project_mm
    assert face_projector(fit_surface(replace(wp, scan="yes"), FIT), wp) is None
    noisy = replace(wp, vertices_mm=wp.vertices_mm + np.random.default_rng(0).normal(0, 0.05, wp.vertices_mm.shape))
    assert face_projector(fit_surface(noisy, FIT), noisy) is None
    assert face_projector(None, wp) is None
    assert face_projector(s, None) is None

def test_a_block_with_a_pocket_as_one_face_is_refused_at_its_upright_wall():
    """A 200 x 150 mm top with a slot 40 mm deep along y, its walls upright (a height field falling 40 mm between
    two grid lines 0.1 mm apart at x = +-50): as one free-form face its rows stretch past STEEP_SCALE at the walls; a raster
    over max_poses is refused with where the face stands upright (on the wall: x = +-50, z between -40 and 0) and
    what to do (the part's faces); a pocket with 30 deg walls is refused as before, without the note."""
    from camtool.path.raster import STEEP_SCALE

    def part(wall_mm):
        x = np.sort(np.concatenate([np.arange(-100.0, 100.01, 2.0), [-50.0 - wall_mm, 50.0 + wall_mm]]))
        y = np.arange(-75.0, 75.01, 2.0)
        V, F = grid_mesh(x, y, lambda X, Y: -40.0 * np.clip((50.0 + wall_mm - np.abs(X)) / wall_mm, 0.0, 1.0))
        return fit_surface(mesh_workpiece(V, F)[0], FIT)

    settings = RasterSettings.make(step_over_mm=5.0, pitch_mm=2.0, max_poses=1000)
    with pytest.raises(BadInput) as e:
        raster_path(part(0.1), settings)
    msg = str(e.value)
    assert "over raster.max_poses = 1000" in msg and "upright wall" in msg and "[faces] select" in msg
    k = float(msg.split("rows stretched ")[1].split(" x")[0])
    assert k > STEEP_SCALE
    p = np.array([float(v) for v in msg.split("near [")[1].split("]")[0].split(",")])
    assert abs(abs(p[0]) - 50.0) < 3.0 and -41.0 <= p[2] <= 1.0
    with pytest.raises(BadInput) as e:
        raster_path(part(40.0 / np.tan(np.radians(30.0))), settings)
    assert "over raster.max_poses" in str(e.value) and "upright" not in str(e.value)
