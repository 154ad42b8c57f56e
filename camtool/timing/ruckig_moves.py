"""Rest-to-rest ruckig moves for free chains (surface pieces: ``ruckig_through.py``).

A ruckig profile is piecewise cubic in time (constant jerk per phase). Sampled
at every phase boundary of every joint, each interval between samples is one
cubic per joint, so the quintic Hermite between samples (``Trajectory.sample``)
reproduces the ruckig profile exactly. Extra samples every ``dt_s`` keep the
waypoints dense enough for controllers.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Synchronization
from ruckig import Trajectory as RuckigTrajectory

from ..errors import CamtoolError

MIN_SAMPLE_GAP_S = 2e-4   # boundaries closer than this are merged: Hermite round-off stays << 1 % of a limit
FREE_SAMPLE_S = 0.010     # sample step of free moves
RUCKIG_SHARE = 0.98       # share of each limit given to ruckig


@dataclass(frozen=True)
class AxisCoupling:
    """Controller axes that sum joints (the IRB2400's axis 3 = j2 + j3): ``rows`` (K, dof) of the
    map from joints to those axes, and each axis' speed, acceleration and jerk limits (K,)."""

    rows: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray

    @staticmethod
    def of(robot) -> "AxisCoupling | None":
        """The robot's coupled controller axes, limited as the joints that drive them; None if none."""
        conv = robot.conventions
        if not conv.coupled:
            return None
        k = conv.coupled_axes
        j = np.asarray(conv.axis_joints)[k]
        L = robot.limits
        return AxisCoupling(conv.matrix[k], L.velocity[j], L.acceleration[j], L.jerk[j])

    def factors(self, d: np.ndarray, limits) -> tuple[float, float, float]:
        """For a straight move along d (phase-synchronised: every joint and axis follows one
        profile, scaled by its share of d), the factors (<= 1) on the joints' speed, acceleration
        and jerk limits that keep the coupled axes within theirs too."""
        c = np.abs(self.rows @ d)
        a = np.abs(d)
        out = []
        for joint_lim, axis_lim in ((limits.velocity, self.velocity), (limits.acceleration, self.acceleration),
                                    (limits.jerk, self.jerk)):
            by_joint = np.min(joint_lim[a > 0] / a[a > 0]) if (a > 0).any() else np.inf
            by_axis = np.min(axis_lim[c > 0] / c[c > 0]) if (c > 0).any() else np.inf
            out.append(min(1.0, by_axis / by_joint) if np.isfinite(by_joint) else 1.0)
        return out[0], out[1], out[2]

    def independent_factors(self, limits) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per-joint factors (<= 1) for moves whose joints move independently (time-synchronised):
        the joints of a coupled axis share its limit in proportion to their own (the IRB2400's j2
        and j3 at half speed each), so the axis stays within it whatever their signs."""
        out = []
        for joint_lim, axis_lim in ((limits.velocity, self.velocity), (limits.acceleration, self.acceleration),
                                    (limits.jerk, self.jerk)):
            f = np.ones(len(joint_lim))
            for row, lim in zip(self.rows, axis_lim):
                on = row != 0
                f[on] = np.minimum(f[on], min(1.0, lim / float(np.sum(np.abs(row[on]) * joint_lim[on]))))
            out.append(f)
        return out[0], out[1], out[2]


class RuckigMover:
    """Reusable ruckig instance for one robot's dof and limits (scaled by ``share``); with a
    ``coupling``, phase-synchronised moves keep the coupled controller axes within their limits."""

    def __init__(self, limits, share: float = RUCKIG_SHARE, coupling: AxisCoupling | None = None):
        self.dof = len(limits.velocity)
        self.otg = Ruckig(self.dof)
        self.inp = InputParameter(self.dof)
        self.traj = RuckigTrajectory(self.dof)
        self.share = share
        self.inp.max_velocity = list(share * limits.velocity)
        self.inp.max_acceleration = list(share * limits.acceleration)
        self.inp.max_jerk = list(share * limits.jerk)
        self.limits = limits
        self.coupling = coupling
        self.lower = limits.lower
        self.upper = limits.upper

    def breaks_limits(self, t, q, qd, qdd, share: float = 0.995) -> np.ndarray:
        """Per interval of consecutive samples: True if its quintic Hermite passes ``share`` of a limit."""
        from .quintic import limit_ratio, piece_peaks

        if len(t) < 2:
            return np.zeros(0, bool)
        L = self.limits
        pk = piece_peaks(q[:-1], q[1:], qd[:-1], qd[1:], qdd[:-1], qdd[1:], np.diff(t), L.lower, L.upper)
        return (limit_ratio(pk, L.velocity, L.acceleration, L.jerk, share) > 1.0) | pk.position_break.any(axis=1)

    def move(self, q0, q1, v0=None, v1=None, a0=None, a1=None, min_duration_s: float | None = None,
             phase: bool = False) -> RuckigTrajectory | None:
        """Time-optimal (or at least ``min_duration_s``) move between two states; None on failure."""
        z = [0.0] * self.dof
        inp = self.inp
        inp.current_position = list(q0)
        inp.target_position = list(q1)
        inp.current_velocity = z if v0 is None else list(v0)
        inp.target_velocity = z if v1 is None else list(v1)
        inp.current_acceleration = z if a0 is None else list(a0)
        inp.target_acceleration = z if a1 is None else list(a1)
        inp.synchronization = Synchronization.Phase if phase else Synchronization.Time
        inp.minimum_duration = min_duration_s
        if self.coupling is not None:
            L, c = self.limits, self.coupling
            f = c.factors(np.asarray(q1, float) - np.asarray(q0, float), L) if phase else c.independent_factors(L)
            inp.max_velocity = list(self.share * f[0] * L.velocity)
            inp.max_acceleration = list(self.share * f[1] * L.acceleration)
            inp.max_jerk = list(self.share * f[2] * L.jerk)
        try:
            result = self.otg.calculate(inp, self.traj)
        except RuntimeError:
            return None
        if result not in (Result.Working, Result.Finished):
            return None
        return self.traj

    def within_position_limits(self, traj: RuckigTrajectory) -> bool:
        """True if the move's position extrema stay inside the joint limits."""
        ext = traj.position_extrema
        return all(self.lower[i] <= ext[i].min and ext[i].max <= self.upper[i] for i in range(self.dof))


def sample_times(traj: RuckigTrajectory, dt_s: float | None, extra=(), min_gap_s: float = MIN_SAMPLE_GAP_S) -> np.ndarray:
    """Sample times of a ruckig move: phase boundaries, optional grid, extra times, and both ends."""
    T = traj.duration
    bounds = [0.0, T]
    for prof in traj.profiles[0]:
        t0 = prof.brake.duration  # zero when starting within the limits, as all our moves do
        bounds.append(t0)
        bounds.extend(t0 + np.cumsum(prof.t))
    bounds.extend(extra)
    b = np.unique(np.clip(np.asarray(bounds, float), 0.0, T))
    keep = [b[0]]
    for x in b[1:]:
        if x - keep[-1] >= min_gap_s:
            keep.append(x)
    if T - keep[-1] < min_gap_s and len(keep) > 1:
        keep[-1] = T
    elif keep[-1] != T:
        keep.append(T)
    b = np.asarray(keep)
    if dt_s:
        grid = np.arange(dt_s, T, dt_s)
        near = np.abs(grid[:, None] - b[None, :]).min(axis=1) < MIN_SAMPLE_GAP_S if len(grid) else []
        b = np.union1d(b, grid[~np.asarray(near, bool)]) if len(grid) else b
    return b


def sample_move(traj: RuckigTrajectory, times: np.ndarray):
    """(q, qd, qdd) of a ruckig move at ``times`` (s from the move start)."""
    n = len(times)
    dof = traj.degrees_of_freedom
    q = np.empty((n, dof))
    qd = np.empty((n, dof))
    qdd = np.empty((n, dof))
    for i, t in enumerate(times):
        p, v, a = traj.at_time(float(t))[:3]
        q[i], qd[i], qdd[i] = p, v, a
    return q, qd, qdd


def rest_to_rest_chain(mover: RuckigMover, qs: np.ndarray, dt_s: float = FREE_SAMPLE_S):
    """``_chain`` with a check of the sampled pieces; retried with lower ruckig limits if needed."""
    share = RUCKIG_SHARE
    for _ in range(6):
        out = _chain(mover if share == RUCKIG_SHARE else RuckigMover(mover.limits, share, mover.coupling), qs, dt_s)
        if not mover.breaks_limits(out[0], out[1], out[2], out[3]).any():
            return out
        share *= 0.9
    raise CamtoolError("ruckig moves between free poses could not be sampled within the joint limits")


def _chain(mover: RuckigMover, qs: np.ndarray, dt_s: float):
    """Time a chain of poses with a rest-to-rest, phase-synchronised ruckig move per step.

    Phase synchronisation makes every joint follow the same profile shape, so
    each step runs on the straight joint-space line between its two poses (and
    so stays inside the joint box). Consecutive steps in the same direction are
    merged into one move that passes through the middle poses. Returns
    (t, q, qd, qdd, pose_of_sample) with ``pose_of_sample`` = index into ``qs``
    or -1 for in-between samples.
    """
    qs = np.asarray(qs, float)
    out_t, out_q, out_qd, out_qdd, out_pose = [np.zeros(1)], [qs[:1]], [np.zeros((1, qs.shape[1]))], \
        [np.zeros((1, qs.shape[1]))], [np.zeros(1, int)]
    t_now = 0.0
    i = 0
    m = len(qs)
    while i < m - 1:
        d = qs[i + 1] - qs[i]
        if np.max(np.abs(d)) < 1e-12:
            i += 1
            continue
        j = i + 1
        u = d / np.linalg.norm(d)
        while j < m - 1:  # merge following steps along the same direction
            d2 = qs[j + 1] - qs[j]
            n2 = np.linalg.norm(d2)
            if n2 < 1e-12 or np.dot(d2 / n2, u) < 1 - 1e-10:
                break
            j += 1
        traj = mover.move(qs[i], qs[j], phase=True)
        if traj is None:
            raise CamtoolError(f"ruckig could not time the move between free poses {i} and {j}")
        big = int(np.argmax(np.abs(qs[j] - qs[i])))
        mids = {}
        for k in range(i + 1, j):
            tk = traj.get_first_time_at_position(big, float(qs[k, big]))
            if tk is not None:
                mids[float(tk)] = k
        times = sample_times(traj, dt_s, extra=list(mids))
        q, qd, qdd = sample_move(traj, times)
        q[-1], qd[-1], qdd[-1] = qs[j], 0.0, 0.0
        pose = np.full(len(times), -1)
        pose[-1] = j
        for tk, k in mids.items():
            hit = np.nonzero(np.abs(times - tk) < 1e-12)[0]
            pose[hit] = k
        out_t.append(t_now + times[1:])
        out_q.append(q[1:])
        out_qd.append(qd[1:])
        out_qdd.append(qdd[1:])
        out_pose.append(pose[1:])
        t_now += traj.duration
        i = j
    return (np.concatenate(out_t), np.concatenate(out_q), np.concatenate(out_qd),
            np.concatenate(out_qdd), np.concatenate(out_pose))
