"""part/folds.py: triangles folded back onto the surface beside them (a CAD surface folded over itself)."""
from __future__ import annotations

import numpy as np


def _strip(xs, zs, width=4.0):
    """A strip along x through stations ``xs`` (heights ``zs``), y from 0 to ``width``; wound consistently, so a
    station stepping back in x makes triangles that face -z (a fold)."""
    xs, zs = np.asarray(xs, float), np.asarray(zs, float)
    n = len(xs)
    V = np.concatenate([np.stack([xs, np.zeros(n), zs], 1), np.stack([xs, np.full(n, width), zs], 1)])
    a, b = np.arange(n - 1), np.arange(1, n)
    F = np.concatenate([np.stack([a, b, b + n], 1), np.stack([a, b + n, a + n], 1)])
    return V, F


def _z_fold(lift=1e-3):
    """A strip in z = 0 from x = 0 to 20, folded back to x = 17 (lifted ``lift`` mm), then on to x = 40."""
    xs = np.r_[np.arange(0.0, 21.0), np.arange(19.0, 16.0, -1.0), np.arange(17.5, 40.0), 40.0]   # (no two layers'
    # stations coincide: a mesh merges coincident vertices)
    zs = np.zeros(len(xs))
    zs[21:24] = lift                                     # the middle layer's inner stations (its ends are shared)
    return _strip(xs, zs)


def test_the_middle_layer_of_a_z_fold_is_found_and_nothing_else():
    from camtool.part.folds import folded_triangles

    V, F = _z_fold()
    folds = folded_triangles(V, F)
    tri = V[F]
    faces_down = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 2] < 0
    assert faces_down.sum() == 6 and np.array_equal(folds.mask, faces_down)   # the 3 mm back, 2 triangles each
    assert folds.largest_mm2 > 0


def test_a_thin_wall_or_a_bend_is_no_fold():
    """A hairpin (a sheet turned back 1 mm above itself: a thin wall's two sides) and a 90 deg bend have creases
    past FOLD_DEG or none, but no triangle lies on a surface facing against it."""
    from camtool.part.folds import folded_triangles

    xs = np.r_[np.arange(0.0, 21.0), np.arange(20.0, -1.0, -1.0)]
    zs = np.r_[np.zeros(21), np.ones(21)]
    V, F = _strip(xs, zs)
    assert not folded_triangles(V, F).mask.any()
    xs = np.r_[np.arange(0.0, 21.0), np.full(20, 20.0)]
    zs = np.r_[np.zeros(21), np.arange(1.0, 21.0)]
    V, F = _strip(xs, zs)
    assert not folded_triangles(V, F).mask.any()


def test_the_motion_check_reads_a_point_in_front_of_a_fold_as_in_front():
    """The hull's self-motions passed 10 mm in front of a fold and read 10 mm behind it: a point above the middle
    layer (its closest triangle, 1 um above the others) is 10 mm in front; one under it 10 mm behind."""
    from camtool.motion.geometry import PartGeometry
    from camtool.part.workpiece import Workpiece

    V, F = _z_fold()
    wp = Workpiece(V.copy(), np.zeros_like(V), F, "fold", "mm", (), V)
    part = PartGeometry.from_workpiece(wp, np.array([[5.0, 2.0, 0.0], [35.0, 2.0, 0.0]]), np.array([[0, 0, 1.0]] * 2))
    sd = part.signed_distance(np.array([[18.5, 2.0, 10.0], [18.5, 2.0, -10.0], [5.0, 2.0, 10.0]]))
    np.testing.assert_allclose(sd, [10.0 - 1e-3, -10.0, 10.0], atol=2e-3)


def test_a_mesh_that_folds_over_itself_loads_with_one_warning_line(tmp_path):
    """The loader says so in one line (the count and the largest); a mesh without folds says nothing of them."""
    import trimesh

    from camtool.part.workpiece import load_workpiece

    V, F = _z_fold()
    trimesh.Trimesh(V, F, process=False).export(tmp_path / "fold.ply")
    wp = load_workpiece(tmp_path / "fold.ply", units="mm")
    lines = [w for w in wp.warnings if "folds back onto itself" in w]
    assert len(lines) == 1 and "at 6 triangles" in lines[0]
    V, F = _strip(np.arange(0.0, 21.0), np.zeros(21))
    trimesh.Trimesh(V, F, process=False).export(tmp_path / "flat.ply")
    assert not any("folds" in w for w in load_workpiece(tmp_path / "flat.ply", units="mm").warnings)


def _turned_over(spacing_mm=50.0, past_mm=5.0):
    """A flat grid (z = 0, triangles ``spacing_mm`` on a side, wound to face +z) with one inner triangle's corner
    moved ``past_mm`` across its opposite edge: that triangle alone is turned over (it faces -z), lying flat under
    its three neighbours, each folded 180 deg back over it (the reach demo shell's two folds, 50-165 mm triangles).
    (vertices, faces, the turned triangle's index)."""
    n = 8
    x, y = np.meshgrid(np.arange(n) * spacing_mm, np.arange(n) * spacing_mm)
    V = np.c_[x.ravel(), y.ravel(), np.zeros(n * n)]
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1))
    a = (j * n + i).ravel()
    F = np.r_[np.c_[a, a + 1, a + n + 1], np.c_[a, a + n + 1, a + n]]
    t = int(np.flatnonzero((F[:, 0] == 3 * n + 3) & (F[:, 1] == 3 * n + 4))[0])   # corners (3,3), (4,3), (4,4)
    A, B, C = F[t]
    mid = 0.5 * (V[A] + V[C])                     # B moved across its opposite edge A-C (the cell's diagonal)
    out = mid - V[B]
    V[B] = mid + past_mm * out / np.linalg.norm(out)
    return V, F, t


def test_a_triangle_turned_over_under_its_neighbours_is_a_fold_on_a_coarse_mesh():
    """Its neighbours' centroids lie 20-30 mm from its own (none within REACH_MM): the surface around it and the
    triangles it lies on are those of its own size and those sharing its corners."""
    from camtool.part.folds import REACH_MM, folded_triangles

    V, F, t = _turned_over()
    tri = V[F]
    normal_z = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 2]
    assert np.flatnonzero(normal_z < 0).tolist() == [t]                # the one turned over, as built
    centroid = tri.mean(axis=1)
    assert np.sort(np.linalg.norm(centroid - centroid[t], axis=1))[1] > REACH_MM
    folds = folded_triangles(V, F)
    assert np.flatnonzero(folds.mask).tolist() == [t]
    assert folds.largest_mm2 == 0.5 * abs(normal_z[t])

