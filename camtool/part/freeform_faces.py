"""Free-form faces in a segmentation: smooth regions split at sharp edges, kept analytic where a model fits.

``segment.segment`` finds plane, sphere and cylinder faces by RANSAC. On a free-form part
(a scanned dome, a mould's trough, a car panel) that search breaks each smooth region into
dozens of analytic fragments and leaves a share of its points on no face. This pass looks
at the part as a set of **smooth regions** and gives each region the analytic model only
where the analytic faces really hold it:

1. **Smooth regions.** On an evenly strided sample of the points (at most ``SAMPLE``), each
   point's normal is its triangle's on a mesh, and on a scan the thinnest principal
   direction of its ``EDGE_NEIGHBOURS`` nearest neighbours (a scan's own normals are as
   noisy as the scan; the sample's neighbours span several millimetres). A point is on a **sharp
   edge** when the surface turns by more than ``sharp_edge_deg`` across an edge near it
   (``faces.sharp_edge_deg``, default 30 deg: a chamfer of 45 deg or a box's 90 deg
   corner is an edge; a dome's or a door's curvature is not): on a mesh, a crease of the mesh
   (``creases``: two triangles turning by more) lies within ``EDGE_SPACINGS`` point spacings, or a
   neighbour within ``EDGE_MM`` turns its normal by more (a scale that does not grow with the part:
   a large part's sample lies millimetres apart, and a car door's window frame turning at radius
   8-25 mm is no edge); on a scan, ``EDGE_VOTES`` of those neighbours within ``EDGE_SPACINGS``
   point spacings turn its normal (unsigned) by more. The
   other points, linked to their nearest neighbours closer than ``sampling.CONNECT_SPACINGS``
   spacings, fall into connected regions; an edge point joins the region of its nearest
   non-edge neighbour whose normal agrees within ``sharp_edge_deg``. A mesh's normals are oriented: neighbours
   facing apart are the two sides of a thin wall (a propeller blade), no link; each workpiece point then takes
   the region of its nearest sample point facing its way (``_nearest_facing``).
2. **Analytic or free-form.** A region smaller than ``MIN_FREE_SHARE`` of the sample (a mesh's:
   ``MIN_FREE_SHARE_MESH``) stays as RANSAC left it (a scan's thin rim). A larger region is analytic when the RANSAC faces hold at least
   ``COVER_SHARE`` of its points and no more than ``MAX_PIECES`` of them meet one another
   at smooth seams (a dome on a cylinder, a fillet between two planes: two or three
   models meeting along tangent seams; a seam is smooth when the two models' normals at
   neighbouring points agree within ``sharp_edge_deg``, median over the seam). Faces that
   meet at creases stay apart even where a scan's noise blurred the crease and the
   region runs over it (a chamfered plate's scan). Two dozen cylinders and spheres
   tiling a mould's trough along smooth seams are a free-form region. Otherwise it is free-form: the analytic faces that lie mostly in
   it are dropped, unless one holds ``KEEP_SHARE`` of the region solidly (``SOLID_SHARE``
   of its points' neighbours its own: a plane a trough runs into, not a sphere speckled
   over a noisy scan) and less than ``SMOOTH_BORDER_SHARE`` of its border with the other
   analytic faces inside the region is a smooth seam (a fragment is surrounded by fragments it meets
   tangentially; a plane the trough's rim creases into is not; the border across the region's own sharp
   edges does not count: a mould's curved wall creased into the rim is still the trough's), and its points (those the kept analytic faces do
   not hold) become one
   ``FreeformSurface`` (``freeform.freeform_surface``, a mesh's own triangles of the
   region sampled exactly, a scan smoothed); its points are those over its material
   nodes (a scan's rim within two smoothing sigmas) and near it (``_on_material``).
3. **Charts.** A region whose one face leaves more than ``freeform_charts.UNHELD_SHARE`` of its points off its
   material (it turns further than a height field holds: a deep pocket, a sheet bent 150 deg) is cut into
   height-field charts (``freeform_charts``), each a free-form face of its own, when they hold more of it
   (``_region_faces``). A region its one face holds is never cut.

When no region is free-form (or none gives a free-form face of ``min_area_mm2``) the
segmentation is returned unchanged: the faces of a
purely analytic part do not depend on this pass. Deterministic (no random draws).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..errors import BadInput
from .crease_strips import cad_mesh, dense_strip, on_strips, only_free_strips, strip_regions
from .creases import crease_points

SHARP_EDGE_DEG = 30.0     # default of faces.sharp_edge_deg: a dihedral angle above this splits two regions
SAMPLE = 20000            # points (strided) the regions are found on
EDGE_NEIGHBOURS = 16      # the edge test looks at this many nearest neighbours ...
EDGE_SPACINGS = 4.0       # ... closer than this many median point spacings ...
EDGE_MM = 3.0             # on a mesh, the neighbours' normal test looks no farther than this (its creases do the rest)
EDGE_VOTES = 1            # ... and a point is on an edge when this many of them turn its normal past sharp_edge_deg
COVER_SHARE = 0.9         # a region whose analytic faces hold less than this share of its points is free-form,
MAX_PIECES = 3            # ... and one whose largest MAX_PIECES analytic faces hold less than COVER_SHARE of it
KEEP_SHARE = 0.2          # an analytic face holding this share of a free-form region stays a face of its own ...
SOLID_SHARE = 0.8         # ... when this share of its points' nearest neighbours are its own (not a noisy speckle)
SOLID_NEIGHBOURS = 8      # neighbours of a sample point for the solidity and the seams between analytic faces
SMOOTH_BORDER_SHARE = 0.5 # ... and less than this share of its border runs along smooth seams (no fragment)
SEAM_PAIRS = 200          # neighbouring point pairs a seam's angle is measured on at most
OFF_SURFACE_THRESHOLDS = 10.0  # a point of a free-form region farther than this many thresholds is not its face's
MIN_FREE_SHARE = 0.05     # a free-form region holds at least this share of the sample (a scan's thin rim is none) ...
MIN_FREE_SHARE_MESH = 0.02  # ... of a mesh's, this (no noisy rim: a propeller's blade side, 1/10 of its sides)
JOIN_PASSES = 3           # passes of edge points joining the regions of their neighbours
MIN_REGION_SHARE = 0.01   # regions holding less than this share of the sample are not faces of their own


@dataclass(frozen=True)
class _FitKeys:
    """The ``FitSettings`` fields ``freeform_surface`` reads, from the segmentation settings."""

    threshold_mm: float
    close_gaps_mm: float
    smoothing_mm: float = 0.0


def _sample(n: int) -> np.ndarray:
    return np.arange(n) if n <= SAMPLE else np.linspace(0, n - 1, SAMPLE).astype(np.int64)


def _unit(N: np.ndarray) -> np.ndarray:
    N = np.where(np.isfinite(N), N, 0.0)
    return N / np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-12)


def _pca_normals(P: np.ndarray, nb: np.ndarray) -> np.ndarray:
    """Unit normals (unsigned) of the points: the thinnest principal direction of each point's neighbours ``nb``
    (a scan's own normals, estimated over a few points, are as noisy as the scan; these average over the
    sample's neighbours, several millimetres)."""
    Q = P[nb] - P[nb].mean(axis=1, keepdims=True)
    C = np.einsum("nki,nkj->nij", Q, Q)
    C += np.eye(3) * 1e-12 * np.maximum(np.trace(C, axis1=1, axis2=2), 1e-300)[:, None, None]
    _, vecs = np.linalg.eigh(C)
    return vecs[:, :, 0]


def _edge_points(P: np.ndarray, dist: np.ndarray, cos_nb: np.ndarray, cos_sharp: float, spacing: float,
                 mesh) -> np.ndarray:
    """Whether each sample point is on a sharp edge. A scan (``mesh`` None): a neighbour within ``EDGE_SPACINGS``
    spacings turns its normal past the angle. A mesh ``(vertices_mm, faces, sharp_edge_deg)``: a crease of the mesh
    (``creases``) lies within ``EDGE_SPACINGS`` spacings, or a neighbour within ``EDGE_MM`` (and those spacings)
    turns its normal past the angle (a tight bend the mesh tessellates finer than the angle)."""
    within = dist <= EDGE_SPACINGS * spacing
    if mesh is None:
        return ((cos_nb < cos_sharp) & within).sum(axis=1) >= EDGE_VOTES
    near = within & (dist <= EDGE_MM)
    edge = ((cos_nb < cos_sharp) & near).sum(axis=1) >= EDGE_VOTES
    creases = crease_points(mesh[0], mesh[1], mesh[2], spacing / 2.0)
    if len(creases):
        edge |= cKDTree(creases).query(P, distance_upper_bound=EDGE_SPACINGS * spacing)[0] <= EDGE_SPACINGS * spacing
    return edge


def smooth_regions(P: np.ndarray, N: np.ndarray | None, sharp_edge_deg: float, connect_spacings: float,
                   mesh=None) -> np.ndarray:
    """Region label of each point (-1: none), the points split at sharp edges (see the module docstring).
    ``N``: the points' normals when they are exact (a mesh's triangles'); None: estimated (a scan).
    ``mesh``: ``(vertices_mm, faces)`` of a mesh workpiece, whose own creases mark its edges; None: a scan."""
    n = len(P)
    if n < 2 * EDGE_NEIGHBOURS:
        return np.full(n, -1, np.int64)
    tree = cKDTree(P)
    k = min(EDGE_NEIGHBOURS, n - 1) + 1
    dist, nb = tree.query(P, k=k)
    spacing = max(float(np.median(dist[:, 1])), 1e-9)
    oriented = N is not None
    N = _pca_normals(P, nb) if N is None else _unit(np.asarray(N, float))
    cos_sharp = math.cos(math.radians(sharp_edge_deg))
    signed_nb = np.einsum("ij,ikj->ik", N, N[nb])
    cos_nb = np.abs(signed_nb)   # unsigned: scans' normals are unoriented
    within = dist <= EDGE_SPACINGS * spacing
    edge = _edge_points(P, dist, cos_nb, cos_sharp, spacing, None if mesh is None else (*mesh, sharp_edge_deg))
    # a mesh's oriented normals facing apart lie on the two sides of a thin wall (a propeller blade 5 mm thick
    # sampled 1.7 mm apart), not on one smooth surface: they are no link, and no edge either (unsigned above)
    cos_link = signed_nb if oriented else cos_nb
    # the smooth points linked to their near neighbours that are smooth too
    link = within & (dist <= connect_spacings * spacing) & (cos_link >= cos_sharp) & ~edge[:, None] & ~edge[nb]
    link[:, 0] = False
    rows = np.repeat(np.arange(n), k)[link.ravel()]
    cols = nb.ravel()[link.ravel()]
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    _, comp = connected_components(graph, directed=False)
    label = np.where(edge, -1, comp).astype(np.int64)
    # an edge point joins the region of its nearest labelled neighbour whose normal agrees (a few passes: a noisy
    # scan's edge marks come in clusters)
    for _ in range(JOIN_PASSES):
        e = np.flatnonzero(label < 0)
        if len(e) == 0:
            break
        ok = (label[nb[e]] >= 0) & (cos_link[e] >= cos_sharp) & within[e]
        first = np.argmax(ok, axis=1)
        has = ok[np.arange(len(e)), first]
        if not has.any():
            break
        label[e[has]] = label[nb[e[has], first[has]]]
    # regions numbered by size, small ones dropped
    ids, counts = np.unique(label[label >= 0], return_counts=True)
    keep = ids[counts >= max(MIN_REGION_SHARE * n, 30)]
    order = keep[np.argsort(-counts[np.isin(ids, keep)], kind="stable")]
    out = np.full(n, -1, np.int64)
    for r, i in enumerate(order):
        out[label == i] = r
    return out


def _face_normals(face, P: np.ndarray) -> np.ndarray:
    """The analytic face's model normals at points P (unit)."""
    uv = face.surface.uv_from_points(P)
    return _unit(np.asarray(face.surface.normal_at(uv[:, 0], uv[:, 1]), float).reshape(-1, 3))


def _smooth_groups(idx: np.ndarray, owner_s: np.ndarray, nb: np.ndarray, S: np.ndarray, by_index: dict,
                   cos_sharp: float) -> dict[int, int]:
    """Each analytic face of the region's group size: the groups of analytic faces of a region (sample points ``idx``) that meet at smooth seams: two
    faces whose neighbouring points' model normals agree within the sharp-edge angle (median over the seam) are
    one group (the fragments of a free-form surface); faces meeting at a crease (a chamfer the scan's noise
    blurred) are not."""
    a = np.repeat(idx, nb.shape[1] - 1)
    b = nb[idx, 1:].ravel()
    fa, fb = owner_s[a], owner_s[b]
    cross = (fa >= 0) & (fb >= 0) & (fa != fb)
    a, b, fa, fb = a[cross], b[cross], fa[cross], fb[cross]
    pieces = np.unique(owner_s[idx][owner_s[idx] >= 0])
    parent = {int(f): int(f) for f in pieces}

    def root(f):
        while parent[f] != f:
            f = parent[f]
        return f

    for x, y in {(int(min(p, q)), int(max(p, q))) for p, q in zip(fa, fb)}:
        if x not in parent or y not in parent:
            continue
        sel = np.flatnonzero(((fa == x) & (fb == y)) | ((fa == y) & (fb == x)))
        sel = sel[np.linspace(0, len(sel) - 1, min(len(sel), SEAM_PAIRS)).astype(int)]
        i = np.where(fa[sel] == x, a[sel], b[sel])
        j = np.where(fa[sel] == x, b[sel], a[sel])
        cos = np.abs(np.sum(_face_normals(by_index[x], S[i]) * _face_normals(by_index[y], S[j]), axis=1))
        if float(np.median(cos)) >= cos_sharp:
            parent[root(x)] = root(y)
    roots = {f: root(f) for f in parent}
    size = {r: sum(1 for q in roots.values() if q == r) for r in set(roots.values())}
    return {f: size[r] for f, r in roots.items()}


def _smooth_border_share(face, owner_s: np.ndarray, nb: np.ndarray, S: np.ndarray, by_index: dict,
                         cos_sharp: float, in_region: np.ndarray) -> float:
    """The share of the face's border inside its smooth region (its points' neighbours on other analytic faces, both
    in the region: ``in_region`` of the sample) where the two models' normals agree within the sharp-edge angle:
    about 1 for a fragment tiling a smooth surface with others, small for a face bounded by creases. The border
    across the region's own sharp edges says nothing of that: a mould's curved wall, tangent to the trough's floor
    and creased into the rim along as long a line, had half its border smooth and stayed a face of its own."""
    mine = np.flatnonzero(owner_s == face.index)
    a = np.repeat(mine, nb.shape[1] - 1)
    b = nb[mine, 1:].ravel()
    other = owner_s[b]
    cross = (other >= 0) & (other != face.index) & in_region[a] & in_region[b]
    a, b, other = a[cross], b[cross], other[cross]
    if len(a) == 0:
        return 0.0
    sel = np.linspace(0, len(a) - 1, min(len(a), 20 * SEAM_PAIRS)).astype(int)
    a, b, other = a[sel], b[sel], other[sel]
    na = _face_normals(face, S[a])
    nb_ = np.zeros_like(na)
    for g in np.unique(other):
        k = other == g
        nb_[k] = _face_normals(by_index[int(g)], S[b[k]])
    return float((np.abs(np.sum(na * nb_, axis=1)) >= cos_sharp).mean())


def _is_freeform(idx: np.ndarray, owner_s: np.ndarray, groups: dict) -> bool:
    """The region's analytic faces hold too little of it, or in too many pieces joined at smooth seams."""
    held = owner_s[idx] >= 0
    if held.sum() < COVER_SHARE * len(idx):
        return True
    return max(groups.values(), default=0) > MAX_PIECES


def _on_material(surface, P: np.ndarray, threshold_mm: float) -> np.ndarray:
    """Which points lie on the free-form face: over one of its material nodes (or a scan's rim) and within ``OFF_SURFACE_THRESHOLDS``
    thresholds of it (not a stray edge point of the region that the face's largest connected region left out)."""
    c = (P - surface.origin_mm) @ surface.frame
    g = surface.grid
    i = np.rint((c[:, 0] - g.x0) / g.g).astype(np.int64)
    j = np.rint((c[:, 1] - g.y0) / g.g).astype(np.int64)
    inside = (i >= 0) & (i < g.nx) & (j >= 0) & (j < g.ny)
    from scipy.ndimage import binary_dilation

    # a scan's face keeps a smoothing sigma inside its last points (freeform.py): its rim points are its own
    near = binary_dilation(surface.material, iterations=1 + int(round(2.0 * surface.smoothing_mm / g.g)))
    on = np.zeros(len(P), bool)
    on[inside] = near[j[inside], i[inside]]
    h = g.interp(surface.height, c[:, 0], c[:, 1])
    return on & (np.abs(c[:, 2] - h) <= OFF_SURFACE_THRESHOLDS * threshold_mm + 3.0 * surface.smoothing_mm)


def _region_workpiece(workpiece, idx: np.ndarray, point_region: np.ndarray, r: int,
                      triangle_label: np.ndarray | None = None):
    """The workpiece's points ``idx`` as a workpiece; a mesh keeps the triangles whose middle lies in region r
    (``triangle_label``: each triangle's label instead, r the kept ones)."""
    from .workpiece import Workpiece

    P = np.asarray(workpiece.points_mm, float)
    F, V = getattr(workpiece, "faces", None), getattr(workpiece, "vertices_mm", None)
    tris = None
    if F is not None and V is not None and len(F):
        V = np.asarray(V, float)
        F = np.asarray(F)
        if triangle_label is None:
            T = V[F]
            near = _nearest_facing(cKDTree(P), np.asarray(workpiece.normals, float), T.mean(axis=1),
                                   np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]))
            triangle_label = point_region[near]
        tris = F[triangle_label == r]
        if len(tris) == 0:
            tris, V = None, None
    return Workpiece(P[idx], np.asarray(workpiece.normals, float)[idx], tris, workpiece.source, workpiece.units,
                     (), V if tris is not None else None)


def _holding_chart(tree: cKDTree, label: np.ndarray, axes: np.ndarray, Q: np.ndarray, NQ: np.ndarray,
                   signed: bool) -> np.ndarray:
    """Each query point's chart (normal NQ): of the charts ``label`` of its ``SOLID_NEIGHBOURS`` nearest tree
    points, the one whose plane normal (``axes``) its normal leans least from; -1 where even that one leans past
    ``freeform.MAX_SLOPE_DEG`` (no chart holds it). Where a pocket's walls meet in a narrow groove, the nearest
    point may lie on the wall across it, in a chart that cannot hold this one."""
    from .freeform import MAX_SLOPE_DEG

    _, nb = tree.query(Q, k=min(SOLID_NEIGHBOURS, tree.n))
    cand = label[nb.reshape(len(Q), -1)]
    cos = np.einsum("ij,ikj->ik", _unit(NQ), axes[cand])
    cos = cos if signed else np.abs(cos)
    best = np.argmax(cos, axis=1)
    rows = np.arange(len(Q))
    return np.where(cos[rows, best] >= math.cos(math.radians(MAX_SLOPE_DEG)), cand[rows, best], -1)


def _nearest_facing(tree: cKDTree, normals: np.ndarray | None, Q: np.ndarray, NQ: np.ndarray | None) -> np.ndarray:
    """Index of each query point's nearest tree point whose oriented normal faces its own way (of its
    ``SOLID_NEIGHBOURS`` nearest; the nearest when none does, or when either has no oriented normals): across a
    wall thinner than the sample's spacing (a propeller blade's trailing edge) the nearest point lies on the
    wall's other side."""
    k = min(SOLID_NEIGHBOURS, tree.n)
    _, nb = tree.query(Q, k=k)
    nb = nb.reshape(len(Q), k)
    if normals is None or NQ is None or k < 2:
        return nb[:, 0]
    facing = np.einsum("ij,ikj->ik", _unit(NQ), _unit(normals)[nb]) > 0.0
    first = np.argmax(facing, axis=1)
    rows = np.arange(len(Q))
    return np.where(facing[rows, first], nb[rows, first], nb[:, 0])


@dataclass(frozen=True)
class _RegionSample:
    """The strided sample the regions were found on: points, exact normals (a mesh's; None: a scan), KD-tree,
    region labels, and each workpiece point's nearest sample point."""

    points: np.ndarray
    normals: np.ndarray | None
    tree: cKDTree
    region: np.ndarray
    near: np.ndarray
    exact: bool


def _built_face(workpiece, idx: np.ndarray, labels: np.ndarray, r: int, keys: _FitKeys,
                triangle_label: np.ndarray | None = None):
    """(free-form surface, the points of ``idx`` on its material, area mm^2) of the workpiece's points ``idx``
    (triangles where ``labels`` is r, or ``triangle_label``), or None when they hold no surface."""
    from .freeform import freeform_surface

    try:
        surface = freeform_surface(_region_workpiece(workpiece, idx, labels, r, triangle_label), keys, part=workpiece)
    except BadInput:
        return None
    P = np.asarray(workpiece.points_mm, float)[idx]
    return surface, idx[_on_material(surface, P, keys.threshold_mm)], surface.area_mm2()


def _chart_faces(workpiece, idx: np.ndarray, point_region: np.ndarray, r: int, keys: _FitKeys,
                 sample: _RegionSample) -> list:
    """The faces (``_built_face``) of region r's charts (``freeform_charts``), cut on its sample points; [] when
    the region is one chart. The workpiece's points and triangles go to the chart of the nearby sample point
    whose normal agrees best (``_agreeing``)."""
    from .freeform_charts import height_field_charts, oriented_normals

    s = np.flatnonzero(sample.region == r)
    S = sample.points[s]
    if sample.normals is not None:
        NS = sample.normals[s]
    else:
        _, nb = sample.tree.query(S, k=min(EDGE_NEIGHBOURS + 1, len(sample.points)))
        NS = _pca_normals(sample.points, nb)
    NS = oriented_normals(S, NS, sample.exact)
    chart = height_field_charts(S, NS)
    if chart.max() == 0:
        return []
    from .freeform_sample import chart_frame

    axes = np.array([chart_frame(S[chart == c], NS[chart == c])[1][:, 2] for c in range(int(chart.max()) + 1)])
    P = np.asarray(workpiece.points_mm, float)
    NP = np.asarray(workpiece.normals, float)
    labels = np.full(len(P), -1, np.int64)
    labels[idx] = _holding_chart(cKDTree(S), chart, axes, P[idx], NP[idx], sample.exact)
    triangle_label = None
    F, V = getattr(workpiece, "faces", None), getattr(workpiece, "vertices_mm", None)
    if F is not None and V is not None and len(F):
        T = np.asarray(V, float)[np.asarray(F)]
        _, near = cKDTree(P).query(T.mean(axis=1))
        triangle_label = np.full(len(T), -1, np.int64)
        mine = np.flatnonzero(point_region[near] == r)
        tn = np.cross(T[mine, 1] - T[mine, 0], T[mine, 2] - T[mine, 0])
        held = labels[idx] >= 0
        triangle_label[mine] = _holding_chart(cKDTree(P[idx[held]]), labels[idx[held]], axes, T[mine].mean(axis=1),
                                              tn, True)
    if triangle_label is not None:
        return [_built_face(workpiece, idx[labels[idx] == c], labels, c, keys, triangle_label)
                for c in range(int(chart.max()) + 1)]
    faces = []
    for c in range(int(chart.max()) + 1):       # a scan's chart: built over a seam band, its own points its inliers
        own = idx[labels[idx] == c]
        face = _built_face(workpiece, _past_the_seam(P, NP, idx, own, axes[c], keys), labels, c, keys)
        faces.append(None if face is None else (face[0], np.intersect1d(face[1], own), face[2]))
    return faces


def _past_the_seam(P: np.ndarray, NP: np.ndarray, idx: np.ndarray, own: np.ndarray, axis: np.ndarray,
                   keys: _FitKeys) -> np.ndarray:
    """A scan's chart points ``own`` and the region's points ``idx`` within two smoothing sigmas of them that the
    chart's plane holds (normal within ``freeform.MAX_SLOPE_DEG``, unsigned): a scan's face keeps a sigma inside its
    last points (``freeform.py``), so two charts built on their own points alone leave a strip along their seam
    uncovered (1.5 % of a scanned sheet bent 150 deg)."""
    from .freeform import MAX_SLOPE_DEG, SCAN_SMOOTHING_MIN_MM, SCAN_SMOOTHING_SPACINGS

    if len(own) < 2:
        return own
    tree = cKDTree(P[own])
    spacing = float(np.median(tree.query(P[own], k=2)[0][:, 1]))
    sigma = keys.smoothing_mm or max(SCAN_SMOOTHING_SPACINGS * spacing, SCAN_SMOOTHING_MIN_MM)
    other = np.setdiff1d(idx, own)
    near = tree.query(P[other], distance_upper_bound=2.0 * sigma)[0] < np.inf
    held = np.abs(_unit(NP[other]) @ axis) >= math.cos(math.radians(MAX_SLOPE_DEG))
    return np.union1d(own, other[near & held])


def _region_faces(workpiece, idx: np.ndarray, point_region: np.ndarray, r: int, keys: _FitKeys,
                  sample: _RegionSample) -> list:
    """Region r's free-form faces (``_built_face``; None where none was built): one height field when it holds all
    but ``UNHELD_SHARE`` of the region's points, else the region's charts when they hold more of it
    (``freeform_charts``)."""
    from .freeform_charts import UNHELD_SHARE

    whole = _built_face(workpiece, idx, point_region, r, keys)
    held = 0 if whole is None else len(whole[1])
    if held >= (1.0 - UNHELD_SHARE) * len(idx):
        return [whole]
    charts = _chart_faces(workpiece, idx, point_region, r, keys, sample)
    if sum(len(c[1]) for c in charts if c is not None) > held:
        return charts
    return [whole]


def _kept(f, owner_s: np.ndarray, region: np.ndarray, free: list, nb: np.ndarray, S: np.ndarray, by_index: dict,
          cos_sharp: float) -> bool:
    """Whether the analytic face f stays: an analytic face that lies mostly in a free-form region is a fragment of
    it, unless it holds a large solid part of it (a plane the free-form region runs into). ``S``: the sample."""
    s = owner_s == f.index
    if s.sum() == 0:
        return True
    r = np.bincount(np.maximum(region[s], 0) if (region[s] >= 0).any() else [0]).argmax()
    # mostly in free-form regions, if in several: a cylinder over both sides of a thin blade's tip
    if r not in free or np.isin(region[s], free).mean() <= 0.5:
        return True
    solid = float((owner_s[nb[s, 1:]] == f.index).mean())
    return bool(s.sum() >= KEEP_SHARE * (region == r).sum() and solid >= SOLID_SHARE
                and _smooth_border_share(f, owner_s, nb, S, by_index, cos_sharp, region == r) < SMOOTH_BORDER_SHARE)


def _strip_faces(workpiece, idx: np.ndarray, point_region: np.ndarray, r: int, keys: _FitKeys,
                 sample: _RegionSample) -> list:
    """A strip's faces (``_region_faces``), built on its points and a lattice of points on its own triangles
    (``crease_strips.dense_strip``); their inliers the workpiece's points only."""
    dense, at, labels = dense_strip(workpiece, idx, point_region, r)
    n = len(workpiece.points_mm)
    return [None if f is None else (f[0], f[1][f[1] < n], f[2])
            for f in _region_faces(dense, at, labels, r, keys, sample)]


def with_freeform_faces(seg, workpiece, settings, make_face):
    """``seg`` with each free-form smooth region of the workpiece as one free-form face (module docstring).

    ``make_face(index, surface, inliers, area)``: the segmentation's ``Face``. Faces numbered by area, largest
    first. ``seg`` itself when no region is free-form."""
    P = np.asarray(workpiece.points_mm, float)
    n = len(P)
    pick = _sample(n)
    finite = np.isfinite(P[pick]).all(axis=1)
    pick = pick[finite]
    from .sampling import CONNECT_SPACINGS, MIN_FACE_SAMPLES

    mesh = getattr(workpiece, "faces", None) is not None
    N = np.asarray(workpiece.normals, float)[pick] if mesh else None
    region = smooth_regions(P[pick], N, settings.sharp_edge_deg, CONNECT_SPACINGS,
                            (workpiece.vertices_mm, workpiece.faces) if mesh and workpiece.vertices_mm is not None else None)
    strips, point_strip = [], None
    if cad_mesh(workpiece):   # strips narrower than the edge band (a CAD mesh's chamfer): crease_strips
        region, strips, point_strip = strip_regions(workpiece, pick, region, MIN_FACE_SAMPLES)
    owner = np.full(n, -1, np.int64)
    faces = list(seg.faces) if seg is not None else []
    for f in faces:
        owner[f.inliers] = f.index
    owner_s = owner[pick]
    tree = cKDTree(P[pick])
    _, nb = tree.query(P[pick], k=min(SOLID_NEIGHBOURS + 1, len(pick)))
    by_index = {f.index: f for f in faces}
    cos_sharp = math.cos(math.radians(settings.sharp_edge_deg))
    groups = {}
    for r in range(int(region.max()) + 1):
        idx = np.flatnonzero(region == r)
        groups[r] = _smooth_groups(idx, owner_s, nb, P[pick], by_index, cos_sharp)
    min_free = MIN_FREE_SHARE_MESH if mesh else MIN_FREE_SHARE
    free = [r for r in groups if ((region == r).sum() >= min_free * len(pick) or r in strips)
            and _is_freeform(np.flatnonzero(region == r), owner_s, groups[r])]
    if not free:
        return seg
    region, point_strip = only_free_strips(region, point_strip, strips, free)
    # each workpiece point's region: its nearest sample point's
    near = _nearest_facing(tree, N, np.where(np.isfinite(P), P, 0.0),
                           np.asarray(workpiece.normals, float) if mesh else None)
    point_region = region[near] if point_strip is None else on_strips(region[near], point_strip, list(strips))
    kept = [f for f in faces if _kept(f, owner_s, region, free, nb, P[pick], by_index, cos_sharp)]
    taken = np.zeros(n, bool)
    for f in kept:
        taken[f.inliers] = True
    keys = _FitKeys(float(settings.threshold_mm), float(settings.close_gaps_mm))
    built = [(f.surface, f.inliers, f.area_mm2) for f in kept]
    dropped = seg.dropped_faces if seg is not None else 0
    sample = _RegionSample(P[pick], N, tree, region, near, mesh)
    for r in free:
        idx = np.flatnonzero((point_region == r) & ~taken & np.isfinite(P).all(axis=1))
        if len(idx) < max(MIN_FACE_SAMPLES, 100):
            continue
        faces_r = _strip_faces(workpiece, idx, point_region, r, keys, sample) if r in strips else \
            _region_faces(workpiece, idx, point_region, r, keys, sample)
        for face in faces_r:
            if face is None or face[2] < settings.min_area_mm2 or len(face[1]) < MIN_FACE_SAMPLES:
                dropped += 1
                continue
            built.append(face)
    if len(built) == len(kept):   # no free-form face after all: the analytic segmentation as it was
        return seg
    order = sorted(range(len(built)), key=lambda k: (-round(built[k][2], 6), k))
    out = tuple(make_face(i, built[k][0], built[k][1], built[k][2]) for i, k in enumerate(order))
    assigned = sum(len(f.inliers) for f in out)
    return type(seg)(out, n, n - assigned, dropped) if seg is not None else (out, n, n - assigned, dropped)


def mesh_region_faces(region, threshold_mm: float, close_gaps_mm: float) -> list:
    """The free-form faces ``(surface, inliers, area mm^2)`` of one smooth region given as its own mesh workpiece
    (all its points and triangles; a STEP part's tangent B-rep faces, ``step_freeform``): one height field, or its
    charts when one leaves too much off (``_region_faces``). ``inliers`` index the region's points."""
    P = np.asarray(region.points_mm, float)
    n = len(P)
    pick = _sample(n)
    tree = cKDTree(P[pick])
    sample = _RegionSample(P[pick], np.asarray(region.normals, float)[pick], tree, np.zeros(len(pick), np.int64),
                           tree.query(P)[1], True)
    keys = _FitKeys(float(threshold_mm), float(close_gaps_mm))
    faces = _region_faces(region, np.arange(n), np.zeros(n, np.int64), 0, keys, sample)
    return [f for f in faces if f is not None]
