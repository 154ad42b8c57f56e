"""camtool.part.face_edges: boundary vertices moved onto neighbours' intersections, tangent seams, mesh free edges
and a scan's extent; corners closed; a full cylinder's seam kept at u = +-pi."""
import json

import numpy as np
import pytest
from scipy.spatial import cKDTree

from camtool.part import face_edges as fe
from camtool.part.segment import segment
from camtool.part.surface import Boundary, PlaneSurface
from camtool.part.workpiece import load_workpiece

from conftest import SAMPLES

TRUTH = json.loads((SAMPLES / "faces_truth.json").read_text())


def _plane(origin, normal, u_axis, outer_uv):
    normal, u_axis = np.asarray(normal, float), np.asarray(u_axis, float)
    return PlaneSurface(np.asarray(origin, float), normal, u_axis, np.cross(normal, u_axis),
                        Boundary(np.asarray(outer_uv, float)))


def _grid(x, y, z):
    """Points of the grid x * y * z (1-D ranges; one of them a single value)."""
    return np.stack(np.meshgrid(x, y, z, indexing="ij"), axis=-1).reshape(-1, 3)


def _outline_distance_mm(surface, outline_xyz) -> float:
    """Largest distance of the boundary (densified) from a polyline outline (densified to 0.05 mm)."""
    seg = np.diff(np.vstack([outline_xyz, outline_xyz[:1]]), axis=0)
    dense = np.vstack([outline_xyz[k] + np.linspace(0, 1, int(np.linalg.norm(seg[k]) / 0.05) + 1)[:, None] * seg[k]
                       for k in range(len(seg))])
    poly = np.vstack([surface.boundary.outer_uv, surface.boundary.outer_uv[:1]])
    uv = np.vstack([poly[k] + np.linspace(0, 1, 20, endpoint=False)[:, None] * (poly[k + 1] - poly[k])
                    for k in range(len(poly) - 1)])
    return float(cKDTree(dense).query(surface.point_mm(uv[:, 0], uv[:, 1]))[0].max())


def test_an_inset_boundary_moves_onto_the_neighbours_and_its_corners_close():
    """A 100 x 60 mm floor (z = 0) with a wall along each side, its traced outline 4 mm inside: every edge is
    a neighbour's intersection, and the rounded corners become the true corners."""
    t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    inset = np.stack([np.clip(48 * np.cos(t), -46, 46) * 1.0, np.clip(30 * np.sin(t), -26, 26)], axis=-1)
    inset = inset[np.r_[True, np.any(np.diff(inset, axis=0) != 0, axis=1)]]  # a rounded rectangle 92 x 52
    floor = _plane([0, 0, 0], [0, 0, 1], [1, 0, 0], inset)
    walls = [_plane([50, 0, 0], [1, 0, 0], [0, 1, 0], [[-30, 0], [30, 0], [30, 20], [-30, 20]]),
             _plane([-50, 0, 0], [-1, 0, 0], [0, 1, 0], [[-30, 0], [30, 0], [30, 20], [-30, 20]]),
             _plane([0, 30, 0], [0, 1, 0], [1, 0, 0], [[-50, 0], [50, 0], [50, 20], [-50, 20]]),
             _plane([0, -30, 0], [0, -1, 0], [1, 0, 0], [[-50, 0], [50, 0], [50, 20], [-50, 20]])]
    step = np.arange(0.5, 20, 1.0)
    points = [_grid(np.arange(-46, 46.1, 1.0), np.arange(-26, 26.1, 1.0), [0.0]),
              _grid([50.0], np.arange(-29.5, 30, 1.0), -step), _grid([-50.0], np.arange(-29.5, 30, 1.0), -step),
              _grid(np.arange(-49.5, 50, 1.0), [30.0], -step), _grid(np.arange(-49.5, 50, 1.0), [-30.0], -step)]
    cloud = np.vstack(points)
    owner = np.repeat(np.arange(5), [len(p) for p in points])
    moved = fe.on_edges([floor, *walls], points, cloud, owner, 0.5)[0]
    rectangle = np.array([[-50, -30, 0], [50, -30, 0], [50, 30, 0], [-50, 30, 0]], float)
    assert _outline_distance_mm(floor, rectangle) > 3.5  # as traced
    assert _outline_distance_mm(moved, rectangle) < 0.05


def test_a_sparse_scans_free_edges_are_found_without_a_bias():
    """A 200 x 80 mm face scanned at random (0.3 points per mm2, about 0.9 mm apart) whose traced outline is
    5 mm short of its free edges, with no neighbour: the vertices go out to the points' extent and settle on
    discs of the points. The long sides come out within a spacing (95 %) and without a bias (the farthest of
    a window of rays alone falls short by about a third of a spacing)."""
    rng = np.random.default_rng(7)
    xy = rng.uniform([-100, -40], [100, 40], size=(4800, 2))
    cloud = np.column_stack([xy, np.zeros(len(xy))])
    face = _plane([0, 0, 0], [0, 0, 1], [1, 0, 0], [[-95, -35], [95, -35], [95, 35], [-95, 35]])
    moved = fe.on_edges([face], [cloud], cloud, np.zeros(len(cloud), int), 0.5)[0]
    spacing = fe.spacing_mm(cKDTree(cloud), cloud)
    poly = np.vstack([moved.boundary.outer_uv, moved.boundary.outer_uv[:1]])
    dense = np.vstack([poly[k] + np.linspace(0, 1, 20, endpoint=False)[:, None] * (poly[k + 1] - poly[k])
                       for k in range(len(poly) - 1)])
    long_sides = dense[np.abs(dense[:, 0]) < 80]   # away from the corners
    error = np.abs(long_sides[:, 1]) - 40.0        # + beyond the edge
    assert 0.8 < spacing < 1.0
    assert abs(error.mean()) < 0.2 * spacing
    assert np.percentile(np.abs(error), 95) < spacing


def test_a_boundary_with_no_edge_in_reach_is_returned_as_it_was():
    square = _plane([0, 0, 0], [0, 0, 1], [1, 0, 0], [[-10, -10], [10, -10], [10, 10], [-10, 10]])
    far = _plane([0, 0, 500], [0, 0, 1], [1, 0, 0], [[-10, -10], [10, -10], [10, 10], [-10, 10]])
    points = [_grid(np.arange(-30, 31, 1.0), np.arange(-30, 31, 1.0), [0.0]),
              _grid(np.arange(-10, 11, 1.0), np.arange(-10, 11, 1.0), [500.0])]
    cloud = np.vstack(points)
    owner = np.repeat([0, 1], [len(p) for p in points])
    # the points run on past the outline by far more than the reach: nothing says where the face ends
    out = fe.on_edges([square, far], points, cloud, owner, 0.5)
    assert out[0] is square and out[1] is not None


def test_mesh_free_edges_are_the_edges_of_one_triangle():
    V = np.array([[0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0]], float)
    F = np.array([[0, 1, 2], [0, 2, 3]])
    free = fe.FreeEdges.of_mesh(V, F)
    assert len(free.start_mm) == 4  # the diagonal is shared
    d, X = free.nearest_mm(np.array([[5.0, -2.0, 0.0], [5.0, 5.0, 0.0]]))
    assert d[0] == pytest.approx(2.0) and np.allclose(X[0], [5, 0, 0])
    assert np.isinf(d[1]) or d[1] == pytest.approx(5.0)
    closed = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]])
    assert fe.FreeEdges.of_mesh(V[[0, 1, 2, 3]] + [[0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 5]], closed) is None
    assert fe.FreeEdges.of_mesh(None, None) is None


def test_runs_are_cyclic_and_short_ones_drop():
    mask = np.array([1, 1, 0, 0, 1, 0, 1, 1], bool)
    assert fe._runs(mask) == [(4, 1), (6, 4)]  # the last run wraps round to the start
    source = np.array([2, 2, 2, fe.UNMOVED, 5, fe.UNMOVED, 2, 2])
    u = fe.UNMOVED
    assert list(fe._without_short_runs(source, 3)) == [2, 2, 2, u, u, u, 2, 2]


def test_window_max_keeps_to_agreeing_normals():
    values = np.array([0.0, 3.0, 0.0, 0.0, np.inf, 0.0])
    normals = np.array([[0, 1], [0, 1], [0, 1], [1, 0], [1, 0], [1, 0]], float)
    out = fe._window_max(values, normals, 1)
    assert list(out[:4]) == [3.0, 3.0, 3.0, 0.0] and np.isinf(out[4])


@pytest.mark.parametrize("part", ["box_open", "plate_chamfer", "pipe_half", "dome_cylinder"])
def test_sample_mesh_boundaries_meet_the_true_outlines(part):
    """On the sample meshes (100k points, as the benchmark), every face's boundary lies on its true outline: within
    0.5 mm for the 95th percentile of its length (it was 2-6 mm before the pass, 0.9 mm at a chamfer's mitre before
    the corners were squared); benchmarks/segment_accuracy.py has the figures against half a sampling step."""
    from benchmarks.segment_accuracy import boundary_errors_mm, match

    seg = segment(load_workpiece(SAMPLES / f"{part}.stl"))
    for i, face in match(seg.faces, TRUTH[part]["faces"]):
        assert face is not None
        p95, _ = boundary_errors_mm(face, TRUTH[part]["faces"][i])
        assert p95 < 0.5, (part, i, p95)


def test_a_cut_or_notched_corner_is_squared_onto_its_two_edges():
    """Two straight edges with a short chain of edges between them meet at their lines' corner; a fillet longer
    than CORNER_CHAIN_MM and a gentle bend (under CORNER_TURN_DEG) are left as they are."""
    cut = np.array([[0, 0], [100, 0], [100, 57.0], [99.2, 59.4], [97.0, 60.0], [0, 60]], float)
    assert np.allclose(fe._corners_squared(cut), [[0, 0], [100, 0], [100, 60], [0, 60]])
    notch = np.array([[0, 0], [100, 0], [100, 58.0], [98.5, 58.5], [98.0, 60.0], [0, 60]], float)
    assert np.allclose(fe._corners_squared(notch), [[0, 0], [100, 0], [100, 60], [0, 60]])
    a = np.linspace(0, np.pi / 2, 12)   # a 10 mm fillet: 15.7 mm of short edges
    fillet = np.vstack([[[0, 0], [100, 0]], np.c_[90 + 10 * np.cos(a), 50 + 10 * np.sin(a)], [[0, 60]]])
    assert np.array_equal(fe._corners_squared(fillet), fillet)
    bend = np.array([[0, 0], [100, 0], [110, 2.0], [120, 6.0], [0, 60]], float)
    assert np.array_equal(fe._corners_squared(bend), bend)


def test_a_scans_straight_free_edge_goes_onto_its_fitted_line():
    """A long run of extent estimates scattering about a line (and dipping at a corner) goes onto the line fitted
    to the ones near it; a run that turns is left alone."""
    rng = np.random.default_rng(3)
    x = np.arange(0, 100.0)
    xy = np.c_[x, rng.normal(0, 0.3, len(x))]
    xy[-4:, 1] -= [0.8, 1.4, 1.9, 2.2]          # the corner's dip
    out = xy.copy()
    fe._extent_straightened(out, np.ones(len(xy), bool) & (np.arange(len(xy)) > 0))
    assert np.abs(out[1:, 1]).max() < 0.15 and np.array_equal(out[0], xy[0])
    turning = np.c_[x, np.where(x < 50, 0.0, (x - 50) * 0.5)]
    out = turning.copy()
    fe._extent_straightened(out, np.ones(len(x), bool) & (np.arange(len(x)) > 0))
    assert np.array_equal(out, turning)


def test_a_whole_ball_keeps_its_outline_within_one_turn(tmp_path):
    """A whole sphere (trimesh's icosphere, R 100): its outline runs through both poles of the azimuth-elevation
    chart, where the flat chart's x / cos v ran off to millions of rad; it stays within u = -pi..pi, and the
    ball is rastered and covered."""
    import trimesh

    from camtool.path.raster import raster_path, raster_summary
    from camtool.settings import RasterSettings

    trimesh.creation.icosphere(subdivisions=5, radius=100).export(tmp_path / "ball.stl")
    seg = segment(load_workpiece(tmp_path / "ball.stl"))
    assert [f.model for f in seg.faces] == ["sphere"]
    s = seg.faces[0].surface
    lo, hi = s.boundary.bounds()
    assert lo[0] >= -np.pi and hi[0] <= np.pi
    assert seg.faces[0].area_mm2 == pytest.approx(4 * np.pi * 100 ** 2, rel=0.02)
    assert raster_summary(raster_path(s, RasterSettings.make(step_over_mm=10, pitch_mm=5)), s)["coverage"] >= 0.995


def test_a_hemisphere_rim_through_the_charts_poles_is_followed_in_u_v():
    """A dome's rim runs through both poles of the chart its mean direction spans; read as straight (u, v)
    edges (the raster's reading) the outline stays on the rim, where the flat chart's simplification went round
    the poles by up to a mm."""
    from camtool.part.surface import SpherePatch

    frame = np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])  # e1 = +z (columns e1, e2, e3)
    s = SpherePatch(np.zeros(3), 100.0, frame, Boundary(np.zeros((3, 2))))
    a = np.linspace(0, 2 * np.pi, 700, endpoint=False)
    rim = 100.0 * np.c_[np.cos(a), np.sin(a), np.zeros_like(a)] + 1e-3 * np.c_[0 * a, 0 * a, np.sin(7 * a)]
    xy = fe.flat_mm(s, s.uv_from_points(rim))
    truth = cKDTree(100.0 * np.c_[np.cos(np.linspace(0, 2 * np.pi, 63000)), np.sin(np.linspace(0, 2 * np.pi, 63000)),
                                  np.zeros(63000)])

    def off_mm(uv):
        closed = np.vstack([uv, uv[:1]])
        f = np.linspace(0, 1, 200, endpoint=False)
        pts = np.vstack([closed[k] + f[:, None] * (closed[k + 1] - closed[k]) for k in range(len(uv))])
        return truth.query(s.point_mm(pts[:, 0], pts[:, 1]))[0].max()

    uv = fe._sphere_outline_uv(s, xy)
    assert off_mm(uv) < 2 * fe.SIMPLIFY_MM and len(uv) < 100
    flat_simplified = fe.cv2.approxPolyDP(xy.reshape(-1, 1, 2).astype(np.float32), fe.SIMPLIFY_MM, True)
    assert off_mm(fe._sphere_uv(s, flat_simplified.reshape(-1, 2).astype(float))) > 0.3   # what it was


def test_the_faces_moved_in_a_forked_child_are_the_faces_moved_here(monkeypatch):
    """From ALONGSIDE_FACES faces on, half of them move in a forked child: each face moves on its own, so the
    boundaries are those of one process, vertex for vertex."""
    from camtool.part.segment import boundaries_on_edges

    wp = load_workpiece(SAMPLES / "box_open.stl", sample_points=30000)
    seg = segment(wp)
    surfaces, inliers = [f.surface for f in seg.faces], [f.inliers for f in seg.faces]
    monkeypatch.setattr(fe, "ALONGSIDE_FACES", 2)
    forked = boundaries_on_edges(surfaces, inliers, wp, 0.5)
    monkeypatch.setattr(fe, "ALONGSIDE_FACES", 10 ** 9)
    here = boundaries_on_edges(surfaces, inliers, wp, 0.5)
    assert len(seg.faces) >= 4 and len(forked) == len(here)
    moved = 0
    for a, b in zip(forked, here):
        assert np.array_equal(a.boundary.outer_uv, b.boundary.outer_uv)
        assert all(np.array_equal(x, y) for x, y in zip(a.boundary.holes_uv, b.boundary.holes_uv))
        moved += a is not b
    assert moved >= 1


def test_the_halves_split_the_work_within_lpt_bound_of_the_best_split():
    """The faces go to the two processes by their outline length (largest first, each to the lighter half):
    every face once, each half in order, and the heavier half within 7/6 of the best split (Graham's bound for
    two machines), the best found by trying every split."""
    import itertools

    rng = np.random.default_rng(7)
    for n in (1, 2, 5, 11):
        work = list(rng.uniform(1.0, 100.0, n))
        here, there = fe._halves(work)
        assert sorted(here + there) == list(range(n)) and here == sorted(here) and there == sorted(there)
        heavier = max(sum(work[k] for k in here), sum(work[k] for k in there))
        best = min(max(sum(w for w, s in zip(work, side) if s), sum(w for w, s in zip(work, side) if not s))
                   for side in itertools.product((0, 1), repeat=n))
        assert heavier <= 7 / 6 * best + 1e-9


def test_an_outline_length_is_the_perimeter_of_its_polygons_in_the_flat_chart():
    """A plane's 100 x 50 mm rectangle with a 10 mm square hole: 300 + 40 mm."""
    outer = np.array([[0, 0], [100, 0], [100, 50], [0, 50]], float)
    hole = np.array([[10, 10], [20, 10], [20, 20], [10, 20]], float)
    s = PlaneSurface(np.zeros(3), np.array([0, 0, 1.0]), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]),
                     Boundary(outer, (hole,)))
    assert fe._outline_mm(s) == pytest.approx(340.0)


def test_the_rows_interpolation_is_numpys_to_the_bit():
    """``_interp_rows`` (a sphere's outline resampled, every edge at once) gives np.interp's values bit for bit,
    row by row: knots hit exactly, repeated knots (an edge piece of no length), x at the row's end."""
    rng = np.random.default_rng(3)
    xp = np.cumsum(rng.uniform(0.0, 2.0, (40, 33)) * (rng.uniform(size=(40, 33)) > 0.2), axis=1)
    xp[:, 0] = 0.0
    xp[5] = 0.0   # a row of no length at all
    fp = rng.normal(size=(40, 33, 2)) * 50
    row = np.repeat(np.arange(40), 25)
    x = rng.uniform(size=len(row)) * xp[row, -1]
    x[::7] = xp[row[::7], rng.integers(0, 33, len(row[::7]))]   # on knots, the last included
    got = fe._interp_rows(x, xp, fp, row)
    for c in (0, 1):
        want = np.array([np.interp(x[i], xp[row[i]], fp[row[i], :, c]) for i in range(len(x))])
        assert np.array_equal(got[:, c], want)


def test_the_lengths_are_numpys_norms_to_the_bit():
    """``_norm`` (the squares summed in turn) is ``np.linalg.norm(..., axis=-1)`` bit for bit on the shapes the
    pass uses: rays (m, K, 3), points (n, 3), a single row, flat-chart vectors (n, 2), a strided view."""
    rng = np.random.default_rng(11)
    for shape in ((1, 3), (2, 3), (517, 3), (40, 61, 3), (1, 61, 3), (300, 2), (1, 2)):
        for scale in (1e-6, 1.0, 1e4):
            d = rng.normal(size=shape) * scale
            assert np.array_equal(fe._norm(d), np.linalg.norm(d, axis=-1))
    d = rng.normal(size=(30, 61, 3))[:, 5:40:3]
    assert np.array_equal(fe._norm(d), np.linalg.norm(d, axis=-1))


def test_the_discs_second_farthest_points_are_those_of_one_disc_at_a_time(monkeypatch):
    """``_second_farthest`` (every disc in one padded block, in blocks as small as one disc) equals the disc by
    disc reading: the second largest of (points - centre) @ direction, bit for bit; NaN for a sparse disc."""
    rng = np.random.default_rng(5)
    pts = rng.uniform(-50, 50, (4000, 3)) * [1, 1, 0.02]
    own = fe._FacePoints(pts)
    X = rng.uniform(-55, 55, (200, 3)) * [1, 1, 0]
    direction = rng.normal(size=(200, 3))
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    want = np.full(200, np.nan)
    for i, near in enumerate(own.tree.query_ball_point(X, 6.0)):
        if len(near) >= fe.END_DISC_POINTS:
            want[i] = np.partition((pts[near] - X[i]) @ direction[i], -2)[-2]
    assert np.isnan(want).sum() > 0 and np.isfinite(want).sum() > 100
    for block in (fe.DISC_BLOCK_ENTRIES, 1):
        monkeypatch.setattr(fe, "DISC_BLOCK_ENTRIES", block)
        assert np.array_equal(fe._second_farthest(own, X, direction, 6.0), want, equal_nan=True)
