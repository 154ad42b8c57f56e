"""A point cloud's normals: open3d's PCA of each point's k nearest neighbours, the points taken in voxel order.

open3d's ``estimate_normals`` builds a KD-tree and, for each point, gathers its ``k`` nearest neighbours and
takes the direction of least spread of their covariance. A scan's points come in no spatial order (a
depth camera's rows, a resampled mesh's random triangles), and then each point's search walks tree nodes
far apart in memory: on a 10^6-point scan the caches miss, and the normals took 11.4 s of CPU, while
125 000 of its points took 0.45 s. Handed the same points sorted by the voxel they fall in (cubes of
``ORDER_VOXEL_SPACINGS`` point spacings, row-major), open3d takes 2.7 s for the 10^6 and each point gets the same
neighbours, the same covariance and so the same normal (measured: bit for bit on that scan); the normals are then
put back in the file's order. open3d has no such switch; hence the sort by hand (numpy, 0.15 s).

Only points tied in distance to a point (an exact grid) may be visited in another order, which may
change the last bit of a sum or which of two equidistant k-th neighbours is taken; so clouds of up to
``ORDERED_NORMALS_POINTS`` points, where the caches still hold, keep the file's order and are bit for bit
what they were.

Either way a normal points towards the file's origin (the sensor viewpoint convention of PCD and open3d),
each point's by its own position. open3d's own ``orient_*`` calls do the same but are threaded; the flip is one
line of numpy.
"""
from __future__ import annotations

import numpy as np

ORDERED_NORMALS_POINTS = 200_000
"""A cloud with more points than this is handed to open3d in voxel order: three times the shipped scans'
60 000 points (which keep the file's order, bit for bit), a fifth of a 10^6-point scan; below it the sort saves
little (125 000 unordered points: 0.45 s of CPU)."""
ORDER_VOXEL_SPACINGS = 4.0
"""The sorting voxels' edge in median point spacings: a voxel holds some 16 points of a scan's surface,
a neighbourhood of 30 lies in a few neighbouring voxels (the edge mattered little: 1 to 16 mm on the 1 mm-spaced
10^6-point scan all took 2.6-2.9 s)."""


def cloud_normals(points_mm: np.ndarray, k: int) -> np.ndarray:
    """(N, 3) unit normals of a cloud (mm) from ``k`` neighbours (open3d), towards the origin; a cloud of more
    than ``ORDERED_NORMALS_POINTS`` points is handed to open3d in voxel order (the module doc)."""
    P = np.asarray(points_mm, float)
    if len(P) <= ORDERED_NORMALS_POINTS:
        return estimated_normals(P, k)
    order = voxel_order(P, ORDER_VOXEL_SPACINGS * spacing_mm(P))
    n = np.empty_like(P)
    n[order] = estimated_normals(P[order], k)
    return n


def estimated_normals(points_mm: np.ndarray, k: int) -> np.ndarray:
    """(N, 3) unit normals by open3d's PCA of each point's ``k`` nearest neighbours, towards the origin."""
    P = np.asarray(points_mm, float)
    if len(P) < 3:
        return np.zeros_like(P)
    from .open3d_import import import_open3d, open3d_quiet
    o3d = import_open3d()

    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(P))
    with open3d_quiet():
        pc.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=int(min(k, len(P)))))
    n = np.asarray(pc.normals, dtype=float)
    flip = np.einsum("ij,ij->i", n, -P) < 0
    n[flip] *= -1
    return n


def voxel_order(points_mm: np.ndarray, size_mm: float) -> np.ndarray:
    """The permutation that sorts the points by the cubic voxel of edge ``size_mm`` they fall in (row-major
    over the points' box; the file's order within a voxel)."""
    P = np.asarray(points_mm, float)
    extent = float((P.max(axis=0) - P.min(axis=0)).max())
    size = max(float(size_mm), extent * 1e-6, 1e-9)          # at most 10^6 voxels along an axis: int64 keys
    ijk = np.floor((P - P.min(axis=0)) / size).astype(np.int64)
    dims = ijk.max(axis=0) + 1
    return np.argsort((ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2], kind="stable")


def spacing_mm(points_mm: np.ndarray, sample: int = 20_000, queries: int = 2_000) -> float:
    """The median nearest-neighbour distance (mm) of a surface's points, from a strided subsample rescaled by
    the square root of its share (a surface's spacing goes as 1 / sqrt(points)): a scan's points in random
    order give their own; a grid's, half its pitch (the subsample's gaps are random)."""
    from scipy.spatial import cKDTree

    P = np.asarray(points_mm, float)
    m = min(len(P), sample)
    sub = P[np.linspace(0, len(P) - 1, m).astype(int)]
    q = sub[np.linspace(0, m - 1, min(m, queries)).astype(int)]
    dist, _ = cKDTree(sub).query(q, k=2)
    return max(float(np.median(dist[:, 1])) * float(np.sqrt(m / len(P))), 1e-6)
