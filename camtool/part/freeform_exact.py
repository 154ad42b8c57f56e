"""A CAD mesh face's exact heights over its chart plane, between the height field's nodes (issue #46).

A free-form face from a mesh is a height field sampled exactly at its grid's nodes (``freeform_sample.mesh_heights``,
the top-most triangle over each node) and bilinear between them. Where the face bends tightly and steeply
against its chart plane -- a car door's window frame, radius 8-25 mm, on a 2.6 mm grid -- the bilinear height is
off the triangles by up to 0.8 mm, and so were the raster's poses and the sag's midposes on it: the motion check
found the TCP 1.7 mm off the door. ``ChartMesh.heights`` gives the height of the same top-most triangle at any
chart point, so the surface's points are on the part's own facets wherever the face has one.

open3d's ``RaycastingScene`` (Embree) finds the triangle: a ray cast down the chart normal from above the face hits
the top-most triangle first, the z-buffer's rule. It works in float32, so the height is then taken in float64 from
the hit triangle's own plane (by hand: a barycentric solve, the mesh's vertices in chart coordinates).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

EDGE_ON_REL = 1e-12   # a triangle whose chart-plane area is this share of its extent squared is seen edge-on


@dataclass(frozen=True, eq=False)
class ChartMesh:
    """A mesh face in chart coordinates: ``vertices`` (n, 3) as (x, y, h) mm, ``faces`` (m, 3) indices."""

    vertices: np.ndarray
    faces: np.ndarray
    _scene: list = field(default_factory=list, repr=False)   # the raycasting scene, made on first use

    def __post_init__(self):
        object.__setattr__(self, "vertices", np.asarray(self.vertices, float))
        object.__setattr__(self, "faces", np.asarray(self.faces, np.int64))

    def __getstate__(self):   # the scene is open3d's and does not pickle: made again where needed
        return {"vertices": self.vertices, "faces": self.faces, "_scene": []}

    def __setstate__(self, state):
        for k, v in state.items():
            object.__setattr__(self, k, v)

    @staticmethod
    def of(vertices_chart: np.ndarray, faces: np.ndarray) -> "ChartMesh":
        """The mesh of ``faces`` with only the vertices they use (renumbered)."""
        F = np.asarray(faces, np.int64)
        used, inverse = np.unique(F, return_inverse=True)
        return ChartMesh(np.asarray(vertices_chart, float)[used], inverse.reshape(F.shape))

    def heights(self, x, y) -> np.ndarray:
        """Heights (mm) of the top-most triangle over chart points (x, y) (any matching shapes); NaN where none."""
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        out = np.full(x.shape, np.nan)
        ok = np.isfinite(x) & np.isfinite(y)
        if not ok.any() or not len(self.faces):
            return out
        px, py = x[ok], y[ok]
        tri = self._hit(px, py)
        h = np.full(len(px), np.nan)
        hit = tri >= 0
        T = self.vertices[self.faces[tri[hit]]]                       # (k, 3, 3)
        a, b = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
        det = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
        extent = np.abs(a[:, :2]).sum(1) * np.abs(b[:, :2]).sum(1)
        good = np.abs(det) > EDGE_ON_REL * np.maximum(extent, 1e-300)
        dx, dy = px[hit] - T[:, 0, 0], py[hit] - T[:, 0, 1]
        safe = np.where(good, det, 1.0)
        l1 = (dx * b[:, 1] - dy * b[:, 0]) / safe
        l2 = (a[:, 0] * dy - a[:, 1] * dx) / safe
        h[hit] = np.where(good, T[:, 0, 2] + l1 * a[:, 2] + l2 * b[:, 2], np.nan)
        out[ok] = h
        return out

    def along(self, points: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        """Points (k, 3) in chart coordinates taken onto the nearest triangle along their lines ``dirs`` (k, 3,
        unit; either way along them); NaN where neither way meets one. Where the face tilts far from its chart
        plane (a hull's bilge and bottom: 74 deg) a point moved down the chart normal lands millimetres along the
        surface from where it was; moved along the surface's own normal it does not. As ``heights``: open3d finds
        the triangle (float32), the point is taken in float64 on its plane."""
        from .open3d_import import import_open3d
        o3d = import_open3d()

        P, D = np.asarray(points, float).reshape(-1, 3), np.asarray(dirs, float).reshape(-1, 3)
        out = np.full(P.shape, np.nan)
        if not len(P) or not len(self.faces):
            return out
        scene = self._raycasting()
        best_t, best_tri = np.full(len(P), np.inf), np.full(len(P), -1, np.int64)
        for sign in (1.0, -1.0):
            rays = np.hstack([P, sign * D]).astype(np.float32)
            ans = scene.cast_rays(o3d.core.Tensor(rays))
            t = ans["t_hit"].numpy().astype(float)
            prim = ans["primitive_ids"].numpy().astype(np.int64)
            nearer = np.isfinite(t) & (prim != o3d.t.geometry.RaycastingScene.INVALID_ID) & (t < best_t)
            best_t[nearer], best_tri[nearer] = t[nearer], prim[nearer]
        hit = best_tri >= 0
        T = self.vertices[self.faces[best_tri[hit]]]
        n = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
        dn = np.einsum("ij,ij->i", D[hit], n)
        good = np.abs(dn) > 1e-12 * np.maximum(np.linalg.norm(n, axis=1), 1e-300)
        lam = np.einsum("ij,ij->i", T[:, 0] - P[hit], n) / np.where(good, dn, 1.0)
        out[np.flatnonzero(hit)[good]] = (P[hit] + lam[:, None] * D[hit])[good]
        return out

    def nearest(self, points: np.ndarray) -> np.ndarray:
        """Points (k, 3) in chart coordinates taken to their nearest point on the triangles (open3d finds the
        triangle, float32; the point is taken on it in float64)."""
        from trimesh.triangles import closest_point

        from .open3d_import import import_open3d
        o3d = import_open3d()

        P = np.asarray(points, float).reshape(-1, 3)
        if not len(P) or not len(self.faces):
            return np.full(P.shape, np.nan)
        prim = self._raycasting().compute_closest_points(o3d.core.Tensor(P.astype(np.float32)))["primitive_ids"]
        return closest_point(self.vertices[self.faces[prim.numpy().astype(np.int64)]], P)

    def _raycasting(self):
        """open3d's scene of the triangles, made once."""
        from .open3d_import import import_open3d
        o3d = import_open3d()

        if not self._scene:
            scene = o3d.t.geometry.RaycastingScene()
            scene.add_triangles(o3d.core.Tensor(self.vertices.astype(np.float32)),
                                o3d.core.Tensor(self.faces.astype(np.uint32)))
            self._scene.append(scene)
        return self._scene[0]

    def _hit(self, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        """The index of the top-most triangle over each point (-1: none), cast down the chart normal."""
        from .open3d_import import import_open3d
        o3d = import_open3d()

        top = float(self.vertices[:, 2].max()) + 1.0
        rays = np.zeros((len(px), 6), np.float32)
        rays[:, 0], rays[:, 1], rays[:, 2], rays[:, 5] = px, py, top, -1.0
        prim = self._raycasting().cast_rays(o3d.core.Tensor(rays))["primitive_ids"].numpy().astype(np.int64)
        return np.where(prim == o3d.t.geometry.RaycastingScene.INVALID_ID, -1, prim)
