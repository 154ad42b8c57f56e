"""Plotly traces of the cell's obstacles for report.html (from report.json's ``motion_check.cell.bodies``)."""
from __future__ import annotations

import numpy as np

OBSTACLE_COLOR = "#d9822b"
FLOOR_HALF_MM = 1500.0


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
    elif shape == "convex":
        m = trimesh.convex.convex_hull(np.asarray(points, float))
    else:
        return None
    return np.asarray(m.vertices), np.asarray(m.faces)


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
