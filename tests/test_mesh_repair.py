"""Damaged meshes (camtool.part.mesh_repair, issue #46 item 5): each defect repaired with one warning line, or
refused with one line naming it. Small OBJ and STL files written here."""
import numpy as np
import pytest
import trimesh

from camtool.errors import BadInput
from camtool.part.workpiece import load_workpiece

from test_freeform import grid_mesh


def write_obj(path, V, F):
    lines = [f"v {x:.12g} {y:.12g} {z:.12g}" for x, y, z in V] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in F]
    path.write_text("\n".join(lines) + "\n")
    return path


def dish():
    """A shallow dish 200 x 160 mm, wound with its normals up."""
    return grid_mesh(np.linspace(-100, 100, 21), np.linspace(-80, 80, 17), lambda X, Y: (X ** 2 + Y ** 2) / 800)


def one_line(w):
    return isinstance(w, str) and "\n" not in w


def test_a_clean_mesh_has_no_warning(tmp_path):
    V, F = dish()
    wp = load_workpiece(write_obj(tmp_path / "dish.obj", V, F), sample_points=2000)
    assert wp.warnings == ()


def test_flipped_triangles_are_turned_with_one_warning(tmp_path):
    V, F = dish()
    F = F.copy()
    rng = np.random.default_rng(0)
    flip = rng.random(len(F)) < 0.3
    F[flip] = F[flip][:, ::-1]
    wp = load_workpiece(write_obj(tmp_path / "flipped.obj", V, F), sample_points=3000)
    (w,) = wp.warnings
    assert one_line(w) and f"{int(flip.sum())} of {len(F)} triangles were wound against" in w
    assert (wp.normals[:, 2] > 0).all()      # every sampled normal on one side again
    clean = load_workpiece(write_obj(tmp_path / "clean.obj", *dish()), sample_points=3000)
    assert np.allclose(wp.normals, clean.normals)


def test_missing_normals_of_a_cloud_are_estimated(tmp_path):
    V, _ = dish()
    path = tmp_path / "cloud.xyz"
    path.write_text("\n".join(f"{x} {y} {z}" for x, y, z in V) + "\n")
    wp = load_workpiece(path)
    assert np.allclose(np.linalg.norm(wp.normals, axis=1), 1.0)
    n_true = np.c_[-V[:, :2] / 400, np.ones(len(V))]
    n_true /= np.linalg.norm(n_true, axis=1, keepdims=True)
    assert np.percentile(np.abs(np.sum(wp.normals * n_true, axis=1)), 5) > 0.99


def test_non_manifold_edges_are_counted_in_one_warning(tmp_path):
    V, F = dish()
    a, b = F[0, 0], F[0, 2]             # a fin on the first cell's diagonal: that edge has three triangles
    V2 = np.vstack([V, V[a] + [0, 0, 30]])
    F2 = np.vstack([F, [[a, b, len(V)]]])
    wp = load_workpiece(write_obj(tmp_path / "fin.obj", V2, F2), sample_points=2000)
    (w,) = wp.warnings
    assert one_line(w) and "1 edges are shared by more than two triangles (non-manifold)" in w


def test_duplicate_vertices_are_merged_with_one_warning(tmp_path):
    V, F = dish()
    V2 = np.vstack([V, V[:50]])         # the first 50 vertices again, the triangles using the copies
    F2 = np.where(F < 50, F + len(V), F)
    F2[: len(F2) // 2] = F[: len(F2) // 2]
    wp = load_workpiece(write_obj(tmp_path / "dup.obj", V2, F2), sample_points=2000)
    (w,) = wp.warnings
    assert one_line(w) and "duplicate vertices merged" in w
    assert len(wp.vertices_mm) == len(V)
    stl = tmp_path / "dish.stl"          # an STL stores every corner apart: merging it is no repair
    trimesh.Trimesh(V, F, process=False).export(stl)
    assert load_workpiece(stl, sample_points=2000).warnings == ()


def test_triangle_soup_is_welded_with_one_warning(tmp_path):
    V, F = dish()
    rng = np.random.default_rng(1)
    Vs = V[F].reshape(-1, 3) + rng.normal(0, 1e-6, (3 * len(F), 3))   # every corner its own, off by a nanometre
    Fs = np.arange(3 * len(F)).reshape(-1, 3)
    wp = load_workpiece(write_obj(tmp_path / "soup.obj", Vs, Fs), sample_points=2000)
    assert len(wp.warnings) == 1 and one_line(wp.warnings[0]) and "triangle soup" in wp.warnings[0]
    assert len(wp.vertices_mm) == len(V)
    edges = np.sort(np.concatenate([wp.faces[:, [0, 1]], wp.faces[:, [1, 2]], wp.faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert (counts == 2).sum() > 0.8 * len(counts)      # the triangles share their edges again


def test_degenerate_triangles_are_dropped_with_one_warning(tmp_path):
    V, F = dish()
    V2 = np.vstack([V, [[0, 0, 50], [10, 0, 50], [20, 0, 50]]])     # three corners on a line: no area
    n = len(V)
    F2 = np.vstack([F, [[n, n + 1, n + 2], [0, 0, 1]]])                # and a triangle with a corner twice
    wp = load_workpiece(write_obj(tmp_path / "degenerate.obj", V2, F2), sample_points=2000)
    (w,) = wp.warnings
    assert one_line(w) and f"2 of {len(F2)} triangles are degenerate" in w
    assert len(wp.faces) == len(F) and len(wp.vertices_mm) == len(V)


def test_a_mesh_of_degenerate_triangles_only_is_refused_in_one_line(tmp_path):
    V = np.array([[0, 0, 0], [10, 0, 0], [20, 0, 0], [30, 0, 0.0]])
    F = np.array([[0, 1, 2], [1, 2, 3]])
    with pytest.raises(BadInput) as e:
        load_workpiece(write_obj(tmp_path / "line.obj", V, F), sample_points=100)
    assert "degenerate (no area)" in str(e.value) and "\n" not in str(e.value)


def test_pair_keys_unique_as_rows():
    """The int64 keys give np.unique(axis=0)'s order, inverse and counts."""
    from camtool.part.mesh_repair import _pair_keys

    rng = np.random.default_rng(3)
    pairs = rng.integers(0, 50, (4000, 2))
    rows, inv_r, cnt_r = np.unique(pairs, axis=0, return_inverse=True, return_counts=True)
    keys, inv_k, cnt_k = np.unique(_pair_keys(pairs), return_inverse=True, return_counts=True)
    assert np.array_equal(inv_r.ravel(), inv_k.ravel()) and np.array_equal(cnt_r, cnt_k)
    assert np.array_equal(rows, pairs[np.unique(_pair_keys(pairs), return_index=True)[1]])


def test_tree_signs_are_products_along_the_path():
    """Pointer jumping gives each node the product of the steps to the root, as a walk from the node does."""
    from camtool.part.mesh_repair import _tree_signs

    rng = np.random.default_rng(4)
    n = 3000
    parent = np.r_[0, [rng.integers(0, i) for i in range(1, n)]]   # node 0 is the root, parents come first
    step = np.r_[1, rng.choice([-1, 1], n - 1)]
    expected = np.empty(n, int)
    for v in range(n):
        s, u = 1, v
        while u != 0:
            s, u = s * step[u], parent[u]
        expected[v] = s
    assert np.array_equal(_tree_signs(parent, step), expected)
