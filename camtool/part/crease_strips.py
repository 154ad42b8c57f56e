"""Strips between creases: a CAD mesh's narrow faces that the smooth regions' sample cannot see (issue #46).

``freeform_faces.smooth_regions`` works on a strided sample of the points (at most 20 000: 5 mm apart on the
0.5 m^2 TOOLING4G mould) and marks every sample point within ``EDGE_SPACINGS`` spacings of a crease as an edge
point, which joins a region only through a neighbour whose normal agrees within ``sharp_edge_deg``. A strip
narrower than that band and creased on both long sides (the mould's 7 mm chamfer at the foot of a wall, 41 deg
from the wall and 33-36 deg from the floor) holds edge points only: no region took them, and the strip stayed as
three small planes RANSAC found along it and points on no face (4 % of the trough's area uncovered).

The mesh holds the strip exactly: its triangles, joined across edges where they turn by at most
``STRIP_LINK_DEG`` (trimesh's face adjacency angles), make a piece bounded by the creases on either side. A piece
is a strip when most of its sample points are on no region (``smooth_regions`` saw only its edge) and it holds
at least ``min_points`` of them; a piece of a smooth region (a trough's floor, a fillet's facets) holds that
region's points and is none. Each strip becomes a region of its own, numbered after the others, and every
workpiece point lying on its triangles is its (``on_triangles``: the points are sampled from those triangles).
A strip is then a region like the others (analytic where RANSAC's faces hold it, free-form where they do not),
but needs no share of the sample: it is narrow by definition.

- Only the free-form strips are kept (``only_free_strips``): an analytic one (a planar chamfer, a block's top all
  within the band of its rims) stays as RANSAC found it and its points as they were, so the faces of a part
  without a free-form strip do not change.
- Only on a CAD mesh (``cad_mesh``): a scanned mesh's crumpled rims gave half a dozen strips of no use (the
  reach demo's shell, 16-165 mm triangles).
- A free-form strip's face is traced from its points and a lattice of points ``LATTICE_MM`` apart on its own
  triangles (``dense_strip``): the face's material is the workpiece's random points dilated by about their
  spacing, closed and eroded back, and across a strip three points wide one 5 mm gap of the random sample broke
  it in two (the face held half the mould's chamfer).
- ``STRIP_LINK_DEG`` is tighter than ``sharp_edge_deg``: where the mould's chamfer ends it turns smoothly into the
  fillets at the trough's ends and on into the wall and the floor; joined at 30 deg, the trough, its chamfer and
  the block's top were one piece.
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

STRIP_LINK_DEG = 10.0   # a strip's triangles are joined across edges turning by at most this
LATTICE_MM = 1.0        # a strip's face is traced from points this far apart on its triangles (its grid's cell)
ON_MESH_MM = 1e-6       # a point this near a triangle lies on it (the points are sampled from the triangles)
UNSEEN_SHARE = 0.5      # a piece is a strip when more than this share of its sample points are on no region


def cad_mesh(workpiece) -> bool:
    """Whether the workpiece is a mesh judged CAD, not a scan (``roughness.mesh_is_scan`` by its ``workpiece.scan``,
    as the free-form face judges it)."""
    from .roughness import mesh_is_scan

    V, F = getattr(workpiece, "vertices_mm", None), getattr(workpiece, "faces", None)
    if V is None or F is None or len(F) < 2:
        return False
    return not mesh_is_scan(V, getattr(workpiece, "scan", "auto"), F)


def triangle_pieces(vertices_mm: np.ndarray, faces: np.ndarray, link_deg: float = STRIP_LINK_DEG) -> np.ndarray:
    """Each triangle's piece: the triangles joined across mesh edges where their normals turn by at most
    ``link_deg`` (unsigned, as ``creases``), as connected components."""
    import trimesh

    mesh = trimesh.Trimesh(np.asarray(vertices_mm, float), np.asarray(faces, np.int64), process=False, validate=False)
    angle = np.degrees(np.asarray(mesh.face_adjacency_angles, float))
    angle = np.minimum(angle, 180.0 - angle)
    adj = np.asarray(mesh.face_adjacency, np.int64)[np.isfinite(angle) & (angle <= link_deg)]
    n = len(mesh.faces)
    graph = coo_matrix((np.ones(len(adj)), (adj[:, 0], adj[:, 1])), shape=(n, n))
    return connected_components(graph, directed=False)[1]


def on_triangles(P: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Index into ``triangles`` (k, 3, 3) of a triangle each point lies on (within ``ON_MESH_MM``), -1 for none."""
    import trimesh

    from .box_grid import BoxGrid

    out = np.full(len(P), -1, np.int64)
    if len(triangles) == 0 or len(P) == 0:
        return out
    grid = BoxGrid(triangles.min(axis=1) - ON_MESH_MM, triangles.max(axis=1) + ON_MESH_MM, P)
    row, hit = grid.holding(P)
    if len(hit):
        close = trimesh.triangles.closest_point(triangles[hit], P[row])
        on = np.einsum("ij,ij->i", P[row] - close, P[row] - close) <= ON_MESH_MM ** 2
        out[row[on]] = hit[on]
    return out


def strip_regions(workpiece, pick: np.ndarray, region: np.ndarray, min_points: int):
    """(the sample's region labels with the strips added, numbered after the regions; the strips' labels; each
    workpiece point's strip label, -1 for none). ``pick``: the sample's indices into the workpiece's points;
    ``region``: ``smooth_regions``' labels of the sample (-1: none)."""
    P = np.asarray(workpiece.points_mm, float)
    V, F = np.asarray(workpiece.vertices_mm, float), np.asarray(workpiece.faces, np.int64)
    out, point_strip = np.asarray(region, np.int64).copy(), np.full(len(P), -1, np.int64)
    unseen = np.flatnonzero(out < 0)
    if len(unseen) < min_points or len(F) < 2:
        return out, [], point_strip
    piece = triangle_pieces(V, F)
    triangles = V[F]
    on = on_triangles(P[pick], triangles)
    held = on >= 0
    n_piece = int(piece.max()) + 1
    total = np.bincount(piece[on[held]], minlength=n_piece)
    free = np.bincount(piece[on[held]], weights=(out[held] < 0).astype(float), minlength=n_piece)
    strips = np.flatnonzero((free >= min_points) & (free > UNSEEN_SHARE * np.maximum(total, 1)))
    strips = strips[np.argsort(-free[strips], kind="stable")]     # largest first, as the regions
    if len(strips) == 0:
        return out, [], point_strip
    first = int(out.max()) + 1
    label_of = np.full(n_piece, -1, np.int64)
    label_of[strips] = first + np.arange(len(strips))
    tri_strip = label_of[piece]
    mine = np.flatnonzero(tri_strip >= 0)
    at = on_triangles(P, triangles[mine])
    point_strip[at >= 0] = tri_strip[mine[at[at >= 0]]]
    sample_strip = np.where(held, tri_strip[np.maximum(on, 0)], -1)
    out = np.where((out < 0) & (sample_strip >= 0), sample_strip, out)
    return out, [int(x) for x in label_of[strips]], point_strip


def only_free_strips(region: np.ndarray, point_strip, strips: list[int], free: list[int]):
    """(sample labels, workpiece points' strip labels) with the strips that are not free-form undone: their
    sample points on no region again, their workpiece points on no strip."""
    undo = [r for r in strips if r not in free]
    if not undo:
        return region, point_strip
    return np.where(np.isin(region, undo), -1, region), np.where(np.isin(point_strip, undo), -1, point_strip)


def on_strips(nearest_region: np.ndarray, point_strip: np.ndarray, strips: list[int]) -> np.ndarray:
    """Each workpiece point's region: its strip's where it lies on one (``point_strip``), else its nearest sample
    point's (``nearest_region``) unless that is a strip's: a point beside a strip (on the wall above a chamfer) whose
    nearest sample point lies on the strip is no point of it."""
    return np.where(point_strip >= 0, point_strip, np.where(np.isin(nearest_region, strips), -1, nearest_region))


def dense_strip(workpiece, idx: np.ndarray, point_region: np.ndarray, r: int):
    """(the workpiece with points added on a lattice ``LATTICE_MM`` apart on the triangles the points ``idx`` lie
    on, each with its triangle's normal turned to the side of those points'; ``idx`` with the added points; the
    region labels with them labelled r). The added points come after the workpiece's own (index >= its count)."""
    from .workpiece import Workpiece

    P, NP = np.asarray(workpiece.points_mm, float), np.asarray(workpiece.normals, float)
    V, F = np.asarray(workpiece.vertices_mm, float), np.asarray(workpiece.faces, np.int64)
    T = V[F]
    tri = on_triangles(P[idx], T)
    mine = np.unique(tri[tri >= 0])
    pts, nrm = [], []
    for t in mine:
        a, b, c = T[t]
        k = max(1, int(np.ceil(max(np.linalg.norm(b - a), np.linalg.norm(c - b), np.linalg.norm(a - c)) / LATTICE_MM)))
        i, j = np.triu_indices(k + 1)
        u, v = (k - j) / k, (j - i) / k           # barycentric (u, v, 1 - u - v) on a lattice, u + v <= 1
        pts.append(a + u[:, None] * (b - a) + v[:, None] * (c - a))
        n = np.cross(b - a, c - a)
        n = n / max(np.linalg.norm(n), 1e-300)
        side = NP[idx][tri == t].sum(axis=0)
        nrm.append(np.repeat((n if n @ side >= 0 else -n)[None], len(pts[-1]), axis=0))
    if not pts:
        return workpiece, idx, point_region
    extra, extra_n = np.concatenate(pts), np.concatenate(nrm)
    dense = Workpiece(np.concatenate([P, extra]), np.concatenate([NP, extra_n]), workpiece.faces, workpiece.source,
                      workpiece.units, (), workpiece.vertices_mm, getattr(workpiece, "scan", "auto"))
    added = np.arange(len(P), len(P) + len(extra))
    return dense, np.concatenate([idx, added]), np.concatenate([point_region, np.full(len(extra), r, np.int64)])
