"""Damaged meshes (issue #46 item 5): repaired with one warning line each, or refused with one line.

``repaired_mesh(verts_mm, faces, source, indexed)`` is what ``workpiece.load_workpiece`` makes of a mesh
after its values were checked:

- **Duplicate vertices** are merged (trimesh's ``merge_vertices``). An STL or a STEP
  tessellation stores every triangle's or face's corners apart by design: merging
  them is no repair and says nothing. In an indexed format (OBJ, OFF, PLY, glTF:
  ``indexed``) a duplicate is a defect of the export: one warning line with the count.
- **Triangle soup**: when most triangles share no edge with another even after the
  exact merge (corners that differ in the last digits), vertices closer than
  ``WELD_SHARE`` of the part's diagonal are welded, with one warning line.
- **Degenerate triangles** (two corners the same, or no area) are dropped, with one
  warning line; a mesh of nothing else is refused.
- **Flipped triangles** (wound against their neighbours across a shared edge) are turned
  to agree with the larger area of their connected piece (a breadth-first walk), with
  one warning line: the sampled points' normals then agree, so the segmentation's normal
  test and a free-form face's side see one surface.
- **Non-manifold edges** (shared by more than two triangles) are kept: the workpiece is
  sampled from its triangles as they are, and the segmentation and a free-form face's
  z-buffer need no manifold; one warning line gives their count.

A mesh has no stored normals to miss: its normals are its triangles'. A point cloud's
missing normals are estimated by the loader (``workpiece._cloud_normals``, ``cloud_normals``), as always.
"""
from __future__ import annotations

import numpy as np

from ..errors import BadInput

WELD_SHARE = 1e-6          # triangle soup: corners closer than this share of the diagonal are one vertex
SOUP_SHARE = 0.5           # a mesh whose triangles share no edge for more than this share is a soup
DEGENERATE_AREA_SHARE = 1e-12  # a triangle with less area than this share of the diagonal squared is degenerate


def _pair_keys(pairs: np.ndarray) -> np.ndarray:
    """One int64 per (a, b) row of vertex indices, ordered as the rows are lexicographically: ``np.unique`` of
    these gives what ``np.unique(pairs, axis=0)`` gives (order, inverse, counts) at the speed of a 1-D sort (the
    row-wise form sorts a structured view: seconds on a part of a million triangles)."""
    pairs = np.asarray(pairs, np.int64)
    base = int(pairs.max()) + 1 if len(pairs) else 1
    return pairs[:, 0] * base + pairs[:, 1]


def _edges(faces: np.ndarray) -> np.ndarray:
    """The triangles' undirected edges (3 n, 2; smaller index first): every triangle's edge (0, 1) first."""
    return np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)


def _edge_use(faces: np.ndarray) -> np.ndarray:
    """How many triangles use each undirected edge (one count per distinct edge)."""
    return np.unique(_pair_keys(_edges(faces)), return_counts=True)[1]


def _isolated_share(faces: np.ndarray) -> float:
    """The share of triangles none of whose edges another triangle uses."""
    _, inverse, counts = np.unique(_pair_keys(_edges(faces)), return_inverse=True, return_counts=True)
    shared = (counts[inverse.ravel()] > 1).reshape(3, len(faces)).any(axis=0)
    return float(1.0 - shared.mean()) if len(faces) else 0.0


def _wound_both_ways(faces: np.ndarray) -> bool:
    """True when some directed edge is used by two triangles (neighbours wound against each other)."""
    d = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    key = np.sort(_pair_keys(d))   # (a sort, not np.unique: numpy's hashed unique is slower here)
    return bool((key[1:] == key[:-1]).any())


def _tree_signs(parent: np.ndarray, step: np.ndarray) -> np.ndarray:
    """Each node's sign in a tree: the product of the ±1 ``step`` along its path from the root (the root is its
    own parent, step 1). By pointer jumping: log2(depth) array passes, not one Python step per node."""
    side, up = step.copy(), parent.copy()
    while True:
        above = up[up]
        moving = above != up
        if not moving.any():
            return side * side[up]   # (the root's own step, 1)
        side = np.where(moving, side * side[up], side)
        up = above


def _winding_flips(F: np.ndarray, V: np.ndarray) -> np.ndarray:
    """Which triangles to turn so that neighbours across every manifold edge agree: a breadth-first walk of each
    connected piece gives each triangle its side relative to the piece's first; the side holding the larger area
    wins (written here: trimesh's ``fix_winding`` needs networkx)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order, connected_components

    n = len(F)
    d = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    tri = np.tile(np.arange(n), 3)
    _, inverse, counts = np.unique(_pair_keys(np.sort(d, axis=1)), return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    two = counts[inverse] == 2
    order = np.argsort(inverse[two], kind="stable")
    e_tri, e_dir = tri[two][order].reshape(-1, 2), d[two][order].reshape(-1, 2, 2)
    same = (e_dir[:, 0, 0] == e_dir[:, 1, 0])   # the shared edge run the same way: the two disagree
    a, b = e_tri[:, 0], e_tri[:, 1]
    sign = np.where(same, -1, 1)
    g = coo_matrix((np.ones(2 * len(a)), (np.r_[a, b], np.r_[b, a])), shape=(n, n)).tocsr()
    n_comp, comp = connected_components(g, directed=False)
    # one walk over every piece: a root node n joined to each piece's first triangle
    firsts = np.unique(comp, return_index=True)[1]
    a2, b2 = np.r_[a, np.full(n_comp, n)], np.r_[b, firsts]
    sign2 = np.r_[sign, np.ones(n_comp, int)]
    g = coo_matrix((np.ones(2 * len(a2)), (np.r_[a2, b2], np.r_[b2, a2])), shape=(n + 1, n + 1)).tocsr()
    keys = np.minimum(a2, b2).astype(np.int64) * (n + 1) + np.maximum(a2, b2)
    korder = np.argsort(keys)
    keys, ksign = keys[korder], sign2[korder]
    nodes, pred = breadth_first_order(g, n, directed=False, return_predecessors=True)
    v = nodes[1:]
    p = pred[v]
    step = ksign[np.searchsorted(keys, np.minimum(p, v).astype(np.int64) * (n + 1) + np.maximum(p, v))]
    parent, steps = np.full(n + 1, n, np.int64), np.ones(n + 1, np.int64)
    parent[v], steps[v] = p, step
    side = _tree_signs(parent, steps)[:n]
    area = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
    plus = np.bincount(comp, weights=area * (side == 1), minlength=n_comp)
    minus = np.bincount(comp, weights=area * (side == -1), minlength=n_comp)
    flip = side == np.where(plus < minus, 1, -1)[comp]
    return flip


def repaired_mesh(verts_mm: np.ndarray, faces: np.ndarray, source: str,
                  indexed: bool) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """(vertices mm, triangles, warnings) of a checked mesh: see the module docstring. BadInput when no triangle
    with an area is left."""
    import trimesh

    warnings: list[str] = []
    n_in = len(verts_mm)
    mesh = trimesh.Trimesh(verts_mm, faces, process=True)   # duplicate vertices merged exactly
    merged = n_in - len(mesh.vertices)
    if indexed and merged > 0:
        warnings.append(f"{source}: {merged} duplicate vertices merged")
    diag = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0))) if len(mesh.vertices) else 0.0
    if len(mesh.faces) > 1 and _isolated_share(np.asarray(mesh.faces)) > SOUP_SHARE and diag > 0:
        before = len(mesh.vertices)
        tol = WELD_SHARE * diag
        key = np.round(np.asarray(mesh.vertices) / tol).astype(np.int64)
        _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
        mesh = trimesh.Trimesh(np.asarray(mesh.vertices)[first], inverse.ravel()[np.asarray(mesh.faces)],
                               process=False)
        warnings.append(f"{source}: a triangle soup (most triangles share no edge): {before - len(mesh.vertices)} "
                        f"vertices within {tol:.2g} mm welded")
    F = np.asarray(mesh.faces, dtype=np.int64)
    V = np.asarray(mesh.vertices, dtype=float)
    if len(F):
        area2 = np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
        bad = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0]) \
            | (area2 <= DEGENERATE_AREA_SHARE * max(diag, 1e-300) ** 2)
    else:
        bad = np.zeros(0, bool)
    if len(F) == 0 or bad.all():
        raise BadInput(f"{source}: every one of its {len(F)} triangles is degenerate (no area); "
                       "the mesh holds no surface, export it again")
    if bad.any():
        warnings.append(f"{source}: {int(bad.sum())} of {len(F)} triangles are degenerate (no area) and were dropped")
        F = F[~bad]
    over = int((_edge_use(F) > 2).sum())
    if over:
        warnings.append(f"{source}: {over} edges are shared by more than two triangles (non-manifold); the "
                        "triangles are sampled as they are")
    if _wound_both_ways(F):   # a directed edge used twice: two neighbours wound against each other
        flip = _winding_flips(F, V)
        if flip.any():
            F = F.copy()
            F[flip] = F[flip][:, ::-1]
            warnings.append(f"{source}: {int(flip.sum())} of {len(F)} triangles were wound against their neighbours "
                            "and are turned to agree with them")
    used = np.flatnonzero(np.bincount(F.ravel(), minlength=len(V))) if bad.any() else None
    if used is not None and len(used) < len(V):   # vertices of dropped triangles only
        new = np.full(len(V), -1, np.int64)
        new[used] = np.arange(len(used))
        V, F = V[used], new[F]
    return V, F, tuple(warnings)
