"""Triangles folded back onto the surface beside them (a CAD surface that folds over itself).

A B-spline patch whose control net crosses itself maps a small region of its (u, v) domain back over the
surface it has just made: the tessellation then holds a Z-fold, three coplanar layers (on, back, on again),
every triangle wound consistently with its neighbours, the middle layer facing the other way. The ship
hull of ``benchmarks/parts/freeform/optiwise_hull.step`` has 26 such places (slivers of up to 0.8 mm2,
up to 7.8 mm long, inside one B-rep face). Nothing there is behind the surface; but a point in front of it
whose closest triangle is the middle layer reads as behind it (the motion check found the tool 10 and 15 mm
"in" the hull on self-motions that passed 10 mm in front of it).

A triangle is **folded** when
- its normal is turned more than ``FOLD_DEG`` from a neighbour's across a shared edge (the fold's crease),
- its normal is turned more than ``AGAINST_DEG`` from the area-weighted mean normal of the mesh's
  triangles around it (their centroids within ``REACH_MM`` of its own, or within its own size where that is
  larger: on a coarse mesh no other centroid lies within a few mm) (the surface it lies on faces the other way),
  that mean holding at least ``AGREE_SHARE`` of their area (the surface there has one side: not both faces of a
  thin wall),
- and its corners lie within ``ON_MM`` of triangles that face the other way, among those around it and those
  sharing its corners (it lies on that surface: a thin wall's other face, a millimetre behind, is no fold).

The reach demo shell (``reach_demo_part.ply``, 16-165 mm triangles) has the other shape of fold: two triangles
(1895 and 3908) turned over inside the surface, each lying flat under its three neighbours, which fold back over
it (180 deg at each of its edges) and face the surface's way: the middle layer again, its neighbours the
layers on either side. Sought within 5 mm only, they were missed (no centroid but one lies that near theirs).

Written by hand (trimesh and open3d repair windings, not folds: the fold's windings agree); its
neighbours are trimesh's ``graph.face_adjacency``, its closest-point test trimesh's ``triangles.closest_point``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial import cKDTree

FOLD_DEG = 120.0      # a crease this sharp between neighbours may be a fold
AGAINST_DEG = 120.0   # a triangle turned this far from the surface around it faces against it
REACH_MM = 5.0        # the surface around a triangle: triangles whose centroids lie this near its own
AGREE_SHARE = 0.5     # that surface has one side when its mean normal holds this share of its area
ON_MM = 0.01          # a triangle lies on a surface when its corners are this near it


@dataclass(frozen=True)
class Folds:
    """The triangles folded back onto the surface beside them: a mask, and their largest area (mm2)."""

    mask: np.ndarray
    largest_mm2: float

    @property
    def count(self) -> int:
        return int(self.mask.sum())


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)


class _Surround:
    """The tests of triangles against the surface around them (module docstring)."""

    def __init__(self, F: np.ndarray, tri: np.ndarray, area: np.ndarray, N: np.ndarray):
        self.F, self.tri, self.area, self.N = F, tri, area, N
        self.centroid = tri.mean(axis=1)
        self.size = np.linalg.norm(tri - self.centroid[:, None], axis=2).max(axis=1)   # centroid to farthest corner
        self.tree = cKDTree(self.centroid)
        self.cos_against = np.cos(np.radians(AGAINST_DEG))
        corner = F.ravel()
        self.by_vertex = np.argsort(corner, kind="stable") // 3                  # the triangles at each vertex ...
        self.vertex_start = np.searchsorted(corner[np.argsort(corner, kind="stable")], np.arange(F.max() + 2))

    def _around(self, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(k, j): triangle k lies around ``ts[j]`` (its centroid within ``REACH_MM``, or the triangle's own size
        where that is larger: a coarse mesh's triangles are far apart), the triangle itself left out."""
        pairs = self.tree.sparse_distance_matrix(cKDTree(self.centroid[ts]), REACH_MM, output_type="ndarray")
        k, j = pairs["i"].astype(np.int64), pairs["j"].astype(np.int64)
        big = np.flatnonzero(self.size[ts] > REACH_MM)
        if len(big):
            keep = ~np.isin(j, big)
            found = self.tree.query_ball_point(self.centroid[ts[big]], self.size[ts[big]], return_sorted=True)
            k = np.r_[k[keep], np.concatenate([np.asarray(f, np.int64) for f in found])]
            j = np.r_[j[keep], np.repeat(big, [len(f) for f in found])]
        other = k != ts[j]
        return k[other], j[other]

    def _ring(self, t: int) -> np.ndarray:
        """The triangles that share a corner with ``t`` (``t`` included)."""
        return np.concatenate([self.by_vertex[self.vertex_start[v]:self.vertex_start[v + 1]] for v in self.F[t]])

    def folded(self, ts: np.ndarray) -> np.ndarray:
        """Which of the triangles ``ts`` face against the one-sided surface around them and lie on it: the mean
        normals of all at once (a sparse sum over the pairs around them), the closest points of the few left one by
        one, against the triangles around them and those sharing their corners."""
        ts = np.asarray(ts, np.int64)
        k, j = self._around(ts)
        w = self.area[k]
        summed = np.stack([np.bincount(j, w * self.N[k, c], minlength=len(ts)) for c in range(3)], axis=1)
        held = np.linalg.norm(summed, axis=1)
        against = (held >= AGREE_SHARE * np.bincount(j, w, minlength=len(ts))) & (held > 0) \
            & (np.einsum("ij,ij->i", self.N[ts], summed) <= self.cos_against * held) & (self.area[ts] > 0)
        out = np.zeros(len(ts), bool)
        for i in np.flatnonzero(against):
            out[i] = self._lies_on_against(int(ts[i]), np.unique(np.r_[k[j == i], self._ring(int(ts[i]))]))
        return out

    def _lies_on_against(self, t: int, near: np.ndarray) -> bool:
        """Whether triangle ``t``'s corners lie within ``ON_MM`` of triangles among ``near`` that face against it
        (trimesh's closest points)."""
        other = near[self.N[near] @ self.N[t] < self.cos_against]
        size = np.linalg.norm(self.tri[other] - self.centroid[other][:, None], axis=2).max(axis=1)
        for c in self.tri[t]:   # each corner against the triangles whose reach holds it
            o = other[np.linalg.norm(self.centroid[other] - c, axis=1) <= size + ON_MM]
            if not len(o) or np.linalg.norm(trimesh.triangles.closest_point(
                    self.tri[o], np.repeat(c[None], len(o), axis=0)) - c, axis=1).min() > ON_MM:
                return False
        return True


def folded_triangles(verts_mm: np.ndarray, faces: np.ndarray) -> Folds:
    """The triangles of a mesh folded back onto the surface beside them (module docstring): those at a crease
    first, then, across smooth edges, the rest of the layer they start (each tested as they were)."""
    V, F = np.asarray(verts_mm, float), np.asarray(faces, np.int64)
    mask = np.zeros(len(F), bool)
    if len(F) < 3:
        return Folds(mask, 0.0)
    tri = V[F]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    N = _unit(cross)
    a, b = trimesh.graph.face_adjacency(F).T   # (its pairs on a non-manifold edge are dropped: a fold's
    # crease is manifold)
    sharp = np.einsum("ij,ij->i", N[a], N[b]) < np.cos(np.radians(FOLD_DEG))
    if not sharp.any():
        return Folds(mask, 0.0)
    surround = _Surround(F, tri, area, N)
    tested = np.zeros(len(F), bool)
    todo = np.unique(np.r_[a[sharp], b[sharp]])
    smooth_a, smooth_b = np.r_[a[~sharp], b[~sharp]], np.r_[b[~sharp], a[~sharp]]
    order = np.argsort(smooth_a, kind="stable")
    smooth_a, smooth_b = smooth_a[order], smooth_b[order]
    while len(todo):
        tested[todo] = True
        found = todo[surround.folded(todo)]
        mask[found] = True
        lo, hi = np.searchsorted(smooth_a, found), np.searchsorted(smooth_a, found, side="right")
        nxt = np.concatenate([smooth_b[i:j] for i, j in zip(lo, hi)]) if len(found) else np.zeros(0, np.int64)
        todo = np.unique(nxt[~tested[nxt]])
    return Folds(mask, float(area[mask].max()) if mask.any() else 0.0)
