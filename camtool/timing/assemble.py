"""Assemble a timed trajectory from its pieces: surface runs, free chains, the time line.

``time_trajectory`` is the chain of these steps, each a function returning a
frozen dataclass (no shared state between them)::

    layout  = run_layout(joint_path, path)                        # RunLayout: runs of surface rows
    surface = time_surface(joint_path, path, robot, layout, ...)   # SurfaceTiming: all runs at once (runs.py)
    pieces  = timeline_pieces(joint_path, robot, layout, surface, zones)  # [Piece]: chain, run, chain, ...
    placed  = place(pieces)                                        # Placement: one Samples, piece starts
    slowdowns(surface, pieces, placed, joint_path, robot)          # the report of slowed work stretches

A ``Piece`` holds its samples with times from its own start; ``place`` puts the
pieces one after another on the time line (a piece's first sample is the
previous piece's last one and is dropped) and concatenates every field once.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..path.toolpath import SURFACE_ZONES, ZONES, ZONE_CODE, row_segments, run_bounds
from ..trajectory import quintic_coefficients
from .flow import corner_poses, flow_chain, hard_steps
from .quintic import MARGIN
from .ruckig_moves import AxisCoupling, RuckigMover, rest_to_rest_chain
from .ruckig_through import on_grid, through_pieces
from .runs import RunsTiming, run_leads, time_runs



# ----------------------------------------------------------------------------- runs


@dataclass(frozen=True)
class RunLayout:
    """Per JointPath row: surface pose, first row of a run, last row of a run (a run: surface poses of one segment)."""

    surface: np.ndarray  # (n,) bool
    start: np.ndarray    # (n,) bool
    end: np.ndarray      # (n,) bool

    def runs(self) -> list[tuple[int, int]]:
        """(first row, last row) of every run, in JointPath order."""
        return [(int(a), int(b)) for a, b in zip(np.nonzero(self.start)[0], np.nonzero(self.end)[0])]


def run_layout(joint_path, path) -> RunLayout:
    """The runs of ``joint_path``: consecutive surface poses (work, lead-in, lead-out) of one Path segment."""
    zone = np.asarray(joint_path.zone)
    seg = row_segments(joint_path.path_index, zone, path.segment)
    return RunLayout(*run_bounds(zone, seg))


def tcp_positions_mm(joint_path, path, robot) -> np.ndarray:
    """World-frame TCP position per JointPath row: from the Path, or by FK for inserted poses."""
    pidx = np.asarray(joint_path.path_index)
    pos = np.empty((len(pidx), 3))
    on = pidx >= 0
    pos[on] = np.asarray(path.poses_mm)[pidx[on], :3, 3]
    for i in np.nonzero(~on)[0]:
        pos[i] = (robot.base_T_mm @ robot.fk_tcp(joint_path.q[i]))[:3, 3]
    return pos


# ----------------------------------------------------------------------------- surface runs


@dataclass(frozen=True)
class InnerSamples:
    """Samples inside surface pieces (ruckig pieces written out at their jerk switches).

    ``waypoint``: surface waypoint the piece starts at; ``t_s``: time from the piece start.
    """

    waypoint: np.ndarray  # (K,)
    t_s: np.ndarray       # (K,)
    q: np.ndarray         # (K, dof)
    qd: np.ndarray
    qdd: np.ndarray


@dataclass(frozen=True)
class PieceInterpolation:
    """How the surface pieces are interpolated: final durations, inner samples, ruckig flag and reason.

    ``inner``: samples inside pieces (the time law's S-curve samples, or ruckig's jerk switches).
    """

    h_s: np.ndarray                 # (S-1,) final piece durations (undefined across run ends)
    inner: InnerSamples | None      # None: every piece is the quintic between its waypoints
    piece_ruckig: np.ndarray        # (P,) bool
    piece_reason: np.ndarray        # (P,) "" or why a ruckig piece kept the law's samples
    on_grid: bool = False           # runs start on the ruckig time grid (ruckig pieces)


@dataclass(frozen=True)
class SurfaceTiming:
    """Every run timed at once, indexed by surface waypoint k (the k-th surface row of the JointPath).

    Piece p goes from surface waypoint ``pieces[p]`` to the next one (same run).
    ``law``: the runs' time law with its report (slowed stretches, short leads, feed per run).
    """

    rows: np.ndarray        # (S,) JointPath row of each surface waypoint
    run_id: np.ndarray      # (S,) run number
    q: np.ndarray           # (S, dof)
    qd: np.ndarray          # (S, dof) through-velocities (0 at run ends)
    qdd: np.ndarray         # (S, dof) through-accelerations
    pieces: np.ndarray      # (P,) surface waypoint each piece starts at
    interpolation: PieceInterpolation
    law: RunsTiming

    @property
    def h_s(self) -> np.ndarray:
        return self.interpolation.h_s

    def waypoint_of_row(self, row: int) -> int:
        """Surface waypoint index of a JointPath row that is a surface pose."""
        return int(np.searchsorted(self.rows, row))


def _law_inner(law: RunsTiming, keep: np.ndarray | None = None) -> InnerSamples | None:
    """The time law's samples inside pieces (those starting at waypoints in ``keep``, if given)."""
    sel = np.ones(len(law.inner_waypoint), bool) if keep is None else np.isin(law.inner_waypoint, keep)
    if not sel.any():
        return None
    return InnerSamples(law.inner_waypoint[sel], law.inner_t_s[sel], law.inner_q[sel], law.inner_qd[sel],
                        law.inner_qdd[sel])


def _quintic_pieces(limits, q, law: RunsTiming, pieces) -> PieceInterpolation:
    return PieceInterpolation(law.h_s.copy(), _law_inner(law), np.zeros(len(pieces), bool),
                              np.full(len(pieces), "", dtype=object))


def _ruckig_pieces(limits, q, law: RunsTiming, pieces) -> PieceInterpolation:
    """Every piece a ruckig state-to-state move between the law's through-states; a piece ruckig
    cannot give keeps the law's own samples (``ruckig_through``)."""
    if not len(pieces):
        return _quintic_pieces(limits, q, law, pieces)
    through = through_pieces(limits, q, law.qd, law.qdd, law.h_s, pieces, share=MARGIN)
    # a piece ruckig could only give in more time than the law's keeps the law's samples: ruckig would
    # reach the same end velocity later, i.e. leave the path between the poses
    used = np.asarray(through.used, bool).copy()
    reason = np.asarray(through.reason, object).copy()
    longer = used & (through.duration_s > on_grid(law.h_s[pieces], up=True))
    used[longer] = False
    reason[longer] = "longer"
    h = law.h_s.copy()
    h[pieces] = np.where(used, through.duration_s, on_grid(law.h_s[pieces], up=True))
    keep = used[through.piece]
    parts = [InnerSamples(pieces[through.piece[keep]], through.t_s[keep], through.q[keep], through.qd[keep],
                          through.qdd[keep])]
    fallback = _law_inner(law, pieces[~used])
    if fallback is not None:
        parts.append(_stretched(fallback, law, h))
    inner = InnerSamples(*(np.concatenate([getattr(p, f) for p in parts])
                           for f in ("waypoint", "t_s", "q", "qd", "qdd")))
    return PieceInterpolation(h, inner, used, reason.astype(str), on_grid=True)


def _stretched(inner: InnerSamples, law: RunsTiming, h_new: np.ndarray) -> InnerSamples:
    """The law's samples of pieces whose duration was rounded up to the ruckig time grid (< 1 ns).

    Times are scaled by f = new / planned duration and the states with them (q' / f,
    q'' / f^2: the same motion, slower by f); the piece ends keep the law's states, so
    the mismatch this leaves there (~1e-7 of q' and q'') is removed by adding the
    quintic that carries it, spread over the whole piece (the Hermite pieces
    reproduce a quintic exactly).
    """
    w = inner.waypoint
    f = (h_new / law.h_s)[w][:, None]
    T = h_new[w][:, None]
    v0, a0, v1, a1 = law.qd[w], law.qdd[w], law.qd[w + 1], law.qdd[w + 1]
    zero = np.zeros_like(v0)
    c = quintic_coefficients(zero, (v0 - v0 / f) * T, (a0 - a0 / f**2) * T**2, zero, (v1 - v1 / f) * T,
                             (a1 - a1 / f**2) * T**2)
    t = inner.t_s * f[:, 0]
    u = (t / T[:, 0])[:, None]
    q = inner.q + c[0] + u * (c[1] + u * (c[2] + u * (c[3] + u * (c[4] + u * c[5]))))
    qd = inner.qd / f + (c[1] + u * (2 * c[2] + u * (3 * c[3] + u * (4 * c[4] + u * 5 * c[5])))) / T
    qdd = inner.qdd / f**2 + (2 * c[2] + u * (6 * c[3] + u * (12 * c[4] + u * 20 * c[5]))) / T**2
    return InnerSamples(w, t, q, qd, qdd)


PIECE_INTERPOLATIONS = {"quintic": _quintic_pieces, "ruckig": _ruckig_pieces}  # timing.method


def time_surface(joint_path, path, robot, layout: RunLayout, method: str, tcp_speed_mm_s: float,
                 feed: str = "constant", slow_scope: str = "row", feed_factor=None) -> SurfaceTiming:
    """Time every run: splines through the poses, constant-feed time law with ramps at the run ends
    (``runs.py``, ``pathlaw.py``); then the pieces' interpolation by ``method`` (the law's own
    samples, or ruckig state-to-state moves between its through-states, ``ruckig_through.py``)."""
    q = np.asarray(joint_path.q, float)
    sidx = np.nonzero(layout.surface)[0]
    pos = tcp_positions_mm(joint_path, path, robot)
    first, last = layout.start[sidx], layout.end[sidx]
    run_id = np.cumsum(first) - 1
    step_mm = np.linalg.norm(np.diff(pos[sidx], axis=0), axis=1)
    zone = np.asarray(joint_path.zone)[sidx]
    factor = None
    if feed_factor is not None:  # per Path pose (camtool.process.dwell); inserted rows are not capped
        pidx = np.asarray(joint_path.path_index)[sidx]
        factor = np.where(pidx >= 0, np.asarray(feed_factor, float)[np.maximum(pidx, 0)], 1.0)
    law = time_runs(q[sidx], step_mm, first, last, run_id, zone, robot.limits, tcp_speed_mm_s, feed, slow_scope,
                    factor)
    pieces = np.nonzero(~last[:-1])[0] if len(sidx) > 1 else np.zeros(0, int)
    interpolation = PIECE_INTERPOLATIONS[method](robot.limits, q[sidx], law, pieces)
    return SurfaceTiming(sidx, run_id, q[sidx], law.qd, law.qdd, pieces, interpolation, law)


# ----------------------------------------------------------------------------- pieces of the time line


@dataclass(frozen=True)
class Samples:
    """Waypoints of a trajectory, or of one piece of it (then ``t_s`` counts from the piece's start)."""

    t_s: np.ndarray         # (M,)
    q: np.ndarray           # (M, dof)
    qd: np.ndarray
    qdd: np.ndarray
    zone: np.ndarray        # (M,) zone codes
    path_index: np.ndarray  # (M,) Path pose, -1 for samples and inserted poses


@dataclass(frozen=True)
class Piece:
    """One free chain or one run, timed on its own; ``rows``: its first and last JointPath row."""

    samples: Samples
    rows: tuple[int, int]
    run: bool               # a surface run (else a free chain)
    starts_on_grid: bool    # must start on the exact ruckig time grid (a run with ruckig pieces)


def _inner_zone(z0: np.ndarray, z1: np.ndarray) -> np.ndarray:
    """Zone of samples inside a piece: its ends' zone, or the non-work one where they differ.

    So a piece counts as work time (both ends work) exactly as it does without samples.
    """
    return np.where((z0 == z1) | (z1 == ZONE_CODE["work"]), z0, z1)


def _stop_chain(mover, joint_path, rows, robot):
    return rest_to_rest_chain(mover, np.asarray(joint_path.q, float)[rows])


def _flow_chain(mover, joint_path, rows, robot):
    q = np.asarray(joint_path.q, float)[rows]
    zone = np.asarray(joint_path.zone)[rows]
    hard = hard_steps(q, robot.prismatic, np.asarray(joint_path.jump)[rows],
                      (zone == ZONE_CODE["retract"]) | np.asarray(joint_path.retract)[rows])
    rest = corner_poses(q, np.asarray(joint_path.path_index)[rows] < 0, robot.limits.velocity)
    return flow_chain(mover, q, hard, rest)


CHAIN_TIMINGS = {"stop": _stop_chain, "flow": _flow_chain}  # timing.zones


def free_chain(rows, joint_path, robot, layout: RunLayout, mover: RuckigMover, zones: str) -> Piece:
    """Time the free chain through JointPath ``rows`` (from the last pose of a run to the first of the next).

    Samples inside a step get the zone of the step's free pose (``self_motion``
    for a hop between two runs); samples at a pose carry its zone and Path index.
    """
    rows = np.asarray(rows)
    zone = np.asarray(joint_path.zone)
    pidx = np.asarray(joint_path.path_index)
    t_rel, cq, cv, ca, pose = CHAIN_TIMINGS[zones](mover, joint_path, rows, robot)
    surface = layout.surface
    step_zone = np.empty(len(rows), int)
    for k in range(len(rows)):
        nxt = rows[min(k + 1, len(rows) - 1)]
        if not surface[nxt]:
            step_zone[k] = zone[nxt]
        elif not surface[rows[k]]:
            step_zone[k] = zone[rows[k]]
        else:
            step_zone[k] = ZONE_CODE["self_motion"]
    prev_pose = np.maximum.accumulate(np.where(pose >= 0, pose, 0))
    zz = np.where(pose >= 0, zone[rows[np.maximum(pose, 0)]], step_zone[prev_pose])
    pp = np.where(pose >= 0, pidx[rows[np.maximum(pose, 0)]], -1)
    return Piece(Samples(t_rel, cq, cv, ca, zz, pp), (int(rows[0]), int(rows[-1])), run=False,
                 starts_on_grid=False)


def run_waypoint_times(surface: SurfaceTiming, ka: int, kb: int) -> np.ndarray:
    """Times (s from the run start) of surface waypoints ``ka`` .. ``kb`` (one run)."""
    return np.concatenate([[0.0], np.cumsum(surface.h_s[ka:kb])])


def surface_run(a: int, b: int, surface: SurfaceTiming, joint_path) -> Piece:
    """The run from JointPath row ``a`` to row ``b``: its waypoints, plus the ruckig pieces' inner samples."""
    zone = np.asarray(joint_path.zone)
    pidx = np.asarray(joint_path.path_index)
    sidx = surface.rows
    inner = surface.interpolation.inner
    ka, kb = surface.waypoint_of_row(a), surface.waypoint_of_row(b)
    t_way = run_waypoint_times(surface, ka, kb)
    t_rel, rq, rv, ra = t_way, surface.q[ka:kb + 1], surface.qd[ka:kb + 1], surface.qdd[ka:kb + 1]
    zz, pp = zone[sidx[ka:kb + 1]], pidx[sidx[ka:kb + 1]]
    if inner is not None and kb > ka:
        sel = (inner.waypoint >= ka) & (inner.waypoint < kb)
        if sel.any():
            w = inner.waypoint[sel]
            t_rel = np.concatenate([t_rel, t_way[w - ka] + inner.t_s[sel]])
            rq = np.concatenate([rq, inner.q[sel]])
            rv = np.concatenate([rv, inner.qd[sel]])
            ra = np.concatenate([ra, inner.qdd[sel]])
            zz = np.concatenate([zz, _inner_zone(zone[sidx[w]], zone[sidx[w + 1]])])
            pp = np.concatenate([pp, np.full(int(sel.sum()), -1)])
            o = np.argsort(t_rel, kind="stable")
            t_rel, rq, rv, ra, zz, pp = t_rel[o], rq[o], rv[o], ra[o], zz[o], pp[o]
    return Piece(Samples(t_rel, rq, rv, ra, zz, pp), (a, b), run=True,
                 starts_on_grid=surface.interpolation.on_grid)


def timeline_pieces(joint_path, robot, layout: RunLayout, surface: SurfaceTiming, zones: str) -> list[Piece]:
    """The pieces in JointPath order: the free chain before each run (if any), the run, and the tail."""
    mover = RuckigMover(robot.limits, coupling=AxisCoupling.of(robot))
    pieces: list[Piece] = []
    prev_end = 0
    for a, b in layout.runs():
        if a + 1 - prev_end >= 2:
            pieces.append(free_chain(np.arange(prev_end, a + 1), joint_path, robot, layout, mover, zones))
        pieces.append(surface_run(a, b, surface, joint_path))
        prev_end = b
    n = len(layout.surface)
    if n - prev_end >= 2 or not pieces:
        pieces.append(free_chain(np.arange(prev_end, n), joint_path, robot, layout, mover, zones))
    return pieces


# ----------------------------------------------------------------------------- the time line


@dataclass(frozen=True)
class Placement:
    """The pieces on one time line: all samples concatenated, and each piece's start time (s)."""

    samples: Samples
    start_s: tuple[float, ...]


def place(pieces: list[Piece]) -> Placement:
    """Put the pieces one after another on the time line and concatenate them once.

    Every piece but the first drops its first sample (the previous piece's last).
    A piece that ``starts_on_grid`` starts at the next multiple of the ruckig time
    grid: the previous sample is moved there (the last free interval stretched by < 1 ns).
    """
    t_parts: list[np.ndarray] = []
    starts: list[float] = []
    t_offset = 0.0
    for i, piece in enumerate(pieces):
        if piece.starts_on_grid and i > 0:
            g = float(on_grid(t_offset, up=True))
            if g != t_offset:
                last = next(p for p in reversed(t_parts) if len(p))
                last[-1] = g  # an array made here, below
                t_offset = g
        s = 1 if i > 0 else 0
        starts.append(t_offset)
        t_parts.append(t_offset + piece.samples.t_s[s:])
        t_offset += float(piece.samples.t_s[-1])
    samples = Samples(np.concatenate(t_parts), *(_joined(pieces, name) for name in ("q", "qd", "qdd", "zone",
                                                                                  "path_index")))
    return Placement(samples, tuple(starts))


def _joined(pieces: list[Piece], name: str) -> np.ndarray:
    """Field ``name`` of every piece's samples, concatenated (first sample of every piece but the first dropped)."""
    return np.concatenate([np.asarray(getattr(p.samples, name))[1 if i else 0:] for i, p in enumerate(pieces)])


# ----------------------------------------------------------------------------- report of slowed pieces


def _waypoint_times(surface: SurfaceTiming, pieces: list[Piece], placement: Placement) -> np.ndarray:
    """Time (s, on the whole time line) of every surface waypoint."""
    t = np.zeros(len(surface.rows))
    for piece, start in zip(pieces, placement.start_s):
        if piece.run:
            ka, kb = surface.waypoint_of_row(piece.rows[0]), surface.waypoint_of_row(piece.rows[1])
            t[ka:kb + 1] = start + run_waypoint_times(surface, ka, kb)
    return t


def slowdowns(surface: SurfaceTiming, pieces: list[Piece], placement: Placement, joint_path, robot=None) -> tuple:
    """One dict per slowed work stretch (``runs.py``): rows, Path indices, time span, feed, binding joint."""
    if not surface.law.slow:
        return ()
    t_way = _waypoint_times(surface, pieces, placement)
    zone = np.asarray(joint_path.zone)
    pidx = np.asarray(joint_path.path_index)
    names = None if robot is None else tuple(robot.joint_names)
    out = []
    for s in surface.law.slow:
        ka, kb = s["first_waypoint"], s["last_waypoint"]
        a, b = int(surface.rows[ka]), int(surface.rows[kb])
        j = int(s["joint"])
        out.append({
            "first_row": a, "last_row": b, "first_path_index": int(pidx[a]), "last_path_index": int(pidx[b]),
            "t_start_s": float(t_way[ka]), "t_end_s": float(t_way[kb]),
            "speed_ratio": float(s["speed_ratio"]), "feed_mm_s": float(s["feed_mm_s"]),
            "joint": names[j] if names else j, "limit": s["limit"], "run": int(s["run"]),
            "zone": ZONES[int(zone[a])], "at_run_end": bool(s["at_run_end"]),
        })
    return tuple(out)


def short_leads(surface: SurfaceTiming, joint_path) -> tuple:
    """One dict per ramp that does not fit its lead: run, side, first / last work row, lead and needed length."""
    pidx = np.asarray(joint_path.path_index)
    out = []
    for s in surface.law.short_leads:
        row = int(surface.rows[s["waypoint"]])
        out.append({"run": int(s["run"]), "side": s["side"], "work_row": row, "work_path_index": int(pidx[row]),
                    "lead_mm": round(float(s["lead_mm"]), 3), "needed_mm": round(float(s["needed_mm"]), 3),
                    "feed_mm_s": float(s["feed_mm_s"])})
    return tuple(out)


def lead_needed_mm(joint_path, path, robot, settings) -> dict:
    """The lead length every run of ``joint_path`` needs for its ramps at ``settings``' feed.

    ``settings``: ``TimingSettings`` (feed, policy). Returns ``lead_in_mm`` and
    ``lead_out_mm`` (the largest over the runs) and ``per_run``: run number, the
    lead lengths it has and the ones it needs (``runs.run_leads``), planned exactly
    as ``time_trajectory`` plans them.
    """
    layout = run_layout(joint_path, path)
    pos = tcp_positions_mm(joint_path, path, robot)
    zone = np.asarray(joint_path.zone)
    q = np.asarray(joint_path.q, float)
    per_run = []
    for r, (a, b) in enumerate(layout.runs()):
        step = np.linalg.norm(np.diff(pos[a:b + 1], axis=0), axis=1)
        item = run_leads(q[a:b + 1], step, zone[a:b + 1], robot.limits, settings.tcp_speed_mm_s, settings.feed,
                         settings.slow_scope)
        if item:
            per_run.append({"run": r, **item})
    return {"lead_in_mm": max((x["lead_in_needed_mm"] for x in per_run), default=0.0),
            "lead_out_mm": max((x["lead_out_needed_mm"] for x in per_run), default=0.0), "per_run": per_run}
