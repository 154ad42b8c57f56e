"""Raster stage: a Surface becomes a Path of tool poses in S (boustrophedon) order.

Rows are straight lines in a **metric chart** of the (u, v) domain,
``x = kx * u``, ``y = ky * v`` (mm), rotated by ``angle_deg`` from the u axis.
``kx``, ``ky`` are the largest mm-per-unit scales (``metric_scale``) over the
domain: 1 and 1 on a plane; ``R cos v_ref`` and ``R`` on a sphere patch, with
``v_ref`` the elevation of the patch nearest the equator. Rows are ``step_over_mm``
apart in this chart, so on a sphere rows of constant elevation (angle 0) are
exactly ``step_over_mm`` apart along the surface (geodesic), and at any other
angle the spacing on the surface is never larger than ``step_over_mm``. On a
cylinder the chart ``(R u, v)`` is an isometry: rows are geodesics (circles
round the axis at angle 0, lines along it with ``cylinder_rows = "along"``,
helices between) and exactly ``step_over_mm`` apart on the surface
(noether issue #178 asks for rows around a cylinder).
Rows are centred across the domain (each outer edge is at most half a
step-over from the nearest row).

Each row is cut into runs of material by its exact crossings with the boundary
polygons (outer contour and holes); ``Boundary.contains`` at the middle of each
piece decides which pieces are material. Each run is one **segment**; along it,
points are exactly ``pitch_mm`` apart in arc length on the surface (the arc
length is integrated with ``metric_scale``) and centred strictly inside the run,
so each run end is at most about half a pitch from the nearest point and no
work point sits on a boundary edge.

Where the rows alone cover less than ``CONTOUR_BELOW`` of the face (``raster.contour =
"auto"``; "on" always, "off" never), a contour pass follows: runs along every edge
of the face, half a step inside it, after the rows (``camtool.path.contour``), each a
segment with leads like a row's, their poses marked in ``Path.contour``.

Around every segment: ``lead_in`` / ``lead_out`` poses continue along the row
beyond the segment ends by ``lead_mm`` (the lift along the normal rises from 0
to ``clearance_mm`` as the cube of the distance from the work, tangent to the
surface at the work end); between segments, ``transition_points`` ``self_motion``
poses (positions interpolated in (u, v) and lifted, orientation by slerp); an
``approach`` zone before the first pose and a ``depart`` zone after the last one
back off along the normal by ``max(clearance_mm, APPROACH_MIN_MM)``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from .contour import contour_blocks, contour_runs, spans_full_turn
from ..errors import BadInput
from .face_set import raster_faces
from ..settings import RasterSettings
from ..part.surface import FaceSet
from .toolpath import ZONE_CODE, ZONES, Path

APPROACH_POINTS = 3  # poses in the approach and in the depart zone
APPROACH_MIN_MM = 10.0  # smallest back-off of approach / depart along the normal
COVERAGE_TOL_FRACTION = 0.02  # coverage radius tolerance, as a fraction of the step-over
MAX_POSES = 5_000_000  # refuse rasters larger than this (memory)
STEEP_SCALE = 10.0  # a free-form face's rows stretched this many times over its chart (a slope past 84 deg): upright

_LEAD_IN, _LEAD_OUT, _WORK = ZONE_CODE["lead_in"], ZONE_CODE["lead_out"], ZONE_CODE["work"]
_SELF, _APPROACH, _DEPART = ZONE_CODE["self_motion"], ZONE_CODE["approach"], ZONE_CODE["depart"]


# ----------------------------------------------------------------------------- chart


@dataclass(frozen=True)
class _Chart:
    """Metric chart (x, y) = (kx u, ky v) mm, rotated by angle: s along rows, t across."""

    kx: float
    ky: float
    angle_rad: float

    def st_from_uv(self, uv: np.ndarray) -> np.ndarray:
        c, s = math.cos(self.angle_rad), math.sin(self.angle_rad)
        x, y = uv[..., 0] * self.kx, uv[..., 1] * self.ky
        return np.stack([x * c + y * s, -x * s + y * c], axis=-1)

    def uv_from_st(self, s_mm, t_mm) -> np.ndarray:
        c, sn = math.cos(self.angle_rad), math.sin(self.angle_rad)
        s_mm, t_mm = np.broadcast_arrays(np.asarray(s_mm, float), np.asarray(t_mm, float))
        x, y = s_mm * c - t_mm * sn, s_mm * sn + t_mm * c
        return np.stack([x / self.kx, y / self.ky], axis=-1)

    @property
    def duv_ds(self) -> np.ndarray:
        """Change of (u, v) per mm of chart s (the row direction)."""
        return np.array([math.cos(self.angle_rad) / self.kx, math.sin(self.angle_rad) / self.ky])


def _domain_grid(boundary, n: int = 33) -> np.ndarray:
    """(n*n, 2) samples of the boundary's (u, v) bounding box, plus v = 0 when inside."""
    lo, hi = boundary.bounds()
    us = np.linspace(lo[0], hi[0], n)
    vs = np.linspace(lo[1], hi[1], n)
    if lo[1] < 0 < hi[1]:
        vs = np.append(vs, 0.0)
    U, V = np.meshgrid(us, vs)
    return np.stack([U.ravel(), V.ravel()], axis=-1)


def _chart_for(surface, angle_rad: float) -> tuple[_Chart, float, float]:
    """The metric chart of the surface, the smallest arc-length rate g along rows and the largest rate over the
    face itself (``_face_rate``: the raster's estimate)."""
    uv = _domain_grid(surface.boundary)
    scale = surface.metric_scale(uv)
    kx, ky = float(scale[:, 0].max()), float(scale[:, 1].max())
    if not (kx > 0 and ky > 0):
        raise BadInput("surface: degenerate (u, v) parameterisation (zero metric scale)")
    g_lo = float(np.minimum(scale[:, 0] / kx, scale[:, 1] / ky).min())
    chart = _Chart(kx, ky, angle_rad)
    return chart, max(g_lo, 0.05), _face_rate(surface.boundary, chart, uv, scale)


def _face_rate(boundary, chart: _Chart, uv: np.ndarray, scale: np.ndarray) -> float:
    """The largest arc length on the surface per mm of chart s (along the rows, <= 1) at the samples inside the
    face (all of them where none is). The chart's own scale is the largest over the domain's bounding box, whose
    corners past a free-form face's edge are the height field's continuation: there the geodesic rows may run
    almost across the chart's x (a 78 x stretch at a corner of the folded sheet's box, 2.6 x within the face, its
    rows turned 45 deg on it by the placement), and an estimate from it refused a raster of 7 500 poses for
    "1.49e6" (issue #46)."""
    inside = np.asarray(boundary.contains(uv), bool)
    s = np.asarray(scale, float)[inside] if inside.any() else np.asarray(scale, float)
    rate = np.hypot(s[:, 0] * chart.duv_ds[0], s[:, 1] * chart.duv_ds[1])
    return float(min(rate.max(), 1.0))


# ----------------------------------------------------------------------------- rows and runs


def _polygon_edges_st(boundary, chart: _Chart) -> tuple[np.ndarray, np.ndarray]:
    """Start and end points (E x 2 each, chart s, t) of every boundary edge."""
    a, b = [], []
    for poly in (boundary.outer_uv, *boundary.holes_uv):
        st = chart.st_from_uv(np.asarray(poly, float))
        a.append(st)
        b.append(np.roll(st, -1, axis=0))
    return np.concatenate(a), np.concatenate(b)


ROW_SLACK = 0.01  # a domain up to this share of a step-over wider than whole steps gets no extra row


def _row_offsets(t_lo: float, t_hi: float, step_mm: float, edge_margin: float = 0.0) -> np.ndarray:
    """Row positions t (mm) across the domain, step_mm apart and centred.

    A width a hair over whole steps (a face's exact boundary, 300.01 mm at 10 mm) takes
    the rows of whole steps, each edge half a step (plus ROW_SLACK of one) from a row:
    one more row would put the first and last rows on the edges themselves. Where the
    centred rows would still come nearer an edge than ``edge_margin`` of a step (a scan's
    face a little over whole steps, its outline weaving by a point spacing), they are
    drawn closer together (never farther apart) to keep that margin: a row along a
    weaving edge finds little material, and the strip beside it goes unworked."""
    width = t_hi - t_lo
    n = max(1, math.ceil(width / step_mm - ROW_SLACK))
    margin, least = (width - (n - 1) * step_mm) / 2, edge_margin * step_mm
    if n > 1 and margin < least:
        return t_lo + least + (width - 2 * least) / (n - 1) * np.arange(n)
    return t_lo + margin + step_mm * np.arange(n)


def _row_runs(boundary, chart: _Chart, rows_t: np.ndarray, e0: np.ndarray, e1: np.ndarray):
    """Material runs on the rows: (row index, s start, s end), chart mm, sorted by row then s."""
    t1, t2 = e0[:, 1:2], e1[:, 1:2]
    crosses = ((t1 <= rows_t) & (rows_t < t2)) | ((t2 <= rows_t) & (rows_t < t1))
    e, k = np.nonzero(crosses)
    s = e0[e, 0] + (rows_t[k] - e0[e, 1]) * (e1[e, 0] - e0[e, 0]) / (e1[e, 1] - e0[e, 1])
    order = np.lexsort((s, k))
    k, s = k[order], s[order]
    same = k[1:] == k[:-1]
    ia, ib, ik = s[:-1][same], s[1:][same], k[:-1][same]
    keep = ib - ia > 1e-9
    ia, ib, ik = ia[keep], ib[keep], ik[keep]
    if len(ia) == 0:
        return ik, ia, ib
    mid = chart.uv_from_st((ia + ib) / 2, rows_t[ik])
    material = boundary.contains(mid)
    ia, ib, ik = ia[material], ib[material], ik[material]
    if len(ia) == 0:
        return ik, ia, ib
    # merge touching material pieces of one row into one run
    new = np.ones(len(ia), bool)
    new[1:] = (ik[1:] != ik[:-1]) | (ia[1:] > ib[:-1] + 1e-9)
    first = np.flatnonzero(new)
    last = np.append(first[1:] - 1, len(ia) - 1)
    return ik[first], ia[first], ib[last]


# ----------------------------------------------------------------------------- arc length along rows


class _ArcTable:
    """Cumulative surface arc length (mm) along each used row, on a common s grid."""

    def __init__(self, surface, chart: _Chart, rows_t: np.ndarray, s_lo: float, s_hi: float, h_mm: float):
        n = int(min(max(math.ceil((s_hi - s_lo) / h_mm), 16), 4096)) + 1
        self.s = np.linspace(s_lo, s_hi, n)
        uv = chart.uv_from_st(self.s[None, :], rows_t[:, None])
        scale = surface.metric_scale(uv.reshape(-1, 2)).reshape(uv.shape)
        g = np.hypot(scale[..., 0] * chart.duv_ds[0], scale[..., 1] * chart.duv_ds[1])
        ds = np.diff(self.s)
        arc = np.zeros_like(g)
        arc[:, 1:] = np.cumsum(0.5 * (g[:, 1:] + g[:, :-1]) * ds, axis=1)
        self.arc = arc
        self.s_span = self.s[-1] - self.s[0] + 1.0
        self.arc_off = np.concatenate([[0.0], np.cumsum(arc[:, -1] + 1.0)[:-1]])
        self._s_flat = (self.s[None, :] + self.s_span * np.arange(len(rows_t))[:, None]).ravel()
        self._arc_flat = (arc + self.arc_off[:, None]).ravel()

    def arc_at(self, row: np.ndarray, s_mm: np.ndarray) -> np.ndarray:
        """Arc length (mm) from the start of the table at chart position s on each row."""
        return np.interp(s_mm + self.s_span * row, self._s_flat, self._arc_flat) - self.arc_off[row]

    def s_at(self, row: np.ndarray, arc_mm: np.ndarray) -> np.ndarray:
        """Chart position s at arc length arc_mm on each row (clamped to the table)."""
        arc_mm = np.clip(arc_mm, 0.0, self.arc[row, -1])
        return np.interp(arc_mm + self.arc_off[row], self._arc_flat, self._s_flat) - self.s_span * row


# ----------------------------------------------------------------------------- orientation


def _rotate(v: np.ndarray, axis: np.ndarray, angle_rad: float) -> np.ndarray:
    """Rodrigues rotation of vectors v (N x 3) about unit axes (N x 3) by one angle."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return v * c + np.cross(axis, v) * s + axis * np.sum(axis * v, axis=-1, keepdims=True) * (1 - c)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)


def _tool_rotations(normal: np.ndarray, travel: np.ndarray, tool_x: str, tool_x_world: np.ndarray,
                    lead_rad: float, tilt_rad: float) -> np.ndarray:
    """Tool rotations (N x 3 x 3, columns x, y, z): z = -normal, then lead and tilt.

    ``fixed``: x is ``tool_x_world`` projected onto the tangent plane. If that
    direction comes within ~5.7 deg of a normal anywhere (projection < 0.1), the
    world axis (x, y, z, first on ties) most perpendicular to all normals is used
    instead; a pose where even that vanishes takes the travel direction.
    ``travel``: x is the travel direction. Lead: right-hand rotation about the
    side axis ``travel x normal`` (tool z gains +sin(lead) along travel); tilt:
    right-hand rotation about the travel direction.
    """
    z = -normal
    if tool_x == "travel":
        x = travel
    else:
        w = tool_x_world / np.linalg.norm(tool_x_world)
        proj = w - np.sum(w * z, axis=-1, keepdims=True) * z
        norm = np.linalg.norm(proj, axis=-1)
        if norm.min() < 0.1:
            worst = np.abs(normal @ np.eye(3)).max(axis=0)
            w = np.eye(3)[int(np.argmin(worst))]
            proj = w - np.sum(w * z, axis=-1, keepdims=True) * z
            norm = np.linalg.norm(proj, axis=-1)
        x = np.where((norm > 1e-9)[:, None], proj / np.maximum(norm, 1e-300)[:, None], travel)
    y = np.cross(z, x)
    R = np.stack([x, y, z], axis=-1)
    if lead_rad or tilt_rad:
        side = np.cross(travel, normal)
        for col in range(3):
            v = R[:, :, col]
            if lead_rad:
                v = _rotate(v, side, lead_rad)
            if tilt_rad:
                v = _rotate(v, travel, tilt_rad)
            R[:, :, col] = v
    return R


# ----------------------------------------------------------------------------- checks


def _check_boundary(surface) -> None:
    """BadInput unless the surface boundary encloses some area (job keys are checked by the schema)."""
    outer = np.asarray(surface.boundary.outer_uv, dtype=float)
    if outer.ndim != 2 or outer.shape[0] < 3 or outer.shape[1] != 2 or not np.all(np.isfinite(outer)):
        raise BadInput("surface boundary is empty: the outer polygon needs at least 3 (u, v) vertices")
    x, y = outer[:, 0], outer[:, 1]
    if abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) < 1e-12:
        raise BadInput("surface boundary is empty: the outer polygon encloses no area")


def _direction(v) -> np.ndarray:
    w = np.asarray(v, dtype=float).ravel()
    if w.shape != (3,) or not np.all(np.isfinite(w)) or np.linalg.norm(w) < 1e-12:
        raise BadInput(f"raster.tool_x_world: expected a non-zero direction of 3 numbers, found {list(v)!r}")
    return w


# ----------------------------------------------------------------------------- entry


def row_angle_rad(surface, settings: RasterSettings) -> float:
    """The rows' angle from the u axis: ``angle_rad``, plus 90 deg on a cylinder whose rows run along its axis."""
    along = surface.model == "cylinder" and settings.cylinder_rows == "along"
    return settings.angle_rad + (math.pi / 2 if along else 0.0)


def raster_path(surface, settings: RasterSettings) -> Path:
    """Raster ``surface`` into a Path: boustrophedon rows of work points with zones.

    Lengths in mm (measured on the surface), angles in rad (``RasterSettings``).
    Raises ``BadInput`` for an empty boundary or a step-over wider than the
    patch. Poses are in the surface's (world) frame; tool z = -normal. A
    ``surface.FaceSet`` is rastered face by face and joined (``face_set.raster_faces``).
    """
    if isinstance(surface, FaceSet):
        return raster_faces(surface, settings, raster_path)
    if surface.model == "freeform":  # rows are level sets of the geodesic distance, turned on the face itself
        surface, settings = surface.rows_at(settings.angle_rad), replace(settings, angle_rad=0.0)
    _check_boundary(surface)
    if settings.step_over_auto:  # `camtool run` chooses it first (camtool.process.stepover.auto_step_over)
        raise BadInput('raster.step_over_mm = "auto" is chosen from the [process] footprint by `camtool run` '
                       '(docs/process.md); here give a number of mm')
    w = _direction(settings.tool_x_world)
    chart, g_lo, face_rate = _chart_for(surface, row_angle_rad(surface, settings))
    try:
        runs, sign = _rows_and_runs(surface.boundary, chart, face_rate, settings).in_raster_order()
    except _TooManyPoses as e:
        raise BadInput(f"{e}{_upright_note(surface)}") from None
    rows = _row_blocks(surface, chart, g_lo, runs, sign, settings)
    blocks = _with_contour(surface, settings, chart, rows)
    on_surface, normal, lift = _block_poses(surface, blocks, settings, w)
    straight = surface.model == "freeform" and blocks.n_lead   # leads off the surface: from where they end
    transitions = _transitions(surface, blocks, lift, on_surface.R, settings, on_surface.pos if straight else None)
    poses, segment, pidx, zcode = _in_path_order(blocks, on_surface, transitions,
                                                 _approach_and_depart(on_surface.pos, normal, settings.clearance_mm),
                                                 settings.transition_points)
    return Path(poses, segment, pidx, zcode, settings.free_spin, settings.step_over_mm, settings.pitch_mm,
                contour=None if rows.n_seg == blocks.n_seg else segment >= rows.n_seg)


class _TooManyPoses(BadInput):
    """The raster's estimate is over raster.max_poses (``raster_path`` adds where a free-form face is upright)."""


def _upright_note(surface) -> str:
    """Where a free-form face's rows are stretched past STEEP_SCALE over its chart plane (a height field across an
    upright wall: the whole of a block with a pocket as one face), with what to do instead; '' where none is. Its
    chart's largest metric scale sets the raster's estimate: the TOOLING4G mould as one face (its pocket's 45 mm
    upright walls) was refused for '1.65e+06 poses', and a coarser raster or more poses was no way out."""
    if surface.model != "freeform":   # an analytic face's u may be an angle: its scale is a radius, not a slope
        return ""
    uv = _domain_grid(surface.boundary)
    inside = np.asarray(surface.boundary.contains(uv), bool)
    uv = uv[inside] if inside.any() else uv   # the face's own stretch, not its height field's continuation (#46)
    k = np.asarray(surface.metric_scale(uv), float).max(axis=1)
    i = int(np.argmax(k))
    if not k[i] > STEEP_SCALE:
        return ""
    p = np.asarray(surface.point_mm(uv[i:i + 1, 0], uv[i:i + 1, 1]), float).reshape(-1)
    return (f"; the face stands {math.degrees(math.acos(1.0 / k[i])):.0f} deg to its chart plane near "
            f"[{p[0]:.0f}, {p[1]:.0f}, {p[2]:.0f}] mm (its rows stretched {k[i]:.0f} x there): one height field over "
            "an upright wall (a pocket, a block's side); work the part's faces instead: [faces] select = "
            "\"freeform\" or their numbers (`camtool faces JOB` lists them)")


@dataclass(frozen=True)
class _Runs:
    """Runs of material: each its row (an index into ``rows_t``, the rows' chart t) and its ends ``a``, ``b``
    (chart s, mm); ``s_lo``, ``s_hi`` the patch's extent along the rows."""

    rows_t: np.ndarray
    row: np.ndarray
    a: np.ndarray
    b: np.ndarray
    s_lo: float
    s_hi: float

    def in_raster_order(self) -> tuple[_Runs, np.ndarray]:
        """(the runs of the rows with material only, in boustrophedon order: row after row, alternating
        direction; each run's way, +1 along increasing s or -1)."""
        used, run_row = np.unique(self.row, return_inverse=True)
        sign = np.where(run_row % 2 == 0, 1.0, -1.0)
        order = np.lexsort((self.a * sign, run_row))
        return _Runs(self.rows_t[used], run_row[order], self.a[order], self.b[order], self.s_lo, self.s_hi), \
            sign[order]


@dataclass(frozen=True)
class _Blocks:
    """The on-surface samples, block after block [lead-in | work | lead-out] in path order: their (u, v), a step
    along the row (``duv``), the row's way, zone, work point number (0 off work), each lead pose's share of its
    lead from the work (None without leads) and segment; each block's first index and length."""

    uv: np.ndarray
    duv: np.ndarray
    direction: np.ndarray
    zone: np.ndarray
    point: np.ndarray
    away: np.ndarray | None
    seg: np.ndarray
    block: np.ndarray
    start: np.ndarray
    n_lead: int       # poses in each lead

    @property
    def n_seg(self) -> int:
        return len(self.block)


@dataclass(frozen=True)
class _Poses:
    """Tool poses: rotations (N, 3, 3) and positions (N, 3) mm."""

    R: np.ndarray
    pos: np.ndarray


def _rows_and_runs(boundary, chart: _Chart, face_rate: float, settings: RasterSettings) -> _Runs:
    """The rows across the patch and their runs of material; BadInput for a step-over or pitch larger than the
    patch, a raster of too many poses or no material. ``face_rate``: the rows' largest arc length per mm of chart s
    on the face (``_face_rate``)."""
    step, pitch, lead = settings.step_over_mm, settings.pitch_mm, settings.lead_mm
    m = settings.transition_points
    e0, e1 = _polygon_edges_st(boundary, chart)
    t_lo, t_hi = float(e0[:, 1].min()), float(e0[:, 1].max())
    if step > t_hi - t_lo:
        raise BadInput(f"raster.step_over_mm: {step:g} mm is larger than the patch "
                       f"({t_hi - t_lo:.1f} mm across the rows)")
    rows_t = _row_offsets(t_lo, t_hi, step, settings.edge_margin)
    s_lo, s_hi = float(e0[:, 0].min()), float(e0[:, 0].max())
    if pitch > s_hi - s_lo:  # chart s is mm at the largest metric scale: an upper bound of any row's length
        raise BadInput(f"raster.pitch_mm: {pitch:g} mm is longer than the part ({s_hi - s_lo:.1f} mm along the "
                       "rows); use a pitch of a few mm")
    # a row's work is at most its extent along s at the face's largest arc-length rate (measured on the face, not
    # on its bounding box: the estimate must not depend on how the placement turns the face's rows, issue #46)
    estimate = len(rows_t) * ((s_hi - s_lo) * face_rate / pitch + 2 * (lead / pitch + 1) + m)
    cap = min(int(getattr(settings, "max_poses", MAX_POSES)), MAX_POSES)  # time, then memory: before any work
    if estimate > cap:
        raise _TooManyPoses(f"raster: step_over_mm={step:g} and pitch_mm={pitch:g} would give about {estimate:.3g} poses, "
                       f"over raster.max_poses = {cap}; use a coarser raster (raster.pitch_mm, raster.step_over_mm) "
                       "or raise raster.max_poses")
    run_row, run_a, run_b = _row_runs(boundary, chart, rows_t, e0, e1)
    if len(run_row) == 0:
        raise BadInput("surface boundary is empty: no material inside the boundary polygons")
    return _Runs(rows_t, run_row, run_a, run_b, s_lo, s_hi)


def _work_points(table: _ArcTable, runs: _Runs, pitch: float) -> tuple[np.ndarray, np.ndarray]:
    """(arc length of each run's first work point, work points per run): ``pitch`` apart, centred strictly
    inside the run."""
    arc_a = table.arc_at(runs.row, runs.a)
    length = table.arc_at(runs.row, runs.b) - arc_a
    # points strictly inside the run: end margins between 0.005 and 0.505 pitch
    n_int = np.maximum(np.ceil(length / pitch - 0.01).astype(np.int64) - 1, 0)
    count = n_int + 1  # work points per segment, c_i
    return arc_a + (length - n_int * pitch) / 2, count


def _row_blocks(surface, chart: _Chart, g_lo: float, runs: _Runs, sign: np.ndarray,
                settings: RasterSettings) -> _Blocks:
    """The rows' blocks [lead-in | work | lead-out], one per run in path order, each built in forward
    (increasing s) order and walked the run's way."""
    step, pitch, lead = settings.step_over_mm, settings.pitch_mm, settings.lead_mm
    # an arc-length table with room for the leads
    ext = 1.1 * (lead + 2 * pitch) / g_lo
    table = _ArcTable(surface, chart, runs.rows_t, runs.s_lo - ext, runs.s_hi + ext, min(pitch, step) / 2)
    first_arc, count = _work_points(table, runs, pitch)
    n_lead = 0 if lead == 0 else max(1, int(round(lead / pitch)))
    lead_step = lead / n_lead if n_lead else 0.0
    block = count + 2 * n_lead
    seg = np.repeat(np.arange(len(count)), block)
    start = np.concatenate([[0], np.cumsum(block)[:-1]])
    pos = np.arange(len(seg)) - start[seg]  # position in path order within the block
    fwd = np.where(sign[seg] > 0, pos, block[seg] - 1 - pos)  # position in forward order
    c_s = count[seg]
    last_arc = first_arc + (count - 1) * pitch
    arc = np.where(fwd < n_lead, first_arc[seg] - (n_lead - fwd) * lead_step,
                   np.where(fwd < n_lead + c_s, first_arc[seg] + (fwd - n_lead) * pitch,
                            last_arc[seg] + (fwd - n_lead - c_s + 1) * lead_step))
    row = runs.row[seg]
    uv = chart.uv_from_st(table.s_at(row, arc), runs.rows_t[row])
    zone, point, away = _block_zones(pos, c_s, n_lead)
    duv = np.broadcast_to(1e-3 * chart.duv_ds, uv.shape)  # 1 um along the row: a forward difference is exact
    direction = sign[seg]                                  # to ~1e-6 rad; then the row's way
    return _Blocks(uv, duv, direction, zone, point, away, seg, block, start, n_lead)


def _block_zones(pos: np.ndarray, c_s: np.ndarray, n_lead: int):
    """(zone, work point number, share of the lead from the work or None without leads) of each pose of
    the blocks, from its position in its block and its block's work points."""
    zone = np.where(pos < n_lead, _LEAD_IN, np.where(pos < n_lead + c_s, _WORK, _LEAD_OUT)).astype(np.int32)
    point = np.where(zone == _WORK, pos - n_lead + 1, 0).astype(np.int32)
    # share of the lead from the work end (0) to the lead's far end (1); the lift rises as its cube, so
    # the tool path leaves the surface with no kink and no jump in curvature: a linear ramp's kink at
    # the first and last work pose needs more than a wrist's jerk limit at the feed (the whole row slows)
    away = np.where(zone == _LEAD_IN, (n_lead - pos) / n_lead,
                    np.where(zone == _LEAD_OUT, (pos - n_lead - c_s + 1) / n_lead, 0.0)) if n_lead else None
    return zone, point, away


def _with_contour(surface, settings: RasterSettings, chart: _Chart, rows: _Blocks) -> _Blocks:
    """The rows' blocks followed by the contour pass's, when the face wants one (``_wants_contour``)."""
    if not _wants_contour(surface, settings, rows.uv[rows.zone == _WORK]):
        return rows
    runs = contour_runs(surface.boundary, chart.kx, chart.ky,
                        contour_offset_mm(settings.step_over_mm, settings.pitch_mm),
                        periodic=spans_full_turn(surface), start_xy_mm=rows.uv[-1] * (chart.kx, chart.ky),
                        round_corners_mm=SCAN_CONTOUR_ROUND_MM if surface.scanned else 0.0)
    if not runs:
        return rows
    c = contour_blocks(surface, chart.kx, chart.ky, runs, settings.pitch_mm, settings.lead_mm, rows.n_lead)
    block = np.concatenate([rows.block, c.block])
    return _Blocks(uv=np.concatenate([rows.uv, c.uv]), duv=np.concatenate([rows.duv, c.duv]),
                   direction=np.concatenate([rows.direction, np.ones(len(c.uv))]),
                   zone=np.concatenate([rows.zone, c.zone]), point=np.concatenate([rows.point, c.point]),
                   away=np.concatenate([rows.away, c.away]) if rows.n_lead else rows.away,
                   seg=np.concatenate([rows.seg, rows.n_seg + c.segment]), block=block,
                   start=np.concatenate([[0], np.cumsum(block)[:-1]]), n_lead=rows.n_lead)


def _block_poses(surface, blocks: _Blocks, settings: RasterSettings, tool_x_world: np.ndarray):
    """(the blocks' tool poses, the surface normal at each, its lift along the normal): geometry and
    orientation of the on-surface samples, the leads lifted."""
    b = blocks
    lift = np.zeros(len(b.seg)) if b.away is None else settings.clearance_mm * b.away ** 3
    band = float(surface.lead_band_mm)
    if band > 0 and b.away is not None:
        lift = lift + band * _band_ramp(b.away)
    p = surface.point_mm(b.uv[:, 0], b.uv[:, 1])
    normal = _unit(surface.normal_at(b.uv[:, 0], b.uv[:, 1]))
    travel = surface.point_mm(b.uv[:, 0] + b.duv[:, 0], b.uv[:, 1] + b.duv[:, 1]) - p
    travel = travel - np.sum(travel * normal, axis=1, keepdims=True) * normal
    if surface.model == "freeform":   # a CAD mesh face's work on its own triangles
        work = b.zone == _WORK
        p[work] = surface.onto_face_mm(p[work])
    travel = _unit(travel) * b.direction[:, None]
    R = _tool_rotations(normal, travel, settings.tool_x, tool_x_world, settings.lead_rad, settings.tilt_rad)
    if surface.model == "freeform" and b.n_lead:
        p, normal, R = _straight_leads(p, normal, travel, R, b, settings.lead_mm)
    elif settings.lead_path == "tangent" and b.n_lead:
        lift = np.maximum(lift, _tangent_clearing_lift(p, normal, b.zone, b.start, b.block, b.away))
    return _Poses(R, p + lift[:, None] * normal), normal, lift


BAND_RAMP_SHARE = 0.75   # a scan's leads are lifted by its whole noise band this share of the lead from the work


def _band_ramp(away: np.ndarray) -> np.ndarray:
    """0 at the work, 1 from BAND_RAMP_SHARE of the lead on: smootherstep (u^3 (10 - 15 u + 6 u^2)), whose slope
    and curvature are 0 at both ends, so the lead leaves the work without a kink or a jump in curvature (as the
    clearance's cube does) but clears a scan's noise within a few mm of its edge (the cube reached a fifth of it
    at 40 % of the lead, where the shell scan's rim points stand 3 mm above the face's tangent)."""
    u = np.clip(np.asarray(away, float) / BAND_RAMP_SHARE, 0.0, 1.0)
    return u ** 3 * (10.0 - 15.0 * u + 6.0 * u * u)


def _straight_leads(p, normal, travel, R, b: _Blocks, lead_mm: float):
    """(positions, normals, rotations) with each lead of a free-form face run straight on along the row's tangent
    at the work's end, with the work end's normal and tool orientation. Past a free-form face's edge there is no
    surface to follow, only the fill's guess (a scan's edge is one-sided): leads on it turned the tool and kinked
    the path at the work's first pose by 25 deg (more than a controller's blend keeps within 0.1 mm); the
    tangent leaves the work without a kink and, on a convex part, above it."""
    seg = np.repeat(np.arange(len(b.block)), b.block)
    n_in = np.add.reduceat((b.zone == _LEAD_IN).astype(np.int64), b.start)
    n_out = np.add.reduceat((b.zone == _LEAD_OUT).astype(np.int64), b.start)
    lead_in, lead_out = b.zone == _LEAD_IN, b.zone == _LEAD_OUT
    anchor = np.where(lead_in, (b.start + n_in)[seg], (b.start + b.block - n_out - 1)[seg])
    lead = lead_in | lead_out
    k = np.flatnonzero(lead)
    a = anchor[k]
    way = np.where(lead_in[k], -1.0, 1.0)
    p, normal, R = p.copy(), normal.copy(), R.copy()
    p[k] = p[a] + (way * b.away[k] * lead_mm)[:, None] * travel[a]
    normal[k], R[k] = normal[a], R[a]
    return p, normal, R


def _transitions(surface, blocks: _Blocks, lift: np.ndarray, R: np.ndarray, settings: RasterSettings,
                 ends_mm: np.ndarray | None = None) -> _Poses:
    """The self-motion poses between consecutive segments (``transition_points`` each, in order): positions
    interpolated in (u, v) and lifted off the part, orientations by slerp. ``ends_mm``: where the blocks' poses
    really are, when not on the surface at their (u, v) (a free-form face's straight leads): the transition then
    carries the two ends' offsets from there, blended along it, so it starts and ends where its leads do (on the
    noether panel's short contour runs it began 10 mm from its lead-out's end and jumped 10 mm back to the next
    lead-in, a zig-zag the time law's spline cut 2 mm into the part)."""
    m = settings.transition_points
    a_idx = blocks.start[:-1] + blocks.block[:-1] - 1
    b_idx = blocks.start[1:]
    f = np.arange(1, m + 1) / (m + 1)
    uv = blocks.uv
    uv_t = uv[a_idx, None, :] + f[None, :, None] * (uv[b_idx] - uv[a_idx])[:, None, :]
    base = lift[a_idx, None] + f[None, :] * (lift[b_idx] - lift[a_idx])[:, None]
    top = max(settings.clearance_mm, settings.self_motion_lift_mm)  # the self-motion zone runs off the part
    lift_t = base + (top - base) * np.sin(np.pi * f)[None, :]
    uv_t = uv_t.reshape(-1, 2)
    n_t = _unit(surface.normal_at(uv_t[:, 0], uv_t[:, 1]))
    pos_t = surface.point_mm(uv_t[:, 0], uv_t[:, 1]) + lift_t.reshape(-1, 1) * n_t
    if ends_mm is not None and blocks.n_seg > 1:
        ends = np.concatenate([a_idx, b_idx])
        at = surface.point_mm(uv[ends, 0], uv[ends, 1]) + lift[ends, None] * _unit(surface.normal_at(uv[ends, 0], uv[ends, 1]))
        off = ends_mm[ends] - at
        off_a, off_b = off[:len(a_idx)], off[len(a_idx):]
        pos_t = pos_t + (((1 - f)[None, :, None] * off_a[:, None, :]) + f[None, :, None] * off_b[:, None, :]).reshape(-1, 3)
    if blocks.n_seg > 1:
        ra, rb = Rotation.from_matrix(R[a_idx]), Rotation.from_matrix(R[b_idx])
        rel = (ra.inv() * rb).as_rotvec()
        ra_rep = Rotation.from_matrix(np.repeat(R[a_idx], m, axis=0))
        R_t = (ra_rep * Rotation.from_rotvec((rel[:, None, :] * f[None, :, None]).reshape(-1, 3))).as_matrix()
    else:
        R_t = np.zeros((0, 3, 3))
    return _Poses(R_t, pos_t)


def _approach_and_depart(pos_mm: np.ndarray, normal: np.ndarray, clearance_mm: float):
    """(approach positions, depart positions): backed off along the normal of the first / last pose."""
    back = max(clearance_mm, APPROACH_MIN_MM)
    h = back * np.arange(1, APPROACH_POINTS + 1) / APPROACH_POINTS
    return pos_mm[0] + h[::-1, None] * normal[0], pos_mm[-1] + h[:, None] * normal[-1]


def _in_path_order(blocks: _Blocks, on_surface: _Poses, transitions: _Poses, ends, m: int):
    """(poses, segment, point, zone) of the whole path in order: approach, each block with the
    ``m`` transition poses before the next, depart (``ends``: the approach's and depart's positions)."""
    pos_ap, pos_dp = ends
    seg, start, n_seg, R = blocks.seg, blocks.start, blocks.n_seg, on_surface.R
    A = APPROACH_POINTS
    total = 2 * A + len(seg) + (n_seg - 1) * m
    poses = np.zeros((total, 4, 4))
    poses[:, 3, 3] = 1.0
    segment = np.zeros(total, np.int32)
    pidx = np.zeros(total, np.int32)
    zcode = np.zeros(total, np.int32)
    at = A + np.arange(len(seg)) + seg * m
    poses[at, :3, :3], poses[at, :3, 3] = R, on_surface.pos
    segment[at], pidx[at], zcode[at] = seg, blocks.point, blocks.zone
    if n_seg > 1:
        at_t = (A + start[1:] + np.arange(n_seg - 1) * m)[:, None] + np.arange(m)[None, :]
        at_t = at_t.ravel()
        poses[at_t, :3, :3], poses[at_t, :3, 3] = transitions.R, transitions.pos
        segment[at_t] = np.repeat(np.arange(1, n_seg), m)
        zcode[at_t] = _SELF
    poses[:A, :3, :3], poses[:A, :3, 3] = R[0], pos_ap
    zcode[:A] = _APPROACH
    poses[total - A:, :3, :3], poses[total - A:, :3, 3] = R[-1], pos_dp
    segment[total - A:] = n_seg - 1
    zcode[total - A:] = _DEPART
    return poses, segment, pidx, zcode


def _tangent_clearing_lift(p: np.ndarray, normal: np.ndarray, zone: np.ndarray, start: np.ndarray,
                           block: np.ndarray, away: np.ndarray) -> np.ndarray:
    """Per pose, the lift (mm along the normal) that keeps each lead of a face convex along its row at or above the
    row's tangent at the work's end: the lead's ramp ``c * away**3`` with the smallest c that lifts every lead pose
    to where the surface continued has dipped below that tangent (0 on work, and where the face does not dip).

    A straight tangent lead would leave the row with a jump in curvature at its first and last work point, which
    slows the whole row to the wrist's jerk limit; the cubic ramp leaves it without one. ``p``, ``normal``: the
    on-surface samples of the blocks [lead-in | work | lead-out] (path order; ``start``, ``block`` each block's
    first index and length); ``away``: each lead pose's share of its lead from the work (0..1)."""
    seg = np.repeat(np.arange(len(block)), block)
    n_in = np.add.reduceat((zone == _LEAD_IN).astype(np.int64), start)
    n_out = np.add.reduceat((zone == _LEAD_OUT).astype(np.int64), start)
    lead_in, lead_out = zone == _LEAD_IN, zone == _LEAD_OUT
    anchor = np.where(lead_in, (start + n_in)[seg], (start + block - n_out - 1)[seg])  # the work's end of each lead
    lead = lead_in | lead_out
    # how far the surface continued lies below the anchor's tangent plane (mm, > 0 where the face curves away)
    dip_mm = np.where(lead, np.einsum("ij,ij->i", p[anchor] - p, normal[anchor]), 0.0)
    a3 = np.where(lead, away, 1.0) ** 3
    need = np.where(lead & (dip_mm > 0), dip_mm / np.maximum(a3, 1e-12), 0.0)  # the ramp's c each pose needs
    key = 2 * seg + lead_out                                     # (segment, lead-in / lead-out)
    c = np.zeros(2 * len(block))
    np.maximum.at(c, key[lead], need[lead])
    return np.where(lead, c[key] * a3, 0.0)


# ----------------------------------------------------------------------------- coverage and summary


SCAN_CONTOUR_ROUND_MM = 2.0  # a scanned free-form face's contour rounds its corners to this radius: twice its outline's 1 mm weave (path/contour.py)
CONTOUR_BELOW = 0.995  # raster.contour = "auto": a face's rows alone covering less than this share get a contour


def contour_offset_mm(step_over_mm: float, pitch_mm: float) -> float:
    """How far inside the boundary the contour runs (mm): half a step-over, as the outer rows at most are, but
    no farther than keeps the boundary itself within the coverage radius of points ``pitch_mm`` apart."""
    r = coverage_radius_mm(step_over_mm, pitch_mm)
    return min(0.5 * step_over_mm, math.sqrt(max(r * r - 0.25 * pitch_mm * pitch_mm, 0.0)))


def _wants_contour(surface, settings: RasterSettings, work_uv: np.ndarray) -> bool:
    """``raster.contour``: "on", "off", or "auto" (the rows' work points cover less than ``CONTOUR_BELOW``)."""
    if settings.contour != "auto":
        return settings.contour == "on"
    work = surface.point_mm(work_uv[:, 0], work_uv[:, 1])
    return work_coverage(surface, work, settings.step_over_mm, settings.pitch_mm) < CONTOUR_BELOW


def coverage_radius_mm(step_over_mm: float, pitch_mm: float) -> float:
    """Distance within which a surface point counts as covered by a work point (mm).

    Half the diagonal of one pitch x step-over cell (the farthest any point of a
    perfect raster is from its nearest work point) plus COVERAGE_TOL_FRACTION of
    the step-over for sampling and chord-versus-arc effects.
    """
    return 0.5 * math.hypot(step_over_mm, pitch_mm) + COVERAGE_TOL_FRACTION * step_over_mm


def coverage(surface, path: Path, step_over_mm: float, grid: int = 400) -> float:
    """Area share (0..1) of the bounded surface within ``coverage_radius_mm`` of a work point.

    The (u, v) bounding box is sampled on a grid of about ``grid`` samples along
    its longer metric side; samples on material are weighted by their area
    element, and distances are taken in mm between surface points (cKDTree).
    """
    if isinstance(grid, bool) or not isinstance(grid, (int, np.integer)) or grid < 2:
        raise BadInput(f"coverage grid: expected an integer >= 2, found {grid!r}")
    pitch = path.pitch_mm if path.pitch_mm > 0 else step_over_mm
    return work_coverage(surface, path.poses_mm[path.is_work, :3, 3], step_over_mm, pitch, grid)


def work_coverage(surface, work: np.ndarray, step_over_mm: float, pitch: float, grid: int = 400) -> float:
    """``coverage`` of work points ``work`` (N x 3, mm) rastered at ``step_over_mm`` and ``pitch`` (mm)."""
    if len(work) == 0:
        return 0.0
    b = surface.boundary
    lo, hi = b.bounds()
    scale = surface.metric_scale(_domain_grid(b)).max(axis=0)
    extent = (hi - lo) * scale
    n = np.maximum(2, np.ceil(grid * extent / extent.max()).astype(int))
    # cell centres, so that every sample stands for the same (u, v) area
    us = lo[0] + (np.arange(n[0]) + 0.5) * (hi[0] - lo[0]) / n[0]
    vs = lo[1] + (np.arange(n[1]) + 0.5) * (hi[1] - lo[1]) / n[1]
    U, V = np.meshgrid(us, vs)
    uv = np.stack([U.ravel(), V.ravel()], axis=-1)
    uv = uv[b.contains(uv)]
    if len(uv) == 0:
        return 0.0
    weight = np.prod(surface.metric_scale(uv), axis=1)
    dist, _ = cKDTree(work).query(surface.point_mm(uv[:, 0], uv[:, 1]),
                                  distance_upper_bound=coverage_radius_mm(step_over_mm, pitch) * 1.0001)
    covered = dist <= coverage_radius_mm(step_over_mm, pitch)
    return float(weight[covered].sum() / weight.sum())


def count_rows(path: Path) -> int:
    """Rows of a raster path: a new row starts where the travel direction reverses.

    The direction of a segment is taken from its first to its last
    lead-in/work/lead-out pose; a segment with a single pose and no leads
    counts as continuing the row. A contour's runs are no rows (``count_contour_runs``).
    """
    on = np.isin(path.zone, [_LEAD_IN, _WORK, _LEAD_OUT])
    if path.contour is not None:
        on &= ~path.contour
    seg = path.segment[on]
    if len(seg) == 0:
        return 0
    p = path.poses_mm[on, :3, 3]
    _, first = np.unique(seg, return_index=True)
    _, last = np.unique(seg[::-1], return_index=True)
    last = len(seg) - 1 - last
    d = p[last] - p[first]
    # compare the direction at the end of one segment with the start of the next
    dots = np.sum(d[:-1] * d[1:], axis=1)
    return int(1 + np.count_nonzero(dots < 0))


def count_contour_runs(path: Path) -> int:
    """Runs of the contour pass (``raster.contour``) in a raster path."""
    if path.contour is None:
        return 0
    return int(len(np.unique(path.segment[path.contour & path.is_work])))


def raster_summary(path: Path, surface=None, grid: int = 400) -> dict:
    """Figures of a raster path: rows, segments, work and zone points, length (mm), coverage.

    ``coverage`` (0..1) is computed when ``surface`` is given, else None (a path over several faces:
    ``face_report.path_figures``).
    """
    zones = {name: int(np.count_nonzero(path.zone == code)) for code, name in enumerate(ZONES)}
    work = zones["work"]
    return {
        "rows": count_rows(path),
        "contour_runs": count_contour_runs(path),
        "segments": int(len(np.unique(path.segment[path.is_work]))),
        "work_points": work,
        "zone_points": int(len(path) - work),
        "zone_counts": {k: v for k, v in zones.items() if k != "work" and v},
        "path_length_mm": round(path.length_mm(), 3),
        "work_length_mm": round(_work_length_mm(path), 3),
        "step_over_mm": float(path.step_over_mm),
        "pitch_mm": float(path.pitch_mm),
        "free_spin": bool(path.free_spin),
        "coverage": None if surface is None else round(coverage(surface, path, path.step_over_mm, grid), 5),
    }


def _work_length_mm(path: Path) -> float:
    """Length of the work polylines inside segments (mm)."""
    w = path.is_work
    p = path.poses_mm[:, :3, 3]
    both = w[1:] & w[:-1] & (path.segment[1:] == path.segment[:-1])
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1)[both].sum())
