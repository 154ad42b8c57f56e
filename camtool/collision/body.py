"""One collision body: a coal shape (mm) fixed in a joint frame, the robot's base or the world.

The data type every collision module shares (``shapes`` makes the robot's and the cell's
bodies, ``reference_links`` the manufacturer robots' meshes, ``world`` measures them).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import BadInput

MM_PER_M = 1000.0
WORLD, BASE = -1, 0


@dataclass(frozen=True)
class Body:
    """One collision body: a shape (mm) placed by ``local_T_mm`` in its parent frame.

    ``shape``: "capsule" (radius, length; axis z, centred), "cylinder" (radius,
    length), "box" (x, y, z, centred), "sphere" (radius,), "convex" (points in
    ``points_mm``), "halfspace" (z of the top; solid below, world frame).
    ``kind``: "link", "tool", "base" (fixed to the robot base) or "obstacle".
    """

    name: str
    kind: str
    parent: int
    shape: str
    size_mm: tuple[float, ...]
    local_T_mm: np.ndarray = field(repr=False)
    points_mm: np.ndarray | None = field(default=None, repr=False)

    @property
    def extent_mm(self) -> float:
        """Radius of a ball about the parent frame's origin that holds the whole body."""
        p = self.local_T_mm[:3, 3]
        if self.shape == "capsule" or self.shape == "cylinder":
            r, L = self.size_mm
            return float(np.linalg.norm(p) + np.hypot(r, L / 2.0) + r)
        if self.shape == "box":
            return float(np.linalg.norm(p) + 0.5 * np.linalg.norm(self.size_mm))
        if self.shape == "sphere":
            return float(np.linalg.norm(p) + self.size_mm[0])
        if self.shape == "convex":
            pts = self.points_mm @ self.local_T_mm[:3, :3].T + p
            return float(np.linalg.norm(pts, axis=1).max())
        return np.inf

    @property
    def ball_mm(self) -> tuple[np.ndarray, float]:
        """(centre in the body's own frame, radius) of a ball holding the whole body (mm); the
        halfspace gets an infinite one. The world's broad phase skips pairs whose balls are apart."""
        s = self.size_mm
        if self.shape == "convex":
            P = np.asarray(self.points_mm, float)
            c = 0.5 * (P.min(axis=0) + P.max(axis=0))
            return c, float(np.linalg.norm(P - c, axis=1).max())
        radius = {"capsule": lambda: s[1] / 2.0 + s[0], "cylinder": lambda: np.hypot(s[0], s[1] / 2.0),
                  "box": lambda: 0.5 * np.linalg.norm(s), "sphere": lambda: s[0]}.get(self.shape, lambda: np.inf)()
        return np.zeros(3), float(radius)

    def coal_geometry(self):
        """The coal shape (mm)."""
        import coal

        s = self.size_mm
        if self.shape == "capsule":
            return coal.Capsule(s[0], s[1])
        if self.shape == "cylinder":
            return coal.Cylinder(s[0], s[1])
        if self.shape == "box":
            return coal.Box(*s)
        if self.shape == "sphere":
            return coal.Sphere(s[0])
        if self.shape == "convex":
            return convex_hull(self.points_mm)
        if self.shape == "halfspace":
            return coal.Halfspace(np.array([0.0, 0.0, 1.0]), s[0])
        raise ValueError(self.shape)

    def describe(self) -> dict:
        d = {"name": self.name, "kind": self.kind, "parent": self.parent, "shape": self.shape,
             "size_mm": [round(float(x), 3) for x in self.size_mm],
             "xyz_mm": [round(float(x), 3) for x in self.local_T_mm[:3, 3]]}
        if self.points_mm is not None:
            d["hull_points"] = int(len(self.points_mm))
        if self.kind in ("obstacle", "tool"):   # enough to draw it (report.html)
            d["T_mm"] = np.round(self.local_T_mm, 4).tolist()
            if self.points_mm is not None:
                d["points_mm"] = np.round(self.points_mm, 2).tolist()
        return d


def convex_hull(points_mm: np.ndarray):
    """coal convex hull (qhull inside coal) of a point set (mm)."""
    import coal

    v = coal.StdVec_Vec3s()
    v.extend([np.asarray(p, float) for p in points_mm])
    return coal.Convex.convexHull(v, False, None)


def hull_points(points_mm: np.ndarray) -> np.ndarray:
    """The vertices of the convex hull of a point set (scipy's qhull): few points, fast queries."""
    from scipy.spatial import ConvexHull

    P = np.asarray(points_mm, float).reshape(-1, 3)
    if len(P) < 4:
        raise BadInput("a convex shape needs at least 4 points")
    try:
        return P[ConvexHull(P).vertices]
    except Exception as exc:  # qhull: flat or degenerate point sets
        raise BadInput(f"the mesh is flat or degenerate, no convex hull ({str(exc).splitlines()[0]})") from None


def mesh_points(path: Path, units: str, drop_damaged: bool = False) -> np.ndarray:
    """Vertices (mm) of a mesh file (the workpiece loader: every format and check it has).
    ``drop_damaged``: leave out triangles with non-finite or denormal coordinates (robot meshes:
    ROS-Industrial's carry 1e-33 m values) instead of refusing the file."""
    from ..part.workpiece import load_workpiece

    wp = load_workpiece(Path(path), units=units, sample_points=100, drop_nonfinite=drop_damaged)
    pts = wp.vertices_mm if wp.vertices_mm is not None else wp.points_mm
    return np.asarray(pts, float)


def se3_mm(M) -> np.ndarray:
    """4 x 4 (mm) of a Pinocchio SE3 (m)."""
    T = np.eye(4)
    T[:3, :3] = M.rotation
    T[:3, 3] = np.asarray(M.translation) * MM_PER_M
    return T


