"""Closest points on a triangle mesh, from coal's BVH distance (double precision).

``MeshQuery(mesh)`` builds coal's OBBRSS tree of a trimesh once; ``closest(P)``
gives, for each point, the nearest point on the surface and its triangle;
``distance(P)`` the unsigned distance; ``signed_distance(P)`` the distance made
negative inside a watertight mesh (trimesh's ray parity test decides inside).

coal answers one point at a time (a zero-radius sphere against the tree, about
20 us a point); the free-move checker queries a few thousand points a job, so
this costs less than loading open3d (0.7 s and 170 MB) for its batched query.
"""
from __future__ import annotations

import coal
import numpy as np

from ..errors import BadInput


def mesh_bvh(vertices_mm, faces):
    """coal's OBBRSS tree of a triangle mesh (its vertices' frame, mm)."""
    V = np.asarray(vertices_mm, float)
    F = np.asarray(faces, np.int64)
    tree = coal.BVHModelOBBRSS()
    tree.beginModel(len(F), len(V))
    tree.addVertices(V)
    tree.addTriangles(F)
    tree.endModel()
    return tree


class MeshQuery:
    """Nearest-point queries against one triangle mesh (mm, the mesh's frame)."""

    def __init__(self, mesh):
        V = np.asarray(mesh.vertices, float)
        F = np.asarray(mesh.faces, np.int64)
        if len(F) == 0:
            raise BadInput("the collision check needs a triangle mesh of the workpiece")
        self.mesh = mesh
        self.tree = mesh_bvh(V, F)
        self._point = coal.Sphere(0.0)
        self._request = coal.DistanceRequest()
        self._result = coal.DistanceResult()
        self._identity = coal.Transform3s()

    def closest(self, points_mm) -> tuple[np.ndarray, np.ndarray]:
        """Nearest surface point (N, 3) mm and its triangle index (N,) for each point (N, 3) mm."""
        P = np.asarray(points_mm, float).reshape(-1, 3)
        near = np.empty_like(P)
        triangle = np.empty(len(P), np.int64)
        res, req, ball, eye = self._result, self._request, self._point, self._identity
        at = coal.Transform3s()
        for i, p in enumerate(P):
            res.clear()
            at.setTranslation(p)
            coal.distance(self.tree, eye, ball, at, req, res)
            near[i] = res.getNearestPoint1()
            triangle[i] = res.b1
        return near, triangle

    def distance(self, points_mm) -> np.ndarray:
        """Unsigned distance (N,) mm of each point from the surface."""
        P = np.asarray(points_mm, float).reshape(-1, 3)
        return np.linalg.norm(P - self.closest(P)[0], axis=1)

    def signed_distance(self, points_mm) -> np.ndarray:
        """Distance (N,) mm, negative inside; for a watertight mesh only (an open one has no inside)."""
        if not self.mesh.is_watertight:
            raise BadInput("a signed distance needs a closed (watertight) mesh")
        P = np.asarray(points_mm, float).reshape(-1, 3)
        d = self.distance(P)
        if len(P):
            d[self.mesh.contains(P)] *= -1.0
        return d
