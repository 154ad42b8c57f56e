"""A STEP part's free-form B-rep faces as free-form faces (issue #46).

``faces.step_segmentation`` takes a STEP part's plane, sphere and cylinder B-rep faces exactly. Every
other face (B-spline, Bezier, revolution, extrusion, offset, cone, torus: ``model == "other"``) is a
free-form face here, made as the mesh path makes one (``freeform_faces.mesh_region_faces``:
``freeform.freeform_surface`` on the face's own OCP tessellation, ``step.DEFLECTION_MM`` from the B-rep,
so its points lie on the part's own triangles; a region one height field cannot hold is cut into charts).

**Tangent B-rep faces are one face.** A car panel or a blade is exported as several patches meeting
tangentially (G1); a process engineer picks the panel, not its patches. Two non-analytic B-rep faces
are one region where they meet across tessellation edges whose dihedral angle (unsigned, as
``creases`` takes it) is at most ``faces.sharp_edge_deg`` (median over their shared edges): the crease
key of the mesh path. A sharp edge keeps them apart. Analytic faces are not joined to them: they keep
their exact surface and their boundary on the B-rep edges (the edge pass counts the points of the B-rep
faces made free-form as another face's, never an analytic face's extent).

The patches of an open shell need not agree on a side: a group's faces are wound as its first face
(``reversed_faces``: across a seam whose normals turn past 90 deg the neighbour is wound the other way).

A free-form face's boundary is the material of its own triangles, so it ends on the B-rep edges that
bound its patches. Where the region's faces hold less than ``MIN_HELD_SHARE`` of its points (too few
points, a region no chart holds), its B-rep faces are tried one by one, and what still gives none goes to
RANSAC, as before (where RANSAC finds nothing in those leftovers, they stay on no face).

The shared edges are found on the tessellation: OCP tessellates each edge once for both of its faces,
so their nodes coincide; nodes within ``MERGE_MM`` are merged (by hand: a union of the pairs a KD-tree
finds, since trimesh merges only to its own fixed digits).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

MERGE_MM = 1e-3   # tessellation nodes of two B-rep faces this close are one node of their shared edge
ORIENT_SEAM_DEG = 45.0   # a seam tells two faces' sides only when their normals are within this of (anti)parallel
MIN_HELD_SHARE = 0.5     # a tangent group whose free-form faces hold less of its points is tried face by face


@dataclass(frozen=True)
class BrepMesh:
    """The placed tessellation of a STEP part: vertices (mm, world), triangles, each triangle's B-rep face."""

    vertices_mm: np.ndarray
    triangles: np.ndarray
    owner: np.ndarray


def _merged(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """``F`` with nodes closer than ``MERGE_MM`` renumbered to one (the lowest index of their cluster)."""
    used = np.unique(F)
    pairs = cKDTree(V[used]).query_pairs(MERGE_MM, output_type="ndarray")
    n = len(used)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, comp = connected_components(graph, directed=False)
    first = np.full(int(comp.max()) + 1, n, np.int64)
    np.minimum.at(first, comp, np.arange(n))
    canon = np.zeros(int(V.shape[0]), np.int64)
    canon[used] = used[first[comp]]
    return canon[F]


def _seams(mesh: BrepMesh, faces: np.ndarray) -> dict[tuple[int, int], float]:
    """Each pair (p, q), p < q, of the B-rep faces ``faces`` that share tessellation edges: the median angle
    (deg, 0..180) between their triangles' normals across those edges (near 180: the same surface wound the
    other way)."""
    import trimesh

    tri = np.flatnonzero(np.isin(mesh.owner, faces))
    F = _merged(mesh.vertices_mm, mesh.triangles[tri])
    tm = trimesh.Trimesh(mesh.vertices_mm, F, process=False, validate=False)
    pairs = np.asarray(tm.face_adjacency, np.int64).reshape(-1, 2)
    angle = np.degrees(np.asarray(tm.face_adjacency_angles, float))
    a, b = mesh.owner[tri[pairs[:, 0]]], mesh.owner[tri[pairs[:, 1]]]
    cross = (a != b) & np.isfinite(angle)
    lo, hi, angle = np.minimum(a[cross], b[cross]), np.maximum(a[cross], b[cross]), angle[cross]
    key = lo * (int(mesh.owner.max()) + 1) + hi
    order = np.argsort(key, kind="stable")
    key, lo, hi, angle = key[order], lo[order], hi[order], angle[order]
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]]) if len(key) else np.zeros(0, np.int64)
    return {(int(lo[s]), int(hi[s])): float(np.median(angle[s:e])) for s, e in zip(starts, np.r_[starts[1:], len(key)])}


def tangent_groups(mesh: BrepMesh, faces: np.ndarray, sharp_edge_deg: float) -> list[np.ndarray]:
    """The B-rep faces ``faces`` (indices) in groups that meet tangentially (module docstring), each group
    ascending, the groups by their first face."""
    faces = np.asarray(faces, np.int64)
    if len(faces) < 2:
        return [faces] if len(faces) else []
    slot = {int(f): k for k, f in enumerate(faces)}
    joined = [(slot[p], slot[q]) for (p, q), ang in _seams(mesh, faces).items()
              if min(ang, 180.0 - ang) <= sharp_edge_deg]
    n = len(faces)
    rows = [p for p, _ in joined]
    cols = [q for _, q in joined]
    graph = coo_matrix((np.ones(len(joined)), (rows, cols)), shape=(n, n))
    _, comp = connected_components(graph, directed=False)
    groups = [faces[comp == c] for c in range(int(comp.max()) + 1)]
    return sorted(groups, key=lambda g: int(g[0]))


def reversed_faces(mesh: BrepMesh, group: np.ndarray) -> np.ndarray:
    """The B-rep faces of a tangent group wound against its first face (an open shell's patches need not agree on
    a side): across a tangent seam (normals within ``ORIENT_SEAM_DEG`` of parallel or antiparallel) whose normals
    turn by more than 90 deg the neighbour is wound the other way; taken breadth first from the group's first face."""
    group = np.asarray(group, np.int64)
    seams = _seams(mesh, group) if len(group) > 1 else {}
    flip = {int(group[0]): False}
    todo = [int(group[0])]
    while todo:
        p = todo.pop(0)
        for (a, b), ang in sorted(seams.items()):
            q = b if a == p else a if b == p else None
            if q is not None and q not in flip and min(ang, 180.0 - ang) <= ORIENT_SEAM_DEG:
                flip[q] = flip[p] != (ang > 90.0)
                todo.append(q)
    return np.array(sorted(k for k, v in flip.items() if v), np.int64)


def _group_faces(mesh: BrepMesh, group: np.ndarray, idx: np.ndarray, point_face: np.ndarray, workpiece,
                 settings) -> list:
    """The free-form faces ``(surface, inliers)`` of one group of B-rep faces whose points are ``idx``
    (``point_face``: each workpiece point's B-rep face), its faces wound as its first one."""
    from .freeform_faces import mesh_region_faces
    from .sampling import MIN_FACE_SAMPLES
    from .workpiece import Workpiece

    if len(idx) < max(MIN_FACE_SAMPLES, 100):
        return []
    mine = np.isin(mesh.owner, group)
    flipped = reversed_faces(mesh, group)
    F = np.where(np.isin(mesh.owner[mine], flipped)[:, None], mesh.triangles[mine][:, ::-1], mesh.triangles[mine])
    N = np.asarray(workpiece.normals, float)[idx]
    if len(flipped):   # the points of the faces wound the other way turn their normals with them
        N = np.where(np.isin(point_face[idx], flipped)[:, None], -N, N)
    region = Workpiece(np.asarray(workpiece.points_mm, float)[idx], N, F, workpiece.source, workpiece.units, (),
                       mesh.vertices_mm)
    built = mesh_region_faces(region, settings.threshold_mm, settings.close_gaps_mm)
    return [(s, idx[local]) for s, local, area in built
            if area >= settings.min_area_mm2 and len(local) >= MIN_FACE_SAMPLES]


def freeform_step_faces(mesh: BrepMesh, other: np.ndarray, point_face: np.ndarray, points_of, workpiece,
                        settings) -> tuple[list, list]:
    """The free-form faces ``(surface, inliers)`` of the non-analytic B-rep faces ``other``, and the points
    (index arrays) of those that gave none (for RANSAC). ``point_face``: each workpiece point's B-rep face;
    ``points_of(k)``: the workpiece points of B-rep face k. ``settings``: ``SegmentSettings``."""
    built, rest = [], []
    for group in tangent_groups(mesh, other, settings.sharp_edge_deg):
        idx = np.sort(np.concatenate([points_of(int(k)) for k in group]))
        faces = _group_faces(mesh, group, idx, point_face, workpiece, settings)
        held = sum(len(i) for _, i in faces)
        if len(group) > 1 and held < MIN_HELD_SHARE * len(idx):   # the region gives no face: its B-rep faces one by one
            faces = []
            for k in group:
                mine = points_of(int(k))
                one = _group_faces(mesh, np.array([k]), mine, point_face, workpiece, settings)
                faces += one
                if not one:
                    rest.append(mine)
        elif not faces:
            rest.append(idx)
        built += faces
    return built, rest
