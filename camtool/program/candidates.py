"""The waypoints a program's targets are picked from, and the ordered steps that pick them.

``Candidates`` holds the timed trajectory's waypoints with what merging needs (TCP poses,
Jacobians, zones, tolerances, which are straight process moves) and the picked ones
(``keep``). Each ``CandidateStep`` returns new candidates; ``candidate_steps()`` runs them
in order (``camtool.program.plan`` module doc says why each exists):

1. ``AddPlannedPoints``: a step whose joint-linear chord bows off the planned motion by more
   than ``DENSIFY_SHARE`` of the tolerance gets points of the planned motion (its quintic pieces).
2. ``MarkAnchors``: the ends, every work row's first and last point, every retract waypoint and
   where the move kind changes are always targets.
3. ``MergeChords``: Douglas-Peucker keeps the fewest waypoints such that the controller's
   interpolation stays within ``MERGE_SHARE`` of the tolerance of every waypoint it skips (by
   each waypoint's Jacobian, then exactly), and, on work, the feed within ``FEED_LAG_MM``; where the
   targets state joints the controller moves linearly in a straight move (a 7th axis, a track), straight
   moves also keep the joints it solves near the plan's (``HeldJointChords``).

``merged_candidates`` runs the three for a trajectory and keeps the last result: the RAPID
and INFORM programs of one run are merged once.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, replace

import numpy as np

from camtool.path.toolpath import ZONE_CODE

from .kinematics import Kinematics

WORK = ZONE_CODE["work"]
RETRACT = ZONE_CODE["retract"]
FREE_ZONES = np.array([ZONE_CODE[z] for z in ("self_motion", "approach", "depart", "retract")])
MERGE_SHARE = 0.6       # share of the tolerance the chords may use
FREE_TOL_FACTOR = 10.0  # free motion (off the surface) may deviate this many path tolerances
JOINT_GUARD = 0.05      # rad (or 50 mm): larger chord deviations in joint space are never linearised
MIN_DEXTERITY = 0.01    # linear moves only where the Jacobian's singular values differ by less than 100x:
                        # nearer a singularity a straight line needs joint speeds that grow without bound.
                        # Above it the simulator runs every linear move through the controller's IK and
                        # checks each joint's speed and limits on 4 ms samples (camtool.simulate), so a row
                        # passing near a wrist singularity stays linear (the irb2400 sphere job: 432 -> 64
                        # moves on work); 0.05 wrote 389 joint moves on its 12 rows that pass near one


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


HELD_JOINT_GUARD = 0.05  # rad (or 50 mm): how far a straight move may take the joints the controller solves
                         # from the plan's, where the targets state joints it moves linearly (issue #48)


class HeldJointChords:
    """Straight moves of a robot whose Cartesian targets also state some joints (``held``: the SIA20D's
    E axis on INFORM's ``Re``, the seed arm's track and 7th joint on RAPID's ``eax``). The controller
    moves those joints linearly from target to target, by the move's share of its line, and solves
    the others for the TCP pose; so a skipped waypoint where the plan has the held joints elsewhere is
    reached with the other joints moved by ``-pinv(J_free) J_held dq_held`` (first order). Near a
    wrist singularity a few degrees of the E axis turn the wrist by tens of degrees, or no solution
    is left. The ratio is the largest such move over ``HELD_JOINT_GUARD`` (inf where the free joints'
    Jacobian is singular)."""

    def __init__(self, kin: Kinematics, q, P, held):
        self.kin, self.q, self.P = kin, q, P
        self.held = np.asarray(held, bool)
        self.scale = np.where(kin.prismatic, 1e-3, 1.0)[~self.held]  # 1 rad ~ 1000 mm, as JointChords
        self._J: np.ndarray | None = None          # (S, 6, dof) each waypoint's weighted Jacobian, once asked
        self._made = np.zeros(len(q), bool)

    def _jacobians(self, k: np.ndarray) -> np.ndarray:
        """The waypoints' TCP Jacobians, the angular rows times 1000 (1 rad of the tool's orientation weighs
        like 1000 mm): each made once, the first time Douglas-Peucker asks for it (the new ones in one batch)."""
        new = np.unique(k[~self._made[k]])
        if len(new):
            if self._J is None:
                self._J = np.empty((len(self.q), 6, self.q.shape[1]))
            J = self.kin.jacobian6(self.q[new])
            J[:, 3:] *= 1000.0
            self._J[new] = J
            self._made[new] = True
        return self._J[k]

    def __call__(self, a, b, k):
        d = self.P[b] - self.P[a]
        dd = np.einsum("ki,ki->k", d, d)
        s = np.clip(np.einsum("ki,ki->k", self.P[k] - self.P[a], d) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
        h, q = self.held, self.q
        dh = q[a][:, h] + s[:, None] * (q[b][:, h] - q[a][:, h]) - q[k][:, h]
        J = self._jacobians(k)
        rhs = -np.einsum("kij,kj->ki", J[:, :, h], dh)
        U, sv, Vt = np.linalg.svd(J[:, :, ~h], full_matrices=False)
        ok = sv[:, -1] > 1e-9 * np.maximum(sv[:, 0], 1e-300)
        inv = np.where(ok[:, None], 1.0 / np.where(sv > 0, sv, 1.0), 0.0)
        dq = np.einsum("kji,kj->ki", Vt, inv * np.einsum("kji,kj->ki", U, rhs))
        ratio = np.abs(dq * self.scale).max(axis=1) / HELD_JOINT_GUARD
        return np.where(ok, ratio, np.inf)


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


def slerp_deviation(Ra, Rb, Rk, s) -> np.ndarray:
    """Angle (rad) between Rk and the slerp from Ra to Rb at s."""
    from scipy.spatial.transform import Rotation
    rel = Rotation.from_matrix(np.transpose(Ra, (0, 2, 1)) @ Rb).as_rotvec()
    at = Ra @ Rotation.from_rotvec(rel * s[:, None]).as_matrix()
    err = Rotation.from_matrix(np.transpose(at, (0, 2, 1)) @ Rk).magnitude()
    return err


# --- the waypoint arrays ------------------------------------------------------------------------

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


def _held_ratio(st: dict, held_fn, geometric):
    """``geometric`` with, on straight moves (both ends in ``st["in_proc"]``), the larger of it and
    ``held_fn`` (``HeldJointChords``); ``geometric`` alone without held joints."""
    if held_fn is None:
        return geometric
    in_proc = st["in_proc"]

    def ratio(a, b, k):
        r = geometric(a, b, k)
        pm = in_proc[a] & in_proc[b]
        if pm.any():
            r[pm] = np.maximum(r[pm], held_fn(a[pm], b[pm], k[pm]))
        return r
    return ratio


STATE_BLOCK_ROWS = 32768   # waypoints whose poses and Jacobians are made at a time (bounded temporaries)


def _state(kin, t, q, qd, qdd, zone, process, linear: bool) -> dict:
    """Waypoint arrays with what merging and blending need (poses, Jacobians, tolerances).

    Poses, Jacobians and dexterity are each waypoint's own, made ``STATE_BLOCK_ROWS`` at a time:
    the kinematics' (S, dof, 3) temporaries of a dense job's 180k waypoints would be hundreds of MB."""
    S, dof = np.shape(q)
    P, R, J, dexterous = np.empty((S, 3)), np.empty((S, 3, 3)), np.empty((S, 3, dof)), np.zeros(S, bool)
    for a in range(0, S, STATE_BLOCK_ROWS):
        rows = slice(a, a + STATE_BLOCK_ROWS)
        P[rows], R[rows], J[rows] = kin.pose_jacobian(q[rows])
        if linear:
            dexterous[rows] = kin.dexterity(q[rows]) >= MIN_DEXTERITY
    free = np.isin(zone, FREE_ZONES)
    # within the spans the post stage writes closer to the plan (``ProcessInfo.closer_s``), a share of it
    tol = np.where(free, FREE_TOL_FACTOR, 1.0) * float(process.path_tol_mm) * span_shares(t, process.closer_s)
    # straight TCP moves between process waypoints away from singularities (where a straight TCP
    # line can need unbounded joint speeds) and outside the spans the post stage asks joint moves for;
    # joint moves elsewhere
    in_proc = ~free & dexterous & ~in_spans(t, process.joint_moves_s) if linear \
        else np.zeros(len(t), bool)
    return dict(t=t, q=q, qd=qd, qdd=qdd, zone=zone, P=P, R=R, J=J, free=free, tol=tol,
                merge_tol=MERGE_SHARE * tol, in_proc=in_proc)


SPAN_SLACK_S = 0.005  # a span's ends take the waypoints this near (the program's clock against the plan's)


def in_spans(t: np.ndarray, spans) -> np.ndarray:
    """(len(t),) True for the times ``t`` (s; measured from ``t[0]``) inside any (start, end) span,
    within ``SPAN_SLACK_S``."""
    t = np.asarray(t, float)
    out = np.zeros(len(t), bool)
    if len(t):
        tt = t - t[0]
        for a, b in spans:
            out |= (tt >= a - SPAN_SLACK_S) & (tt <= b + SPAN_SLACK_S)
    return out


def span_shares(t: np.ndarray, spans) -> np.ndarray:
    """(len(t),) the share of the tolerance at the times ``t`` (s; measured from ``t[0]``): the smallest
    share of the (start, end, share) ``spans`` holding each (within ``SPAN_SLACK_S``), 1 outside them."""
    t = np.asarray(t, float)
    out = np.ones(len(t))
    if len(t):
        tt = t - t[0]
        for a, b, share in spans:
            inside = (tt >= a - SPAN_SLACK_S) & (tt <= b + SPAN_SLACK_S)
            out[inside] = np.minimum(out[inside], share)
    return out


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


# --- the candidates and their steps -------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class Candidates:
    """Waypoints to pick move targets from: the trajectory's and points of its planned motion
    (``origin`` -1; else the trajectory waypoint), their arrays ``st`` (``_state``), the picked
    ones (``keep``) and the exact chord deviation over tolerance of merged moves (``ratio_exact``)."""

    kin: Kinematics
    process: object
    linear: bool
    st: dict
    keep: np.ndarray
    origin: np.ndarray
    ratio_exact: object = None
    held: tuple = ()

    @classmethod
    def from_trajectory(cls, trajectory, robot, process, linear: bool, held=()) -> "Candidates":
        """Every waypoint of a timed trajectory, none picked yet (``held``: the joints a Cartesian
        target states, by index, ``HeldJointChords``)."""
        kin = Kinematics(robot)
        t = np.asarray(trajectory.t_s, float)
        q = np.asarray(trajectory.q, float)
        qd = np.asarray(getattr(trajectory, "qd", np.zeros_like(q)), float)
        qdd = np.asarray(getattr(trajectory, "qdd", np.zeros_like(q)), float)
        st = _state(kin, t, q, qd, qdd, np.asarray(trajectory.zone), process, linear)
        return cls(kin, process, bool(linear), st, np.zeros(len(t), bool), np.arange(len(t)), held=tuple(held))

    def __len__(self) -> int:
        return len(self.st["t"])

    def held_mask(self) -> np.ndarray:
        """(dof,) True for the joints a Cartesian target states (``held``)."""
        mask = np.zeros(self.kin.dof, bool)
        mask[list(self.held)] = True
        return mask

    def with_points(self, steps: np.ndarray, times: np.ndarray, picked: bool) -> "Candidates":
        """These candidates with points of the planned motion at ``times`` inside ``steps``
        (waypoint k to k+1), picked or not; the chords' deviations measured again."""
        st, where_old = _with_samples(self.kin, self.st, steps, times, self.process, self.linear)
        keep = np.full(len(st["t"]), bool(picked))
        keep[where_old] = self.keep
        origin = np.full(len(st["t"]), -1)
        origin[where_old] = self.origin
        ratio_exact = None if self.ratio_exact is None else _ratios(self.kin, st, self.process, self.linear)[1]
        return replace(self, st=st, keep=keep, origin=origin, ratio_exact=ratio_exact)


class CandidateStep(ABC):
    """One step on the candidates: ``apply(c)`` returns new ``Candidates``."""

    @abstractmethod
    def apply(self, c: Candidates) -> Candidates:
        """The candidates after this step."""


@dataclass(frozen=True)
class AddPlannedPoints(CandidateStep):
    """Points of the planned motion where a joint-linear chord bows off it (``_bowed_steps``)."""

    def apply(self, c: Candidates) -> Candidates:
        steps, times = _bowed_steps(c.kin, c.st, c.linear)
        return c.with_points(steps, times, picked=False) if len(steps) else c


@dataclass(frozen=True)
class MarkAnchors(CandidateStep):
    """The waypoints that are always targets (``anchors``) and where the move kind changes."""

    def apply(self, c: Candidates) -> Candidates:
        keep = c.keep | anchors(c.st["zone"])
        keep[np.flatnonzero(np.diff(c.st["in_proc"].astype(np.int8)) != 0) + 1] = True
        return replace(c, keep=keep)


@dataclass(frozen=True)
class MergeChords(CandidateStep):
    """Douglas-Peucker within the tolerances and the feed (``simplify``, ``FeedKeeper``): by each
    waypoint's Jacobian first, then exactly."""

    def apply(self, c: Candidates) -> Candidates:
        st = c.st
        ratio, ratio_exact = _ratios(c.kin, st, c.process, c.linear)
        feed = FeedKeeper(st["P"], st["t"], st["q"], st["zone"] == WORK,
                          lambda a, b: st["in_proc"][a] & st["in_proc"][b])
        held = HeldJointChords(c.kin, st["q"], st["P"], c.held_mask()) if c.linear and c.held else None
        keep = simplify(c.keep, feed.wrap(_held_ratio(st, held, ratio)))
        keep = simplify(keep, feed.wrap(_held_ratio(st, held, ratio_exact)))
        return replace(c, keep=keep, ratio_exact=ratio_exact)


@dataclass(frozen=True)
class CompoundCandidateStep(CandidateStep):
    """Candidate steps run in order."""

    steps: tuple

    def apply(self, c: Candidates) -> Candidates:
        for step in self.steps:
            c = step.apply(c)
        return c


def candidate_steps() -> CompoundCandidateStep:
    """The steps from a trajectory's waypoints to the merged targets, in order."""
    return CompoundCandidateStep((AddPlannedPoints(), MarkAnchors(), MergeChords()))


_MERGED: dict = {}  # the last merge, by trajectory (kept alive here) and settings: formats share it


def forget_merged() -> None:
    """Drop the last merge and the trajectory it holds (the post stage, when every format is done)."""
    _MERGED.clear()


def merged_candidates(trajectory, robot, process, linear: bool, held=()) -> Candidates:
    """``candidate_steps()`` on a trajectory's waypoints; the last result is reused (RAPID and
    INFORM of one run merge the same way). ``held``: the joints (indices) a Cartesian target
    states, which the controller moves linearly in a straight move (``HeldJointChords``)."""
    held = tuple(int(i) for i in held)
    key = (id(trajectory), robot.name, np.asarray(robot.tool_T_mm, float).tobytes(),
           np.asarray(robot.base_T_mm, float).tobytes(), float(process.path_tol_mm), float(process.ori_tol_deg),
           bool(linear), held, tuple(process.joint_moves_s), tuple(process.closer_s))
    if _MERGED.get("key") == key and _MERGED.get("trajectory") is trajectory:
        return _MERGED["value"]
    value = candidate_steps().apply(Candidates.from_trajectory(trajectory, robot, process, linear, held))
    _MERGED.clear()
    _MERGED.update(key=key, trajectory=trajectory, value=value)
    return value
