"""Program moves from a timed trajectory: what the RAPID and INFORM writers share.

A controller does not replay a trajectory sample by sample: it interpolates
between the targets of its motion instructions (joint-linear for ``MoveAbsJ`` /
``MOVJ``, a straight TCP line for ``MoveL`` / ``MOVL``) and rounds the corners
of moves that carry a zone (``z…``) or a position level (``PL>0``). So the
writers do not write one move per waypoint; ``plan_moves`` picks the waypoints
that become move targets:

- **Anchors** are always targets: the first and last waypoint, the first and
  last point of every work row (where the process switches on and off) and
  every retract pose (and, for linear moves, where straight moves start or
  stop: process zones away from singularities, ``MIN_DEXTERITY``).
- **The planned motion.** A step whose joint-linear chord bows off the planned
  motion by more than ``DENSIFY_SHARE`` of the tolerance gets waypoints on the
  planned motion (the trajectory's quintic pieces).
- **Merging.** Between anchors, a Douglas-Peucker pass keeps the fewest
  waypoints such that the controller's interpolation between consecutive
  targets stays within ``MERGE_SHARE`` of the path tolerance of every planned
  waypoint it skips (``ProcessInfo.path_tol_mm`` on the process zones, that
  times ``FREE_TOL_FACTOR`` in free motion). For joint moves the distance is
  measured in TCP mm, first with each waypoint's TCP Jacobian, then exactly
  (batch forward kinematics); for linear moves it is the TCP's distance from
  the straight line, and the tool orientation's deviation from the slerp
  (``ProcessInfo.ori_tol_deg``). On work a waypoint is also kept where the
  move's single pace would lead or lag the plan by more than ``FEED_LAG_MM``
  (``FeedKeeper``).
- **Blending.** Every target but the first, the last and the top of each
  retract gets the largest blend level (zone radius in mm) whose corner
  rounding stays within ``BLEND_SHARE`` of the tolerance (a chord deviates
  most in the middle of its move, a corner at its target, and between them
  both fall off about quadratically, so the two do not add up). The model is
  the simulator's: a parabolic blend over equal times before and after the
  target, cutting at most r and at most half of either move, so it deviates by
  a quarter of the difference of the two cut vectors. Where even the smallest
  level cuts a corner of the surface too much, the moves beside it are
  shortened (a skipped waypoint, or a point of the planned motion near the
  corner, becomes a target) until it fits.
- **Splitting.** Long programs are split into parts (modules, jobs) only
  after a target off the surface (outside every row), never on it
  (``split_parts``).

Timing is the planned time of each target; the writers turn it into ``\\T``,
VJ or a TCP speed.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camtool.errors import BadInput
from camtool.toolpath import ZONE_CODE

from .kinematics import Kinematics
from .moves import joint_travel  # the controller's zone convention for joint moves

WORK = ZONE_CODE["work"]
RETRACT = ZONE_CODE["retract"]
FREE_ZONES = np.array([ZONE_CODE[z] for z in ("self_motion", "approach", "depart", "retract")])
MERGE_SHARE = 0.6       # share of the tolerance the chords may use
BLEND_SHARE = 0.9       # share of the tolerance a corner may cut: a chord deviates most mid-move, a corner
                        # at its target, and between them both fall off about quadratically
FREE_TOL_FACTOR = 10.0  # free motion (off the surface) may deviate this many path tolerances
JOINT_GUARD = 0.05      # rad (or 50 mm): larger chord deviations in joint space are never linearised
MIN_DEXTERITY = 0.01    # linear moves only where the Jacobian's singular values differ by less than 100x:
                        # nearer a singularity a straight line needs joint speeds that grow without bound.
                        # Above it the simulator runs every linear move through the controller's IK and
                        # checks each joint's speed and limits on 4 ms samples (camtool.simulate), so a row
                        # passing near a wrist singularity stays linear (the irb2400 sphere job: 432 -> 64
                        # moves on work); 0.05 wrote 389 joint moves on its 12 rows that pass near one
KIND_JOINT, KIND_LINEAR, KIND_CIRCULAR = "J", "L", "C"


# --- rows and anchors ---------------------------------------------------------------------------

def runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(first, last) indices of the runs of True in a boolean array."""
    m = np.asarray(mask, bool).astype(np.int8)
    d = np.diff(np.concatenate([[0], m, [0]]))
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1


def anchors(zone: np.ndarray) -> np.ndarray:
    """Waypoints that are always move targets: the ends, the first and last point of every
    work run (where the process switches on and off) and every retract waypoint. Other zone
    changes need none: each skipped waypoint is held to its own zone's tolerance."""
    n = len(zone)
    keep = np.zeros(n, bool)
    keep[0] = keep[-1] = True
    first, last = runs(zone == WORK)
    keep[first] = keep[last] = True
    keep |= zone == RETRACT
    return keep


# --- merging ------------------------------------------------------------------------------------

def simplify(keep: np.ndarray, ratio_fn, max_rounds: int = 200) -> np.ndarray:
    """Douglas-Peucker on index ranges, all segments at once per round.

    ``keep`` marks the anchors; ``ratio_fn(a, b, k)`` gives, for skipped waypoints k
    between kept a and b, their deviation over their tolerance. A segment whose worst
    skipped waypoint has a ratio above 1 is split there. Only the waypoints of segments
    split in the last round are evaluated again. Returns the kept mask.
    """
    keep = np.asarray(keep, bool).copy()
    n = len(keep)
    ratio = np.zeros(n)
    dirty = ~keep
    for _ in range(max_rounds):
        idx = np.flatnonzero(keep)
        kd = np.flatnonzero(dirty & ~keep)
        if len(kd):
            seg = np.searchsorted(idx, kd, side="right") - 1
            ratio[kd] = ratio_fn(idx[seg], idx[seg + 1], kd)
        ratio[keep] = 0.0
        kb = np.flatnonzero(ratio > 1.0)
        if not len(kb):
            break
        sb = np.searchsorted(idx, kb, side="right") - 1
        order = np.lexsort((-ratio[kb], sb))
        _, first = np.unique(sb[order], return_index=True)
        new = kb[order[first]]
        keep[new] = True
        # the waypoints of the split segments are evaluated again
        s_new = np.searchsorted(idx, new, side="right") - 1
        mark = np.zeros(n + 1, int)
        np.add.at(mark, idx[s_new] + 1, 1)
        np.add.at(mark, idx[s_new + 1], -1)
        dirty = np.cumsum(mark[:n]) > 0
    return keep


def segment_max(keep: np.ndarray, ratio_fn) -> np.ndarray:
    """Per kept segment (between consecutive kept waypoints), the largest ratio of its
    skipped waypoints (0 when it skips none); one value per move after the first."""
    idx = np.flatnonzero(keep)
    out = np.zeros(max(len(idx) - 1, 0))
    k = np.flatnonzero(~keep)
    if len(k) and len(idx) > 1:
        seg = np.searchsorted(idx, k, side="right") - 1
        r = ratio_fn(idx[seg], idx[seg + 1], k)
        np.maximum.at(out, seg, r)
    return out


class JointChords:
    """Deviation of joint-linear moves from the planned waypoints they skip (TCP mm)."""

    def __init__(self, kin: Kinematics, q, P, J, tol):
        self.kin, self.q, self.P, self.J, self.tol = kin, q, P, J, tol
        self.scale = np.where(kin.prismatic, 1e-3, 1.0)  # joint-space guard: 1 rad ~ 1000 mm

    def _s(self, a, b, k):
        u = np.einsum("kij,kj->ki", self.J[k], self.q[a] - self.q[k])
        v = np.einsum("kij,kj->ki", self.J[k], self.q[b] - self.q[a])
        vv = np.einsum("ki,ki->k", v, v)
        s = np.clip(-np.einsum("ki,ki->k", u, v) / np.where(vv > 0, vv, 1.0), 0.0, 1.0)
        return s, u, v

    def linear(self, a, b, k):
        s, u, v = self._s(a, b, k)
        dev = np.linalg.norm(u + s[:, None] * v, axis=1)
        off = np.abs((self.q[a] - self.q[k] + s[:, None] * (self.q[b] - self.q[a])) * self.scale).max(axis=1)
        return np.where(off > JOINT_GUARD, np.inf, dev / self.tol[k])

    def exact(self, a, b, k):
        s, _u, _v = self._s(a, b, k)
        x = self.kin.pose(self.q[a] + s[:, None] * (self.q[b] - self.q[a]))[0]
        return np.linalg.norm(x - self.P[k], axis=1) / self.tol[k]


class LinearChords:
    """Deviation of straight TCP moves (position linear, orientation slerp) from the planned
    waypoints they skip: the larger of position over ``tol`` and angle over ``ori_tol``."""

    def __init__(self, P, R, tol, ori_tol_rad):
        self.P, self.R, self.tol, self.ori = P, R, tol, ori_tol_rad

    def __call__(self, a, b, k):
        d = self.P[b] - self.P[a]
        dd = np.einsum("ki,ki->k", d, d)
        s = np.clip(np.einsum("ki,ki->k", self.P[k] - self.P[a], d) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
        pos = np.linalg.norm(self.P[a] + s[:, None] * d - self.P[k], axis=1) / self.tol[k]
        ang = slerp_deviation(self.R[a], self.R[b], self.R[k], s) / self.ori
        return np.maximum(pos, ang)


FEED_LAG_MM = 0.5  # on work, the program's TCP keeps within this distance (along the path) of the plan's


class FeedKeeper:
    """The feed on work. The controller runs a move at one pace (a straight move at one TCP
    speed, a joint move at one joint rate); where the plan changes speed along a row
    (accelerating at a run end) a merged move would run the average. A move may skip a work
    waypoint only while, at the waypoint's planned time, the move has it within
    ``FEED_LAG_MM`` (along the path) of where the plan has it: the plan's speed profile is
    followed as a staircase that never lags or leads by more than that."""

    def __init__(self, P, t, q, work, linear_at=None, lag_mm: float = FEED_LAG_MM):
        step = np.linalg.norm(np.diff(P, axis=0), axis=1)
        self.S = np.r_[0.0, np.cumsum(step)]
        self.P, self.t, self.q = P, t, q
        self.work = work
        self.linear_at = linear_at  # (a, b) -> bool: the move is a straight TCP move
        self.lag = lag_mm

    def ratio(self, a, b, k):
        T = self.t[b] - self.t[a]
        share = np.where(T > 0, (self.t[k] - self.t[a]) / np.where(T > 0, T, 1.0), 0.0)
        L = self.S[b] - self.S[a]
        lag = np.abs(self.S[a] + share * L - self.S[k])  # a straight move: TCP arc length at one speed
        lin = self.linear_at(a, b) if self.linear_at is not None else np.zeros(len(k), bool)
        if (~lin).any():  # a joint move: its joint-space progress at one rate, times its TCP length
            j = ~lin
            d = self.q[b[j]] - self.q[a[j]]
            dd = np.einsum("ki,ki->k", d, d)
            prog = np.einsum("ki,ki->k", self.q[k[j]] - self.q[a[j]], d) / np.where(dd > 0, dd, 1.0)
            lag[j] = np.abs(share[j] - prog) * np.linalg.norm(self.P[b[j]] - self.P[a[j]], axis=1)
        return np.where(self.work[k], lag / self.lag, 0.0)

    def wrap(self, geometric):
        def fn(a, b, k):
            return np.maximum(geometric(a, b, k), self.ratio(a, b, k))
        return fn


def rotvec(R: np.ndarray) -> np.ndarray:
    """Rotation vectors (S, 3) of rotations (S, 3, 3)."""
    from scipy.spatial.transform import Rotation
    return Rotation.from_matrix(R).as_rotvec()


def slerp_deviation(Ra, Rb, Rk, s) -> np.ndarray:
    """Angle (rad) between Rk and the slerp from Ra to Rb at s."""
    from scipy.spatial.transform import Rotation
    rel = Rotation.from_matrix(np.transpose(Ra, (0, 2, 1)) @ Rb).as_rotvec()
    at = Ra @ Rotation.from_rotvec(rel * s[:, None]).as_matrix()
    err = Rotation.from_matrix(np.transpose(at, (0, 2, 1)) @ Rk).magnitude()
    return err


# --- blending -----------------------------------------------------------------------------------


def corner_deviation(m: np.ndarray, d_in: np.ndarray, d_out: np.ndarray) -> np.ndarray:
    """Distance of corner-curve points ``p_k + m`` (C, 3) from the polyline through the
    corner: the rays from ``p_k`` back along the incoming move (``-d_in``) and on along
    the outgoing one (``d_out``); unit directions, or zero for a move that does not move
    the TCP."""
    def ray(v):
        along = np.maximum(np.einsum("ki,ki->k", m, v), 0.0)
        return np.linalg.norm(m - along[:, None] * v, axis=1)
    return np.minimum(ray(-d_in), ray(d_out))


def blend_fractions(r: float, L_in: np.ndarray, L_out: np.ndarray, T_in: np.ndarray,
                    T_out: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Share of the incoming and outgoing move a corner of radius r cuts.

    The corner starts ``tau`` before the target and ends ``tau`` after it, where
    ``tau = min(f_in T_in, f_out T_out)`` with ``f = min(1/2, r / L)`` (a move of length 0
    is cut by half): equal times on both sides, so the speed along the corner goes linearly
    from the incoming move's to the outgoing one's (a parabolic blend). Returns the cut
    shares ``tau / T_in`` and ``tau / T_out``.
    """
    f_in = np.where(L_in > 1e-9, np.minimum(0.5, r / np.maximum(L_in, 1e-9)), 0.5)
    f_out = np.where(L_out > 1e-9, np.minimum(0.5, r / np.maximum(L_out, 1e-9)), 0.5)
    tau = np.minimum(f_in * T_in, f_out * T_out)
    return (np.where(T_in > 0, tau / np.where(T_in > 0, T_in, 1.0), 0.0),
            np.where(T_out > 0, tau / np.where(T_out > 0, T_out, 1.0), 0.0))


def blend_levels(dev_at, C: int, budget, levels_mm) -> np.ndarray:
    """Index of the largest blend level (radius, mm, ascending) whose corner deviation
    ``dev_at(r, sel)`` (mm, for the corners ``sel``) stays within ``budget`` at each of C
    corners, every smaller level fitting too; -1 where even the smallest does not.

    The corner model (``blend_fractions``): from ``g_in`` of the incoming move before the
    target to ``g_out`` of the outgoing one after it the path is a quadratic curve with the
    target as control point; its middle, the point farthest from the corner, lies a
    quarter of ``g_out dq_out - g_in dq_in`` from the target (``corner_deviation``).
    """
    out = np.full(C, -1, int)
    ok = np.ones(C, bool)
    for i, r in enumerate(levels_mm):
        sel = np.flatnonzero(ok)
        if not len(sel):
            break
        good = dev_at(r, sel) <= budget[sel]
        ok[sel[~good]] = False
        out[sel[good]] = i
    return out


# --- the plan -----------------------------------------------------------------------------------

@dataclass
class MovePlan:
    """The moves of a program, one entry per motion instruction, in order.

    ``wp`` waypoint index of each move's target (``wp[0] == 0``: the first move comes
    from wherever the robot is); ``kind`` J (joint) or L (linear); ``t`` planned time at
    the target (s); ``level`` blend level index (-1 = exact stop); ``row`` 0-based work
    row of the move's target when the target lies on the surface (from the row's first
    to its last work point), else -1; ``row_start`` / ``row_end`` the move that reaches
    a row's first / last work point; ``free`` the target lies off the surface (outside
    every row: free motion, leads, retracts; a part may end there); ``deviation_mm`` the
    largest deviation of the skipped waypoints; kind C (``camtool.program.steps.FitArcs``)
    a circular move through ``via_P`` (with ``via_R``, ``via_q``).
    """

    wp: np.ndarray
    kind: np.ndarray
    t: np.ndarray
    level: np.ndarray
    row: np.ndarray
    row_start: np.ndarray
    row_end: np.ndarray
    free: np.ndarray
    deviation_mm: np.ndarray
    P: np.ndarray          # (n, 3) TCP position of each target, base frame
    R: np.ndarray          # (n, 3, 3) TCP rotation of each target, base frame
    q: np.ndarray          # (n, dof) joint values of each target
    rows: int = 0
    via_P: np.ndarray | None = None  # (n, 3) circle point of each circular move (kind C), NaN elsewhere
    via_R: np.ndarray | None = None  # (n, 3, 3) its TCP rotation
    via_q: np.ndarray | None = None  # (n, dof) its joint values

    def __len__(self) -> int:
        return len(self.wp)


def _corner_levels(kin, idx, kind_moves, dev, P, q, J, t, zone, free, tol, levels):
    """Blend level of every corner (targets 1 .. m-2) within what the chords left of the
    tolerance (``blend_levels``, the linearised choice checked exactly); -1 where even the
    smallest level cuts the corner too much. Levels beyond what the moves' halves allow are
    written as the smallest such."""
    m = len(idx)
    c = np.arange(1, m - 1)
    a, k, b = idx[c - 1], idx[c], idx[c + 1]
    L_in = np.linalg.norm(P[k] - P[a], axis=1)
    L_out = np.linalg.norm(P[b] - P[k], axis=1)
    T_in, T_out = t[k] - t[a], t[b] - t[k]
    L_in = np.where(kind_moves[c] == KIND_JOINT, np.maximum(L_in, joint_travel(q[k] - q[a], kin.prismatic)), L_in)
    L_out = np.where(kind_moves[c + 1] == KIND_JOINT, np.maximum(L_out, joint_travel(q[b] - q[k], kin.prismatic)),
                     L_out)
    # a corner next to free motion (the end of a lead-out, ...) is cut off the surface
    corner_tol = np.where((free[a] | free[b]) & (zone[k] != WORK), np.maximum(tol[a], tol[b]), tol[k])
    budget = BLEND_SHARE * corner_tol  # chord and corner deviations peak at different places (see doc)
    lin_corner = (kind_moves[c] == KIND_LINEAR) & (kind_moves[c + 1] == KIND_LINEAR)
    d_in = _unit(P[k] - P[a])
    d_out = _unit(P[b] - P[k])
    dq_in, dq_out = q[k] - q[a], q[b] - q[k]

    def dev_at(r, sel, exact=False):
        f_in, f_out = blend_fractions(r, L_in[sel], L_out[sel], T_in[sel], T_out[sel])
        lc = lin_corner[sel]
        mid = np.empty((len(sel), 3))
        if lc.any():
            s_ = sel[lc]
            mid[lc] = (f_out[lc, None] * (P[b[s_]] - P[k[s_]]) - f_in[lc, None] * (P[k[s_]] - P[a[s_]])) / 4
        if (~lc).any():
            s_ = sel[~lc]
            cut = (f_out[~lc, None] * dq_out[s_] - f_in[~lc, None] * dq_in[s_]) / 4
            if exact:
                mid[~lc] = kin.pose(q[k[s_]] + cut)[0] - P[k[s_]]
            else:
                mid[~lc] = np.einsum("kij,kj->ki", J[k[s_]], cut)
        return corner_deviation(mid, d_in[sel], d_out[sel])

    lv = blend_levels(dev_at, len(c), budget, levels)
    for _ in range(4):  # the linearised choice, checked exactly; one level down where it fails
        sel = np.flatnonzero((lv >= 0) & ~lin_corner)
        if not len(sel):
            break
        radii = levels[lv[sel]]
        devs = np.empty(len(sel))
        for r in np.unique(radii):
            w = radii == r
            devs[w] = dev_at(r, sel[w], exact=True)
        over = sel[devs > budget[sel]]
        if not len(over):
            break
        lv[over] -= 1
    # levels beyond what the moves' halves allow cut the same corner: write the smallest such
    reach = np.maximum(L_in, L_out) / 2
    smallest = np.searchsorted(levels, reach - 1e-9)  # first level at least half the longer move
    return np.where(lv >= 0, np.minimum(lv, smallest), lv)


_MERGED: dict = {}  # the last merge, by trajectory (kept alive here) and settings: formats share it


def _ratios(kin, st: dict, process, linear: bool):
    """(ratio, ratio_exact): the deviation-over-tolerance functions of merged moves for the
    waypoint arrays ``st`` (straight moves between process waypoints where ``st["in_proc"]``,
    joint moves elsewhere)."""
    joint = JointChords(kin, st["q"], st["P"], st["J"], st["merge_tol"])
    if not linear:
        return joint.linear, joint.exact
    in_proc = st["in_proc"]
    lin = LinearChords(st["P"], st["R"], st["merge_tol"], np.radians(process.ori_tol_deg))

    def chooser(joint_fn):
        def ratio(a, b, k):
            r = np.empty(len(k))
            pm = in_proc[a] & in_proc[b]
            if pm.any():
                r[pm] = lin(a[pm], b[pm], k[pm])
            if (~pm).any():
                r[~pm] = joint_fn(a[~pm], b[~pm], k[~pm])
            return r
        return ratio
    return chooser(joint.linear), chooser(joint.exact)


def _state(kin, t, q, qd, qdd, zone, process, linear: bool) -> dict:
    """Waypoint arrays with what merging and blending need (poses, Jacobians, tolerances)."""
    P, R, J = kin.pose_jacobian(q)
    free = np.isin(zone, FREE_ZONES)
    tol = np.where(free, FREE_TOL_FACTOR, 1.0) * float(process.path_tol_mm)
    # straight TCP moves between process waypoints away from singularities (where a straight TCP
    # line can need unbounded joint speeds); joint moves elsewhere
    in_proc = ~free & (kin.dexterity(q) >= MIN_DEXTERITY) if linear else np.zeros(len(t), bool)
    return dict(t=t, q=q, qd=qd, qdd=qdd, zone=zone, P=P, R=R, J=J, free=free, tol=tol,
                merge_tol=MERGE_SHARE * tol, in_proc=in_proc)


def _with_samples(kin, st: dict, steps: np.ndarray, times: np.ndarray, process, linear: bool) -> tuple[dict, np.ndarray]:
    """The arrays with extra waypoints on the planned motion (its quintic pieces) at ``times``
    inside ``steps`` (waypoint k to k+1); returns (new arrays, index of every old waypoint)."""
    t, q = st["t"], st["q"]
    qn, qd_n, qdd_n = hermite(t, q, st["qd"], st["qdd"], steps, times, derivatives=True)
    zone = st["zone"]
    zn = np.where((zone[steps] == zone[steps + 1]) | (zone[steps + 1] == WORK), zone[steps], zone[steps + 1])
    key = np.concatenate([np.arange(len(t)) * 1.0, steps + (times - t[steps]) / np.maximum(t[steps + 1] - t[steps], 1e-12)])
    order = np.argsort(key, kind="stable")
    where_old = np.empty(len(order), int)
    where_old[order] = np.arange(len(order))
    cat = lambda a, b: np.concatenate([a, b])[order]  # noqa: E731
    new = _state(kin, cat(t, times), cat(q, qn), cat(st["qd"], qd_n), cat(st["qdd"], qdd_n), cat(zone, zn),
                 process, linear)
    return new, where_old[:len(t)]


def hermite(t_s, q, qd, qdd, k, tt, derivatives: bool = False):
    """Joint values (and, with ``derivatives``, speeds and accelerations) at times ``tt``
    inside steps ``k`` (waypoint k to k+1) of a timed trajectory (``trajectory.quintic_at``)."""
    from camtool.trajectory import quintic_at

    return quintic_at(t_s, q, qd, qdd, k, tt, derivatives=2 if derivatives else 0)


DENSIFY_SHARE = 0.3  # a chord farther than this share of the tolerance from the planned motion is split
MAX_PIECES = 16


def _bowed_steps(kin, st: dict, linear: bool) -> tuple[np.ndarray, np.ndarray]:
    """(steps, times) of the waypoints to add on the planned motion: a step of joint motion
    whose joint-linear chord is farther than ``DENSIFY_SHARE`` of its tolerance from the
    planned motion at the step's middle gets ``ceil(sqrt(deviation / limit))`` pieces (the
    chord's bow falls with the square). A straight move between two waypoints is the path's
    own chord and needs none."""
    t, q = st["t"], st["q"]
    ok = np.flatnonzero(t[1:] > t[:-1])
    if not len(ok):
        return np.zeros(0, int), np.zeros(0)
    if linear:  # a straight move between two waypoints is the path's own chord: only joint steps bow
        ok = ok[~(st["in_proc"][ok] & st["in_proc"][ok + 1])]
        if not len(ok):
            return np.zeros(0, int), np.zeros(0)
    Pm = kin.pose(hermite(t, q, st["qd"], st["qdd"], ok, (t[ok] + t[ok + 1]) / 2))[0]
    dev = np.linalg.norm(Pm - kin.pose((q[ok] + q[ok + 1]) / 2)[0], axis=1)
    limit = DENSIFY_SHARE * np.maximum(st["tol"][ok], st["tol"][ok + 1])
    pieces = np.where(dev > limit, np.minimum(MAX_PIECES, np.ceil(np.sqrt(dev / limit))), 1).astype(int)
    sel = np.flatnonzero(pieces > 1)
    if not len(sel):
        return np.zeros(0, int), np.zeros(0)
    k = np.repeat(ok[sel], pieces[sel] - 1)
    frac = np.concatenate([np.arange(1, p_) / p_ for p_ in pieces[sel]])
    return k, t[k] + frac * (t[k + 1] - t[k])


def _merged(trajectory, robot, process, linear: bool) -> dict:
    """The waypoints kept by merging (``simplify``) and their arrays, for one trajectory,
    robot and tolerance; the last result is reused (RAPID and INFORM of one run merge the
    same way)."""
    key = (id(trajectory), robot.name, np.asarray(robot.tool_T_mm, float).tobytes(),
           np.asarray(robot.base_T_mm, float).tobytes(), float(process.path_tol_mm), float(process.ori_tol_deg),
           bool(linear))
    if _MERGED.get("key") == key and _MERGED.get("trajectory") is trajectory:
        return _MERGED["value"]
    kin = Kinematics(robot)
    t = np.asarray(trajectory.t_s, float)
    q = np.asarray(trajectory.q, float)
    qd = np.asarray(getattr(trajectory, "qd", np.zeros_like(q)), float)
    qdd = np.asarray(getattr(trajectory, "qdd", np.zeros_like(q)), float)
    st = _state(kin, t, q, qd, qdd, np.asarray(trajectory.zone), process, linear)
    # a step whose joint-linear chord (or straight TCP chord) leaves the planned motion by more than
    # DENSIFY_SHARE of the tolerance at its middle gets waypoints on the planned motion
    steps, times = _bowed_steps(kin, st, linear)
    if len(steps):
        st, where_old = _with_samples(kin, st, steps, times, process, linear)
    else:
        where_old = np.arange(len(t))
    origin = np.full(len(st["t"]), -1)
    origin[where_old] = np.arange(len(t))
    keep = anchors(st["zone"])
    keep[np.flatnonzero(np.diff(st["in_proc"].astype(np.int8)) != 0) + 1] = True  # where the kind changes
    ratio, ratio_exact = _ratios(kin, st, process, linear)
    feed = FeedKeeper(st["P"], st["t"], st["q"], st["zone"] == WORK, lambda a, b: st["in_proc"][a] & st["in_proc"][b])
    keep = simplify(keep, feed.wrap(ratio))
    keep = simplify(keep, feed.wrap(ratio_exact))
    value = dict(kin=kin, st=st, keep=keep, ratio_exact=ratio_exact, origin=origin)
    _MERGED.clear()
    _MERGED.update(key=key, trajectory=trajectory, value=value)
    return value


def plan_moves(trajectory, robot, process, *, linear: bool, levels_mm, min_level_on_surface: int = 0,
               max_level: int | None = None) -> MovePlan:
    """Pick the move targets of a program (see module doc).

    ``linear`` True plans straight TCP moves on the process zones (work, leads) and joint
    moves in free motion; False plans joint moves everywhere. ``levels_mm`` are the
    format's blend radii (ascending, all > 0); a corner on the surface never gets less than
    ``min_level_on_surface`` (never an exact stop there); ``max_level`` caps the level.
    ``wp`` of the plan indexes the trajectory's waypoints, with targets added on the planned
    motion (between waypoints) where a corner needed shorter moves (-1 there).
    """
    m_ = _merged(trajectory, robot, process, linear)
    kin, st, ratio_exact = m_["kin"], m_["st"], m_["ratio_exact"]
    keep = m_["keep"].copy()
    origin = m_["origin"]  # trajectory waypoint of every waypoint (-1: added on the planned motion)
    levels = np.asarray(levels_mm, float)
    rounds = 8
    for round_ in range(rounds + 1):
        t, q, zone, P, J = st["t"], st["q"], st["zone"], st["P"], st["J"]
        first, last = runs(zone == WORK)
        idx = np.flatnonzero(keep)
        # a move is linear when it starts and ends on process waypoints (and is not the first)
        in_proc = st["in_proc"]
        kind_moves = np.where(in_proc[idx] & np.r_[False, in_proc[idx[:-1]]], KIND_LINEAR, KIND_JOINT)
        kind_moves[0] = KIND_JOINT
        m = len(idx)
        dev = np.concatenate([[0.0], segment_max(keep, ratio_exact) * st["merge_tol"][idx[1:]]]) if m > 1 \
            else np.zeros(m)
        level = np.full(m, -1, int)
        if m <= 2:
            break
        lv = _corner_levels(kin, idx, kind_moves, dev, P, q, J, t, zone, st["free"], st["tol"], levels)
        # where even the smallest level a corner must have (on the surface: no stop) cuts it too
        # much, shorter moves flatten it: a skipped waypoint in the middle of each move beside it
        # becomes a target, or, where none is skipped, a point of the planned motion near the corner
        c = np.arange(1, m - 1)
        on_row = np.zeros(m, bool)
        for i0, i1 in zip(np.searchsorted(idx, first), np.searchsorted(idx, last)):
            on_row[i0:i1 + 1] = True
        bad = c[lv < np.where(on_row[c], max(min_level_on_surface, 0), 0)]
        level[c] = lv
        if not len(bad) or round_ == rounds:
            break
        added = False
        steps, times = [], []
        for j in bad:
            for a_, b_, near in ((idx[j - 1], idx[j], idx[j]), (idx[j], idx[j + 1], idx[j])):
                if b_ - a_ > 1:
                    keep[(a_ + b_) // 2] = True
                    added = True
                elif t[b_] > t[a_] and on_row[j]:
                    # a quarter of the move from the corner, on the planned motion
                    steps.append(a_)
                    times.append(t[near] + (0.25 if near == a_ else -0.25) * (t[b_] - t[a_]))
        if steps:
            steps, times = np.array(steps), np.array(times)
            u, i_u = np.unique(times, return_index=True)
            st, where_old = _with_samples(kin, st, steps[i_u], u, process, linear)
            keep_new = np.zeros(len(st["t"]), bool)
            keep_new[where_old[keep]] = True
            keep_new[np.setdiff1d(np.arange(len(keep_new)), where_old)] = True
            origin_new = np.full(len(st["t"]), -1)
            origin_new[where_old] = origin
            keep, origin = keep_new, origin_new
            _ratio, ratio_exact = _ratios(kin, st, process, linear)
            added = True
        if not added:
            break
    t, q, zone, P, R = st["t"], st["q"], st["zone"], st["P"], st["R"]
    first, last = runs(zone == WORK)
    free = st["free"]
    if max_level is not None:
        level = np.minimum(level, max_level)
    # rows: from a row's first to its last work point the tool is on the surface
    row = np.full(m, -1, int)
    row_start = np.zeros(m, bool)
    row_end = np.zeros(m, bool)
    pos_first = np.searchsorted(idx, first)
    pos_last = np.searchsorted(idx, last)
    for r_, (i0, i1) in enumerate(zip(pos_first, pos_last)):
        row[i0:i1 + 1] = r_
        row_start[i0] = True
        row_end[i1] = True
    on_surface = row >= 0
    level[on_surface & (level < min_level_on_surface)] = min_level_on_surface
    level[level < 0] = 0  # never an exact stop but where one is meant (below)
    # exact stops: the first and last move, the top of every retract, and a row of one point (a touch)
    level[0] = -1
    level[-1] = -1
    level[row_start & row_end] = -1
    rz = zone[idx] == RETRACT
    for a0, b0 in zip(*runs(rz)):
        seg = np.arange(a0, b0 + 1)
        start = P[idx[max(a0 - 1, 0)]]
        top = seg[np.argmax(np.linalg.norm(P[idx[seg]] - start, axis=1))]
        level[top] = -1
    return MovePlan(wp=origin[idx], kind=kind_moves, t=t[idx], level=level, row=row, row_start=row_start,
                    row_end=row_end, free=~on_surface, deviation_mm=dev, P=P[idx], R=R[idx],
                    q=q[idx], rows=len(first))


def move_lengths(plan: MovePlan) -> np.ndarray:
    """(n,) TCP path length of each move (mm): its line, or for a circular move its arc; 0 for
    the first (from wherever the robot is)."""
    from .arcs import circle_through

    length = np.r_[0.0, np.linalg.norm(np.diff(plan.P, axis=0), axis=1)]
    circ = np.flatnonzero(np.asarray(plan.kind) == KIND_CIRCULAR)
    circ = circ[circ > 0]
    if len(circ):
        c, rad, n, r0, sweep, ok = circle_through(plan.P[circ - 1], plan.via_P[circ], plan.P[circ])
        length[circ] = np.where(ok, rad * sweep, length[circ])
    return length


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=1, keepdims=True)
    return np.where(n > 1e-9, v / np.maximum(n, 1e-12), 0.0)


def profile_tool(profile) -> np.ndarray:
    """The TCP (4 x 4, mm, flange frame) of a profile's tool: what the program's Cartesian
    targets refer to."""
    from camtool.transforms import matrix_from_xyz_rpy

    return matrix_from_xyz_rpy(profile.tool["tcp_xyz_mm"], profile.tool["tcp_rpy_deg"])


def split_parts(n: int, limit: int, allowed_after: np.ndarray, what: str, where: str) -> list[range]:
    """Split n items into consecutive parts of at most ``limit``, each part (but the last)
    ending on an item after which a split is allowed (``allowed_after[i]``: after item i).

    BadInput naming ``what`` and ``where`` when some stretch between allowed points is longer
    than ``limit``.
    """
    parts, s = [], 0
    allowed = np.flatnonzero(np.asarray(allowed_after, bool))
    while n - s > limit:
        hi = s + limit - 1  # the last item that fits in this part
        cand = allowed[(allowed >= s) & (allowed <= hi)]
        cand = cand[cand < n - 1]
        if not len(cand):
            raise BadInput(f"{where}: more than {limit} {what} between two points off the surface (from item "
                           f"{s + 1}); raise the option or loosen post.path_tol_mm")
        e = int(cand[-1]) + 1
        parts.append(range(s, e))
        s = e
    parts.append(range(s, n))
    return parts


def round_durations(dt: np.ndarray, resolution: float, fastest: np.ndarray | None = None) -> np.ndarray:
    """Durations on a grid of ``resolution`` whose running sum tracks the planned one (error
    diffusion): each written duration is the planned one rounded up or down so that the
    program's clock never drifts by more than one step. ``fastest`` (optional) is the
    shortest duration each move may take (a speed limit); no written value is below it
    (rounded up to the grid), and never below one step."""
    dt = np.asarray(dt, float)
    out = np.empty_like(dt)
    floor_ = np.full(len(dt), resolution) if fastest is None else np.maximum(resolution, fastest)
    planned = 0.0
    written = 0.0
    for i, d in enumerate(dt):
        planned += d
        ticks = round((planned - written) / resolution)
        v = ticks * resolution
        lo = np.ceil(floor_[i] / resolution - 1e-9) * resolution
        v = max(v, lo)
        out[i] = v
        written += v
    return out
