"""Ordered steps on a program's move list (``MovePlan``), like noether's tool-path modifiers.

``plan_moves`` (``camtool.program.plan``) makes the move list from a trajectory: the
targets (simplify / merge), their blends, the rows. Each step here then takes a move list
and returns a new one, and ``CompoundStep`` runs them in order. Every step keeps the
contract (tests/test_program_steps.py runs it over every step): the first and last target,
every row's first and last target and the row marks stay; times never decrease; kinds are
J, L or C, and a C move has a circle point.

- ``ExactStops``: where the program stops (``plan_moves`` runs it): the first and last move,
  a row of one point (a touch) and the top of every retract; no stop elsewhere, and on the
  surface at least ``min_level_on_surface``; levels capped at ``max_level``.
- ``JoinNullLinear``: a linear move that goes nowhere (< 1 um) becomes a joint move.
- ``FitArcs``: consecutive linear targets of one row that lie on a circle (within a share
  of ``post.path_tol_mm``, the orientation within ``post.ori_tol_deg``) become circular
  moves (MoveC / MOVC) of at most ``max_sweep_deg`` each; their end corners get the
  largest blend level whose rounding stays within the tolerance.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field, replace

import numpy as np

from .arcs import arc_point, circle_through, cross3
from .candidates import RETRACT, runs, span_shares
from .moveplan import KIND_CIRCULAR, KIND_JOINT, KIND_LINEAR, MovePlan
from .remembered import Remembered

ARC_SHARE = 0.4     # share of the path tolerance the circle may leave the planned path by
BLEND_SHARE = 0.4   # share of the tolerance a corner next to a circular move may cut
MIN_ARC_MOVES = 2   # a circular move replaces at least this many linear ones
FITTED = Remembered(200_000)   # the arc fit's tests by their inputs: a program written again tests most of them again


def forget_fitted() -> None:
    """Drop the arc fit's tests kept (the post stage, when a format is done)."""
    FITTED.forget()


@dataclass(frozen=True)
class StepContext:
    """What the steps measure with: the planned path's TCP at every trajectory waypoint
    (``waypoint_P`` (W, 3), ``waypoint_R`` (W, 3, 3), base frame, mm), the tolerances, the
    format's blend radii (mm, ascending) and the smallest level on the surface;
    ``waypoint_mid_P`` (W - 1, 3), the planned motion's TCP halfway (in time) through each step
    between waypoints (empty when not made: arcs are then held to the chords alone), and
    ``waypoint_t`` (W,) the waypoints' times (s, the plan's clock, as ``MovePlan.t``); ``closer_s`` the spans
    the post stage writes closer to the plan (``ProcessInfo.closer_s``): arcs and their corners there are
    held to that share of the tolerance."""

    waypoint_P: np.ndarray
    waypoint_R: np.ndarray
    path_tol_mm: float
    ori_tol_deg: float
    levels_mm: tuple = ()
    min_level_on_surface: int = 0
    waypoint_mid_P: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    waypoint_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    closer_s: tuple = ()   # (start, end, share): spans written within a share of the tolerance (ProcessInfo)


class MoveStep(ABC):
    """One step on a move list: ``apply(plan, ctx)`` returns a new ``MovePlan``."""

    @abstractmethod
    def apply(self, plan: MovePlan, ctx: StepContext) -> MovePlan:
        """The move list after this step."""


@dataclass(frozen=True)
class CompoundStep(MoveStep):
    """Steps run in order."""

    steps: tuple

    def apply(self, plan: MovePlan, ctx: StepContext) -> MovePlan:
        for step in self.steps:
            plan = step.apply(plan, ctx)
        return plan


@dataclass(frozen=True)
class ExactStops(MoveStep):
    """Exact stops (level -1) only where one is meant: the first and last move, a row of one
    point and the top of every retract (the pose farthest from where the retract starts);
    elsewhere at least level 0, on the surface at least ``min_level_on_surface``, and never
    above ``max_level``."""

    min_level_on_surface: int = 0
    max_level: int | None = None

    def apply(self, plan: MovePlan, ctx: StepContext | None = None) -> MovePlan:
        level = np.array(plan.level, int)
        if self.max_level is not None:
            level = np.minimum(level, self.max_level)
        on_surface = np.asarray(plan.row) >= 0
        level[on_surface & (level < self.min_level_on_surface)] = self.min_level_on_surface
        level[level < 0] = 0
        level[0] = -1
        level[-1] = -1
        level[plan.row_start & plan.row_end] = -1
        if plan.zone is not None:
            for a0, b0 in zip(*runs(np.asarray(plan.zone) == RETRACT)):
                seg = np.arange(a0, b0 + 1)
                start = plan.P[max(a0 - 1, 0)]
                level[seg[np.argmax(np.linalg.norm(plan.P[seg] - start, axis=1))]] = -1
        return replace(plan, level=level)


@dataclass(frozen=True)
class JoinNullLinear(MoveStep):
    """A linear move shorter than ``min_mm`` becomes a joint move (it goes nowhere)."""

    min_mm: float = 1e-3

    def apply(self, plan: MovePlan, ctx: StepContext) -> MovePlan:
        kind = np.array(plan.kind)
        length = np.r_[0.0, np.linalg.norm(np.diff(plan.P, axis=0), axis=1)]
        kind[(kind == KIND_LINEAR) & (length < self.min_mm)] = KIND_JOINT
        return replace(plan, kind=kind)


def rotation_angles_rad(Ra: np.ndarray, Rb: np.ndarray) -> np.ndarray:
    """Rotation angles (rad) from each Ra to Rb (N x 3 x 3 each), by atan2: accurate near 0 and pi."""
    R = np.transpose(Ra, (0, 2, 1)) @ Rb
    s = 0.5 * np.linalg.norm(np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0],
                                       R[:, 1, 0] - R[:, 0, 1]], axis=1), axis=1)
    c = (np.trace(R, axis1=1, axis2=2) - 1.0) / 2.0
    return np.arctan2(s, c)


def _slerp(Ra, Rb, s):
    from scipy.spatial.transform import Rotation

    rel = Rotation.from_matrix(Ra.T @ Rb).as_rotvec()
    return Ra[None] @ Rotation.from_rotvec(rel[None] * np.asarray(s)[:, None]).as_matrix()


MIN_ARC_BOW_MM = 0.05   # a circle point this close to its chord makes no circular move (50 x the write resolution)


def _on_circle(P0, Pv, P1, X, tol):
    """(fits, sweep rad): every point of X (K, 3) within ``tol`` of the arc from P0 through Pv to
    P1 and in its order along it; the arc's sweep."""
    c, rad, n, r0, sweep, ok = circle_through(P0[None], Pv[None], P1[None])
    chord = P1 - P0
    bow = np.linalg.norm(cross3(Pv - P0, chord)) / max(float(np.linalg.norm(chord)), 1e-12)
    if not ok[0] or rad[0] > 1e6 or bow < MIN_ARC_BOW_MM:
        return False, 0.0, None   # an arc that written to 0.001 mm may read back as a line: lines there
    c, n, r0, sw, R = c[0], n[0], r0[0], sweep[0], rad[0]
    rel = X - c
    h = rel @ n
    inplane = rel - h[:, None] * n
    dist = np.hypot(h, np.linalg.norm(inplane, axis=1) - R)
    ang = np.arctan2(cross3(r0, inplane) @ n, inplane @ r0) % (2 * np.pi)
    ang = np.where(ang > sw + 0.5 * (2 * np.pi - sw), ang - 2 * np.pi, ang)  # just before the start: negative
    fits = bool(np.all(dist <= tol)) and bool(np.all(np.diff(ang) >= -1e-9)) and ang[0] >= -1e-6 \
        and ang[-1] <= sw + 1e-6
    return fits, sw, (c, n, r0, sw, ang)


def _planned_key(ctx: StepContext) -> bytes:
    """The planned motion ``_arc_follows_plan`` measures against (its waypoints and midpoints), as a digest."""
    import hashlib

    h = hashlib.sha256(f"{np.shape(ctx.waypoint_P)} {np.shape(ctx.waypoint_mid_P)}".encode())
    h.update(np.ascontiguousarray(ctx.waypoint_P, float).tobytes())
    h.update(np.ascontiguousarray(ctx.waypoint_mid_P, float).tobytes())
    return h.digest()


def _waypoints_between(plan: MovePlan, a: int, b: int, ctx: StepContext) -> np.ndarray:
    """The trajectory waypoints from target a to target b, in order: by index, or where either is a point
    of the planned motion between waypoints (``wp`` -1, a target added beside a tight corner), those whose
    time lies between theirs (``ctx.waypoint_t``; none without it)."""
    wp = plan.wp
    if wp[a] >= 0 and wp[b] >= 0:
        return np.arange(wp[a], wp[b] + 1)
    if not len(ctx.waypoint_t):
        return np.zeros(0, int)
    t = ctx.waypoint_t
    return np.flatnonzero((t >= plan.t[a] - 1e-9) & (t <= plan.t[b] + 1e-9))


def _arc_follows_plan(P0, Pv, P1, w: np.ndarray, ctx: StepContext, tol: float) -> bool:
    """True when the arc from P0 through Pv to P1 holds the planned path between the waypoints ``w``
    (consecutive trajectory waypoints, in order): every waypoint within ``tol`` of the arc and in its
    order along it (``_on_circle``), and, between each two, the arc within ``tol`` of the plan there:
    of the chord between them or of the planned motion's point halfway (``ctx.waypoint_mid_P``), the
    nearer, measured at the arc's middle between them, where a circle leaves a chord most (its
    sagitta). Three waypoints 5 mm apart that kink by 1.3 mm lie on a circle of radius 9.5 mm whose
    arcs leave the chords by 0.3 mm: the program's simulator measures that (issue #46's hood)."""
    fits, sweep, geo = _on_circle(P0, Pv, P1, ctx.waypoint_P[w], tol)
    if not fits or len(w) < 2 or sweep <= 0:
        return fits
    c, n, r0, sw, ang = geo
    s = 0.5 * (ang[1:] + ang[:-1]) / sw
    K = len(s)
    mid = arc_point(np.repeat(c[None], K, 0), np.repeat(n[None], K, 0), np.repeat(r0[None], K, 0),
                    np.full(K, sw), s)
    A, B = ctx.waypoint_P[w[:-1]], ctx.waypoint_P[w[1:]]
    d = B - A
    dd = np.einsum("ki,ki->k", d, d)
    u = np.clip(np.einsum("ki,ki->k", mid - A, d) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    off = np.linalg.norm(A + u[:, None] * d - mid, axis=1)
    if len(ctx.waypoint_mid_P) >= int(w[-1]):
        off = np.minimum(off, np.linalg.norm(ctx.waypoint_mid_P[w[:-1]] - mid, axis=1))
    return bool(np.all(off <= tol))


def _blend_deviation(P_a, P_k, P_b, r: float) -> float:
    """How far the corner blend of radius ``r`` at P_k (the simulator's model: a quadratic curve
    from the point r before P_k to the point r after it, P_k its control point) leaves the two
    paths. P_a, P_b (S, 3): dense points of the incoming / outgoing path, ordered."""
    def at(path, dist_from_k):
        d = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))]
        return np.array([np.interp(dist_from_k, d, path[:, j]) for j in range(3)])
    cut = min(r, 0.5 * _length(P_a), 0.5 * _length(P_b))  # equal times before and after, one feed
    A, B = at(P_a[::-1], cut), at(P_b, cut)
    u = np.linspace(0, 1, 21)[:, None]
    curve = (1 - u) ** 2 * A + 2 * u * (1 - u) * P_k + u ** 2 * B
    return float(np.max(np.minimum(_to_polyline(curve, P_a), _to_polyline(curve, P_b))))


def _to_polyline(X: np.ndarray, path: np.ndarray) -> np.ndarray:
    """(K,) distance of each point of X (K, 3) from the polyline ``path`` (S, 3)."""
    a, d = path[:-1], np.diff(path, axis=0)
    dd = np.maximum(np.einsum("si,si->s", d, d), 1e-18)
    s = np.clip(np.einsum("ksi,si->ks", X[:, None] - a[None], d) / dd, 0.0, 1.0)
    return np.min(np.linalg.norm(X[:, None] - (a[None] + s[..., None] * d[None]), axis=2), axis=1)


def _length(path) -> float:
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())


@dataclass(frozen=True)
class FitArcs(MoveStep):
    """Consecutive linear targets of one row on a circle become circular moves (module doc).

    ``max_sweep_deg``: the largest sweep of one circular move (the controller's limit, see
    the format's dialect); ``min_chord_mm``: the start, circle point and target of a
    circular move are at least this far apart (the controller refuses closer points).
    """

    max_sweep_deg: float
    min_chord_mm: float = 0.1
    start_linear: bool = False  # an arc starts only where a linear (or circular) move arrives

    def apply(self, plan: MovePlan, ctx: StepContext) -> MovePlan:
        n = len(plan)
        kind = np.array(plan.kind)
        if n < 3 or not (kind == KIND_LINEAR).any():
            return plan
        share = span_shares(plan.t, ctx.closer_s)   # 1 outside the spans written closer to the plan
        tol_at = ARC_SHARE * ctx.path_tol_mm * share
        ori_tol = np.radians(ctx.ori_tol_deg)
        max_sweep = np.radians(self.max_sweep_deg)
        planned = _planned_key(ctx)
        P, R = plan.P, plan.R
        # a move k may join an arc when it is linear, inside one row, and no row starts at it
        joinable = (kind == KIND_LINEAR) & (plan.row >= 0) & ~plan.row_start
        joinable &= np.r_[False, plan.row[1:] == plan.row[:-1]]
        arcs = []  # (a, m, b): start target, circle point, end target
        a = 0
        while a < n - 1:
            best = None
            if self.start_linear and (a == 0 or kind[a] == KIND_JOINT):
                a += 1
                continue
            b = a + MIN_ARC_MOVES
            while b < n and joinable[a + 1:b + 1].all():
                if plan.level[a + 1:b].min(initial=0) < 0 or plan.row_end[a + 1:b].any():
                    break  # an exact stop or a row end inside: the arc ends before it
                m = (a + b) // 2
                if min(np.linalg.norm(P[m] - P[a]), np.linalg.norm(P[b] - P[m])) < self.min_chord_mm:
                    b += 1
                    continue
                tol = float(tol_at[a:b + 1].min())
                ends = (P[a], P[m], P[b])
                fits, sweep, geo = FITTED.value("on_circle", ends + (P[a:b + 1], tol),
                                                lambda: _on_circle(*ends, P[a:b + 1], tol))
                if not fits or sweep > max_sweep:
                    break
                # the planned path between the targets (every waypoint) and its orientation
                w = _waypoints_between(plan, a, b, ctx)
                if len(w) and not FITTED.value("follows", ends + (w, tol, planned),
                                               lambda: _arc_follows_plan(*ends, w, ctx, tol)):
                    break
                s = geo[4][1:-1] / sweep if sweep > 0 else np.zeros(0)
                if len(s) and FITTED.value("turn", (R[a], R[b], s, R[a + 1:b]), lambda: np.max(
                        rotation_angles_rad(_slerp(R[a], R[b], s), R[a + 1:b]))) > ori_tol:
                    break
                best = (a, m, b)
                b += 1
            if best is None:
                a += 1
                continue
            arcs.append(best)
            a = best[2]
        # an arc whose corner cannot be blended within the tolerance at the smallest level the
        # surface allows is given up (its linear moves stay), until every corner fits
        for _round in range(len(arcs) + 1):
            if not arcs:
                return plan
            new = self._with_arcs(plan, arcs)
            level, bad = self._corner_levels(new, ctx)
            if not bad:
                return replace(new, level=level)
            ends = np.flatnonzero(new.kind == KIND_CIRCULAR)
            drop = {int(k) for k in bad if new.kind[k] == KIND_CIRCULAR} | \
                {int(k) + 1 for k in bad if k + 1 < len(new) and new.kind[k + 1] == KIND_CIRCULAR}
            arcs = [arc for arc, e in zip(arcs, ends) if int(e) not in drop]
        return plan

    def _with_arcs(self, plan: MovePlan, arcs: list) -> MovePlan:
        """The move list with each arc (start, circle point, end target) as one circular move."""
        n = len(plan)
        kind = np.array(plan.kind)
        P, R = plan.P, plan.R
        keep = np.ones(n, bool)
        for a, _m, b in arcs:
            keep[a + 1:b] = False
        via_P = np.full((n, 3), np.nan)
        via_R = np.full((n, 3, 3), np.nan)
        via_q = np.full((n, plan.q.shape[1]), np.nan)
        for a, m, b in arcs:
            kind[b] = KIND_CIRCULAR
            via_P[b], via_R[b], via_q[b] = P[m], R[m], plan.q[m]
        idx = np.flatnonzero(keep)
        return replace(plan, wp=plan.wp[idx], kind=kind[idx], t=plan.t[idx], level=plan.level[idx],
                       row=plan.row[idx], row_start=plan.row_start[idx], row_end=plan.row_end[idx],
                       free=plan.free[idx], deviation_mm=plan.deviation_mm[idx], P=P[idx], R=R[idx], q=plan.q[idx],
                       via_P=via_P[idx], via_R=via_R[idx], via_q=via_q[idx])

    @staticmethod
    def _path(plan: MovePlan, k: int, samples: int = 201) -> np.ndarray:
        """Dense TCP points of move k (from target k-1 to k): its line or its arc."""
        s = np.linspace(0, 1, samples)
        if plan.kind[k] == KIND_CIRCULAR:
            c, rad, n, r0, sweep, ok = circle_through(plan.P[k - 1][None], plan.via_P[k][None], plan.P[k][None])
            if ok[0]:
                return arc_point(np.repeat(c, samples, 0), np.repeat(n, samples, 0), np.repeat(r0, samples, 0),
                                 np.repeat(sweep, samples), s)
        return plan.P[k - 1] + s[:, None] * (plan.P[k] - plan.P[k - 1])

    def _corner_levels(self, plan: MovePlan, ctx: StepContext) -> tuple[np.ndarray, list]:
        """Blend levels at the corners beside circular moves: the largest level (not above the
        one planned) whose rounding stays within BLEND_SHARE of the tolerance, at least the
        smallest level allowed on the surface; and the corners where even that one cuts more."""
        level = plan.level.copy()
        levels = np.asarray(ctx.levels_mm, float)
        bad: list = []
        if not len(levels):
            return level, bad
        budget = BLEND_SHARE * ctx.path_tol_mm * span_shares(plan.t, ctx.closer_s)
        circ = plan.kind == KIND_CIRCULAR
        corners = np.flatnonzero((circ | np.r_[circ[1:], False]) & (level >= 0))
        corners = corners[(corners > 0) & (corners < len(plan) - 1)]
        for k in corners:
            if plan.kind[k + 1] == KIND_JOINT or plan.kind[k] == KIND_JOINT:
                continue
            floor = ctx.min_level_on_surface if plan.row[k] >= 0 else 0
            inputs = (plan.kind[k:k + 2], plan.P[k - 1:k + 2], plan.via_P[k:k + 2], level[k], floor, budget[k], levels)
            level[k], too_far = FITTED.value("corner", inputs,
                                             lambda: self._corner_level(plan, k, int(level[k]), floor, levels, budget[k]))
            if too_far:
                bad.append(int(k))
        return level, bad

    def _corner_level(self, plan: MovePlan, k: int, lv: int, floor: int, levels: np.ndarray, budget: float):
        """(the corner k's level: the largest from ``lv`` down to ``floor`` whose blend cuts at most ``budget``,
        whether even the last cuts more)."""
        P_in, P_out = self._path(plan, k), self._path(plan, k + 1)
        while lv > floor and _blend_deviation(P_in, plan.P[k], P_out, levels[lv]) > budget:
            lv -= 1
        return lv, _blend_deviation(P_in, plan.P[k], P_out, levels[lv]) > budget


def program_steps(*, arcs_max_sweep_deg: float | None, arc_start_linear: bool = False) -> CompoundStep:
    """The steps a writer runs on ``plan_moves``' move list, in order: null linear moves
    become joint moves, then (with ``arcs_max_sweep_deg``) circles become circular moves
    (``arc_start_linear``: only where a linear move arrives, as INFORM's first MOVC point)."""
    steps: tuple = (JoinNullLinear(),)
    if arcs_max_sweep_deg is not None:
        steps += (FitArcs(max_sweep_deg=arcs_max_sweep_deg, start_linear=arc_start_linear),)
    return CompoundStep(steps)


def context_for(trajectory, robot, process, plan: MovePlan, levels_mm, min_level_on_surface: int) -> StepContext:
    """The steps' context for a trajectory: its TCP at every waypoint (``robot``'s tool, base
    frame), the process tolerances and the format's blend levels."""
    from .kinematics import Kinematics

    kin = Kinematics(robot)
    linear = bool((plan.kind == KIND_LINEAR).any())
    q = np.asarray(trajectory.q, float)
    P, R = kin.pose(q) if linear else (np.zeros((0, 3)), np.zeros((0, 3, 3)))
    return StepContext(waypoint_P=P, waypoint_R=R, path_tol_mm=float(process.path_tol_mm),
                       ori_tol_deg=float(process.ori_tol_deg), levels_mm=tuple(levels_mm),
                       min_level_on_surface=min_level_on_surface,
                       waypoint_mid_P=_motion_midpoints(kin, trajectory) if linear else np.zeros((0, 3)),
                       waypoint_t=np.asarray(trajectory.t_s, float), closer_s=tuple(process.closer_s))


def _motion_midpoints(kin, trajectory) -> np.ndarray:
    """(W - 1, 3) the planned motion's TCP halfway in time through each step between waypoints (its
    quintic pieces, ``trajectory.quintic_at``); a step of no time: its first waypoint's."""
    from camtool.trajectory import quintic_at

    t = np.asarray(trajectory.t_s, float)
    q = np.asarray(trajectory.q, float)
    if len(t) < 2:
        return np.zeros((0, 3))
    qd = getattr(trajectory, "qd", None)
    if qd is None:
        return kin.pose(0.5 * (q[1:] + q[:-1]))[0]
    k = np.arange(len(t) - 1)
    qm = quintic_at(t, q, np.asarray(qd, float), np.asarray(trajectory.qdd, float), k, 0.5 * (t[1:] + t[:-1]))
    return kin.pose(qm)[0]


def move_lengths_ok(plan: MovePlan) -> bool:
    """True when every circular move of ``plan`` defines a circle (start, circle point and
    target not on one line)."""
    k = np.flatnonzero(plan.kind == KIND_CIRCULAR)
    k = k[k > 0]
    if not len(k):
        return True
    return bool(circle_through(plan.P[k - 1], plan.via_P[k], plan.P[k])[5].all())
