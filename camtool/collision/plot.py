"""Plotly traces of the cell for report.html: the obstacles (from report.json's
``motion_check.cell.bodies``) and the robot's own link shapes at a configuration."""
from __future__ import annotations

import numpy as np

OBSTACLE_COLOR = "#d9822b"
ROBOT_COLOR = "#5b7fa6"
FLOOR_HALF_MM = 1500.0
DRAWN_HULL_VERTICES = 64   # a hull is drawn from at most this many of its vertices (display only)


def _box(size):
    x, y, z = (np.asarray(size, float) / 2.0)
    V = np.array([[sx * x, sy * y, sz * z] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    return V


def _mesh(shape: str, size, points):
    """Vertices (N, 3) and triangles (T, 3) of a shape in its own frame (mm)."""
    import trimesh

    if shape == "box":
        m = trimesh.creation.box(extents=size)
    elif shape == "cylinder":
        m = trimesh.creation.cylinder(radius=size[0], height=size[1], sections=24)
    elif shape == "sphere":
        m = trimesh.creation.icosphere(subdivisions=2, radius=size[0])
    elif shape == "capsule":
        m = trimesh.creation.capsule(height=size[1], radius=size[0], count=[10, 10])
    elif shape == "convex":
        m = trimesh.convex.convex_hull(_spread(np.asarray(points, float), DRAWN_HULL_VERTICES))
    else:
        return None
    return np.asarray(m.vertices), np.asarray(m.faces)


def _spread(points: np.ndarray, n: int) -> np.ndarray:
    """At most n of the points, spread by farthest-point sampling from the first (deterministic)."""
    if len(points) <= n:
        return points
    chosen = [0]
    d = np.linalg.norm(points - points[0], axis=1)
    for _ in range(n - 1):
        k = int(np.argmax(d))
        chosen.append(k)
        d = np.minimum(d, np.linalg.norm(points - points[k], axis=1))
    return points[chosen]


class RobotShapes:
    """The robot's link, base and tool bodies of a ``CollisionWorld`` as one triangle mesh to draw at
    any configuration, placed by the world's own body poses.

    Hulls are drawn from at most ``DRAWN_HULL_VERTICES`` of their vertices:
    a picture of the shapes the check measures, not the measure itself.
    """

    def __init__(self, world):
        self.world = world
        parts, faces, self.body, n = [], [], [], 0
        for index, b in enumerate(world.robot_bodies):
            mesh = _mesh(b.shape, b.size_mm, b.points_mm)
            if mesh is None:
                continue
            V, F = mesh
            parts.append(V)                   # in the body's own frame
            faces.append(F + n)
            self.body += [index] * len(V)     # which body each vertex draws
            n += len(V)
        self.local = np.vstack(parts) if parts else np.zeros((0, 3))
        self.faces = np.vstack(faces) if faces else np.zeros((0, 3), int)
        self.body = np.asarray(self.body, int)

    def vertices_mm(self, q) -> np.ndarray:
        """(N, 3) world vertices at joint values q (rad / mm)."""
        poses = np.asarray(self.world.body_poses_mm(self.world.joint_frames_mm(q)))[self.body]
        return np.einsum("nij,nj->ni", poses[:, :3, :3], self.local) + poses[:, :3, 3]

    def trace(self, go, q, name: str):
        V = np.round(self.vertices_mm(q), 1)
        return go.Mesh3d(x=V[:, 0], y=V[:, 1], z=V[:, 2], i=self.faces[:, 0], j=self.faces[:, 1],
                         k=self.faces[:, 2], name=name, showlegend=True, color=ROBOT_COLOR, opacity=0.45,
                         flatshading=True, hoverinfo="name")


def obstacle_traces(go, report: dict) -> list:
    """One Mesh3d per obstacle of the run's collision world (none without obstacles)."""
    cell = (report.get("motion_check") or {}).get("cell") or {}
    traces = []
    for b in cell.get("bodies", []):
        if b.get("kind") != "obstacle":
            continue
        if b["shape"] == "halfspace":
            z = b["size_mm"][0]
            h = FLOOR_HALF_MM
            V = np.array([[-h, -h, z], [h, -h, z], [h, h, z], [-h, h, z]])
            F = np.array([[0, 1, 2], [0, 2, 3]])
        else:
            mesh = _mesh(b["shape"], b["size_mm"], b.get("points_mm"))
            if mesh is None:
                continue
            V, F = mesh
            T = np.asarray(b["T_mm"], float)
            V = V @ T[:3, :3].T + T[:3, 3]
        traces.append(go.Mesh3d(x=np.round(V[:, 0], 1), y=np.round(V[:, 1], 1), z=np.round(V[:, 2], 1),
                                i=F[:, 0], j=F[:, 1], k=F[:, 2], name=f"obstacle {b['name']}", showlegend=True,
                                color=OBSTACLE_COLOR, opacity=0.35 if b["shape"] == "halfspace" else 0.6,
                                hoverinfo="name"))
    return traces
