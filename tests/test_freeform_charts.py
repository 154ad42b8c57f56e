"""Free-form regions one height field does not hold, cut into height-field charts (camtool.part.freeform_charts,
freeform_faces._region_faces): a deep trough whose walls turn to 86 deg, a sheet bent 150 deg through a fillet;
regions a height field holds (a 120 deg bend, a shallower trough) stay one face, not cut. Generated parts; the
references are the parts' own meshes (closest points, surface samples)."""
import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from camtool.part import freeform_charts
from camtool.part.freeform_charts import CHART_HOLD_DEG, height_field_charts
from camtool.part.segment import SegmentSettings, segment
from camtool.path.raster import raster_path
from camtool.settings import RasterSettings

from test_freeform import grid_mesh, mesh_workpiece

STEP_MM = 10.0


def trough(depth_mm):
    """A block's top 300 x 200 mm with a trough 240 x 120 mm, depth_mm deep: a parabola across, a quartic along
    with a wave, so its walls steepen to atan(depth / 30) at the rim (86 deg at 400 mm)."""
    x, y = np.arange(-150, 150.01, 2.0), np.arange(-100, 100.01, 1.0)
    inside = lambda X, Y: (np.abs(X) < 120) & (np.abs(Y) < 60)  # noqa: E731
    return grid_mesh(x, y, lambda X, Y: np.where(
        inside(X, Y), -depth_mm * (1 - (X / 120) ** 4) * (1 - (Y / 60) ** 2) * (1 + 0.15 * np.sin(X / 40)), 0.0))


def bent_sheet(bend_deg, base_mm=200.0, flange_mm=150.0, radius_mm=25.0):
    """A sheet 300 mm wide: a base, a fillet of radius_mm bending it by bend_deg, a flange; a wave of 4 mm across
    it (a free-form cross-section). Normals on the inside of the bend. Returns (V, F, arc length of each vertex,
    the fillet's arc-length range)."""
    fillet = radius_mm * np.radians(bend_deg)
    length = base_mm + fillet + flange_mm
    s = np.linspace(0, length, 301)
    theta = np.radians(bend_deg) * np.clip((s - base_mm) / fillet, 0, 1)
    step = np.stack([np.cos(theta), np.sin(theta)], 1)[:-1] * (s[1] - s[0])
    yz = np.concatenate([[[0.0, 0.0]], np.cumsum(step, axis=0)])
    inward = np.stack([-np.sin(theta), np.cos(theta)], 1)
    x = np.linspace(-150, 150, 121)
    X, k = np.meshgrid(x, np.arange(len(s)))
    w = 4 * np.sin(X / 60) * np.sin(np.pi * s[k] / length)
    V = np.stack([X, yz[k, 0] + w * inward[k, 0], yz[k, 1] + w * inward[k, 1]], -1).reshape(-1, 3)
    _, F = grid_mesh(x, np.arange(len(s)), lambda A, B: 0 * A)
    return V, F, s[k].ravel(), (base_mm, base_mm + fillet)


def raster_figures(seg, mesh, region_of_triangles):
    """(coverage: the share of the region's surface samples within 0.6 step of a work TCP of any free-form face,
    p99 of the work TCPs' distance to the mesh (mm))."""
    tcps = []
    for f in seg.faces:
        if f.model == "freeform":
            path = raster_path(f.surface, RasterSettings.make(step_over_mm=STEP_MM, pitch_mm=5.0))
            tcps.append(path.poses_mm[path.is_work, :3, 3])
    tcps = np.vstack(tcps)
    sub = mesh.submesh([np.flatnonzero(region_of_triangles)], append=True)
    samples, _ = trimesh.sample.sample_surface_even(sub, 20000, seed=1)
    covered = cKDTree(tcps).query(samples)[0] <= 0.6 * STEP_MM
    _, dist, _ = trimesh.proximity.closest_point(mesh, tcps)
    return float(covered.mean()), float(np.percentile(dist, 99))


def test_a_deep_troughs_walls_become_charts_that_cover_it_on_the_surface():
    """400 mm deep (walls to 86 deg): one height field leaves 44 % of it off its material; its charts (the long
    walls, the ends) cover >= 99 % of it, their work TCPs on the mesh within 0.1 mm (p99)."""
    V, F = trough(400.0)
    wp, mesh = mesh_workpiece(V, F, n=40000)    # a loaded part's density (20 000 points leave gaps in its steep walls)
    seg = segment(wp, SegmentSettings())
    free = [f for f in seg.faces if f.model == "freeform"]
    assert 2 <= len(free) <= 6
    for f in free:                                    # each chart holds its points within the slope it can carry
        n = wp.normals[f.inliers]
        assert np.quantile(n @ f.surface.frame[:, 2], 0.01) >= np.cos(np.radians(80.0))
    c = mesh.triangles_center
    region = (np.abs(c[:, 0]) < 118) & (np.abs(c[:, 1]) < 58)
    coverage, p99 = raster_figures(seg, mesh, region)
    assert coverage >= 0.99 and p99 <= 0.1, (coverage, p99)
    Q = wp.points_mm
    in_trough = np.flatnonzero((np.abs(Q[:, 0]) < 119) & (np.abs(Q[:, 1]) < 59))
    assert np.isin(in_trough, np.concatenate([f.inliers for f in free])).mean() > 0.98


def test_a_sheet_bent_past_a_height_field_is_its_base_and_its_flange():
    """Bent 150 deg: one height field is garbage (13.9 mm p99 off the mesh, 82 % covered, before the charts); the
    charts are the base and the flange, cut in the fillet, each >= 97 % of its own side's points."""
    V, F, s, (f0, f1) = bent_sheet(150.0)
    wp, mesh = mesh_workpiece(V, F, n=30000)
    seg = segment(wp, SegmentSettings())
    assert [f.model for f in seg.faces] == ["freeform", "freeform"]
    s_pt = s[mesh.faces[cKDTree(mesh.triangles_center).query(wp.points_mm)[1]]].mean(axis=1)
    base, flange = np.flatnonzero(s_pt < f0), np.flatnonzero(s_pt > f1)
    a, b = seg.faces[0].inliers, seg.faces[1].inliers
    assert np.isin(base, a).mean() > 0.97 and np.isin(flange, b).mean() > 0.97
    coverage, p99 = raster_figures(seg, mesh, np.ones(len(mesh.faces), bool))
    assert coverage >= 0.99 and p99 <= 0.1, (coverage, p99)


@pytest.mark.parametrize("part", ["bend120", "trough150"])
def test_a_region_one_height_field_holds_is_not_cut(part, monkeypatch):
    """A 120 deg bend (its chart plane halfway, each leg 60 deg from it) and a 150 mm trough (walls to 79 deg) are
    held whole: the charts are never computed, the region is one free-form face."""
    def refuse(*a):
        raise AssertionError("a region the height field holds was cut")

    monkeypatch.setattr(freeform_charts, "height_field_charts", refuse)
    V, F = bent_sheet(120.0)[:2] if part == "bend120" else trough(150.0)
    wp, _ = mesh_workpiece(V, F, n=20000)
    seg = segment(wp, SegmentSettings())
    assert [f.model for f in seg.faces].count("freeform") == 1


def test_charts_of_a_half_tube_each_hold_their_normals():
    """Points of a half tube (normals turning 180 deg): no plane holds them; the charts do, each within
    CHART_HOLD_DEG of its own mean (the chart plane), in a few connected pieces; a 60 deg cap is one chart."""
    a = np.linspace(0, np.pi, 181)
    x = np.linspace(0, 200, 141)                     # spaced as along the arcs (1.4 mm)
    A, X = np.meshgrid(a, x)
    N = np.stack([0 * A, np.cos(A), np.sin(A)], -1).reshape(-1, 3)
    P = np.stack([X, 80 * np.cos(A), 80 * np.sin(A)], -1).reshape(-1, 3)
    label = height_field_charts(P, -N)                 # worked from inside
    assert 2 <= label.max() + 1 <= 4
    for c in range(label.max() + 1):
        n = -N[label == c]
        m = n.mean(axis=0) / np.linalg.norm(n.mean(axis=0))
        assert np.quantile(n @ m, 0.01) >= np.cos(np.radians(CHART_HOLD_DEG)) - 1e-9
    cap = (A.ravel() > np.radians(60)) & (A.ravel() < np.radians(120))
    assert height_field_charts(P[cap], -N[cap]).max() == 0
    assert (height_field_charts(P, -N) == label).all()            # deterministic


def test_a_scanned_bent_sheet_is_cut_the_same_way_quietly(capfd):
    """The 150 deg sheet as a scan (0.5 mm noise, normals of mixed sign: open3d orients them over the region):
    base and flange, nothing on stderr."""
    from camtool.part.workpiece import Workpiece

    V, F, s, (f0, f1) = bent_sheet(150.0)
    mesh = trimesh.Trimesh(V, F, process=False)
    P, fi = trimesh.sample.sample_surface(mesh, 15000, seed=3)
    rng = np.random.default_rng(2)
    N = mesh.face_normals[fi] * np.where(rng.random(len(P)) < 0.5, -1, 1)[:, None]
    seg = segment(Workpiece(np.asarray(P) + rng.normal(0, 0.5, P.shape), N, None, "bend.ply"), SegmentSettings())
    assert [f.model for f in seg.faces] == ["freeform", "freeform"]
    s_pt = s[mesh.faces[fi]].mean(axis=1)
    base, flange = np.flatnonzero(s_pt < f0), np.flatnonzero(s_pt > f1)
    assert np.isin(base, seg.faces[0].inliers).mean() > 0.95 and np.isin(flange, seg.faces[1].inliers).mean() > 0.95
    assert capfd.readouterr().err == ""


def twisted_blade(twist_deg=40.0, chord_mm=80.0, span_mm=120.0, thick_mm=3.0, camber_mm=6.0):
    """A closed thin blade: two cambered sides (a lens section, thick_mm (3 mm) at mid-chord, 0 at both edges, where the
    sides meet at 14 deg: a sharp edge) twisted by twist_deg from root to tip about the span axis (y), flat caps
    at root and tip. Returns (V, F, side of each triangle: +1 upper, -1 lower, 0 caps)."""
    s = np.linspace(-1.0, 1.0, 61)
    t = np.linspace(0.0, 1.0, 81)
    S, T = np.meshgrid(s, t)
    half = 0.5 * thick_mm * (1 - S ** 2) * (1 + 0.3 * S)
    camber = camber_mm * (1 - S ** 2)
    th = np.radians(twist_deg) * T
    def side(z):
        x = 0.5 * chord_mm * S
        return np.stack([x * np.cos(th) + z * np.sin(th), span_mm * T, -x * np.sin(th) + z * np.cos(th)], -1)
    up, lo = side(camber + half), side(camber - half)
    ns, nt = len(s), len(t)
    V = np.concatenate([up.reshape(-1, 3), lo.reshape(-1, 3)])
    idx = np.arange(ns * nt).reshape(nt, ns)
    low = idx + ns * nt
    low[:, 0], low[:, -1] = idx[:, 0], idx[:, -1]           # the edges: one row of vertices shared by both sides
    def quads(g, flip):
        a, b, c, d = g[:-1, :-1].ravel(), g[:-1, 1:].ravel(), g[1:, :-1].ravel(), g[1:, 1:].ravel()
        F = np.concatenate([np.stack([a, d, b], 1), np.stack([a, c, d], 1)])
        return F[:, ::-1] if flip else F
    Fu, Fl = quads(idx, False), quads(low, True)
    caps = []
    for row, flip in ((0, False), (nt - 1, True)):          # each cap a fan from its section's middle
        ring = np.concatenate([idx[row], low[row, -2:0:-1]])
        centre = len(V)
        V = np.vstack([V, V[ring].mean(axis=0)])
        fan = np.stack([np.full(len(ring), centre), ring, np.roll(ring, -1)], 1)
        caps.append(fan[:, ::-1] if flip else fan)
    F = np.concatenate([Fu, Fl, *caps])
    side = np.concatenate([np.ones(len(Fu)), -np.ones(len(Fl)), np.zeros(sum(len(c) for c in caps))])
    m = trimesh.Trimesh(V, F, process=False)
    if m.volume < 0:                                          # outward normals
        F = F[:, ::-1]
    return V, F, side


def test_a_twisted_thin_blade_is_one_face_a_side():
    """A thin twisted blade (3 mm thick, sides meeting at sharp 9 deg edges): each side one free-form face that
    holds >= 97 % of that side's points and takes none across the wall (the sides lie closer than the regions'
    neighbour links reach: points facing apart are no neighbours; before, both sides were one face). Reference: the mesh's own side of each point."""
    V, F, side = twisted_blade()
    wp, mesh = mesh_workpiece(V, F, n=15000)     # 1.2 mm apart: the other side lies within the regions' links
    assert mesh.is_watertight and mesh.volume > 0
    pts, tri = trimesh.sample.sample_surface(mesh, 15000, seed=0)      # the triangle each point was drawn on
    assert np.array_equal(pts, wp.points_mm)
    side_pt = side[tri]
    seg = segment(wp, SegmentSettings())
    for s in (1, -1):
        mine = np.flatnonzero(side_pt == s)
        share = [np.isin(mine, f.inliers).mean() for f in seg.faces]
        big = [k for k, x in enumerate(share) if x >= 0.02]
        assert len(big) == 1, (s, sorted(share, reverse=True)[:4])
        face = seg.faces[big[0]]
        assert face.model == "freeform" and share[big[0]] >= 0.97, (face.model, share[big[0]])
        assert (side_pt[face.inliers] == s).mean() >= 0.995
