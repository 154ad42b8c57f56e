"""Contour pass: work runs along a face's boundary, a set distance inside it.

Straight rows leave slivers where the boundary runs oblique to them (the curved rim
of a ring, a scan's weaving edge, a strip a little wider than whole steps): the
last point of a row ends where the row meets the edge, and the material between
two such ends is farther than the coverage radius from both. A contour, the
boundary offset into the material by ``offset_mm``, passes along every edge and
covers that band, as a CAM system's finishing contour does after its raster.

The offset is taken in the surface's metric chart ``(kx u, ky v)`` (mm; exact on a
plane and a cylinder, the largest scales on a sphere patch, as the rows' chart) by
shapely's buffer (GEOS): the outer polygon shrinks and holes grow, but never by
more than half the radius of the largest circle inside the face, so a strip about a
step wide gets two runs beside its middle rather than slivers of nothing. On a face all round its axis (a cylinder or
sphere whose outline spans the full turn of u) the outline is repeated one turn
either side before the offset, so the cut at u = +-pi gets no contour.
Each offset ring is split where it turns by more than ``CORNER_DEG`` (the tool lifts
off at a corner rather than stop on it); a ring with no corner is one closed run.
A scan's outline weaves at its boundary cells (1 mm steps turning 40-70 deg at one
vertex): offset as it is, a smooth rim came out as dozens of "corners" and as many
runs a few mm long, each with its leads and a self-motion between them. Such an
outline takes ``round_corners_mm``: the offset ring's convex corners are rounded to
that radius (an erosion by offset + radius, then a dilation by the radius: a
morphological opening, GEOS's own buffers), so the weave leaves no corner and a rim
is one run, while a real corner of the part is worked round at that radius.
Runs keep the material on their left and start at their first corner (a closed
ring: its vertex lowest in y, then x), and rings are worked nearest first.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
import shapely.affinity
import shapely.geometry.polygon
from shapely.geometry import LineString, MultiLineString, Polygon, box

from .toolpath import ZONE_CODE

CORNER_DEG = 40.0      # a ring is split where its direction turns by more than this at one vertex
SIMPLIFY_MM = 0.1      # the offset rings are simplified to this tolerance first (a scan's outline weaves)
SAMPLE_MM = 0.5        # runs are sampled this finely for arc length and tangents
SHORTEST_MM = 1.0      # a piece shorter than this is no run
FULL_TURN_RAD = 2 * math.pi - 0.1  # an outline spanning this much of u goes all round the axis


@dataclass(frozen=True)
class ContourRun:
    """One contour run in the flat chart (x = kx u, y = ky v, mm): its points in travel order, closed or not."""

    xy_mm: np.ndarray   # (K, 2) vertices, material on the left; a closed run does not repeat its first vertex
    closed: bool

    @property
    def length_mm(self) -> float:
        xy = np.vstack([self.xy_mm, self.xy_mm[:1]]) if self.closed else self.xy_mm
        return float(np.linalg.norm(np.diff(xy, axis=0), axis=1).sum())


def contour_runs(boundary, kx: float, ky: float, offset_mm: float, periodic: bool = False,
                 start_xy_mm=None, round_corners_mm: float = 0.0) -> list[ContourRun]:
    """The contour runs of ``boundary`` (a ``surface.Boundary`` in u, v) ``offset_mm`` inside it, in work order.

    ``kx``, ``ky``: mm per unit of u and v (the chart's scales); ``periodic``: u is an
    angle and the outline spans the full turn (``spans_full_turn``); ``start_xy_mm``:
    the chart point the first run should start nearest (the rows' end); ``round_corners_mm``: the radius the
    offset ring's convex corners are rounded to (0: kept sharp; a scan's weaving outline, module doc)."""
    region = _region(boundary, kx, ky)
    if region.is_empty:
        return []
    period = 2 * math.pi * kx
    if periodic:
        region = shapely.union_all([shapely.affinity.translate(region, xoff=k * period) for k in (-1, 0, 1)])
    # never nearer the middle than half the widest inscribed circle: a strip about a step wide gets two runs
    # beside its middle, not the slivers of a region shrunk to nothing
    inscribed = float(shapely.maximum_inscribed_circle(region, 0.05).length)
    offset = min(offset_mm, 0.5 * inscribed)
    rounding = min(round_corners_mm, max(0.5 * inscribed - offset, 0.0))
    inner = region.buffer(-(offset + rounding), join_style="round", quad_segs=16)
    if rounding > 0.0:
        inner = inner.buffer(rounding, join_style="round", quad_segs=16)
    window = None
    if periodic:
        u_lo, u_hi = _u_range(boundary)
        mid = 0.5 * (u_lo + u_hi) * kx
        window = box(mid - period / 2, -1e9, mid + period / 2, 1e9)
    pieces = []
    for ring in _rings(inner):  # counter-clockwise outside, clockwise round a hole: the material on the left
        if window is not None and not window.contains(ring):
            for line in _lines_of(ring.intersection(window)):
                xy = np.asarray(line.simplify(SIMPLIFY_MM).coords, float)
                if len(xy) >= 2:
                    pieces.extend(_split_at_corners(_material_on_left(xy, inner), False))
            continue
        xy = np.asarray(ring.simplify(SIMPLIFY_MM).coords, float)[:-1]
        if len(xy) >= 3:
            pieces.extend(_split_at_corners(xy, True))
    runs = [p for p in pieces if p.length_mm >= SHORTEST_MM]
    return _nearest_first(runs, None if start_xy_mm is None else np.asarray(start_xy_mm, float))


def spans_full_turn(surface) -> bool:
    """Whether u is an angle (cylinder, sphere) and the outline spans the full turn."""
    if surface.model not in ("cylinder", "sphere"):
        return False
    u_lo, u_hi = _u_range(surface.boundary)
    return u_hi - u_lo >= FULL_TURN_RAD


def sampled(run: ContourRun, step_mm: float = SAMPLE_MM) -> np.ndarray:
    """(M, 2) points along the run at most ``step_mm`` apart, both ends included (a closed run returns to its start)."""
    xy = np.vstack([run.xy_mm, run.xy_mm[:1]]) if run.closed else run.xy_mm
    seg = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    n = np.maximum(1, np.ceil(seg / step_mm).astype(int))
    f = [np.arange(k) / k for k in n]
    out = [xy[i] + np.outer(f[i], xy[i + 1] - xy[i]) for i in range(len(seg))]
    return np.vstack([*out, xy[-1:]])


# ----------------------------------------------------------------------------- helpers


def _region(boundary, kx: float, ky: float):
    """The material region as a (valid) shapely geometry in the flat chart."""
    scale = np.array([kx, ky])
    outer = np.asarray(boundary.outer_uv, float) * scale
    holes = [np.asarray(h, float) * scale for h in boundary.holes_uv]
    poly = Polygon(outer, [h for h in holes if len(h) >= 3])
    return poly if poly.is_valid else shapely.make_valid(poly).buffer(0)


def _u_range(boundary) -> tuple[float, float]:
    u = np.asarray(boundary.outer_uv, float)[:, 0]
    return float(u.min()), float(u.max())


def _lines_of(geom) -> list[LineString]:
    if geom.is_empty:
        return []
    if isinstance(geom, LineString):
        return [geom]
    if isinstance(geom, MultiLineString):
        return list(geom.geoms)
    return [g for g in getattr(geom, "geoms", []) if isinstance(g, LineString)]


def _rings(geom) -> list[LineString]:
    """Every ring of the (multi)polygon, oriented: exteriors counter-clockwise, holes clockwise."""
    out = []
    for g in getattr(geom, "geoms", [geom]):
        if isinstance(g, Polygon) and not g.is_empty:
            g = shapely.geometry.polygon.orient(g, 1.0)
            out.extend([LineString(g.exterior.coords), *(LineString(r.coords) for r in g.interiors)])
    return out


def _material_on_left(xy: np.ndarray, inner) -> np.ndarray:
    """An open piece's vertices, reversed where the region lies to the right of the travel."""
    i = (len(xy) - 1) // 2
    a, b = xy[i], xy[i + 1]
    d = b - a
    n = np.array([-d[1], d[0]]) / max(float(np.hypot(*d)), 1e-12)
    return xy if inner.contains(shapely.Point(*(0.5 * (a + b) + 0.05 * n))) else xy[::-1].copy()


def _turning_deg(xy: np.ndarray, closed: bool) -> np.ndarray:
    """Turn of direction (deg, 0..180) at every vertex; 0 at an open run's ends."""
    prev = xy - np.roll(xy, 1, axis=0)
    nxt = np.roll(xy, -1, axis=0) - xy
    a = np.arctan2(prev[:, 1], prev[:, 0])
    b = np.arctan2(nxt[:, 1], nxt[:, 0])
    turn = np.degrees(np.abs((b - a + np.pi) % (2 * np.pi) - np.pi))
    if not closed:
        turn[0] = turn[-1] = 0.0
    return turn


def _split_at_corners(xy: np.ndarray, closed: bool) -> list[ContourRun]:
    corners = np.flatnonzero(_turning_deg(xy, closed) > CORNER_DEG)
    if closed:
        if len(corners) == 0:
            start = int(np.lexsort((xy[:, 0], xy[:, 1]))[0])
            return [ContourRun(np.roll(xy, -start, axis=0), True)]
        xy = np.vstack([np.roll(xy, -corners[0], axis=0), xy[corners[0]:corners[0] + 1]])
        corners = np.append(corners - corners[0], len(xy) - 1)
    else:
        corners = np.unique(np.concatenate([[0], corners, [len(xy) - 1]]))
    return [ContourRun(xy[a:b + 1].copy(), False) for a, b in zip(corners[:-1], corners[1:])]


def _nearest_first(runs: list[ContourRun], start_xy) -> list[ContourRun]:
    """Runs ordered greedily: each next run is the one starting nearest the end of the one before
    (the first: nearest ``start_xy``, else the first found)."""
    left = list(range(len(runs)))
    order: list[int] = []
    end = start_xy
    while left:
        pick = 0 if end is None else int(np.argmin([float(np.hypot(*(runs[i].xy_mm[0] - end))) for i in left]))
        order.append(left.pop(pick))
        last = runs[order[-1]]
        end = last.xy_mm[0 if last.closed else -1]
    return [runs[i] for i in order]


# ----------------------------------------------------------------------------- poses along the runs


@dataclass(frozen=True)
class ContourBlocks:
    """The contour runs as raster blocks [lead-in | work | lead-out], pose by pose in path order."""

    uv: np.ndarray        # (N, 2) surface parameters of the poses on (or, in a lead, beside) the surface
    duv: np.ndarray       # (N, 2) a 1 um step of (u, v) along the travel, for the travel direction
    zone: np.ndarray      # (N,) zone codes: lead_in, work, lead_out
    point: np.ndarray     # (N,) 1-based work point of its run, 0 in a lead
    away: np.ndarray      # (N,) share of the lead from the work end (0) to its far end (1)
    block: np.ndarray     # (runs,) poses per run

    @property
    def segment(self) -> np.ndarray:
        """(N,) each pose's 0-based run."""
        return np.repeat(np.arange(len(self.block)), self.block)


def contour_blocks(surface, kx: float, ky: float, runs: list[ContourRun], pitch_mm: float, lead_mm: float,
                   n_lead: int) -> ContourBlocks:
    """Work points ``pitch_mm`` apart in surface arc length along every run, and ``n_lead`` lead poses
    at each end continuing along the run's end tangent (flat chart) over ``lead_mm``.

    An open run's points are centred between its ends (each end within about half a
    pitch of a point, as a row's); a closed run's are spread evenly round it."""
    scale = np.array([kx, ky])
    lead_step = lead_mm / n_lead if n_lead else 0.0
    parts = []
    for run in runs:
        dense = sampled(run)
        uv_d = dense / scale
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(surface.point_mm(uv_d[:, 0], uv_d[:, 1]),
                                                                           axis=0), axis=1))])
        length = float(arc[-1])
        if run.closed:
            n = max(int(math.ceil(length / pitch_mm - 0.01)), 3)
            at = length / n * np.arange(n)
        else:
            n_int = max(int(math.ceil(length / pitch_mm - 0.01)) - 1, 0)
            at = (length - n_int * pitch_mm) / 2 + pitch_mm * np.arange(n_int + 1)
        xy = np.stack([np.interp(at, arc, dense[:, 0]), np.interp(at, arc, dense[:, 1])], axis=-1)
        i = np.clip(np.searchsorted(arc, at, side="right") - 1, 0, len(dense) - 2)
        tangent = _unit2(dense[i + 1] - dense[i])
        back = -lead_step * np.arange(n_lead, 0, -1)[:, None]
        ahead = lead_step * np.arange(1, n_lead + 1)[:, None]
        xy_all = np.vstack([xy[0] + back * tangent[0], xy, xy[-1] + ahead * tangent[-1]])
        tan_all = np.vstack([np.repeat(tangent[:1], n_lead, 0), tangent, np.repeat(tangent[-1:], n_lead, 0)])
        c = len(at)
        zone = np.concatenate([np.full(n_lead, ZONE_CODE["lead_in"]), np.full(c, ZONE_CODE["work"]),
                               np.full(n_lead, ZONE_CODE["lead_out"])]).astype(np.int32)
        point = np.concatenate([np.zeros(n_lead), np.arange(1, c + 1), np.zeros(n_lead)]).astype(np.int32)
        away = (np.concatenate([np.arange(n_lead, 0, -1), np.zeros(c), np.arange(1, n_lead + 1)]) / n_lead
                if n_lead else np.zeros(c))
        parts.append((xy_all / scale, 1e-3 * tan_all / scale, zone, point, away))
    cols = list(zip(*parts))
    return ContourBlocks(uv=np.concatenate(cols[0]), duv=np.concatenate(cols[1]), zone=np.concatenate(cols[2]),
                         point=np.concatenate(cols[3]), away=np.concatenate(cols[4]),
                         block=np.array([len(z) for z in cols[2]], np.int64))


def _unit2(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)
