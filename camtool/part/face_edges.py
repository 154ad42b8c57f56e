"""Face boundaries on the part's edges: where two faces meet, where a mesh ends, and where a scan's points do.

A face's boundary is traced from its inlier points (``segment.boundary_on_points``),
and the points stop short of the part's edges: on a mesh by about a point
spacing, and the traced outline is moved into the material by a few mm so that
a row along it crosses it once; on a scan the estimated normals blend near an
edge and the normal test rejects points there, so the inliers end 4 to 11 mm
before it. The faces' fitted models are far better than that (a few hundredths
of a mm), so this pass puts each boundary vertex, along the boundary's outward
normal on the face (in the face's flat chart), onto

- the **intersection with a neighbouring face**: a crossing of that face's
  surface met head on within ``SNAP_REACH_MM``, near which the neighbour has
  points (the nearest such neighbour wins); where the two surfaces meet
  tangentially (a dome on a cylinder of its radius) there is no crossing, and
  the vertex goes to the seam, the extremum of the neighbour's distance;
- else a **free edge of the mesh** (an edge of one triangle only) that the
  normal meets, when the workpiece is a mesh;
- else, on a face all round its axis, its **seam** at u = +-pi (the cut of its
  outline, not an edge);
- else **where the face's points end** (a scan's free edge): the farthest of
  the workpiece's points on the surface that no other face owns, then settled
  on discs of those points (the second farthest within 6, then 10 mm, along the
  moved outline's normal, less the mean shortfall of such a point, 1 / (R rho)
  at density rho); where the outline turns next to an edge met exactly, the
  corner of the two edges' lines is taken instead.

Short gaps between two edges are closed at their corner, and a polygon with no
vertex moved is returned as it was. A sphere's moved outline goes back to (u, v)
so that its straight (u, v) edges, which the raster reads, stay on the outline
near the chart's poles (``_sphere_outline_uv``). Last, a long straight run placed by the
points' extent goes onto its fitted line (``_extent_straightened``), and a chain
of short edges cutting a corner between two straight edges is replaced by the
corner of their lines (``_corners_squared``).

Hand-written: trimesh and open3d segment meshes but do not refine a
segmentation's outlines onto the fitted models' intersections; the maths is a
1-D root (or extremum) search per vertex, done for all vertices at once.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cached_property, partial
from itertools import chain

import cv2
import numpy as np
from scipy.spatial import cKDTree

from ..alongside import Alongside
from .surface import Boundary, Cylinder, PlaneSurface

SNAP_REACH_MM = 15.0    # a vertex moves at most this far out of the material along its normal, and the neighbour's
                        # points must come this near the point it moves to
INWARD_MM = 3.0         # ... or this far into the material (the traced outline is inside, or a point spacing out);
                        # a tangent seam, where the two faces' points mingle, is looked for SNAP_REACH_MM either way
DISTANCE_WEIGHT = 0.1   # mm of a neighbour's gap a mm farther along the normal is worth
SEARCH_STEP_MM = 0.5    # the normal is sampled this finely; crossings are interpolated between samples
VERTEX_MM = 1.0         # boundary polygons are resampled to vertices this far apart before they move
TANGENT_DEG = 15.0      # surfaces whose normals differ by less than this meet tangentially
TANGENT_GAP_MM = 0.5    # ... and touch where the neighbour's distance along the normal has an extremum this small
HEAD_ON_DEG = 35.0      # a vertex moves onto an edge only along a normal within this angle of the edge's normal
TANGENT_RADIUS_MM = 10000.0  # ... and the distance curves along the normal at least as much as on this radius
FREE_EDGE_GAP_MM = 0.5  # a mesh free edge counts as met where the normal passes this near it
TANGENT_VERTICES = 4    # the outward normal is taken from the outline over +-4 vertices
MIN_RUN_VERTICES = 3    # vertices moved onto one edge in a run shorter than this stay where they were
LINE_VERTICES = 6       # ... an edge's line into a corner is drawn through its last 6 vertices
GAP_VERTICES = 25       # a run of unmoved vertices this short between moved ones is closed (chord or corner)
END_SPACINGS = 2.0      # a point of the ray is among the face's points when one is this many spacings near
END_WINDOW_VERTICES = 8  # ... the farthest within +-8 vertices
END_TANGENT_VERTICES = 12  # ... along normals taken over +-12 vertices
END_WINDOW_DEG = 10.0   # ... whose normals agree within this angle
END_DISCS_MM = (6.0, 10.0, 10.0)  # then each such vertex goes out to the points' second farthest along the moved
                        # outline's normal within this radius of it, once per radius: a window of the points
                        # themselves, as the outline settles onto the edge its normal does too
END_DISC_POINTS = 5     # ... where at least this many points are in the disc
END_DISC_WIDTH_SHARE = 0.4  # ... of radius at most this share of the face's width
CORNER_VERTICES = 8     # such vertices this near an edge met exactly, where the outline turns, give way to the corner
SEAM_RAD = 0.1          # a face all round its axis keeps the vertices this near its seam where they are
NEIGHBOUR_POINTS = 50000  # a neighbour's points (strided) its nearness is measured on
EXTENT_POINTS = 200000  # a face's points (strided) its extent is read from
PASSES = 2              # the pass is run this many times
SIMPLIFY_MM = 0.05      # the moved polygon is simplified (Douglas-Peucker) to this tolerance
ALONGSIDE_FACES = 8     # from this many faces on, half of them are moved in a forked child (``on_edges``)


# ----------------------------------------------------------------------------- flat charts


def flat_mm(surface, uv: np.ndarray) -> np.ndarray:
    """(u, v) in the surface's flat chart (mm): a plane's own, (R u, v) on a cylinder, sinusoidal on a sphere."""
    if isinstance(surface, PlaneSurface):
        return uv
    if isinstance(surface, Cylinder):
        return np.stack([surface.radius_mm * uv[:, 0], uv[:, 1]], axis=-1)
    r = surface.radius_mm
    return np.stack([r * uv[:, 0] * np.cos(uv[:, 1]), r * uv[:, 1]], axis=-1)


def uv_of_flat(surface, xy: np.ndarray) -> np.ndarray:
    """The surface's (u, v) of flat-chart points (inverse of ``flat_mm``)."""
    if isinstance(surface, PlaneSurface):
        return xy
    if isinstance(surface, Cylinder):
        return np.stack([xy[:, 0] / surface.radius_mm, xy[:, 1]], axis=-1)
    r = surface.radius_mm
    v = np.clip(xy[:, 1] / r, -math.pi / 2 + 1e-6, math.pi / 2 - 1e-6)
    return np.stack([xy[:, 0] / (r * np.cos(v)), v], axis=-1)


# ----------------------------------------------------------------------------- the surfaces as level sets
def _norm(d: np.ndarray) -> np.ndarray:
    """Euclidean length over the last axis (2 or 3 components): ``np.linalg.norm(d, axis=-1)`` to the bit (the
    squares summed in the same order), without its per-row reduction loop (a third of the pass's level time)."""
    return np.sqrt(_squared(d))


def _squared(d: np.ndarray) -> np.ndarray:
    """The squared length over the last axis, as ``_norm`` sums it."""
    s = d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1]
    if d.shape[-1] == 3:
        s += d[..., 2] * d[..., 2]
    return s



def level(surface, X: np.ndarray) -> np.ndarray:
    """Signed distance (mm, to first order) of points X (..., 3) from the surface's plane, sphere or cylinder."""
    if isinstance(surface, PlaneSurface):
        return (X - surface.origin_mm) @ surface.normal
    d = X - surface.center_mm
    if isinstance(surface, Cylinder):
        d = d - (d @ surface.axis)[..., None] * surface.axis
    return _norm(d) - surface.radius_mm


def level_normal(surface, X: np.ndarray) -> np.ndarray:
    """Unit gradient (..., 3) of ``level`` at X."""
    if isinstance(surface, PlaneSurface):
        return np.broadcast_to(surface.normal, X.shape).copy()
    d = X - surface.center_mm
    if isinstance(surface, Cylinder):
        d = d - (d @ surface.axis)[..., None] * surface.axis
    return d / np.maximum(_norm(d), 1e-12)[..., None]


def _projected(surface, X: np.ndarray) -> np.ndarray:
    """The points X (n, 3) moved onto the surface along its normal."""
    return X - level(surface, X)[:, None] * level_normal(surface, X)


# ----------------------------------------------------------------------------- inputs


@dataclass(frozen=True)
class FreeEdges:
    """A mesh's free edges (edges of one triangle only) as segments, with a tree of points along them."""

    start_mm: np.ndarray  # (k, 3)
    end_mm: np.ndarray    # (k, 3)
    tree: cKDTree         # over points every <= 0.5 mm along the segments
    segment_of: np.ndarray  # the segment of each tree point

    @staticmethod
    def of_mesh(vertices_mm, triangles) -> "FreeEdges | None":
        """The free edges of a triangle mesh, or None when it has none. Vertices within 0.1 um are one vertex
        first: a STEP part is tessellated face by face, each B-rep face with its own copy of the vertices on
        its edges (and a cylinder's seam twice), so every face's outline would read as a free edge."""
        if vertices_mm is None or triangles is None or len(triangles) == 0:
            return None
        V, inverse = np.unique(np.round(np.asarray(vertices_mm, float), 4), axis=0, return_inverse=True)
        F = inverse.reshape(-1)[np.asarray(triangles, np.int64)]
        e = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
        key = e[:, 0] * (len(V) + 1) + e[:, 1]
        uniq, first, count = np.unique(key, return_index=True, return_counts=True)
        free = e[first[count == 1]]
        if len(free) == 0:
            return None
        a, b = V[free[:, 0]], V[free[:, 1]]
        n = np.maximum(np.ceil(_norm(b - a) / 0.5).astype(int), 1)
        seg = np.repeat(np.arange(len(free)), n + 1)
        frac = np.concatenate([np.linspace(0, 1, k + 1) for k in n])
        pts = a[seg] + frac[:, None] * (b - a)[seg]
        return FreeEdges(a, b, cKDTree(pts), seg)

    def nearest_mm(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(distance, closest point) of each point X (n, 3) to the free edges, within ``SNAP_REACH_MM``."""
        d, i = self.tree.query(X, distance_upper_bound=SNAP_REACH_MM)
        near = np.isfinite(d)
        closest = np.full(X.shape, np.nan)
        dist = np.full(len(X), np.inf)
        s = self.segment_of[i[near]]
        a, ab = self.start_mm[s], self.end_mm[s] - self.start_mm[s]
        f = np.clip(np.einsum("ij,ij->i", X[near] - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-24), 0, 1)
        closest[near] = a + f[:, None] * ab
        dist[near] = _norm(X[near] - closest[near])
        return dist, closest


# ----------------------------------------------------------------------------- the pass


def on_edges(surfaces: list, points_mm: list[np.ndarray], cloud_mm: np.ndarray, owner: np.ndarray,
             threshold_mm: float, free_edges: FreeEdges | None = None) -> list:
    """The surfaces with their boundary vertices moved onto the part's edges (see the module docstring).

    ``points_mm[k]`` are face k's inlier points (world mm); every other face is a
    possible neighbour of face k, and counts where its points come near. Where no
    edge is met, the workpiece's points ``cloud_mm`` within ``threshold_mm`` of the
    face's surface that no other face owns (``owner``: each point's face, -1 for
    none; near an edge a scan's normals blend and its points are nobody's) say where
    the face ends."""
    trees = [cKDTree(_strided(p, NEIGHBOUR_POINTS)) for p in points_mm]
    boxes = _Boxes.of(trees)

    def moved(faces: list[int]) -> list:
        return [_face_on_edges(k, surfaces, trees, boxes, cloud_mm, owner, threshold_mm, free_edges) for k in faces]

    if len(surfaces) < ALONGSIDE_FACES:
        return moved(list(range(len(surfaces))))
    # each face's boundary moves on its own (its neighbours as given, not as moved): about half the work in a
    # forked child (``alongside``: where the machine gives this process a second CPU), the rest here
    here, there = _halves([_outline_mm(s) for s in surfaces])
    with Alongside(partial(moved, there)) as child:
        out = [None] * len(surfaces)
        for k, s in zip(here, moved(here)):
            out[k] = s
        for k, s in zip(there, child.result()):
            out[k] = s
    return out


def _outline_mm(surface) -> float:
    """The length (mm, in the flat chart) of the face's boundary polygons: the edge pass's work on the face
    grows with it (its vertices are 1 mm apart, a ray each)."""
    b = surface.boundary
    total = 0.0
    for poly in (b.outer_uv, *b.holes_uv):
        xy = flat_mm(surface, np.asarray(poly, float).reshape(-1, 2))
        total += float(_norm(np.roll(xy, -1, axis=0) - xy).sum())
    return total if math.isfinite(total) else 0.0


def _halves(work: list[float]) -> tuple[list[int], list[int]]:
    """The items split in two of about equal work (the largest first, each to the lighter half), each in order."""
    load, half = [0.0, 0.0], ([], [])
    for k in sorted(range(len(work)), key=lambda k: (-work[k], k)):
        lighter = int(load[1] < load[0])
        load[lighter] += work[k]
        half[lighter].append(k)
    return sorted(half[0]), sorted(half[1])


def _face_on_edges(k: int, surfaces: list, trees: list, boxes: "_Boxes", cloud_mm: np.ndarray, owner: np.ndarray,
                   threshold_mm: float, free_edges: FreeEdges | None):
    """Face k's surface with its boundary on the edges (``on_edges``), or as it was when no vertex moves."""
    s = surfaces[k]
    others = _Neighbours(surfaces, trees, boxes, k)
    b = s.boundary
    mine = np.flatnonzero((owner == k) | (owner < 0))   # (the level only of these: a part has many faces)
    own = _FacePoints(_strided(cloud_mm[mine[np.abs(level(s, cloud_mm[mine])) < threshold_mm]], EXTENT_POINTS))
    moved = [_moved_again(s, poly, others, free_edges, own) for poly in (b.outer_uv, *b.holes_uv)]
    if all(m is None for m in moved):
        return s
    polys = [np.asarray(p, float) if m is None else m for p, m in zip((b.outer_uv, *b.holes_uv), moved)]
    return replace(s, boundary=Boundary(polys[0], tuple(polys[1:])))


def _strided(points: np.ndarray, most: int) -> np.ndarray:
    """At most ``most`` of the points, evenly strided."""
    return points if len(points) <= most else points[np.linspace(0, len(points) - 1, most).astype(int)]


class _FacePoints:
    """The points a face's extent is read from, with their tree and spacing made on first use."""

    def __init__(self, points_mm: np.ndarray):
        self.points_mm = points_mm

    @cached_property
    def tree(self) -> cKDTree:
        return cKDTree(self.points_mm)

    @cached_property
    def spacing_mm(self) -> float:
        return spacing_mm(self.tree, self.points_mm)


def _moved_again(surface, poly_uv, others, free_edges, own) -> np.ndarray | None:
    """``_moved`` repeated ``PASSES`` times: a corner the first pass closed lets the rays of a short side
    next to it meet their edge head on."""
    out = None
    for k in range(PASSES):  # the face's own points decide only in the last pass, where no edge was met
        last = k == PASSES - 1
        moved = _moved(surface, poly_uv if out is None else out, others, free_edges, own if last else None, last)
        if moved is not None:
            out = moved
        elif out is not None:
            break   # (a face with no edge met before the last pass: its own points may still say where it ends)
    return out


@dataclass(frozen=True)
class _Rays:
    """A polygon's vertices (flat chart, 1 mm apart), their outward normals and the rays along them: ``t`` (K,)
    mm from the vertex, ``uv`` (m, K, 2) and ``X`` (m, K, 3) the ray's points on the surface."""

    xy: np.ndarray
    outward: np.ndarray
    t: np.ndarray
    uv: np.ndarray
    X: np.ndarray

    @staticmethod
    def of(surface, xy: np.ndarray, outward: np.ndarray, rows=slice(None)) -> "_Rays":
        t = np.arange(-SNAP_REACH_MM, SNAP_REACH_MM + 1e-9, SEARCH_STEP_MM)
        xy, outward = xy[rows], outward[rows]
        uv = uv_of_flat(surface, (xy[:, None, :] + t[None, :, None] * outward[:, None, :]).reshape(-1, 2))
        X = surface.point_mm(uv[:, 0], uv[:, 1]).reshape(len(xy), len(t), 3)
        return _Rays(xy, outward, t, uv.reshape(len(xy), len(t), 2), X)


# what a vertex moved onto (``_moved``'s source codes past the neighbours' indices 0..n-1)
FREE_EDGE, SEAM, EXTENT = -2, -3, -4
UNMOVED = -1


def _moved(surface, poly_uv, others, free_edges, own, square: bool = True) -> np.ndarray | None:
    """The polygon (uv) with its vertices on the edges they reach, or None when none reaches one; with
    ``square``, its cut corners squared (``_corners_squared``)."""
    xy = _flat_outline(surface, np.asarray(poly_uv, float))
    if len(xy) < 2 * TANGENT_VERTICES + 3:
        return None
    rays = _Rays.of(surface, xy, _outward(xy))
    new_xy, source = xy.copy(), np.full(len(xy), UNMOVED)
    _onto_neighbours(surface, rays, others, new_xy, source)
    if free_edges is not None:
        _onto_free_edges(surface, rays, free_edges, new_xy, source)
    _onto_seam(surface, rays, new_xy, source)
    if own is not None:
        _onto_extent(surface, xy, own, new_xy, source)
    _within_turn(surface, xy, new_xy, source)
    source = _without_short_runs(source, MIN_RUN_VERTICES)
    if (source == UNMOVED).all():
        return None
    source = _short_estimates_dropped(source)
    new_xy = _gaps_closed(np.where((source != UNMOVED)[:, None], new_xy, xy), source)
    if surface.model == "sphere" and not _all_round(surface, new_xy, POLE_RAD):
        return _sphere_outline_uv(surface, new_xy)
    simple = cv2.approxPolyDP(new_xy.reshape(-1, 1, 2).astype(np.float32), SIMPLIFY_MM, True).reshape(-1, 2)
    if surface.model == "sphere":  # a whole ball's seam
        return _sphere_uv(surface, new_xy if len(simple) < 3 else simple.astype(float))
    if len(simple) < 3:
        return uv_of_flat(surface, new_xy)
    # a plane's or cylinder's flat chart is an isometry: a straight edge there is an edge of the part
    simple = simple.astype(float)
    return uv_of_flat(surface, _corners_squared(simple) if square else simple)


# ----------------------------------------------------------------------------- a sphere's outline in (u, v)

SPLIT_DEPTH = 12        # a flat edge is halved at most this many times until (u, v) follows it
POLE_RAD = 0.1          # an outline that goes all round u this far from the poles (a whole ball's seam) keeps the
                        # flat chart's simplification: there a seam, not a pole, bends (u, v)


def _sphere_uv(surface, xy: np.ndarray) -> np.ndarray:
    """``uv_of_flat`` on a sphere, u kept within -pi..pi: past the sinusoidal chart's edge is past the seam, and
    near a pole x / cos v would run off to millions of rad (a whole ball)."""
    uv = uv_of_flat(surface, xy)
    uv[:, 0] = np.clip(uv[:, 0], -math.pi, math.pi)
    return uv


def _sphere_outline_uv(surface, closed_xy: np.ndarray) -> np.ndarray:
    """The closed outline (flat chart of a sphere) as a (u, v) polygon whose straight edges in (u, v), the raster's
    and the checks' reading of it, stay within ``SIMPLIFY_MM`` of the outline on the sphere.

    The sinusoidal chart squeezes a pole's neighbourhood to a point: a short straight edge there, or one passing
    the pole, is a long sweep in u, and a straight edge in (u, v) from it goes round the pole (a hemisphere's rim
    runs through both poles of the chart its mean direction spans). So each flat edge is halved until the (u, v)
    midpoint of its ends lands on the sphere where the flat midpoint does, and the polygon is then simplified by
    Douglas-Peucker with the deviation measured on the sphere between the (u, v) edge and the vertices it drops.
    """
    closed = np.vstack([closed_xy, closed_xy[:1]])
    a, ab = closed[:-1], np.diff(closed, axis=0)
    e, lo, hi = np.arange(len(a)), np.zeros(len(a)), np.ones(len(a))
    edges, fracs = [e], [lo]    # the vertices: (flat edge, share along it); the edges' own first
    for _ in range(SPLIT_DEPTH):  # level by level, every piece whose (u, v) midpoint is off the flat one is halved
        if not len(e):
            break
        pa, pb, mid = a[e] + lo[:, None] * ab[e], a[e] + hi[:, None] * ab[e], 0.5 * (lo + hi)
        on = surface.point_mm(*_sphere_uv(surface, 0.5 * (pa + pb)).T)
        halfway = surface.point_mm(*(0.5 * (_sphere_uv(surface, pa) + _sphere_uv(surface, pb))).T)
        off = _norm(halfway - on) > 0.25 * SIMPLIFY_MM
        e, lo, hi, mid = e[off], lo[off], hi[off], mid[off]
        edges.append(e)
        fracs.append(mid)
        e, lo, hi = np.concatenate([e, e]), np.concatenate([lo, mid]), np.concatenate([mid, hi])
    edge, frac = np.concatenate(edges), np.concatenate(fracs)
    order = np.lexsort((frac, edge))
    xy = a[edge[order]] + frac[order][:, None] * ab[edge[order]]
    uv = _sphere_uv(surface, xy)
    keep = _kept_on_sphere(surface, uv, SIMPLIFY_MM)
    return uv[keep]


def _flat_outline(surface, poly_uv: np.ndarray) -> np.ndarray:
    """The closed (u, v) polygon in the flat chart, with vertices at most ``VERTEX_MM`` apart (its own kept). On a
    sphere its edges are straight in (u, v), so each is followed there (32 pieces) and resampled by its flat length."""
    if surface.model != "sphere":
        return _resampled(flat_mm(surface, poly_uv), VERTEX_MM)
    closed = np.vstack([poly_uv, poly_uv[:1]])
    s = np.linspace(0.0, 1.0, 33)
    fine_uv = closed[:-1, None, :] + s[None, :, None] * np.diff(closed, axis=0)[:, None, :]
    fine_xy = flat_mm(surface, fine_uv.reshape(-1, 2)).reshape(fine_uv.shape)
    along = np.concatenate([np.zeros((len(fine_xy), 1)),
                            np.cumsum(_norm(np.diff(fine_xy, axis=1)), axis=1)], axis=1)
    length = along[:, -1]
    n = np.maximum(np.ceil(length / VERTEX_MM).astype(int), 1)   # each edge's vertices
    edge = np.repeat(np.arange(len(n)), n)
    at = (np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)) / n[edge] * length[edge]
    return _interp_rows(at, along, fine_xy, edge)


def _interp_rows(x: np.ndarray, xp: np.ndarray, fp: np.ndarray, row: np.ndarray) -> np.ndarray:
    """``np.interp(x[i], xp[row[i]], fp[row[i], :, c])`` for every i and column c at once, to the bit (numpy's
    rule: the last knot at or before x, its own value there or at the last knot, else slope times offset plus
    value, from the other knot where that is NaN); xp's rows ascending, x within them (an outline's resampling)."""
    last = xp.shape[1] - 1
    j = np.minimum((xp[row] <= x[:, None]).sum(axis=1) - 1, last)
    j = np.maximum(j, 0)
    j1 = np.minimum(j + 1, last)
    x0, x1, y0, y1 = xp[row, j], xp[row, j1], fp[row, j], fp[row, j1]
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = (y1 - y0) / (x1 - x0)[:, None]
        out = slope * (x - x0)[:, None] + y0
        nan = np.isnan(out)
        if nan.any():
            other = slope * (x - x1)[:, None] + y1
            out = np.where(nan, np.where(np.isnan(other) & (y0 == y1), y0, other), out)
    exact = (j == last) | (x0 == x)
    return np.where(exact[:, None], y0, out)


def _kept_on_sphere(surface, uv: np.ndarray, tol_mm: float) -> np.ndarray:
    """Indices of the closed (u, v) polygon's vertices that Douglas-Peucker keeps, with the deviation of a dropped
    vertex measured on the sphere from the (u, v) edge that replaces it (sampled 32 times, to the nearest piece).
    Hand-written: OpenCV's and shapely's simplifications measure in their input's plane, not along a chart's
    straight edges mapped onto a surface."""
    X = surface.point_mm(uv[:, 0], uv[:, 1])
    n = len(uv)
    far = int(np.argmax(_norm(X - X[0])))
    keep = np.zeros(n, bool)
    keep[[0, far]] = True
    spans = np.array([(0, far), (far, n)], np.int64)
    s = np.linspace(0.0, 1.0, 33)
    while len(spans):   # every span of a round at once (each span splits on its own: the order is free)
        spans = spans[spans[:, 1] - spans[:, 0] >= 2]
        if not len(spans):
            break
        i, j = spans[:, 0], spans[:, 1]
        jj = j % n
        line_uv = uv[i][:, None, :] + s[None, :, None] * (uv[jj] - uv[i])[:, None, :]
        curve = surface.point_mm(line_uv[..., 0].ravel(), line_uv[..., 1].ravel()).reshape(len(spans), len(s), 3)
        p, d = curve[:, :-1], curve[:, 1:] - curve[:, :-1]
        count = j - i - 1
        span = np.repeat(np.arange(len(spans)), count)
        inner = np.repeat(i + 1, count) + np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
        Xi = X[inner][:, None]
        ps, ds = p[span], d[span]
        w = np.clip(np.einsum("kij,kij->ki", Xi - ps, ds) / np.maximum(np.einsum("sij,sij->si", d, d), 1e-24)[span],
                    0.0, 1.0)
        dev = np.sqrt(_squared(Xi - (ps + w[..., None] * ds)).min(axis=1))   # (the root is monotone: of the least)
        top = np.maximum.reduceat(dev, np.cumsum(count) - count)
        at_top = np.flatnonzero(dev == top[span])
        first = at_top[np.unique(span[at_top], return_index=True)[1]]   # each span's first vertex at its top
        split = top > tol_mm
        k = inner[first[split]]
        keep[k] = True
        spans = np.concatenate([np.stack([i[split], k], axis=1), np.stack([k, j[split]], axis=1)])
    return np.flatnonzero(keep)


LONG_EDGE_MM = 6.0      # a simplified outline's edge this long is a straight edge of the part
CORNER_CHAIN_MM = 8.0   # ... and shorter edges between two such, this long in all, cut the corner they meet at
CORNER_TURN_DEG = 30.0  # ... where the two straight edges turn by at least this much


def _corners_squared(xy: np.ndarray) -> np.ndarray:
    """The closed outline (K x 2, flat mm) with each short chain of edges between two straight edges replaced by
    the corner where the two edges' lines meet, when it lies within ``CORNER_CHAIN_MM`` of both.

    Snapping moves each vertex along its own normal, and next to a corner the normals turn: the last vertices
    of one edge land on the other's line past the corner, or on a third face's (a chamfer's mitre met by the
    side below it), and the simplified outline cuts or notches the corner by up to a few mm."""
    k = len(xy)
    length = _norm(np.roll(xy, -1, axis=0) - xy)
    straight = np.flatnonzero(length >= LONG_EDGE_MM)
    if len(straight) < 2:
        return xy
    replace_at: dict[int, np.ndarray] = {}
    drop: set[int] = set()
    for a, b in zip(straight, np.roll(straight, -1)):
        chain = [(a + 1 + i) % k for i in range((b - a - 1) % k)]  # the short edges between the two
        if not chain or length[chain].sum() > CORNER_CHAIN_MM:
            continue
        pa, da = xy[(a + 1) % k], xy[(a + 1) % k] - xy[a]
        pb, db = xy[b], xy[(b + 1) % k] - xy[b]
        cos = float(da @ db / (np.linalg.norm(da) * np.linalg.norm(db)))
        if cos > math.cos(math.radians(CORNER_TURN_DEG)):
            continue
        A = np.stack([da, -db], axis=1)
        if abs(np.linalg.det(A)) <= 1e-9:
            continue
        sa, sb = np.linalg.solve(A, pb - pa)
        corner = pa + sa * da
        if np.linalg.norm(corner - pa) > CORNER_CHAIN_MM or np.linalg.norm(corner - pb) > CORNER_CHAIN_MM:
            continue
        verts = [(a + 1 + i) % k for i in range((b - a) % k)]  # the end of a .. the start of b
        if any(v in drop or v in replace_at for v in verts):
            continue
        replace_at[verts[0]] = corner
        drop.update(verts[1:])
    if not replace_at:
        return xy
    out = [replace_at.get(i, xy[i]) for i in range(k) if i not in drop]
    return np.asarray(out, float) if len(out) >= 3 else xy


def _onto_neighbours(surface, rays: _Rays, others, new_xy, source) -> None:
    """Vertices onto the neighbour they meet (crossing or seam) whose points come nearest the meeting point,
    a nearer meeting breaking ties (in place)."""
    best_t = np.full(len(rays.xy), np.inf)
    with np.errstate(invalid="ignore"):   # (a ray off its surface is NaN: its box meets nothing)
        across_k = np.ascontiguousarray(rays.X.transpose(0, 2, 1))   # (m, 3, K): the least and most along each
        ray_lo, ray_hi = across_k.min(axis=2), across_k.max(axis=2)      # ray in one pass each (exact either way)
        lo, hi = ray_lo - SNAP_REACH_MM, ray_hi + SNAP_REACH_MM   # each ray's box
    # each ray within the ball about its box's middle: a surface whose level there is farther from zero than the
    # ball's radius plus TANGENT_GAP_MM is neither crossed nor touched by it (the level changes by at most the
    # distance moved: a plane's, a sphere's and a cylinder's alike), so it is not asked (it meets nothing)
    mid, radius = 0.5 * (ray_lo + ray_hi), 0.5 * _norm(ray_hi - ray_lo) + TANGENT_GAP_MM + 1e-6
    nb, row, f = [], [], []   # the (neighbour, ray) pairs that may meet, with the neighbour's level along the ray
    for j in _near_rays(ray_lo, ray_hi, others):
        other, _ = others[j]
        # only the rays the neighbour's points can come near (``_near_rays``, ray by ray): the others meet
        # nothing of it (``_meeting_rows`` takes each ray on its own)
        near_lo, near_hi = others.box(j)
        sub = np.flatnonzero(np.all(hi >= near_lo, axis=1) & np.all(lo <= near_hi, axis=1))
        sub = sub[np.abs(level(other, mid[sub])) <= radius[sub]]
        if len(sub) == 0:
            continue
        level_j = level(other, rays.X[sub])
        # only rays the surface crosses or comes within TANGENT_GAP_MM of can meet it: the rest meet nothing (a
        # part's faces are mostly far from each other's surfaces, so this skips most rays before the work below)
        with np.errstate(invalid="ignore"):   # (a crossing or a touch: the level passes within the gap of zero)
            maybe = (level_j.min(axis=1) < TANGENT_GAP_MM) & (level_j.max(axis=1) > -TANGENT_GAP_MM)
        if maybe.any():
            nb.append(np.full(int(maybe.sum()), j))
            row.append(sub[maybe])
            f.append(level_j[maybe])
    if nb:   # all neighbours' pairs at once, in the neighbours' order (each pair is taken on its own)
        nb, row = np.concatenate(nb), np.concatenate(row)
        tk = _meeting_rows(surface, others, nb, rays, row, np.concatenate(f))
        hit = np.flatnonzero(np.isfinite(tk))
        nb, row, tk = nb[hit], row[hit], tk[hit]
    if len(nb):
        X = _ray_at(rays.X, rays.t, tk, row)
        gap = _per_neighbour(nb, lambda j, X: others[j][1].query(X, distance_upper_bound=SNAP_REACH_MM)[0], X)
        score = gap + DISTANCE_WEIGHT * np.abs(tk)
        ok = np.flatnonzero(np.isfinite(gap))
        # per vertex the least score, the first neighbour of equals (as a strict ``<`` over the neighbours in turn)
        order = ok[np.lexsort((nb[ok], score[ok], row[ok]))]
        win = order[np.r_[True, row[order][1:] != row[order][:-1]]] if len(order) else order
        best_t[row[win]], source[row[win]] = tk[win], nb[win]
    on = source >= 0
    new_xy[on] = rays.xy[on] + best_t[on, None] * rays.outward[on]


def _near_rays(ray_lo: np.ndarray, ray_hi: np.ndarray, others: "_Neighbours") -> np.ndarray:
    """The neighbours (indices into ``others``) whose points can be within ``SNAP_REACH_MM`` of the rays (their
    boxes ``ray_lo``, ``ray_hi``): their points' box meets the rays' box grown by that reach. A neighbour counts
    only where its points come that near a meeting point on a ray, so the others are skipped with the same
    result (on a part of many faces, most faces are far from each other: this keeps the pass from growing as the
    square of the faces)."""
    if len(ray_lo) == 0 or not (np.isfinite(ray_lo).all() and np.isfinite(ray_hi).all()):
        return np.arange(len(others))
    return others.within(ray_lo.min(axis=0) - SNAP_REACH_MM, ray_hi.max(axis=0) + SNAP_REACH_MM)


@dataclass(frozen=True)
class _Boxes:
    """The boxes of the faces' neighbour points (a face without points: a box holding everything)."""

    lo: np.ndarray   # (F, 3)
    hi: np.ndarray   # (F, 3)

    @staticmethod
    def of(trees: list) -> "_Boxes":
        lo = np.array([t.mins if t.n else np.full(3, -np.inf) for t in trees], float).reshape(-1, 3)
        hi = np.array([t.maxes if t.n else np.full(3, np.inf) for t in trees], float).reshape(-1, 3)
        return _Boxes(lo, hi)


class _Neighbours:
    """Every face but face ``k``, as ``(surface, tree)`` pairs numbered 0.. (face k left out), with their boxes."""

    def __init__(self, surfaces: list, trees: list, boxes: _Boxes, k: int):
        self._faces = [j for j in range(len(surfaces)) if j != k]
        self._surfaces, self._trees = surfaces, trees
        self._lo, self._hi = np.delete(boxes.lo, k, axis=0), np.delete(boxes.hi, k, axis=0)

    def __len__(self) -> int:
        return len(self._faces)

    def __getitem__(self, j: int) -> tuple:
        f = self._faces[j]
        return self._surfaces[f], self._trees[f]

    def __iter__(self):
        return (self[j] for j in range(len(self)))

    def box(self, j: int) -> tuple[np.ndarray, np.ndarray]:
        """Neighbour j's box (lo, hi)."""
        return self._lo[j], self._hi[j]

    def within(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """The neighbours whose box meets the box [lo, hi], in order."""
        return np.flatnonzero(np.all(self._hi >= lo, axis=1) & np.all(self._lo <= hi, axis=1))


def _onto_free_edges(surface, rays: _Rays, free_edges: FreeEdges, new_xy, source) -> None:
    """Unmoved vertices onto the mesh free edge their ray passes nearest to them (in place)."""
    rest = np.flatnonzero(source == UNMOVED)
    if len(rest) == 0:
        return
    K = len(rays.t)
    dist, closest = free_edges.nearest_mm(rays.X[rest].reshape(-1, 3))
    dist = dist.reshape(len(rest), K)
    near = (dist < FREE_EDGE_GAP_MM) & (rays.t >= -INWARD_MM)[None, :]
    kmin = np.argmin(np.where(near, np.abs(rays.t)[None, :], np.inf), axis=1)
    hit = near[np.arange(len(rest)), kmin]
    if not hit.any():
        return
    rows = rest[hit]
    X = closest.reshape(len(rest), K, 3)[hit, kmin[hit]]
    uv = surface.uv_from_points(X)
    if not isinstance(surface, PlaneSurface):  # the angle u on the ray's turn, not wrapped to (-pi, pi]
        ray_u = rays.uv[rows, kmin[hit], 0]
        uv[:, 0] += 2 * np.pi * np.round((ray_u - uv[:, 0]) / (2 * np.pi))
    new_xy[rows] = flat_mm(surface, uv)
    source[rows] = FREE_EDGE


def _onto_seam(surface, rays: _Rays, new_xy, source) -> None:
    """Unmoved vertices on the cut of a face all round its axis, their normals along u: exactly at u = +-pi
    (the points go on across it; in place)."""
    seam = _on_seam(surface, rays.xy) & (source == UNMOVED) & \
        (np.abs(rays.outward[:, 0]) > math.cos(math.radians(HEAD_ON_DEG)))
    if seam.any():
        new_xy[seam, 0] = np.sign(rays.outward[seam, 0]) * math.pi * surface.radius_mm * \
            _flat_u_scale(surface, rays.xy[seam])
        source[seam] = SEAM


def _onto_extent(surface, xy, own: "_FacePoints", new_xy, source) -> None:
    """Unmoved vertices out to where the face's points end, along a steadier normal (a scan's outline weaves;
    the farthest within +-END_WINDOW_VERTICES; in place)."""
    rest = np.flatnonzero(source == UNMOVED)
    if len(rest) == 0:
        return
    steady = _outward(xy, END_TANGENT_VERTICES)
    rays = _Rays.of(surface, xy, steady, rest)
    t_edge = np.full(len(xy), np.inf)
    t_edge[rest] = _points_end(rays.X, rays.t, own)
    t_edge = _window_max(t_edge, steady, END_WINDOW_VERTICES)[rest]
    ok = np.isfinite(t_edge)
    new_xy[rest[ok]] = xy[rest[ok]] + t_edge[ok, None] * steady[rest[ok]]
    source[rest[ok]] = EXTENT
    width_mm = min(cv2.minAreaRect(new_xy.astype(np.float32))[1])   # a disc sees one side of a narrow face
    for radius in END_DISCS_MM:
        _extent_settled(surface, new_xy, source == EXTENT, own, min(radius, END_DISC_WIDTH_SHARE * width_mm))
    _extent_straightened(new_xy, source == EXTENT)
    source[_extent_into_corners(new_xy, source)] = UNMOVED


STRAIGHT_RUN_VERTICES = 15  # a run of vertices placed by the points' extent this long ...
STRAIGHT_SHARE = 0.8        # ... of which this share stays within STRAIGHT_TOL_MM of the line fitted to them ...
STRAIGHT_TOL_MM = 1.0       # ... is a straight free edge: the whole run goes onto that line
STRAY_MM = 3.0              # ... unless a vertex of it is this far off the line (the edge turns there)


def _extent_straightened(xy: np.ndarray, on_extent: np.ndarray) -> None:
    """Each long run of vertices placed by the points' extent that lies along a line, projected onto that line
    (in place). The line is fitted by total least squares to the run's vertices, then twice again to those
    within STRAIGHT_TOL_MM of it (a corner's vertices dip off it). Each vertex's estimate scatters by about a
    point spacing; a scan's straight free edge is better known from all of them than from any one."""
    for start, n in _runs(on_extent):
        if n < STRAIGHT_RUN_VERTICES:
            continue
        idx = (start + np.arange(n)) % len(xy)
        pts = xy[idx]
        near = np.ones(n, bool)
        for _ in range(3):
            mid = pts[near].mean(axis=0)
            normal = np.linalg.svd(pts[near] - mid, full_matrices=False)[2][1]
            off = (pts - mid) @ normal
            near = np.abs(off) <= STRAIGHT_TOL_MM
            if near.sum() < STRAIGHT_SHARE * n:
                break
        if near.sum() >= STRAIGHT_SHARE * n and np.abs(off).max() <= STRAY_MM:
            xy[idx] = pts - off[:, None] * normal


def _extent_into_corners(xy: np.ndarray, source: np.ndarray) -> np.ndarray:
    """Vertices placed by the points' extent where the outline turns (``_straight`` false) within
    CORNER_VERTICES of a run on an edge met exactly: unset, the corner of the two edges' lines is the better
    guess there (``_gaps_closed``)."""
    exact = (source != UNMOVED) & (source != EXTENT)
    near_exact = np.zeros(len(xy), bool)
    for k in range(-CORNER_VERTICES, CORNER_VERTICES + 1):
        near_exact |= np.roll(exact, k)
    return (source == EXTENT) & near_exact & ~_straight(xy)


def _straight(xy: np.ndarray) -> np.ndarray:
    """Vertices where the outline's normal (over +-END_TANGENT_VERTICES) agrees within END_WINDOW_DEG with
    the normals END_TANGENT_VERTICES before and after."""
    k = END_TANGENT_VERTICES
    normal = _outward(xy, k)
    cos_max = math.cos(math.radians(END_WINDOW_DEG))
    return (np.einsum("ij,ij->i", normal, np.roll(normal, k, axis=0)) > cos_max) & \
        (np.einsum("ij,ij->i", normal, np.roll(normal, -k, axis=0)) > cos_max)


def _extent_settled(surface, xy, on_extent: np.ndarray, own: "_FacePoints", radius_mm: float) -> None:
    """The vertices ``on_extent`` moved along the outline's normal (taken over +-END_TANGENT_VERTICES of the
    polygon as it is now) to the second farthest of the face's points within ``radius_mm`` of them: the
    farthest point of a disc lies within a fraction of a spacing of a straight free edge, and the second
    farthest leaves out one stray point (in place)."""
    rows = np.flatnonzero(on_extent)
    if len(rows) == 0:
        return
    normal = _outward(xy, END_TANGENT_VERTICES)[rows]
    a, b = (surface.point_mm(*uv_of_flat(surface, xy[rows] + h * normal).T) for h in (-0.5, 0.5))
    X = 0.5 * (a + b)
    direction = (b - a) / np.maximum(_norm(b - a), 1e-12)[:, None]
    # the second farthest of random points (density rho) in a half disc on a straight edge lies, on average,
    # 1 / (R rho) inside it (the band 2 R wide and g deep holds 2 R g rho points); the face's density from its
    # spacing (median nearest-neighbour distance d of a Poisson sample: rho = ln 2 / (pi d^2))
    inside_mm = 1.0 / (radius_mm * math.log(2) / (math.pi * own.spacing_mm ** 2))
    second = _second_farthest(own, X, direction, radius_mm)
    ok = np.isfinite(second)
    xy[rows[ok]] += (second[ok] + inside_mm)[:, None] * normal[ok]


DISC_BLOCK_ENTRIES = 1 << 21   # ``_second_farthest`` pads the discs' points to blocks of at most this many


def _second_farthest(own: "_FacePoints", X: np.ndarray, direction: np.ndarray, radius_mm: float) -> np.ndarray:
    """Per disc (centre X (n, 3), ``radius_mm``), the second largest of its face points' distances along
    ``direction`` (n, 3) from the centre; NaN where it holds fewer than END_DISC_POINTS points. The discs' points
    are padded to one (discs, most points, 3) block and measured by one stacked matmul, the same product as
    disc by disc (a matrix-vector product per disc: a plain dot or einsum would round differently)."""
    near = own.tree.query_ball_point(X, radius_mm)
    count = np.fromiter(map(len, near), np.intp, len(near))
    out = np.full(len(X), np.nan)
    rows = np.flatnonzero(count >= END_DISC_POINTS)
    if len(rows) == 0:
        return out
    width = int(count[rows].max())
    step = max(DISC_BLOCK_ENTRIES // width, 1)
    for lo in range(0, len(rows), step):
        block = rows[lo:lo + step]
        slot = np.arange(width)[None, :] < count[block][:, None]
        idx = np.zeros((len(block), width), np.intp)
        idx[slot] = np.fromiter(chain.from_iterable(near[block]), np.intp, int(count[block].sum()))
        along = np.matmul(own.points_mm[idx] - X[block][:, None, :], direction[block][:, :, None])[..., 0]
        out[block] = np.partition(np.where(slot, along, -np.inf), -2, axis=1)[:, -2]
    return out


def spacing_mm(tree: cKDTree, points: np.ndarray) -> float:
    """Median distance from a point to its nearest neighbour (at most 2000 points asked)."""
    probe = points[np.linspace(0, len(points) - 1, min(len(points), 2000)).astype(int)]
    return float(np.median(tree.query(probe, k=2)[0][:, 1]))


def _points_end(ray: np.ndarray, t: np.ndarray, own: _FacePoints) -> np.ndarray:
    """Per ray, where the face's own points end along it (mm from the vertex; inf where they do not).

    A ray sample is among the points when one lies within ``END_SPACINGS`` spacings. From the vertex
    (or, if it is out of the points, from the first sample back among them, at most INWARD_MM) the ray
    is followed while it is among them; the edge is the farthest, along the ray, of the points nearest
    those samples (a point's own position: the ray's samples would overshoot where it runs slantwise out)."""
    m, K = ray.shape[:2]
    k0 = int(np.argmin(np.abs(t)))
    inside, idx = _among_points(ray, own, k0, int(np.searchsorted(t, -INWARD_MM)))
    after = np.where(~inside[:, k0:], np.arange(k0, K)[None, :], K).min(axis=1)  # first sample out, from k0
    back = (np.arange(k0) >= np.searchsorted(t, -INWARD_MM))[None, :]
    before = np.where(inside[:, :k0] & back, np.arange(k0)[None, :], -1).max(axis=1)  # last sample in, before k0
    last = np.where(inside[:, k0], after - 1, before)
    start = np.where(inside[:, k0], k0, before)
    ok = (last >= 0) & (last < K - 1)
    direction = ray[:, k0 + 1] - ray[:, k0]
    direction /= np.maximum(_norm(direction), 1e-12)[:, None]
    along = np.einsum("mkj,mj->mk", own.points_mm[idx] - ray[:, k0:k0 + 1], direction)  # (m, K)
    k = np.arange(K)[None, :]
    along = np.where(inside & (k >= np.minimum(start, last)[:, None]) & (k <= last[:, None]), along, -np.inf)
    out = np.where(ok, along.max(axis=1), np.inf)
    return np.where(np.isfinite(out), out, np.inf)


END_BLOCK_SAMPLES = 8   # ``_among_points`` follows the rays out of the points this many samples at a time


def _among_points(ray: np.ndarray, own: _FacePoints, k0: int, k_back: int) -> tuple[np.ndarray, np.ndarray]:
    """(inside, nearest point) (m, K) of the ray samples among the face's points (``_points_end``: a point within
    END_SPACINGS spacings), asked only where ``_points_end`` reads them: from ``k_back`` to the vertex's sample
    ``k0``, then on, block by block, along the rays still among the points (the rest: False, 0). Each sample is
    asked on its own, so those asked are as when all are."""
    r = END_SPACINGS * own.spacing_mm
    m, K = ray.shape[:2]
    inside, idx = np.zeros((m, K), bool), np.zeros((m, K), np.intp)

    def ask(rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        d, i = own.tree.query(ray[rows][:, cols].reshape(-1, 3), distance_upper_bound=r)
        hit = np.isfinite(d).reshape(len(rows), len(cols))
        inside[np.ix_(rows, cols)] = hit
        idx[np.ix_(rows, cols)] = np.where(hit, i.reshape(hit.shape), 0)
        return hit

    ask(np.arange(m), np.arange(k_back, k0 + 1))
    rows, k = np.flatnonzero(inside[:, k0]), k0 + 1
    while len(rows) and k < K:
        cols = np.arange(k, min(k + END_BLOCK_SAMPLES, K))
        rows, k = rows[ask(rows, cols).all(axis=1)], k + len(cols)
    return inside, idx

def _window_max(values: np.ndarray, outward: np.ndarray, half: int) -> np.ndarray:
    """Cyclic running maximum over 2 x half + 1 vertices of the finite values, among vertices whose normals
    agree (within ``END_WINDOW_DEG``; inf entries stay inf, and are left out): the sparse points near a scan's
    free edge reach it only here and there, and a corner's rays measure something else."""
    finite = np.isfinite(values)
    v = np.where(finite, values, -np.inf)
    out = v.copy()
    cos_max = math.cos(math.radians(END_WINDOW_DEG))
    for k in (*range(1, half + 1), *range(-half, 0)):
        agree = np.einsum("ij,ij->i", outward, np.roll(outward, k, axis=0)) > cos_max
        out = np.maximum(out, np.where(agree, np.roll(v, k), -np.inf))
    return np.where(finite, out, np.inf)


def _flat_u_scale(surface, xy: np.ndarray) -> np.ndarray:
    """mm of the flat chart's x per mm of R u: 1 on a cylinder, cos v on a sphere (sinusoidal chart)."""
    if isinstance(surface, Cylinder):
        return np.ones(len(xy))
    return np.cos(uv_of_flat(surface, xy)[:, 1])


def _within_turn(surface, xy: np.ndarray, new_xy: np.ndarray, source: np.ndarray) -> None:
    """On a face all round its axis, vertices moved past its seam (u beyond +-pi) back to where their move
    crosses it (in place): a ray that crosses the seam runs on round the axis over the face's own points, and
    their extent, or a neighbour met there, lies on the far side of the cut. Cylinders only: a sphere's
    sinusoidal chart has no straight seam, and near its pole u means nothing."""
    if not isinstance(surface, Cylinder) or not _all_round(surface, xy):
        return
    u0 = uv_of_flat(surface, xy)[:, 0]
    u = uv_of_flat(surface, new_xy)[:, 0]
    past = np.flatnonzero(np.abs(u) > math.pi)
    if len(past):  # each such vertex to where its move crosses the seam
        a, b = np.abs(u0[past]), np.abs(u[past])
        f = np.clip((math.pi - a) / np.maximum(b - a, 1e-12), 0.0, 1.0)
        new_xy[past] = xy[past] + f[:, None] * (new_xy[past] - xy[past])
        new_xy[past, 0] = np.sign(u[past]) * math.pi * surface.radius_mm
        source[past] = SEAM


def _on_seam(surface, xy: np.ndarray) -> np.ndarray:
    """Vertices near the seam (u = +-pi) of a face that goes all round its axis (the outline's cut there is
    not an edge: those whose normal runs along u stay)."""
    if not _all_round(surface, xy):
        return np.zeros(len(xy), bool)
    u = uv_of_flat(surface, xy)[:, 0]
    return np.abs(np.angle(np.exp(1j * u))) > math.pi - SEAM_RAD


def _all_round(surface, xy: np.ndarray, pole_rad: float = 0.0) -> bool:
    """Whether the outline (flat chart) of a cylinder or sphere face spans the full turn of u, to SEAM_RAD; with
    ``pole_rad``, on a sphere, counting only the vertices farther than that from the chart's poles."""
    if isinstance(surface, PlaneSurface):
        return False
    uv = uv_of_flat(surface, xy)
    u = uv[np.abs(uv[:, 1]) < math.pi / 2 - pole_rad, 0] if pole_rad > 0 else uv[:, 0]
    return bool(len(u)) and bool(u.max() - u.min() >= 2 * math.pi - 2 * SEAM_RAD)


def _outward(xy: np.ndarray, k: int = 0) -> np.ndarray:
    """Unit normals (m, 2) of a closed polygon, to its right (out of the material), from the tangent averaged
    over 2 k + 1 vertices (``TANGENT_VERTICES`` by default: a traced outline weaves by a fraction of a mm)."""
    k = k or TANGENT_VERTICES
    tangent = np.roll(xy, -k, axis=0) - np.roll(xy, k, axis=0)
    outward = np.stack([tangent[:, 1], -tangent[:, 0]], axis=-1)
    return outward / np.maximum(_norm(outward), 1e-12)[:, None]


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Maximal cyclic runs (start, length) of True in mask (not all True)."""
    m = len(mask)
    if mask.all() or not mask.any():
        return [(0, m)] if mask.all() else []
    first = int(np.flatnonzero(~mask)[0])  # start scanning just after a False
    out, start = [], None
    for step in range(1, m + 1):
        i = (first + step) % m
        if mask[i] and start is None:
            start = step
        if not mask[i] and start is not None:
            out.append(((first + start) % m, step - start))
            start = None
    if start is not None:
        out.append(((first + start) % m, m + 1 - start))
    return out


def _without_short_runs(source: np.ndarray, min_len: int) -> np.ndarray:
    """``source`` with runs of one edge shorter than ``min_len`` vertices unset (UNMOVED): stray hits."""
    out = source.copy()
    for value in np.unique(source[source != UNMOVED]):
        for start, n in _runs(source == value):
            if n < min_len:
                out[(start + np.arange(n)) % len(source)] = UNMOVED
    return out


def _short_estimates_dropped(source: np.ndarray) -> np.ndarray:
    """``source`` with short runs (<= GAP_VERTICES) of vertices placed by the points' extent between two edges
    met exactly unset: the corner of those two edges is the better guess there."""
    out = source.copy()
    m = len(source)
    for start, n in _runs(source == EXTENT):
        left, right = source[(start - 1) % m], source[(start + n) % m]
        if n <= GAP_VERTICES and n < m and UNMOVED not in (left, right) and EXTENT not in (left, right):
            out[(start + np.arange(n)) % m] = UNMOVED
    return out


def _run_end(source: np.ndarray, i: int, direction: int) -> int:
    """The vertex up to LINE_VERTICES from i (cyclic, going ``direction``) still on i's edge."""
    m, j = len(source), i
    for _ in range(LINE_VERTICES):
        k = (j + direction) % m
        if source[k] != source[i]:
            break
        j = k
    return j


def _gaps_closed(xy: np.ndarray, source: np.ndarray) -> np.ndarray:
    """Short runs of unmoved vertices between moved ones replaced: by the corner where the two edges' lines
    meet when they are different edges (a box's corner, the smoothing rounded), else by the chord; two
    edges' runs that meet without a gap but a jump get their corner put between them."""
    out = xy.copy()
    m = len(xy)
    for start, n in _runs(source == UNMOVED):
        if n > GAP_VERTICES or n == m:
            continue
        run = (start + np.arange(n)) % m
        left, right = (start - 1) % m, (start + n) % m
        corner = _corner(out, source, left, right) if source[left] != source[right] else None
        out[run] = np.repeat(corner[None], n, axis=0) if corner is not None else \
            out[left] + np.linspace(0, 1, n + 2)[1:-1, None] * (out[right] - out[left])
    jumps = [i for i in range(m) if UNMOVED not in (source[i], source[(i + 1) % m])
             and source[i] != source[(i + 1) % m] and np.linalg.norm(out[(i + 1) % m] - out[i]) > 2 * VERTEX_MM]
    corners = {i: _corner(out, source, i, (i + 1) % m) for i in jumps}
    rows = [np.vstack([out[i], corners[i]]) if corners.get(i) is not None else out[i:i + 1] for i in range(m)]
    return np.vstack(rows)


def _corner(xy: np.ndarray, source: np.ndarray, left: int, right: int) -> np.ndarray | None:
    """Where the line of the edge run ending at ``left`` meets that of the run starting at ``right`` (their
    last / first LINE_VERTICES vertices), when it lies ahead of the one and behind the other within
    GAP_VERTICES mm; else None."""
    a, b = xy[left], xy[right]
    da, db = a - xy[_run_end(source, left, -1)], xy[_run_end(source, right, +1)] - b  # into / out of the corner
    A = np.stack([da, -db], axis=1)
    if abs(np.linalg.det(A)) <= 1e-3 * np.linalg.norm(da) * np.linalg.norm(db):
        return None
    sa, sb = np.linalg.solve(A, b - a)
    if 0 <= sa * np.linalg.norm(da) <= GAP_VERTICES and 0 <= -sb * np.linalg.norm(db) <= GAP_VERTICES:
        return a + sa * da
    return None


def _meeting_rows(surface, others, nb: np.ndarray, rays: _Rays, ray_of: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Per row, a ray (``ray_of``: into ``rays``) and the neighbour ``nb`` (sorted; into ``others``) with its level
    ``f`` (m, K) along the ray: the
    distance t (mm) along the ray where it meets that neighbour, the crossing nearest to the vertex where the
    surfaces cross, the touching point where they meet tangentially; inf if none. The crossings and touching
    points are few (a ray crosses a surface once or twice in K samples): each is taken where it is, (row, column);
    what depends on the neighbour is asked neighbour by neighbour (``_per_neighbour``), the rest all at once."""
    m, t = len(f), rays.t
    best = np.full(m, np.inf)
    # crossings: sign changes between samples, interpolated
    r, c = np.nonzero((f[:, :-1] * f[:, 1:] <= 0) & (f[:, :-1] != f[:, 1:]))
    f0, f1 = f[r, c], f[r, c + 1]
    tc = t[c] + f0 / (f0 - f1) * (t[c + 1] - t[c])
    inside = tc < -INWARD_MM  # a crossing inside the material is another part of the neighbour's surface
    crossings = (r[~inside], c[~inside], tc[~inside], None)
    # touching: an extremum of f within TANGENT_GAP_MM of zero (parabola through three samples)
    r, c = np.nonzero(np.abs(f[:, 1:-1]) < TANGENT_GAP_MM)
    d0, d1 = f[r, c + 1] - f[r, c], f[r, c + 2] - f[r, c + 1]
    curv = d1 - d0  # a touching point is a true extremum: curved at least as a cylinder of TANGENT_RADIUS_MM
    ext = (d0 * d1 < 0) & (np.abs(curv) > (t[1] - t[0]) ** 2 / TANGENT_RADIUS_MM)
    r, c, d0, d1, curv = r[ext], c[ext], d0[ext], d1[ext], curv[ext]
    shift = -0.5 * (d0 + d1) / np.where(curv != 0, curv, 1.0)
    touches = (r, c, t[1:-1][c] + np.clip(shift, -1, 1) * (t[1] - t[0]), curv)
    # which of the two applies depends on the angle between the surfaces there
    cos_tangent = math.cos(math.radians(TANGENT_DEG))
    for (r, c, tk, curv), touching in ((crossings, False), (touches, True)):
        if not len(r):
            continue
        order = np.lexsort((c, np.abs(tk), r))   # per ray, the nearest to the vertex (the first of equals)
        first = order[np.r_[True, r[order][1:] != r[order][:-1]]]
        rows, cand = r[first], tk[first]
        ray = ray_of[rows]
        X = _ray_at(rays.X, t, cand, ray)
        uv = rays.uv[ray, np.clip(np.searchsorted(t, cand), 0, len(t) - 1)]
        group = nb[rows]
        nA = _per_neighbour(group, lambda j, uv: surface.normal_at(uv[:, 0], uv[:, 1]), uv)
        nB = _per_neighbour(group, lambda j, X: level_normal(others[j][0], X), X)
        cos = np.abs(np.einsum("ij,ij->i", nA, nB))
        keep = (cos > cos_tangent) == touching
        # the ray must meet the edge head on, not run along it past a corner
        i = np.clip(np.searchsorted(t, cand), 1, len(t) - 1)
        along = rays.X[ray, i] - rays.X[ray, i - 1]
        along /= np.maximum(_norm(along), 1e-12)[:, None]
        if not touching:  # the edge's normal in the face: the neighbour's normal, less the face's
            across = nB - np.einsum("ij,ij->i", nB, nA)[:, None] * nA
            head_on = np.abs(np.einsum("ij,ij->i", along, across)) >= math.cos(math.radians(HEAD_ON_DEG)) * \
                _norm(across)
        else:  # a seam: the neighbour's distance curves across it, not along it
            h = 1.0
            side = np.cross(nA, along)
            f_side = _per_neighbour(group, lambda j, X, s: _side_curvature(surface, others[j][0], X, s, h), X, side)
            f_ray = np.abs(curv[first]) / (t[1] - t[0]) ** 2
            head_on = np.abs(f_side) <= math.tan(math.radians(HEAD_ON_DEG)) ** 2 * f_ray
        keep &= head_on
        take = keep & (np.abs(cand) < np.abs(best[rows]))
        best[rows[take]] = cand[take]
    return best


def _side_curvature(surface, other, X: np.ndarray, side: np.ndarray, h: float) -> np.ndarray:
    """The second difference (per mm^2) of the neighbour's level across the rays, over +-h mm of the surface."""
    return (level(other, _projected(surface, X + h * side)) + level(other, _projected(surface, X - h * side))
            - 2 * level(other, X)) / h ** 2


def _per_neighbour(nb: np.ndarray, fn, *arrays: np.ndarray) -> np.ndarray:
    """``fn(j, *rows)`` for each neighbour j's run of rows (``nb`` sorted), stacked: the products a neighbour (or
    the face) takes are made on the same rows as when each neighbour is taken in turn (a matrix product of one
    row rounds differently from one of many)."""
    cut = np.flatnonzero(np.diff(nb)) + 1
    bounds = zip(np.r_[0, cut], np.r_[cut, len(nb)])
    return np.concatenate([fn(int(nb[lo]), *(a[lo:hi] for a in arrays)) for lo, hi in bounds])


def _ray_at(ray: np.ndarray, t: np.ndarray, tk: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Points of the rays ``rows`` at distances tk, interpolated between the samples."""
    pos = np.clip((tk - t[0]) / (t[1] - t[0]), 0, len(t) - 1 - 1e-9)
    i = np.floor(pos).astype(int)
    w = (pos - i)[:, None]
    return (1 - w) * ray[rows, i] + w * ray[rows, np.minimum(i + 1, len(t) - 1)]


def _resampled(closed_xy: np.ndarray, step_mm: float) -> np.ndarray:
    """The closed polygon with vertices at most ``step_mm`` apart (its own vertices kept)."""
    closed = np.vstack([closed_xy, closed_xy[:1]])
    seg = np.diff(closed, axis=0)
    n = np.maximum(np.ceil(_norm(seg) / step_mm).astype(int), 1)
    frac = np.concatenate([np.arange(k) / k for k in n])
    return np.repeat(closed[:-1], n, axis=0) + frac[:, None] * np.repeat(seg, n, axis=0)
