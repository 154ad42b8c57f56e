"""Segmentation of a workpiece into faces: planes, spheres and cylinders by sequential RANSAC.

Written here rather than taken from a library: open3d's ``segment_plane`` has
planes only and is not seeded-deterministic when threaded, pyransac3d scores
one hypothesis at a time on every point (both are timed side by side in
benchmarks/segment_speed.py), and neither keeps the point normals in the
score. The steps:

1. **Sample.** ``SAMPLE`` points (or all) are drawn with
   ``numpy.random.default_rng([seed, 3])``; the search runs on them.
2. **Sequential RANSAC with normal consistency.** Each round draws hypotheses
   of every model from the points not yet taken: a plane from one point and
   its normal, a sphere and a cylinder from two nearby points and their
   normals (``fit.cylinder_hypotheses``). A point supports a hypothesis when it
   lies within ``threshold_mm`` and its normal is within ``normal_tol_deg``
   of the model's normal there (either sign: scans' normals are unoriented).
   The model with the most support wins; a plane wins whenever it holds
   ``PLANE_MARGIN`` as many (a huge sphere or cylinder is a plane). The
   winner is refined by least squares (``fit``'s refiners), and its largest
   connected piece (points closer than ``CONNECT_SPACINGS`` sample spacings)
   becomes a face; the rest stay for later rounds.
3. **Every point.** Each point of the workpiece goes to the face whose model it
   fits best (distance and normal) among the faces whose occupied (u, v) cells
   (dilated by one cell) it falls in; points that fit none stay unassigned.
4. **Faces.** Each face's model is refined on its points and gets its
   boundary (outer contour and holes, ``boundary_from_uv``), material side and
   RMS. Faces smaller than ``min_area_mm2`` are dropped, or with
   ``small_faces = "merge"`` their points join the neighbouring face they fit
   (within 3x threshold_mm, normals agreeing) and the rest are dropped.

Deterministic: the same points and seed give the same faces in the same
order: numbered by area, largest first (ties in the order found).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..errors import BadInput
from .fit import (LARGE_SPHERE_FACTOR, _refine_plane, _refine_sphere, cylinder_hypotheses, cylinder_radial,
                  cylinder_residuals, cylinder_surface, plane_surface, refine_cylinder, sphere_patch)
from .face_edges import FreeEdges, flat_mm, on_edges, spacing_mm, uv_of_flat
from .freeform import FreeformSurface
from .freeform_faces import SHARP_EDGE_DEG, with_freeform_faces
from .sampling import CONNECT_SPACINGS, MIN_FACE_SAMPLES
from .surface import Cylinder, FitStats, PlaneSurface, SpherePatch

SAMPLE = 20000            # points the RANSAC rounds search
SCORE_POINTS = 2000       # remaining points every hypothesis of a round is scored on
HYPOTHESES = 300          # hypotheses per model and round
PLANE_MARGIN = 0.98       # a plane wins when it holds this share of the best model's support
PAIR_NEIGHBOURS = 64      # the second point of a sphere / cylinder pair is one of the seed's nearest sample points
SELECT_REFINE_POINTS = 3000  # points (strided) a candidate is refined on while the models of a round compete
BOUNDARY_POINTS = 100000  # points of a face (strided) its boundary is traced from (a job samples 100k in all)
OFFSET_PERCENTILE = 90.0  # the smoothed outline moves into the material by this percentile of its overshoot
SMOOTH_VERTICES = 7      # a face's pulled outline (1 mm vertices) is averaged over 2 x 7 + 1 vertices
REFINE_POINTS = 50000     # points (strided) used by the final least-squares refinement of a face
MODELS = ("plane", "sphere", "cylinder")


@dataclass(frozen=True)
class SegmentSettings:
    """How a workpiece is split into faces (mm, rad)."""

    threshold_mm: float = 0.5
    normal_tol_rad: float = math.radians(10.0)
    min_area_mm2: float = 100.0
    small_faces: str = "drop"   # drop | merge
    max_faces: int = 32
    seed: int = 0
    boundary_cell_mm: float = 2.0
    close_gaps_mm: float = 6.0
    simplify_mm: float = 0.5
    sharp_edge_deg: float = SHARP_EDGE_DEG
    freeform_faces: bool = True  # False: planes, spheres and cylinders only (a STEP part's non-analytic faces)


@dataclass(frozen=True)
class Face:
    """One face of a segmented part: its surface (model, parameters, boundary, stats) and its points."""

    index: int
    surface: PlaneSurface | SpherePatch | Cylinder | FreeformSurface
    inliers: np.ndarray  # indices into the workpiece's points
    area_mm2: float

    @property
    def model(self) -> str:
        return self.surface.model

    def summary(self) -> dict:
        """The ``camtool faces --json`` entry: index, model, area, normal or axis, radius, centre, inliers."""
        s = self.surface
        d = {"index": self.index, "model": s.model, "area_mm2": round(self.area_mm2, 3)}
        if s.model == "freeform":
            d["normal"] = [round(float(x), 6) for x in s.mean_normal()]
            d["center_mm"] = [round(float(x), 4) for x in s.middle_mm()]
            d["radius_mm"] = None
            d["curvature_range"] = [round(float(x), 6) for x in s.curvature_range()]
        elif isinstance(s, PlaneSurface):
            d["normal"] = [round(float(x), 6) for x in s.normal]
            lo, hi = s.boundary.bounds()
            mid = s.point_mm(0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]))
            d["center_mm"] = [round(float(x), 4) for x in mid]
            d["radius_mm"] = None
        else:
            if isinstance(s, Cylinder):
                d["axis"] = [round(float(x), 6) for x in s.axis]
            d["radius_mm"] = round(float(s.radius_mm), 4)
            d["center_mm"] = [round(float(x), 4) for x in s.center_mm]
        if isinstance(s, (SpherePatch, Cylinder)):
            d["concave"] = bool(s.concave)
        d["inliers"] = int(len(self.inliers))
        d["rms_mm"] = round(float(s.stats.rms_mm), 5)
        d["holes"] = len(s.boundary.holes_uv)
        return d


@dataclass(frozen=True)
class Segmentation:
    """The faces of a workpiece (numbered by area, largest first), the points no face took, the small faces left out."""

    faces: tuple[Face, ...]
    n_points: int
    unassigned: int
    dropped_faces: int


# ----------------------------------------------------------------------------- models on arrays


@dataclass(frozen=True)
class _Model:
    """A model's parameters in the centred frame: plane (n, d), sphere (c, r), cylinder (c, a, r)."""

    kind: str
    params: tuple

    def residual(self, P: np.ndarray) -> np.ndarray:
        if self.kind == "plane":
            n, d = self.params
            return np.abs(P @ n - d)
        if self.kind == "sphere":
            c, r = self.params
            return np.abs(np.linalg.norm(P - c, axis=1) - r)
        c, a, r = self.params
        return cylinder_residuals(P, c[None], a[None], np.array([r]))[:, 0]

    def normal_cos(self, P: np.ndarray, N: np.ndarray) -> np.ndarray:
        """|cos| of the angle between the points' normals and the model's normal at them."""
        if self.kind == "plane":
            return np.abs(N @ self.params[0])
        if self.kind == "sphere":
            d = P - self.params[0]
            return np.abs(np.einsum("ij,ij->i", d, N)) / np.maximum(np.linalg.norm(d, axis=1), 1e-12)
        return np.abs(np.einsum("ij,ij->i", cylinder_radial(P, self.params[0], self.params[1]), N))

    def fits(self, P, N, thr, cos_tol) -> np.ndarray:
        return (self.residual(P) < thr) & (self.normal_cos(P, N) > cos_tol)

    def refined(self, P: np.ndarray, thr: float, max_points: int = 20000) -> "_Model":
        if self.kind == "plane":
            n, d = _refine_plane(P, self.params[0], float(self.params[1]), thr)
            return _Model("plane", (n, float(d)))
        if self.kind == "sphere":
            c, r = _refine_sphere(P, self.params[0], float(self.params[1]), thr)
            if not (np.isfinite(r) and np.isfinite(c).all()):
                return self
            return _Model("sphere", (c, float(r)))
        c, a, r = refine_cylinder(P, self.params[0], self.params[1], float(self.params[2]), thr,
                                  max_points=max_points)
        return _Model("cylinder", (c, a, r))


def _support(kind: str, hyp: tuple, Q: np.ndarray, NQ: np.ndarray, thr: float, cos_tol: float) -> np.ndarray:
    """Support (count of the points Q that fit) of every hypothesis of one model."""
    if kind == "plane":
        n, d = hyp
        return ((np.abs(Q @ n.T - d) < thr) & (np.abs(NQ @ n.T) > cos_tol)).sum(axis=0)
    if kind == "sphere":
        c, r = hyp
        diff = Q[:, None, :] - c[None]
        dist = np.linalg.norm(diff, axis=2)
        cosn = np.abs(np.einsum("ijk,ik->ij", diff, NQ)) / np.maximum(dist, 1e-12)
        return ((np.abs(dist - r[None]) < thr) & (cosn > cos_tol)).sum(axis=0)
    c, a, r = hyp
    res = cylinder_residuals(Q, c, a, r)
    diff = Q[:, None, :] - c[None]
    diff = diff - np.einsum("ijk,jk->ij", diff, a)[..., None] * a[None]
    cosn = np.abs(np.einsum("ijk,ik->ij", diff, NQ)) / np.maximum(np.linalg.norm(diff, axis=2), 1e-12)
    return ((res < thr) & (cosn > cos_tol)).sum(axis=0)


def _sphere_hypotheses(P, N, i, j, max_radius, tol_mm):
    """Spheres through point pairs with normals: centre where the normal lines come closest."""
    pi, pj, ni, nj = P[i], P[j], N[i], N[j]
    w = pi - pj
    b = np.einsum("ij,ij->i", ni, nj)
    dn, en = np.einsum("ij,ij->i", ni, w), np.einsum("ij,ij->i", nj, w)
    den = 1.0 - b * b
    ok = den > 0.0025  # normals at least ~3 deg apart
    den = np.where(ok, den, 1.0)
    t = (b * en - dn) / den
    s = (en - b * dn) / den
    ci, cj = pi + t[:, None] * ni, pj + s[:, None] * nj
    gap = np.linalg.norm(ci - cj, axis=1)
    c = 0.5 * (ci + cj)
    ri, rj = np.linalg.norm(pi - c, axis=1), np.linalg.norm(pj - c, axis=1)
    ok &= (gap < tol_mm) & (np.abs(ri - rj) < tol_mm) & (ri < max_radius)
    return c[ok], (0.5 * (ri + rj))[ok]


# ----------------------------------------------------------------------------- search


def _best_hypotheses(S, NS, tree, remaining, rng, extent, settings: SegmentSettings) -> dict:
    """The best hypothesis of every model in one round: {kind: (model, support on the score set)}."""
    thr, cos_tol = settings.threshold_mm, math.cos(settings.normal_tol_rad)
    idx = np.flatnonzero(remaining)
    score = idx if len(idx) <= SCORE_POINTS else np.sort(rng.choice(idx, SCORE_POINTS, replace=False))
    Q, NQ = S[score], NS[score]
    seeds = rng.choice(idx, HYPOTHESES, replace=len(idx) < HYPOTHESES)
    # partners: a random remaining point among the PAIR_NEIGHBOURS nearest sample points of each seed
    _, near = tree.query(S[seeds], k=min(PAIR_NEIGHBOURS, len(S)))
    near = near.reshape(len(seeds), -1)
    ok = remaining[near]
    ok[:, 0] = False  # the seed itself
    key = rng.random(near.shape) + ok  # the largest key is a random remaining neighbour
    col = np.argmax(key, axis=1)
    partner = np.where(ok[np.arange(len(seeds)), col], near[np.arange(len(seeds)), col], seeds)
    best = {}
    n = NS[seeds]
    hyps = {"plane": (n, np.einsum("ij,ij->i", n, S[seeds])),
            "sphere": _sphere_hypotheses(S, NS, seeds, partner, LARGE_SPHERE_FACTOR * extent, 4 * thr),
            "cylinder": cylinder_hypotheses(S, NS, seeds, partner, LARGE_SPHERE_FACTOR * extent, 4 * thr)}
    for kind in MODELS:
        hyp = hyps[kind]
        if len(hyp[0]) == 0:
            continue
        support = _support(kind, hyp, Q, NQ, thr, cos_tol)
        k = int(np.argmax(support))
        best[kind] = (_Model(kind, tuple(h[k] for h in hyp)), int(support[k]))
    return best


def _grow(model: _Model, S, NS, idx, thr, cos_tol, radius):
    """(refined model, its largest connected piece among the points idx, its MSAC score), or None.

    The score sums 1 - (residual / thr)^2 over the piece: a curved model bent
    across two flat faces holds many points loosely and scores below the flat
    face that holds its points exactly.
    """
    for _ in range(2):  # refine on the round's inliers, then take them again
        on = idx[model.fits(S[idx], NS[idx], thr, cos_tol)]
        if len(on) < MIN_FACE_SAMPLES:
            return None
        model = model.refined(S[on], thr, max_points=SELECT_REFINE_POINTS)
    on = idx[model.fits(S[idx], NS[idx], thr, cos_tol)]
    if len(on) < MIN_FACE_SAMPLES:
        return None
    piece = on[_largest_piece(S[on], radius)]
    if len(piece) < MIN_FACE_SAMPLES:
        return None
    score = float(np.sum(1.0 - (model.residual(S[piece]) / thr) ** 2))
    return model, piece, score


def _largest_piece(points: np.ndarray, radius: float) -> np.ndarray:
    """Indices (into ``points``) of its largest connected piece (neighbours closer than ``radius``)."""
    if len(points) < 2:
        return np.arange(len(points))
    pairs = cKDTree(points).query_pairs(radius, output_type="ndarray")
    n = len(points)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    counts = np.bincount(label)
    return np.flatnonzero(label == int(np.argmax(counts)))


# ----------------------------------------------------------------------------- charts for the assignment


class _Chart:
    """Occupied (u, v) cells of a face (flat chart in mm), dilated by one cell."""

    def __init__(self, kind: str, params: tuple, P: np.ndarray, cell_mm: float):
        self.kind, self.params, self.cell = kind, params, cell_mm
        if kind == "plane":
            n = params[0]
            helper = np.eye(3)[int(np.argmin(np.abs(n)))]
            e1 = np.cross(helper, n)
            self.e1 = e1 / np.linalg.norm(e1)
            self.e2 = np.cross(n, self.e1)
        elif kind == "cylinder":
            a = params[1]
            helper = np.eye(3)[int(np.argmin(np.abs(a)))]
            e1 = np.cross(helper, a)
            self.e1 = e1 / np.linalg.norm(e1)
            self.e2 = np.cross(a, self.e1)
        xy = self.xy(P)
        self.lo = xy.min(axis=0) - 2 * cell_mm
        ij = np.floor((xy - self.lo) / cell_mm).astype(np.int64)
        self.shape = ij.max(axis=0) + 3
        if kind != "plane":  # angles wrap: the u cells run round the whole circle
            self.shape[0] = max(self.shape[0], 1)
        occ = np.zeros(tuple(self.shape), bool)
        occ[ij[:, 0], ij[:, 1]] = True
        grown = occ.copy()  # one cell of dilation (8-neighbourhood)
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                grown |= np.roll(np.roll(occ, di, axis=0), dj, axis=1)
        self.occ = grown

    def xy(self, P: np.ndarray) -> np.ndarray:
        if self.kind == "plane":
            return np.stack([P @ self.e1, P @ self.e2], axis=-1)
        if self.kind == "sphere":
            c, r = self.params
            d = P - c
            az = np.arctan2(d[:, 1], d[:, 0])
            el = np.arcsin(np.clip(d[:, 2] / np.maximum(np.linalg.norm(d, axis=1), 1e-12), -1, 1))
            return np.stack([r * az * np.cos(el), r * el], axis=-1)  # sinusoidal (equal-area)
        c, a, r = self.params
        d = P - c
        return np.stack([r * np.arctan2(d @ self.e2, d @ self.e1), d @ a], axis=-1)

    def contains(self, P: np.ndarray) -> np.ndarray:
        ij = np.floor((self.xy(P) - self.lo) / self.cell).astype(np.int64)
        ok = (ij >= 0).all(axis=1) & (ij[:, 0] < self.shape[0]) & (ij[:, 1] < self.shape[1])
        out = np.zeros(len(P), bool)
        out[ok] = self.occ[ij[ok, 0], ij[ok, 1]]
        return out


# ----------------------------------------------------------------------------- entry


def segment(workpiece, settings: SegmentSettings = SegmentSettings()) -> Segmentation:
    """Split a workpiece (world mm) into plane, sphere and cylinder faces, largest first.

    BadInput when no face is found (too few points, or nothing fits within
    ``threshold_mm``).
    """
    P_world = np.asarray(workpiece.points_mm, dtype=float)
    N_all = np.asarray(workpiece.normals, dtype=float)
    source = getattr(workpiece, "source", "") or "workpiece"
    if len(P_world) < 4 * MIN_FACE_SAMPLES:
        raise BadInput(f"{source}: {len(P_world)} points are too few to find faces; give a denser scan or mesh")
    centroid = P_world.mean(axis=0)
    P = P_world - centroid
    extent = float(np.linalg.norm(P.max(axis=0) - P.min(axis=0)))
    thr, cos_tol = settings.threshold_mm, math.cos(settings.normal_tol_rad)
    rng = np.random.default_rng([settings.seed, 3])
    pick = np.sort(rng.choice(len(P), SAMPLE, replace=False)) if len(P) > SAMPLE else np.arange(len(P))
    S, NS = P[pick], N_all[pick]
    tree = cKDTree(S)
    spacing = spacing_mm(tree, S)
    remaining = np.ones(len(S), bool)
    models: list[_Model] = []
    members: list[np.ndarray] = []
    while len(models) < settings.max_faces and remaining.sum() >= MIN_FACE_SAMPLES:
        candidates = _best_hypotheses(S, NS, tree, remaining, rng, extent, settings)
        idx = np.flatnonzero(remaining)
        grown = {}
        for kind, (model, _) in candidates.items():  # each model refined and grown: its largest piece counts
            piece = _grow(model, S, NS, idx, thr, cos_tol, CONNECT_SPACINGS * spacing)
            if piece is not None:
                grown[kind] = piece
        if not grown:
            break
        top = max(g[2] for g in grown.values())
        kind = "plane" if "plane" in grown and grown["plane"][2] >= PLANE_MARGIN * top else \
            max(grown, key=lambda k: grown[k][2])
        model, piece, _ = grown[kind]
        remaining[piece] = False
        models.append(model)
        members.append(piece)
    models, members = _merge_equivalent(S, models, members, CONNECT_SPACINGS * spacing, settings)
    members = _relabel_sample(S, NS, models, members, CONNECT_SPACINGS * spacing, thr, cos_tol)
    keep = [k for k, m in enumerate(members) if len(m) >= MIN_FACE_SAMPLES]
    models, members = [models[k] for k in keep], [members[k] for k in keep]
    if not models and not settings.freeform_faces:
        raise BadInput(f"{source}: no plane, sphere or cylinder face found within threshold_mm = {thr:g}; "
                       "check the units or raise the threshold")
    if not models:
        seg = with_freeform_faces(None, workpiece, settings, Face)
        if seg is None or not seg[0]:
            raise BadInput(f"{source}: no plane, sphere or cylinder face found within threshold_mm = {thr:g}, "
                           "and no smooth region for a free-form face; check the units or raise the threshold")
        return Segmentation(*seg)
    # every point: the best-fitting face whose occupied cells it falls in
    cell = max(2.0 * spacing, 1e-3)
    best_res = np.full(len(P), np.inf)
    label = np.full(len(P), -1, dtype=np.int64)
    for k, (model, piece) in enumerate(zip(models, members)):
        res = model.residual(P)  # cheapest test first: distance, then normal, then the face's cells
        cand = np.flatnonzero((res < thr) & (res < best_res))
        cand = cand[model.normal_cos(P[cand], N_all[cand]) > cos_tol]
        cand = cand[_Chart(model.kind, model.params, S[piece], cell).contains(P[cand])]
        label[cand] = k
        best_res[cand] = res[cand]
    faces, dropped = _faces(P_world, N_all, centroid, models, label, settings, workpiece, source)
    assigned = sum(len(f.inliers) for f in faces)
    if not settings.freeform_faces:
        return Segmentation(tuple(faces), len(P), len(P) - assigned, dropped)
    # smooth regions the analytic faces hold only in fragments become free-form faces (none on an analytic part)
    return with_freeform_faces(Segmentation(tuple(faces), len(P), len(P) - assigned, dropped), workpiece,
                               settings, Face)


def _equivalent(m1: _Model, m2: _Model, thr: float, angle_rad: float) -> bool:
    """The same surface within 2x the threshold and ``angle_rad`` (a face found in two rounds)."""
    if m1.kind != m2.kind:
        return False
    cos = math.cos(angle_rad)
    if m1.kind == "plane":
        (n1, d1), (n2, d2) = m1.params, m2.params
        c = float(n1 @ n2)
        return abs(c) > cos and abs(d1 - math.copysign(1.0, c) * d2) < 2 * thr
    if m1.kind == "sphere":
        (c1, r1), (c2, r2) = m1.params, m2.params
        return float(np.linalg.norm(c1 - c2)) < 2 * thr + 0.01 * r1 and abs(r1 - r2) < 2 * thr
    (c1, a1, r1), (c2, a2, r2) = m1.params, m2.params
    d = c2 - c1
    return abs(float(a1 @ a2)) > cos and float(np.linalg.norm(d - (d @ a1) * a1)) < 2 * thr + 0.01 * r1 \
        and abs(r1 - r2) < 2 * thr


def _merge_equivalent(S, models, members, radius, settings):
    """Faces of one surface found in several rounds, touching each other, become one (model refined)."""
    thr, angle = settings.threshold_mm, math.radians(2.0)
    models, members = list(models), list(members)
    merged = True
    while merged:
        merged = False
        for i in range(len(models)):
            for j in range(i + 1, len(models)):
                if not _equivalent(models[i], models[j], thr, angle):
                    continue
                d, _ = cKDTree(S[members[i]]).query(S[members[j]], distance_upper_bound=radius)
                if not np.isfinite(d).any():
                    continue
                members[i] = np.union1d(members[i], members[j])
                models[i] = models[i].refined(S[members[i]], thr)
                del models[j], members[j]
                merged = True
                break
            if merged:
                break
    return models, members


def _relabel_sample(S, NS, models, members, radius, thr, cos_tol):
    """Each sample point to the face it fits best among the faces whose piece it touches.

    The rounds are greedy: a face found early takes the points near a tangent
    seam that fit it loosely (a cylinder holds a band of the dome on it); here
    the face that fits them closer takes them back.
    """
    best = np.full(len(S), np.inf)
    label = np.full(len(S), -1, dtype=np.int64)
    for k, (model, piece) in enumerate(zip(models, members)):
        res = model.residual(S)
        cand = np.flatnonzero((res < thr) & (res < best))
        cand = cand[model.normal_cos(S[cand], NS[cand]) > cos_tol]
        d, _ = cKDTree(S[piece]).query(S[cand], distance_upper_bound=radius)
        cand = cand[np.isfinite(d)]
        label[cand] = k
        best[cand] = res[cand]
    return [np.flatnonzero(label == k) for k in range(len(models))]


def area_mm2(surface) -> float:
    """Area of the material region (outer polygon minus holes) in the surface's flat chart (mm^2); a
    free-form face's own (its chart is not area-true)."""
    if surface.model == "freeform":
        return float(surface.area_mm2())

    def area(poly):  # the flat chart is area-true (a sphere's is sinusoidal)
        xy = flat_mm(surface, np.asarray(poly, float))
        x, y = xy[:, 0], xy[:, 1]
        return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))

    b = surface.boundary
    return max(area(b.outer_uv) - sum(area(h) for h in b.holes_uv), 0.0)


def _faces(P_world, N_all, centroid, models, label, settings, workpiece, source):
    """Refined faces with boundaries; small faces dropped or merged (``settings.small_faces``)."""
    thr, cos_tol = settings.threshold_mm, math.cos(settings.normal_tol_rad)
    P = P_world - centroid
    bkw = dict(cell_mm=settings.boundary_cell_mm, close_gaps_mm=settings.close_gaps_mm,
               simplify_mm=settings.simplify_mm, source=source)
    built = []
    for k, model in enumerate(models):
        idx = np.flatnonzero(label == k)
        if len(idx) < MIN_FACE_SAMPLES:
            continue
        sub = idx if len(idx) <= REFINE_POINTS else idx[np.linspace(0, len(idx) - 1, REFINE_POINTS).astype(int)]
        model = model.refined(P[sub], thr)
        built.append((model, idx))
    # small faces
    surfaces = [(_surface(m, P_world, N_all, P, idx, centroid, bkw), m, idx) for m, idx in built]
    big = [area_mm2(s) >= settings.min_area_mm2 for s, _, _ in surfaces]
    dropped = big.count(False)
    if settings.small_faces == "merge" and dropped and any(big):
        keep = [(m, idx) for (s, m, idx), b in zip(surfaces, big) if b]
        extra = [[] for _ in keep]
        for (s, m, idx), b in zip(surfaces, big):
            if b:
                continue
            res = np.stack([km.residual(P[idx]) for km, _ in keep], axis=1)
            cos = np.stack([km.normal_cos(P[idx], N_all[idx]) for km, _ in keep], axis=1)
            res[(res >= 3 * thr) | (cos <= cos_tol)] = np.inf
            to = np.argmin(res, axis=1)
            fine = np.isfinite(res[np.arange(len(idx)), to])
            for j in range(len(keep)):
                extra[j].append(idx[fine & (to == j)])
        merged = [(m, np.sort(np.concatenate([idx, *e]))) for (m, idx), e in zip(keep, extra)]
        surfaces = [(_surface(m, P_world, N_all, P, idx, centroid, bkw), m, idx) for m, idx in merged]
    else:
        surfaces = [t for t, b in zip(surfaces, big) if b]
    surfaces = _on_edges(surfaces, P_world, workpiece, thr)
    areas = [area_mm2(s) for s, _, _ in surfaces]
    order = sorted(range(len(surfaces)), key=lambda k: (-round(areas[k], 6), k))  # largest first
    faces = [Face(i, surfaces[k][0], surfaces[k][2], areas[k]) for i, k in enumerate(order)]
    return faces, dropped


def _on_edges(surfaces, P_world, workpiece, threshold_mm):
    """``(surface, model, inliers)`` triples with the surfaces' boundaries on the part's edges."""
    moved = boundaries_on_edges([s for s, _, _ in surfaces], [idx for _, _, idx in surfaces], workpiece,
                                threshold_mm)
    return [(s, m, idx) for s, (_, m, idx) in zip(moved, surfaces)]


def boundaries_on_edges(surfaces: list, inliers: list[np.ndarray], workpiece, threshold_mm: float,
                        held_elsewhere: np.ndarray | None = None) -> list:
    """The faces' surfaces with their boundaries moved onto the part's edges (``face_edges.on_edges``):
    neighbours' intersections and seams, the mesh's free edges when the workpiece is a mesh, else the
    points' extent. ``inliers[k]``: face k's indices into the workpiece's points. ``held_elsewhere``: points
    of faces not among these (a STEP part's free-form faces): no face's extent, though no neighbour either."""
    P_world = np.asarray(workpiece.points_mm, float)
    free = FreeEdges.of_mesh(getattr(workpiece, "vertices_mm", None), getattr(workpiece, "faces", None))
    points = [P_world[idx if len(idx) <= BOUNDARY_POINTS else
                      idx[np.linspace(0, len(idx) - 1, BOUNDARY_POINTS).astype(int)]] for idx in inliers]
    owner = np.full(len(P_world), -1)
    if held_elsewhere is not None:
        owner[held_elsewhere] = len(inliers)
    for k, idx in enumerate(inliers):
        owner[idx] = k
    return on_edges(list(surfaces), points, P_world, owner, threshold_mm, free)


def _surface(model: _Model, P_world, N_all, P, idx, centroid, bkw):
    """The world-frame surface of a face's points idx, with stats, boundary and material side.

    The boundary and the frame are taken from at most ``BOUNDARY_POINTS``
    of them (evenly strided): denser points no longer change the boundary's cells.
    """
    n_points = len(P_world)
    res = model.residual(P[idx])
    stats = FitStats(float(len(idx) / n_points), float(np.sqrt(np.mean(res ** 2))), float(res.max()),
                     int(n_points), int(len(idx)))
    sub = idx if len(idx) <= BOUNDARY_POINTS else idx[np.linspace(0, len(idx) - 1, BOUNDARY_POINTS).astype(int)]
    Q_world, normals = P_world[sub], N_all[sub]
    if model.kind == "plane":
        n, d = model.params
        surface = plane_surface(Q_world, normals, n, d + float(n @ centroid), stats, bkw)
    elif model.kind == "sphere":
        c, r = model.params
        surface = sphere_patch(Q_world, normals, c + centroid, r, stats, bkw)
    else:
        c, a, r = model.params
        cw = c + centroid
        surface = cylinder_surface(Q_world, normals, cw - (cw @ a) * a, a, r, stats, bkw)
    return boundary_on_points(surface, Q_world)


def _pull_within(poly: np.ndarray, tree: cKDTree, xy: np.ndarray, reach_mm: float, step_mm: float) -> np.ndarray:
    """The closed polygon densified to ``step_mm`` and every vertex farther than ``reach_mm`` from the
    points ``xy`` (``tree``) moved to that distance from its nearest point."""
    closed = np.vstack([poly, poly[:1]])
    seg = np.diff(closed, axis=0)
    n = np.maximum(np.ceil(np.linalg.norm(seg, axis=1) / step_mm).astype(int), 1)
    start = np.repeat(closed[:-1], n, axis=0)
    frac = np.concatenate([np.arange(k) / k for k in n])
    dense = start + frac[:, None] * np.repeat(seg, n, axis=0)
    dist, idx = tree.query(dense)
    far = dist > reach_mm
    p = xy[idx[far]]
    dense[far] = p + (dense[far] - p) * (reach_mm / dist[far])[:, None]
    return dense


def boundary_on_points(surface, Q_world: np.ndarray):
    """The face's boundary polygons densified (1 mm) and pulled to within half a point spacing of its points.

    The boundary image's cells and smoothing put the traced contour up to a
    cell or two past the last points; on a face that ends at an edge of the part
    that is work beyond the edge (the motion check sees the tool off the part).
    ``boundary._within_reach_of_points`` (the sparse-scan cut-back of the
    single-surface fit) does the same pulling with a tree of its own per call;
    here one tree per face serves every pull (``_pull_within``).
    """
    from dataclasses import replace

    from .surface import Boundary

    xy = flat_mm(surface, surface.uv_from_points(Q_world))
    tree = cKDTree(xy)
    probe = xy[np.linspace(0, len(xy) - 1, min(len(xy), 2000)).astype(int)]
    d, _ = tree.query(probe, k=2)
    reach = 0.5 * float(np.median(d[:, 1]))
    b = surface.boundary

    def pulled(poly):
        xy_poly = _pull_within(flat_mm(surface, np.asarray(poly, float)), tree, xy, reach, 1.0)
        # the pulled outline follows the points' scatter; smoothed along the outline (circular average over
        # 2 x SMOOTH_VERTICES + 1 vertices 1 mm apart) and moved into the material (the left side of outer
        # contours and holes alike) by the OFFSET_PERCENTILE-th percentile of its overshoot, a row near and
        # along an edge crosses it once instead of weaving in and out; the few vertices still beyond reach
        # of the points are pulled in one by one
        k = SMOOTH_VERTICES
        if len(xy_poly) > 2 * k + 2:
            pad = np.vstack([xy_poly[-k:], xy_poly, xy_poly[:k]])
            kernel = np.ones(2 * k + 1) / (2 * k + 1)
            xy_poly = np.stack([np.convolve(pad[:, i], kernel, mode="valid") for i in range(2)], axis=-1)
            tangent = np.roll(xy_poly, -1, axis=0) - np.roll(xy_poly, 1, axis=0)
            left = np.stack([-tangent[:, 1], tangent[:, 0]], axis=-1)
            left /= np.maximum(np.linalg.norm(left, axis=1), 1e-12)[:, None]
            over = tree.query(xy_poly)[0] - reach
            xy_poly = xy_poly + max(float(np.percentile(over, OFFSET_PERCENTILE)), 0.0) * left
            xy_poly = _pull_within(xy_poly, tree, xy, reach, 1.0)  # where the offset could not reach
        simple = cv2.approxPolyDP(xy_poly.reshape(-1, 1, 2).astype(np.float32), 0.05, True).reshape(-1, 2)
        return uv_of_flat(surface, simple.astype(float) if len(simple) >= 3 else xy_poly)

    return replace(surface, boundary=Boundary(pulled(b.outer_uv), tuple(pulled(h) for h in b.holes_uv)))
