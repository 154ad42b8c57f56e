"""A smooth free-form region one height field does not hold, cut into charts that are each a height field.

A free-form face is stored as heights over its chart plane (``freeform.py``), so it holds material only where
the surface leans less than ``freeform.MAX_SLOPE_DEG`` from that plane, and near that slope its heights are
poorly conditioned (a 1 mm grid step moves them by several mm). A smooth region that turns further (a deep
pocket whose walls steepen past 80 deg, a sheet bent 150 deg, a tube's outside) has no such plane.
``freeform_faces`` builds the region's face as one height field first and keeps it whenever it holds all but
``UNHELD_SHARE`` of the region's points (``freeform_faces._on_material``): a region that works whole stays
exactly as it was, whatever its normals (a 120 deg bend whose legs lean 60 deg from a plane halfway is held).
Only otherwise is the region cut here, on its sample points' normals:

* A set of points is **held** by a chart when ``CHART_QUANTILE`` of its normals lie within ``CHART_HOLD_DEG`` of
  the normal of the plane its face would take (``freeform_sample.chart_frame``): well inside the 80 deg where
  the height field stops, so the walls' heights stay well conditioned.
* The normals are clustered on the sphere by spherical k-means (deterministic farthest-point seeding), k = 2, 3,
  ... ``MAX_CHARTS``; each cluster's connected pieces over the neighbour graph are the charts, a piece holding
  less than ``MIN_CHART_SHARE`` of the region joining the large piece it touches whose mean normal is nearest
  its own. The first k whose charts are all held is taken (a bent sheet: k = 2, its base and its flange cut in
  the fillet; a deep trough: its two long walls and its two ends), else the k whose charts hold the most points.

``freeform_faces`` then gives each workpiece point (and triangle) the chart, among those of its nearest sample
points, whose plane its normal leans least from (none past 80 deg): the nearest point alone may lie across a
narrow groove, on a wall whose chart cannot hold it. The charts' faces replace the region's one face only when
they hold more of its points.

The normals are oriented over the region first: a mesh's are its triangles' (``mesh_repair`` turned them one
way); a scan's unsigned estimates are turned along a minimum spanning tree of the neighbour graph (as open3d's
``orient_normals_consistent_tangent_plane``). Deterministic (no random draws).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .freeform_sample import chart_frame

UNHELD_SHARE = 0.02       # a region's one height field may leave this share of its points off its material
CHART_HOLD_DEG = 70.0     # a chart's normals lie within this of their mean ...
CHART_QUANTILE = 0.99     # ... this share of them (a scan's estimated normals scatter)
CHART_NEIGHBOURS = 8      # the neighbour graph pieces are connected on ...
CHART_LINK_SPACINGS = 3.0 # ... linking points closer than this many median spacings
MIN_CHART_SHARE = 0.05    # a piece holding less than this share of the region joins a neighbouring piece
MAX_CHARTS = 8            # clusters of normals a region is cut into at most
KMEANS_ROUNDS = 20


def oriented_normals(P: np.ndarray, N: np.ndarray, exact: bool) -> np.ndarray:
    """Unit normals of a region's points, turned to one consistent side (module docstring). ``exact``: a mesh's
    triangle normals, kept as they are. A scan's: turned along the minimum spanning tree of the neighbour graph
    weighted by 1 - |n_i . n_j| (Hoppe et al. 1992, as open3d's ``orient_normals_consistent_tangent_plane``; by
    hand over scipy's tree and search, because importing open3d takes seconds where it is not loaded yet), each
    connected piece then to the side most of the given normals face."""
    from scipy.sparse.csgraph import breadth_first_order, minimum_spanning_tree

    N = np.asarray(N, float)
    N = N / np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-12)
    n = len(P)
    if exact or n < CHART_NEIGHBOURS + 2:
        return N
    given = N.copy()
    _, nb = cKDTree(P).query(P, k=CHART_NEIGHBOURS + 1)
    rows, cols = np.repeat(np.arange(n), CHART_NEIGHBOURS), nb[:, 1:].ravel()
    weight = 1.0 - np.abs(np.einsum("ij,ij->i", N[rows], N[cols])) + 1e-6
    tree = minimum_spanning_tree(coo_matrix((weight, (rows, cols)), shape=(n, n)).tocsr())
    count, piece = connected_components(tree, directed=False)
    for c in range(count):
        order, parent = breadth_first_order(tree, int(np.flatnonzero(piece == c)[0]), directed=False)
        for i in order[1:]:                  # each normal to its parent's side, from the root outwards
            if N[i] @ N[parent[i]] < 0:
                N[i] = -N[i]
        if np.einsum("ij,ij->", N[order], given[order]) < 0:
            N[order] = -N[order]
    return N


def _direction(P: np.ndarray, N: np.ndarray) -> np.ndarray | None:
    """The chart plane's normal a face of these points would take (``freeform_sample.chart_frame``: the normals'
    mean, or the points' thinnest direction when the normals nearly cancel out); None when the normals agree on
    no side."""
    _, frame, consistent = chart_frame(P, N)
    return frame[:, 2] if consistent else None


def _held(P: np.ndarray, N: np.ndarray) -> bool:
    """``CHART_QUANTILE`` of the normals lie within ``CHART_HOLD_DEG`` of the chart plane's normal."""
    m = _direction(P, N)
    if m is None:
        return False
    return float(np.quantile(N @ m, 1.0 - CHART_QUANTILE)) >= math.cos(math.radians(CHART_HOLD_DEG))


def _k_means(N: np.ndarray, k: int) -> np.ndarray:
    """Cluster label (0..k-1) of each unit normal: spherical k-means, started deterministically at the normal
    nearest the mean and then, one by one, the normal farthest from those taken (farthest-point seeding)."""
    m = N.sum(axis=0)
    centres = [N[int(np.argmax(N @ m))] if np.linalg.norm(m) > 1e-9 else N[0]]
    while len(centres) < k:
        centres.append(N[int(np.argmin((N @ np.array(centres).T).max(axis=1)))])
    C = np.array(centres)
    label = np.full(len(N), -1, np.int64)
    for _ in range(KMEANS_ROUNDS):
        new = np.argmax(N @ C.T, axis=1)
        if (new == label).all():
            break
        label = new
        for c in range(k):
            if (label == c).any():
                v = N[label == c].sum(axis=0)
                C[c] = v / max(np.linalg.norm(v), 1e-12)
    return label


def _graph(P: np.ndarray):
    """(neighbour indices (n, k), link mask) of the points' neighbour graph."""
    k = min(CHART_NEIGHBOURS + 1, len(P))
    dist, nb = cKDTree(P).query(P, k=k)
    spacing = max(float(np.median(dist[:, 1])) if k > 1 else 1.0, 1e-9)
    link = dist <= CHART_LINK_SPACINGS * spacing
    link[:, 0] = False
    return nb, link


def _pieces(label: np.ndarray, N: np.ndarray, nb: np.ndarray, link: np.ndarray) -> np.ndarray:
    """Connected pieces (0..m-1) of equal label over the neighbour graph. A piece smaller than ``MIN_CHART_SHARE``
    joins the large piece it touches whose mean normal is nearest its own (not the one it touches most: a
    groove's stray bit of one cluster would carry the wall across the groove into a chart that cannot hold it)."""
    n = len(label)
    same = link & (label[nb] == label[:, None])
    rows = np.repeat(np.arange(n), nb.shape[1])[same.ravel()]
    graph = coo_matrix((np.ones(len(rows)), (rows, nb.ravel()[same.ravel()])), shape=(n, n))
    _, comp = connected_components(graph, directed=False)
    sizes = np.bincount(comp)
    large = sizes >= MIN_CHART_SHARE * n
    if not large.any():
        large[int(np.argmax(sizes))] = True
    mean = np.zeros((len(sizes), 3))
    np.add.at(mean, comp, N)
    mean /= np.maximum(np.linalg.norm(mean, axis=1, keepdims=True), 1e-12)
    for _ in range(8):                   # a few passes: a small piece may touch only other small ones at first
        small = np.unique(comp[~large[comp]])
        if len(small) == 0:
            break
        for c in small:
            members = np.flatnonzero(comp == c)
            for touched in (comp[nb[members]][link[members]], comp[nb[members]].ravel()):  # linked ones first
                t = np.unique(touched[large[touched] & (touched != c)])
                if len(t):
                    comp[members] = int(t[np.argmax(mean[t] @ mean[c])])
                    break
    return np.unique(comp, return_inverse=True)[1]


def _held_share(P: np.ndarray, N: np.ndarray, pieces: np.ndarray) -> float:
    """The share of the points within ``CHART_HOLD_DEG`` of their piece's chart plane normal."""
    cos_hold = math.cos(math.radians(CHART_HOLD_DEG))
    held = 0
    for p in range(int(pieces.max()) + 1):
        m = _direction(P[pieces == p], N[pieces == p])
        held += 0 if m is None else int((N[pieces == p] @ m >= cos_hold).sum())
    return held / len(N)


def height_field_charts(P: np.ndarray, N: np.ndarray) -> np.ndarray:
    """Chart label (0..m-1, largest first) of each point of one smooth region with oriented unit normals ``N``:
    the connected pieces of the fewest spherical k-means clusters of the normals (k from 2 to ``MAX_CHARTS``)
    whose pieces are each held (module docstring); all 0 when the region is held already or too small."""
    n = len(P)
    if n < 4 * CHART_NEIGHBOURS or _held(P, N):
        return np.zeros(n, np.int64)
    nb, link = _graph(P)
    best, best_share = np.zeros(n, np.int64), -1.0
    for k in range(2, MAX_CHARTS + 1):
        pieces = _pieces(_k_means(N, k), N, nb, link)
        if all(_held(P[pieces == p], N[pieces == p]) for p in range(int(pieces.max()) + 1)):
            best = pieces
            break
        share = _held_share(P, N, pieces)
        if share > best_share:
            best, best_share = pieces, share
    sizes = np.bincount(best)
    order = np.argsort(-sizes, kind="stable")
    return np.argsort(order)[best]
