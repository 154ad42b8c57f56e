"""The motion check's cell pass: every robot and tool body against the obstacles, the floor and the
robot's own links (the pairs of ``camtool.collision.CollisionWorld``), on the check's samples.

Shared with the planner: only the bodies and pairs (what the cell *is*). The
sampling, the forward kinematics (``fk_batch``; for the few samples of a
simulated program that ``check_sampled_motion`` evaluates, Pinocchio's, one
sample at a time) and the bounds are the check's own.

Conservative advancement. A point of body b moves, over a joint-linear step
dq, by at most sum_j |dq_j| R_jb: R_jb is 1 for a prismatic joint j before b
and, for a revolute one, the chain length from joint j's origin to b's frame
plus b's extent (the farthest point of b from that frame), an upper bound of
the point's distance from j's axis in every configuration. A pair's distance
changes by at most the sum of its two bodies' motions (``C``, cumulated over
the samples). After an exact coal distance d at a sample, the samples whose
bound d - (C[j] - C[k]) stays above both the clearance and the pair's smallest
distance so far (less 1 mm or 10 %) are skipped: none of them can fail or
change the reported minimum by more than that. Between two consecutive samples
the distance is at least (d_a + d_b - m) / 2 (m the motion bound of the step);
where that bound is below the clearance but both ends are not, the step is
bisected (configurations on the same joint-linear motion) until the bound
holds or a failing configuration is found: a thin wall cannot pass between
two samples.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..collision.shapes import BASE, WORLD

MIN_SLACK_MM = 1.0
SLACK_FRACTION = 0.1
MAX_BISECTIONS = 12


@dataclass
class _PairState:
    k: int = -1            # last exactly evaluated sample
    d: float = np.inf      # its distance
    best: float = np.inf
    best_at: float = -1.0  # sample (fractional between samples after a bisection)
    best_points: tuple = ()
    evaluations: int = 0
    fails: list = None


def motion_rates(world) -> np.ndarray:
    """(dof, B) R_jb: the most a point of body b moves per unit of joint j (mm per rad, mm per mm)."""
    from ..collision.shapes import joint_offsets

    robot = world.robot
    dof = robot.dof
    prism = np.asarray(robot.prismatic, bool)
    lo, hi = np.asarray(robot.limits.lower, float), np.asarray(robot.limits.upper, float)
    off = np.array([np.linalg.norm(o) for o in joint_offsets(robot)])
    stroke = np.where(prism, np.maximum(np.abs(lo), np.abs(hi)), 0.0)
    Rjb = np.zeros((dof, len(world.bodies)))
    for b, body in enumerate(world.bodies):
        if body.parent <= BASE:
            continue
        f = body.parent - 1            # the joint (0-based) whose frame carries the body
        ext = body.extent_mm
        for j in range(f + 1):
            Rjb[j, b] = 1.0 if prism[j] else off[j:f].sum() + stroke[j + 1:f + 1].sum() + ext
    return Rjb


BOUND_BLOCK_ROWS = 65536   # rows of q taken at a time by motion_bounds (bounded temporaries)


def motion_bounds(world, q: np.ndarray) -> np.ndarray:
    """(S, B) cumulated motion bound (mm) of each body along the joint-linear motion through the rows of q.

    Summed a block of rows at a time, each block's first step carrying the sum so far: the same
    additions in the same order as one cumulative sum over every step, without (S, dof) temporaries."""
    rates = motion_rates(world)
    S = len(q)
    out = np.zeros((S, rates.shape[1]))
    for a in range(0, S - 1, BOUND_BLOCK_ROWS):
        b = min(a + BOUND_BLOCK_ROWS, S - 1)
        step = np.abs(np.diff(q[a:b + 1], axis=0)) @ rates
        step[0] += out[a]
        np.cumsum(step, axis=0, out=out[a + 1:b + 1])
    return out


def sampled_motion_bounds(world, q_waypoints: np.ndarray, seg: np.ndarray, frac: np.ndarray) -> np.ndarray:
    """(S, B) the same at the samples (waypoint interval ``seg``, fraction ``frac``), from the waypoints alone."""
    W = motion_bounds(world, q_waypoints)
    nxt = np.minimum(seg + 1, len(W) - 1)
    return W[seg] + frac[:, None] * (W[nxt] - W[seg])


def between_rows(rows, S: int):
    """``q_at(x)``: joint values at fractional sample positions x, linear between the rows
    ``rows(k)`` (k an index array into S samples) on either side (the bisection's configurations)."""
    def q_at(x):
        x = np.asarray(x, float)
        k = np.minimum(np.floor(x).astype(np.int64), S - 1)
        qa, qb = rows(k), rows(np.minimum(k + 1, S - 1))
        return qa + (x - k)[:, None] * (qb - qa)
    return q_at


class CellPass:
    """Runs the pairs of a CollisionWorld over the samples, chunk by chunk (module docstring).

    ``feed(start, fkb)`` takes the check's FK of samples start.. (with joint
    frames); ``states()`` the per-pair figures once every sample was fed.
    """

    def __init__(self, world, fk, q_at, C: np.ndarray, clearance_mm: float, track_minimum: bool = True):
        import coal

        self.world, self.fk, self.q_at, self.C = world, fk, q_at, C
        self.track_minimum = track_minimum   # False: only whether a pair comes below the clearance
        self.S = len(C)
        self.thr = float(clearance_mm)
        self.geo = world.geometry
        self.req = coal.DistanceRequest()
        self.res = coal.DistanceResult()
        self._coal = coal
        self.static_T = {}
        for i, b in enumerate(world.bodies):
            if b.parent == WORLD:
                self.static_T[i] = self._tf(b.local_T_mm)
            elif b.parent == BASE:
                self.static_T[i] = self._tf(np.asarray(world.robot.base_T_mm, float) @ b.local_T_mm)
        self._pair_C = [None] * len(world.pairs)   # each pair's bound, made when it is first advanced
        self._states = [_PairState(fails=[]) for _ in world.pairs]
        self._next = [0] * len(world.pairs)
        self.seconds = 0.0

    def _tf(self, T):
        return self._coal.Transform3s(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))

    def _distance_at(self, pair, R, P, best: float):
        """(coal distance, nearest points) of a pair at one configuration's joint frames (R (dof, 3, 3),
        P (dof, 3)); the points only below ``best`` (a new minimum keeps them), else None."""
        tf = []
        for i in (pair.a, pair.b):
            t = self.static_T.get(i)
            if t is None:
                b = self.world.bodies[i]
                f = b.parent - 1
                Rf = R[f]
                t = self._coal.Transform3s(Rf @ b.local_T_mm[:3, :3], P[f] + Rf @ b.local_T_mm[:3, 3])
            tf.append(t)
        self.res.clear()
        d = self._coal.distance(self.geo[pair.a], tf[0], self.geo[pair.b], tf[1], self.req, self.res)
        if d >= best:
            return d, None
        return d, (self.res.getNearestPoint1().copy(), self.res.getNearestPoint2().copy())

    def _evaluated(self, n: int, pair, j: int, frames_at, best: float):
        """``_distance_at`` pair n at sample j (its frames ``frames_at(j)``)."""
        return self._distance_at(pair, *frames_at(j), best)

    def _at_fraction(self, pair, s: float, best: float):
        fkb = self.fk(self.q_at(np.array([s], float)), frames=True)
        return self._distance_at(pair, fkb.joint_R[0], fkb.joint_origins[0], best)

    def feed(self, c0: int, fkb) -> None:
        """Advance every pair through the samples c0 .. c0 + len(fkb.tcp) - 1."""
        R, P = fkb.joint_R, fkb.joint_origins
        self.feed_frames(c0, c0 + len(fkb.tcp), lambda j: (R[j - c0], P[j - c0]))

    def feed_frames(self, c0: int, c1: int, frames_at) -> None:
        """Advance every pair through the samples c0 .. c1 - 1; ``frames_at(j)`` gives sample j's
        joint frames (rotations (dof, 3, 3), origins (dof, 3), mm)."""
        clock = time.perf_counter()
        S, thr = self.S, self.thr
        for n, pair in enumerate(self.world.pairs):
            st, j = self._states[n], self._next[n]
            if j >= c1:
                continue
            cp = self._pair_bound(n)
            while j < c1:
                d, pts = self._evaluated(n, pair, j, frames_at, st.best)
                st.evaluations += 1
                if st.k >= 0 and j > st.k:
                    lb_prev = st.d - (cp[j - 1] - cp[st.k])
                    m = cp[j] - cp[j - 1]
                    if lb_prev >= thr and d >= thr and (lb_prev + d - m) / 2.0 < thr:
                        self._bisect(pair, st, j - 1, j, lb_prev, d, m)
                self._offer(st, j, d, pts)
                st.k, st.d = j, d
                target = max(thr, st.best - max(MIN_SLACK_MM, SLACK_FRACTION * max(st.best, 0.0))) \
                    if self.track_minimum else thr
                if d >= target:
                    j = max(int(cp.searchsorted(cp[j] + d - target, side="right")), j + 1)
                else:
                    j += 1
            self._next[n] = j
            if j >= S:
                self._pair_C[n] = None   # the pair is through every sample: its bound goes
        self.seconds += time.perf_counter() - clock

    def _pair_bound(self, n: int) -> np.ndarray:
        """(S,) pair n's motion bound: its two bodies' cumulated bounds summed."""
        if self._pair_C[n] is None:
            pair = self.world.pairs[n]
            self._pair_C[n] = self.C[:, pair.a] + self.C[:, pair.b]
        return self._pair_C[n]

    def states(self) -> list[_PairState]:
        return self._states

    def _offer(self, st, s, d, pts):
        if d < st.best:
            st.best, st.best_at, st.best_points = float(d), float(s), pts
        if d < self.thr:
            st.fails.append((float(s), float(d)))

    def _bisect(self, pair, st, a, b, da, db, m, depth=0):
        """Between samples (or fractions) a and b, distance bounds da, db, motion bound m."""
        if depth >= MAX_BISECTIONS or (da + db - m) / 2.0 >= self.thr:
            return
        mid = (a + b) / 2.0
        d, pts = self._at_fraction(pair, mid, st.best)
        st.evaluations += 1
        self._offer(st, mid, d, pts)
        if d < self.thr:
            return
        self._bisect(pair, st, a, mid, da, d, m / 2.0, depth + 1)
        self._bisect(pair, st, mid, b, d, db, m / 2.0, depth + 1)


@dataclass(frozen=True)
class SampledCellReport:
    """The cell pass over sampled joint values (a simulated program): the pairs that come closer
    than the threshold, each at its worst sample."""

    threshold_mm: float
    evaluations: int
    seconds: float
    collisions: tuple        # (body a, body b, distance mm, sample (fractional: bisected), nearest points)


def check_sampled_motion(world, q: np.ndarray, threshold_mm: float = 0.0) -> SampledCellReport:
    """Every pair of ``world`` over the joint values ``q`` (S, dof), linear between rows (a
    program sampled at the controller's step): which pairs come below ``threshold_mm``
    (conservative advancement and bisection as above; no search for the minimum). Only the
    samples the advancement lands on are evaluated, so their frames are made one by one."""
    from .fk_batch import BatchFK

    clock = time.perf_counter()
    q = np.asarray(q, float)
    S = len(q)
    fk = BatchFK(world.robot)

    cp = _SampledPass(world, fk, between_rows(lambda k: q[k], S), motion_bounds(world, q), threshold_mm,
                      track_minimum=False)
    cp.measured, cp.q = _measured_in(world), q
    frames = _FramesAt(world.robot, q)
    # a block of samples at a time, every pair through it: the frames of a sample several pairs land on are
    # made once (pair after pair through every sample, the kept frames were gone before the next pair came:
    # the hood's program made 28 k frames for 28 k evaluations). Each pair's evaluations are the same either way
    for c0 in range(0, S, _FramesAt.KEEP):
        frames.forget()
        cp.feed_frames(c0, min(c0 + _FramesAt.KEEP, S), frames)
    collisions = []
    for pair, st in zip(world.pairs, cp.states()):
        if st.fails:   # the closest evaluated sample is the pair's worst
            a, b = world.pair_name(pair)
            collisions.append((a, b, float(st.best), float(st.best_at), st.best_points))
    return SampledCellReport(float(threshold_mm), int(sum(st.evaluations for st in cp.states())),
                             time.perf_counter() - clock, tuple(collisions))


class _FramesAt:
    """Joint frames (world, mm) of single samples, as ``feed_frames`` asks for them: Pinocchio's
    forward kinematics a sample (about 20 us; a batch of every sample would cost more, as the
    advancement evaluates a few in a hundred), the last few kept."""

    KEEP = 4096

    def __init__(self, robot, q):
        from ..robots.joint_frames import joint_frames_mm

        self._frames, self._robot, self._q = joint_frames_mm, robot, q
        self._data = robot.model.createData()
        self._base = np.asarray(robot.base_T_mm, float)
        self._memo: dict = {}

    def forget(self) -> None:
        """Drop the frames kept."""
        self._memo.clear()

    def __call__(self, j: int):
        hit = self._memo.get(j)
        if hit is None:
            if len(self._memo) >= self.KEEP:
                self._memo.clear()
            F = self._base @ self._frames(self._robot, self._q[j], self._data)
            hit = self._memo[j] = (F[:, :3, :3], F[:, :3, 3])
        return hit


# The pair distances measured at sampled joint values of the last world asked: the post stage writes a program
# again closer to the plan (``camtool.program.post``' rounds) and simulates it again; its samples away from the
# stretches written again are the same joint values, whose distances are looked up, not measured again (the same
# numbers: coal's distance of the same shapes at the same frames; 0.7 s of the hood's 0.8 s second pass).
_MEASURED: dict = {"world": None, "distances": {}}
MEASURED_KEEP = 200_000   # distances kept at most (about 100 MB): then the memo starts again


def forget_measured() -> None:
    """Drop the distances kept (the post stage, when a format is done)."""
    _MEASURED["world"], _MEASURED["distances"] = None, {}


def _measured_in(world) -> dict:
    """The distances kept for ``world`` (a new world: none)."""
    if _MEASURED["world"] is not world or len(_MEASURED["distances"]) > MEASURED_KEEP:
        _MEASURED["world"], _MEASURED["distances"] = world, {}
    return _MEASURED["distances"]


class _SampledPass(CellPass):
    """The cell pass over sampled joint values (``check_sampled_motion``): each pair's distance at a sample looked
    up by the sample's exact joint values (``measured``, the rows ``q``) before it is measured."""

    measured: dict
    q: np.ndarray

    def _evaluated(self, n: int, pair, j: int, frames_at, best: float):
        key = (n, self.q[j].tobytes())
        hit = self.measured.get(key)
        if hit is None:   # measured with its nearest points whatever ``best``: a later pass may need them
            hit = self.measured[key] = self._distance_at(pair, *frames_at(j), np.inf)
        d, pts = hit
        return d, (pts if d < best else None)
