"""A mesh's sharp edges (creases): the mesh edges whose two triangles turn by more than an angle, as points along them.

The free-form faces' edge test (``freeform_faces.smooth_regions``) compares the normals of a
sample of points a few point spacings apart. That spacing grows with the part (a 1.4 m car
door's 20 000-point sample lies 3.4 mm apart), so on a large part it reads a tight but smooth
bend (a door's window frame turning at radius 8-25 mm) as an edge. A CAD mesh holds the true
dihedral angle at each of its edges, independent of any sample: this module gives the edges
where it exceeds ``sharp_edge_deg``, for the edge test to mark the points near them.

trimesh gives the adjacency and the angle between the two triangles' normals
(``face_adjacency_angles``); the angle is taken unsigned (a turn of a and of 180 - a are one
crease, as in the sample's test, whose scans carry unoriented normals).
"""
from __future__ import annotations

import numpy as np
import trimesh


def crease_points(vertices_mm: np.ndarray, faces: np.ndarray, sharp_edge_deg: float, step_mm: float) -> np.ndarray:
    """Points (k x 3, mm) along every mesh edge whose two triangles' normals differ (unsigned) by more than
    ``sharp_edge_deg``, at most ``step_mm`` apart, both ends included. Empty (0 x 3) when there is none."""
    V = np.asarray(vertices_mm, float)
    F = np.asarray(faces, np.int64)
    if len(F) < 2 or step_mm <= 0:
        return np.zeros((0, 3))
    mesh = trimesh.Trimesh(V, F, process=False, validate=False)
    angle_deg = np.degrees(np.asarray(mesh.face_adjacency_angles, float))
    angle_deg = np.minimum(angle_deg, 180.0 - angle_deg)
    sharp = np.asarray(mesh.face_adjacency_edges, np.int64)[np.isfinite(angle_deg) & (angle_deg > sharp_edge_deg)]
    if len(sharp) == 0:
        return np.zeros((0, 3))
    a, b = V[sharp[:, 0]], V[sharp[:, 1]]
    count = np.maximum(np.ceil(np.linalg.norm(b - a, axis=1) / step_mm).astype(np.int64), 1) + 1
    edge = np.repeat(np.arange(len(sharp)), count)
    start = np.repeat(np.cumsum(count) - count, count)
    t = (np.arange(int(count.sum())) - start) / np.repeat(count - 1, count)
    return a[edge] + t[:, None] * (b - a)[edge]
