"""camtool.process.mesh_map: the process map on a free-form face's own mesh.

A flat mesh gives the analytic plane's figures; on a curved CAD mesh (a saddle) the map equals direct sums of
the footprint over a dense sampling of the true surface (written here, independent of the module); the vertex
areas are on the surface, not on the projection; ``step_over_mm = "auto"`` meets its target on a free-form face."""
import math

import numpy as np
import pytest

from camtool.part.fit import fit_surface
from camtool.part.surface import Boundary, Cylinder, PlaneSurface
from camtool.path.raster import raster_path
from camtool.process.figures import map_figures, plot_map_png, save_map_npz
from camtool.process.footprint import Footprint
from camtool.process.html import process_heat_map_figure
from camtool.process.integrate import contacts_from_tcp
from camtool.process.maps import surface_map, track_map
from camtool.process.mesh_map import RIPPLE_SAMPLES, MeshMap, mesh_process_map
from camtool.process.stepover import _track, choose_step_over, predicted_map
from camtool.settings import ProcessSettings, RasterSettings
from tests.process_reference import contacts, removal_at
from tests.test_freeform import FIT, grid_mesh, mesh_workpiece

POLISH = ProcessSettings.make(kind="polish", profile="parabolic", diameter_mm=30, grid_mm=2.0)
TILT = math.radians(30.0)


def tilted(P):
    """Points turned by TILT about world x."""
    c, s = math.cos(TILT), math.sin(TILT)
    return P @ np.array([[1, 0, 0], [0, c, s], [0, -s, c]], float)


@pytest.fixture(scope="module")
def flat_pair():
    """(the analytic plane, the same plane as a free-form face from its mesh), 300 x 200 mm, tilted 30 deg."""
    V, F = grid_mesh(np.linspace(-150, 150, 31), np.linspace(-100, 100, 21), lambda X, Y: 0 * X)
    wp, _ = mesh_workpiece(tilted(V), F)
    free = fit_surface(wp, FIT)
    ex, ey = tilted(np.eye(3))[0], tilted(np.eye(3))[1]
    b = Boundary(np.array([[-150, -100], [150, -100], [150, 100], [-150, 100]], float))
    plane = PlaneSurface(np.zeros(3), np.cross(ex, ey), ex, ey, b)
    return plane, free


def saddle(X, Y):
    return (X ** 2 - Y ** 2) / 400.0


@pytest.fixture(scope="module")
def saddle_face():
    V, F = grid_mesh(np.linspace(-120, 120, 97), np.linspace(-90, 90, 73), saddle)
    wp, _ = mesh_workpiece(V, F)
    return fit_surface(wp, FIT)


def plane_track(plane, step_mm=10.0):
    path = raster_path(plane, RasterSettings.make(step_over_mm=step_mm, pitch_mm=5, lead_mm=20))
    return _track(path, 100.0, 1.0, 11.0)


def face_chart_points(face, n_points: int, seed: int = 0) -> np.ndarray:
    """(N, 2) stratified random chart points, uniform over the face's worked area (its material nodes' cells):
    the region the face defines, sampled without camtool.process."""
    g = face.grid
    xy = g.node_xy()[face.material]
    lo, hi = xy.min(axis=0) - 0.5 * g.g, xy.max(axis=0) + 0.5 * g.g
    n_box = n_points * float(np.prod(hi - lo)) / (face.material.sum() * g.g ** 2)
    nx = int(round(math.sqrt(n_box * (hi[0] - lo[0]) / (hi[1] - lo[1]))))
    ny = int(round(n_box / nx))
    rng = np.random.default_rng(seed)
    ix, iy = np.meshgrid(np.arange(nx), np.arange(ny))
    x = lo[0] + (ix.ravel() + rng.random(ix.size)) / nx * (hi[0] - lo[0])
    y = lo[1] + (iy.ravel() + rng.random(iy.size)) / ny * (hi[1] - lo[1])
    i, j = np.rint((x - g.x0) / g.g).astype(int), np.rint((y - g.y0) / g.g).astype(int)
    keep = face.material[np.clip(j, 0, g.ny - 1), np.clip(i, 0, g.nx - 1)]
    return np.column_stack([x[keep], y[keep]])


def share_of(h, weights, band=0.05):
    mean = np.sum(h * weights) / np.sum(weights)
    return float(np.sum(weights * (np.abs(h - mean) <= band * mean)) / np.sum(weights))


def test_a_flat_mesh_gives_the_analytic_planes_figures(flat_pair):
    plane, free = flat_pair
    t, tcp = plane_track(plane)
    grid_map, mesh_map = track_map(POLISH, plane, t, tcp, rows_mm=10.0), track_map(POLISH, free, t, tcp, rows_mm=10.0)
    assert isinstance(mesh_map.grid, MeshMap) and mesh_map.method == "mesh-direct"
    assert grid_map.method == "convolution"
    a, b = map_figures(grid_map), map_figures(mesh_map)
    # the face's material is its 1 mm nodes' (camtool.part.freeform): its edge may lie half a node off the plate's
    assert b["worked_area_mm2"] == pytest.approx(a["worked_area_mm2"], rel=0.01)
    assert b["mean"] == pytest.approx(a["mean"], rel=0.003)
    for key in ("uniformity_within_10pct", "uncovered_share"):
        assert b[key] == pytest.approx(a[key], abs=0.015), key
    assert b["edge_rolloff_width_mm"] == pytest.approx(a["edge_rolloff_width_mm"], abs=POLISH.grid_mm)
    assert b["samples_across_rows_mm"] <= 10.0 / RIPPLE_SAMPLES + 1e-9
    # within 5 % against the exact reference (tests/process_reference.py: direct sums of the TCP track's segments)
    # over the face's own worked area. The ripple's peaks lie at the band's edge here, so the share moves ~4 pp
    # per 0.5 mm of the worked area's edge: the plate's (the grid map's, 0.673) is not the face's (0.709).
    k = POLISH.preston_coefficient_per_pa * POLISH.force_n * 1e-3 * 1e12
    segments = contacts(plane, t, tcp, POLISH.contact_tol_mm, k)
    xy = face_chart_points(free, 40_000)
    P = free.origin_mm + xy[:, :1] * free.frame[:, 0] + xy[:, 1:] * free.frame[:, 1]
    P -= np.outer((P - plane.origin_mm) @ plane.normal, plane.normal)      # onto the true plate
    h = removal_at(P, segments, "parabolic", 15.0)
    exact = share_of(h, np.ones(len(P)))
    assert b["uniformity_within_5pct"] == pytest.approx(exact, abs=0.005)
    assert b["rms_pct"] == pytest.approx(100 * h.std() / h.mean(), abs=0.1)   # the region's too (the plate's 9.08)
    unrefined = map_figures(mesh_process_map(POLISH, free, t, tcp, mesh_map.grid, 10.0, refine=False))
    assert abs(unrefined["uniformity_within_5pct"] - exact) > 0.02          # the vertices alone overstate it
    # the refined map's samples are the exact direct sums there
    fine = mesh_map.fine
    some = np.flatnonzero(fine.grid.material)[::50]
    Q = fine.grid.points_mm()[some]
    Q -= np.outer((Q - plane.origin_mm) @ plane.normal, plane.normal)
    assert np.abs(fine.values[some] - removal_at(Q, segments, "parabolic", 15.0)).max() < 1e-4 * fine.values.max()
    # every contact puts exactly its amount on the surface (the saved map: the samples' averages over each cell)
    c = contacts_from_tcp(POLISH, free, t, tcp, spacing_mm=0.5 * mesh_map.grid.spacing_mm)
    assert np.sum(fine.values * fine.grid.spread_area_mm2()) == pytest.approx(c.amount.sum(), rel=1e-9)
    assert np.sum(mesh_map.values * mesh_map.grid.area_mm2) == pytest.approx(c.amount.sum(), rel=1e-3)


def saddle_point(face, xy):
    """Points of the true saddle over chart points (along the chart normal e3, Newton)."""
    e1, e2, e3 = face.frame[:, 0], face.frame[:, 1], face.frame[:, 2]
    base = face.origin_mm + xy[:, :1] * e1 + xy[:, 1:] * e2
    s = np.zeros(len(xy))
    for _ in range(6):
        P = base + s[:, None] * e3
        f = saddle(P[:, 0], P[:, 1]) - P[:, 2]
        df = (2 * P[:, 0] * e3[0] - 2 * P[:, 1] * e3[1]) / 400.0 - e3[2]
        s -= f / df
    return base + s[:, None] * e3


def saddle_normal(P):
    n = np.column_stack([-P[:, 0] / 200.0, P[:, 1] / 200.0, np.ones(len(P))])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def small_saddle_face():
    """The saddle CAD mesh 140 x 110 mm taken as a free-form face."""
    V, F = grid_mesh(np.linspace(-70, 70, 57), np.linspace(-55, 55, 45), saddle)
    return fit_surface(mesh_workpiece(V, F)[0], FIT)


def saddle_raster(step_mm: float):
    """(times, TCP track) at 100 mm/s: passes along x step_mm apart on the true saddle, past the small saddle's
    edges, each followed by a 20 mm lift."""
    rows = []
    for k, y0 in enumerate(np.arange(-70.0, 70.1, step_mm) + 0.3):
        x = np.arange(-85.0, 85.0 + 1e-9, 0.4) * (1 if k % 2 == 0 else -1)
        rows += [np.column_stack([x, np.full_like(x, y0), saddle(x, y0)]),
                 np.array([[x[-1], y0, saddle(x[-1], y0) + 20]])]
    tcp = np.vstack(rows)
    return np.arange(len(tcp)) * 0.004, tcp


def saddle_exact_share(face, tcp, n_points: int) -> float:
    """The exact share within 5 % of the track on the true saddle: direct sums of its segments in contact (both
    ends within the contact tolerance of the face, the true normals) over n_points random points of the true
    saddle, uniform in area over the face's worked area."""
    uv = face.uv_from_points(tcp)
    off = np.einsum("ij,ij->i", tcp - face.point_mm(uv[:, 0], uv[:, 1]), face.normal_at(uv[:, 0], uv[:, 1]))
    on = np.abs(off) <= POLISH.contact_tol_mm
    kk = np.flatnonzero(on[:-1] & on[1:])
    mid = 0.5 * (tcp[kk] + tcp[kk + 1])
    per_mm = POLISH.preston_coefficient_per_pa * POLISH.force_n * 1e-3 * 1e12
    segments = (tcp[kk], tcp[kk + 1], mid, saddle_normal(mid), per_mm * np.linalg.norm(tcp[kk + 1] - tcp[kk], axis=1))
    P = saddle_point(face, face_chart_points(face, n_points))
    area = 1.0 / np.abs(saddle_normal(P) @ face.frame[:, 2])      # chart-uniform points: the area element
    return share_of(removal_at(P, segments, "parabolic", 15.0), area)


def test_a_raster_on_a_curved_mesh_matches_the_exact_reference():
    """Passes 13 mm apart across a saddle CAD mesh (140 x 110 mm), on the true surface and past the face's edges:
    the share within +-5 % against direct sums of the TCP track's segments over random points of the true saddle
    (the true normals; uniform in area over the face's worked area), within 0.5 pp; the map on the vertices alone
    is farther off. The segments in contact are those whose ends lie within the contact tolerance of the face
    (continued past its edge, as camtool.part makes it), the only part of the reference taken from camtool."""
    face = small_saddle_face()
    t, tcp = saddle_raster(13.0)
    pm = track_map(POLISH, face, t, tcp, rows_mm=13.0)
    exact = saddle_exact_share(face, tcp, 40_000)
    assert 0.2 < exact < 0.8                # the ripple crosses the band: the share is a real measurement (0.361)
    assert map_figures(pm)["uniformity_within_5pct"] == pytest.approx(exact, abs=0.005)
    unrefined = map_figures(mesh_process_map(POLISH, face, t, tcp, pm.grid, 13.0, refine=False))
    assert abs(unrefined["uniformity_within_5pct"] - exact) > 0.01   # 0.398


def test_refined_samples_hold_the_materials_area_and_the_cells_average(saddle_face):
    """Each refined sample's area is its cell's share on the material (against a brute-force count of 0.02 mm
    points by their nearest node); a vertex's saved value is its samples' area-weighted average."""
    x = np.arange(-80.0, 80.0, 0.5)
    tcp = np.column_stack([x, np.zeros_like(x), saddle(x, 0.0)])
    pm = track_map(POLISH, saddle_face, np.arange(len(tcp)) * 0.005, tcp, rows_mm=10.0)
    fine = pm.fine.grid
    m_x, m_y = fine.sub
    assert m_y >= 48 * pm.grid.spacing_mm / 10.0 - 1 and fine.vertices_mm.shape[0] == m_x * m_y * len(pm.values)
    g = saddle_face.grid
    dx, dy = fine.xs[1] - fine.xs[0], fine.ys[1] - fine.ys[0]
    share = fine.area_mm2 / fine.spread_area_mm2()
    edge = np.flatnonzero((share > 0.01) & (share < 0.99))
    assert len(edge) > 100
    k = np.random.default_rng(0).choice(edge, 40, replace=False)
    X, Y = np.meshgrid(fine.xs, fine.ys)
    ox, oy = np.meshgrid((np.arange(50) + 0.5) / 50 - 0.5, (np.arange(50) + 0.5) / 50 - 0.5)
    px, py = X.ravel()[k, None] + ox.ravel() * dx, Y.ravel()[k, None] + oy.ravel() * dy
    i, j = np.rint((px - g.x0) / g.g).astype(int), np.rint((py - g.y0) / g.g).astype(int)
    brute = saddle_face.material[j, i].mean(axis=1)
    assert np.abs(share[k] - brute).max() < 0.03
    a = fine.as_lattice(fine.spread_area_mm2()).reshape(len(pm.grid.ys), m_y, len(pm.grid.xs), m_x)
    v = fine.as_lattice(pm.fine.values).reshape(a.shape)
    assert np.allclose(pm.values, ((a * v).sum(axis=(1, 3)) / a.sum(axis=(1, 3))).ravel())


def test_the_refinement_is_bounded_and_reported(saddle_face, monkeypatch):
    import camtool.process.mesh_map as mm

    x = np.arange(-80.0, 80.0, 0.5)
    tcp = np.column_stack([x, np.zeros_like(x), saddle(x, 0.0)])
    t = np.arange(len(tcp)) * 0.005
    full = track_map(POLISH, saddle_face, t, tcp, rows_mm=10.0)
    monkeypatch.setattr(mm, "MAX_PAIRS", 60_000)
    bounded = track_map(POLISH, saddle_face, t, tcp, rows_mm=10.0)
    assert 1 < bounded.fine.grid.sub[1] < full.fine.grid.sub[1]
    c = contacts_from_tcp(POLISH, saddle_face, t, tcp, spacing_mm=mm.CONTACT_SPACINGS * full.grid.spacing_mm)
    assert len(c.amount) * mm.pairs_per_contact(bounded.fine.grid, 15.0) <= 60_000 * 1.01
    assert map_figures(bounded)["samples_across_rows_mm"] == pytest.approx(
        full.grid.spacing_mm / bounded.fine.grid.sub[1], abs=1e-4)
    assert map_figures(full)["samples_across_rows_mm"] <= 10.0 / mm.RIPPLE_SAMPLES + 1e-4


def test_vertex_areas_are_on_the_surface_not_the_projection(saddle_face):
    m = surface_map(POLISH, saddle_face)
    P = m.points_mm()
    inner = m.material & (m.edge_distance_mm() > 5.0)
    slope = np.hypot(2 * P[inner, 0] / 400.0, -2 * P[inner, 1] / 400.0)
    on_surface = np.sqrt(1.0 + slope ** 2) * m.spacing_mm ** 2   # the area element of z = (x^2 - y^2) / 400
    assert np.percentile(np.abs(m.area_mm2[inner] / on_surface - 1.0), 99) < 0.005
    assert np.max(on_surface / m.spacing_mm ** 2) > 1.1        # the projection would be 10 % short there
    assert np.abs(P[m.material, 2] - saddle(P[m.material, 0], P[m.material, 1])).max() < 0.05


def dense_reference(points, contacts, normals, weights, fp_radius, shape, step=0.5):
    """Per point: sum over contacts of weight * footprint(tangent distance) / (the footprint summed over a dense
    sampling of the true saddle round the contact, each sample with its exact area element)."""
    r = np.arange(-1.3 * fp_radius, 1.3 * fp_radius + step, step)
    out = np.zeros(len(points))
    for c, n, w in zip(contacts, normals, weights):
        X, Y = np.meshgrid(c[0] + r, c[1] + r)
        Q = np.stack([X, Y, saddle(X, Y)], -1).reshape(-1, 3)
        dA = step * step * np.sqrt(1 + (X / 200.0) ** 2 + (Y / 200.0) ** 2).ravel()
        dq = Q - c
        dq -= np.outer(dq @ n, n)
        norm = np.sum(shape(np.linalg.norm(dq, axis=1)) * dA)
        dp = points - c
        dp -= np.outer(dp @ n, n)
        out += w * shape(np.linalg.norm(dp, axis=1)) / norm
    return out


def three_passes() -> list[np.ndarray]:
    """Three passes across the saddle, along x at y = -10, 0, 10 every 0.5 mm on the true surface, each followed
    by its 20 mm lift: [pass, lift, pass, lift, pass, lift]."""
    rows = []
    for k, y0 in enumerate((-10.0, 0.0, 10.0)):
        x = np.arange(-80.0, 80.0 + 1e-9, 0.5) * (1 if k % 2 == 0 else -1)
        rows.append(np.column_stack([x, np.full_like(x, y0), saddle(x, y0)]))
        rows.append(rows[-1][-1:] + [0, 0, 20.0])
    return rows


def test_a_curved_mesh_matches_direct_sums_over_the_true_surface(saddle_face):
    rows = three_passes()
    tcp = np.vstack(rows)
    t = np.arange(len(tcp)) * 0.005    # 100 mm/s
    pm = track_map(POLISH, saddle_face, t, tcp)
    m = pm.grid
    # the reference: one contact per 0.5 mm interval, at its midpoint, the true normal, k_p F travel
    per_mm = POLISH.preston_coefficient_per_pa * POLISH.force_n * 1e-3 * 1e12   # um * mm^2 per mm of travel
    mids, weights = [], []
    for row in rows[0::2]:
        mids.append(0.5 * (row[1:] + row[:-1]))
        weights.append(per_mm * np.linalg.norm(np.diff(row, axis=0), axis=1))
    mids, weights = np.vstack(mids), np.concatenate(weights)
    normals = np.column_stack([-mids[:, 0] / 200.0, mids[:, 1] / 200.0, np.ones(len(mids))])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    P = m.points_mm()
    near = m.material & (np.abs(P[:, 1]) < 30) & (np.abs(P[:, 0]) < 100)
    fp = Footprint.from_settings(POLISH)
    ref = dense_reference(P[near], mids, normals, weights, fp.radius_mm, fp.shape)
    got = pm.values[near]
    # the passes' middle (away from their ends): the map within 0.5 % of the reference's peak everywhere
    mid = np.abs(P[near, 0]) < 60
    assert np.abs(got[mid] - ref[mid]).max() < 0.005 * ref.max()
    assert np.sum(got * m.area_mm2[near]) == pytest.approx(np.sum(ref * m.area_mm2[near]), rel=0.01)
    # the map's total is what the passes did
    assert np.sum(pm.values * m.area_mm2) == pytest.approx(weights.sum(), rel=0.01)


def test_inspect_counts_the_passes_on_the_mesh(saddle_face):
    s = ProcessSettings.make(kind="inspect", diameter_mm=30, grid_mm=2.0)
    x = np.arange(-80.0, 80.0, 0.5)
    a = np.column_stack([x, np.zeros_like(x), saddle(x, 0.0)])
    b = np.column_stack([x[::-1], np.full_like(x, 10.0), saddle(x[::-1], 10.0)])
    tcp = np.vstack([a, a[-1:] + [0, 0, 30.0], b])
    pm = track_map(s, saddle_face, np.arange(len(tcp)) * 0.005, tcp)
    P = pm.grid.points_mm()
    at = lambda p: pm.values[np.argmin(np.linalg.norm(P - p, axis=1))]   # noqa: E731
    assert at([0, 5.0, saddle(0, 5.0)]) == 2 and at([0, -12.0, saddle(0, -12.0)]) == 1
    assert at([0, 40.0, saddle(0, 40.0)]) == 0


def test_files_and_the_3d_view_of_a_mesh_map(saddle_face, tmp_path):
    x = np.arange(-80.0, 80.0, 0.5)
    tcp = np.column_stack([x, np.zeros_like(x), saddle(x, 0.0)])
    pm = track_map(POLISH, saddle_face, np.arange(len(tcp)) * 0.005, tcp)
    fig = map_figures(pm)
    npz = save_map_npz(pm, tmp_path / "process_map.npz")
    assert save_map_npz(pm, tmp_path / "again.npz").read_bytes() == npz.read_bytes()
    d = np.load(npz)
    assert str(d["layout"]) == "mesh" and d["values"].shape == (len(d["vertices_mm"]),)
    assert d["faces"].max() < len(d["vertices_mm"])
    assert plot_map_png(pm, fig, tmp_path / "plots" / "process_map.png").stat().st_size > 1000
    trace = process_heat_map_figure({**fig, "file": str(npz)}, None).data[0]
    assert trace.type == "mesh3d"
    shown = np.asarray(trace.intensity, float)
    assert len(shown) == len(trace.x) and np.nanmax(shown) == pytest.approx(pm.values.max(), rel=1e-3)
    assert len(trace.x) <= int(pm.grid.material.sum())   # the material's vertices only


def test_auto_step_over_on_a_free_form_face_predicts_on_its_mesh():
    V, F = grid_mesh(np.linspace(-150, 150, 61), np.linspace(-105, 105, 43), lambda X, Y: (X ** 2 - Y ** 2) / 1000.0)
    face = fit_surface(mesh_workpiece(V, F)[0], FIT)
    raster = RasterSettings.make(step_over_mm="auto", pitch_mm=10, lead_mm=20)
    chosen, record = choose_step_over(face, raster, POLISH, 100.0)
    assert record["surface"] == "freeform" and chosen.step_over_mm == record["step_over_mm"]
    # the first candidate (the ripple's bound) meets the target away from the edges; since a free-form face's
    # leads rise at least 1 mm (ffe5ff2, past the 0.5 mm contact tolerance) the rows' ends roll off and the whole
    # face is short of it by a little (0.946 on the refined map, 0.940 on its vertices alone): edges limit it
    first = record["candidates"][0]
    assert first["interior_share_within_band"] >= POLISH.uniformity_target
    assert record["met"] == (record["predicted_share_within_band"] >= POLISH.uniformity_target)
    assert record["met"] or (record["limited_by"] == "edges" and "note" in record)
    assert record["predicted_share_within_band"] == max(c["share_within_band"] for c in record["candidates"])
    path, pmap = predicted_map(face, chosen, POLISH, 100.0)
    assert isinstance(pmap.grid, MeshMap) and len(path) > 0
    assert map_figures(pmap, POLISH.uniformity_band)["uniformity_within_band"] == record["predicted_share_within_band"]



def test_a_cylinder_gets_its_own_mesh_and_matches_the_closed_form():
    """A pass along a cylinder's axis (R 40 mm, footprint 30 mm): the map at arc offset s is
    ``A pass_profile(R sin(s / R)) / integral pass_profile(R sin(sigma / R)) d sigma`` (the footprint in the
    contact's tangent plane, the cylinder's exact area element); a 1-D quadrature, independent of the module."""
    R = 40.0
    cyl = Cylinder(np.zeros(3), R, np.eye(3), Boundary(np.array([[-1.2, -100], [1.2, -100], [1.2, 100], [-1.2, 100]])))
    v = np.arange(-150.0, 150.0 + 1e-9, 0.5)
    tcp = cyl.point_mm(np.zeros_like(v), v)
    pm = track_map(POLISH, cyl, np.arange(len(v)) * 0.005, tcp)
    m = pm.grid
    assert isinstance(m, MeshMap) and pm.method == "mesh-direct"
    P = m.points_mm()
    # the vertex areas are the cylinder's: R du dv
    inner = m.material & (m.edge_distance_mm() > 3.0)
    assert np.allclose(m.area_mm2[inner], POLISH.grid_mm ** 2, rtol=1e-3)
    fp = Footprint.from_settings(POLISH)
    sigma = np.linspace(-R * math.asin(min(1.0, fp.radius_mm / R)), R * math.asin(min(1.0, fp.radius_mm / R)), 20001)
    Z = np.trapezoid(fp.pass_profile(R * np.sin(sigma / R)), sigma)
    per_mm = POLISH.preston_coefficient_per_pa * POLISH.force_n * 1e-3 * 1e12
    mid = m.material & (np.abs(P[:, 2]) < 50)
    s = R * np.arctan2(P[mid, 1], P[mid, 0])
    closed = per_mm * fp.pass_profile(R * np.sin(s / R)) / Z
    assert np.abs(pm.values[mid] - closed).max() < 0.005 * closed.max()
    # the tangent plane, not the arc: the arc's profile would be off by more than the tolerance at the sides
    arc = per_mm * fp.pass_profile(s) / np.trapezoid(fp.pass_profile(sigma), sigma)
    assert np.abs(arc - closed).max() > 0.01 * closed.max()
