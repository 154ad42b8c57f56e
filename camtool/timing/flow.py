"""Free chains timed as one continuous motion (``timing.zones = "flow"``).

A free chain (self-motion between two runs, approach, depart) starts and ends
at rest, because runs do. With ``zones = "stop"`` every step of it is a
rest-to-rest ruckig move (``ruckig_moves.rest_to_rest_chain``): the tool
stops at every free pose. Here the chain's intermediate poses are passed with
a through-velocity instead:

- **Through-velocities.** Each step k gets its shortest cruise time
  ``h_k = max_j |dq_kj| / (0.98 v_j)``; the velocity at an intermediate pose is
  the central finite difference ``(h_r d_l + h_l d_r) / (h_l + h_r)`` of the
  step slopes ``d = dq / h`` (a convex combination of two slopes, each within
  98 % of every speed limit), times a scale c. Poses next to a *hard* step keep
  zero velocity.
- **Hard steps** stay rest-to-rest, phase-synchronised moves on the straight
  joint-space line: reconfiguration jumps (a revolute joint step above
  ``JUMP_DEG``, or the planner's jump flag) and every step into or out of a
  retract pose (a retract must stay a pure lift, never cut a corner).
- **Moves.** Every step is one multi-DOF ruckig state-to-state move (98 %
  limits, time synchronisation, target acceleration 0) from (q_k, V_k) to
  (q_k+1, V_k+1); a step with zero velocity at both ends is the phase-
  synchronised rest-to-rest move of the "stop" timing. Moves are sampled as
  free moves are (every phase boundary plus every 10 ms), the pose itself is
  written exactly, and the whole chain is checked with the exact Hermite
  bounds at 99.5 % of every limit and for its position extrema.
- **Choice.** The scales ``SCALES`` are tried and the chain keeps the shortest
  candidate that passes, the rest-to-rest chain included: a chain is never
  slower than with "stop". Deterministic (no randomness, fixed order).
"""
from __future__ import annotations

import numpy as np
from ruckig import InputParameter, Ruckig, RuckigError
from ruckig import Trajectory as RuckigTrajectory

from ..trajectory import quintic_coefficients
from .ruckig_moves import FREE_SAMPLE_S, RUCKIG_SHARE, RuckigMover, rest_to_rest_chain, sample_move, sample_times

JUMP_DEG = 20.0                    # a revolute step above this between free poses is a reconfiguration jump
SCALES = (1.0, 0.8, 0.6, 0.4, 0.2)  # through-velocity scales tried (the rest-to-rest chain is the fallback)
FLOW_MIN_GAP_S = 1e-4              # phase boundaries of different joints closer than this are merged
V_CAP = 0.995                      # through-velocities stay below this share of ruckig's speed limits
RETRY_SHARES = (0.9, 0.8)          # a candidate that breaks a limit when sampled is retried at these shares
MIN_STEP = 1e-12                   # steps shorter than this (a repeated pose) are skipped, as in "stop"


def hard_steps(qs: np.ndarray, prismatic: np.ndarray, jump_flag=None, retract=None) -> np.ndarray:
    """Per step of a chain (len(qs) - 1): True if it must stay a rest-to-rest move."""
    d = np.abs(np.diff(qs, axis=0))
    rev = ~np.asarray(prismatic, bool)
    hard = (d[:, rev] > np.radians(JUMP_DEG)).any(axis=1) if rev.any() else np.zeros(len(d), bool)
    if jump_flag is not None:
        hard |= np.asarray(jump_flag, bool)[1:]
    if retract is not None:
        r = np.asarray(retract, bool)
        hard |= r[:-1] | r[1:]
    return hard


def _path_speed(h: np.ndarray, limits) -> np.ndarray:
    """Speed ds/dt (<= 1) at every pose of a rest-to-rest, time-optimal 1-DOF move along s.

    s is the chain's cumulative cruise time (``h`` per step, s = time at 98 % of
    the binding speed limit), so ds/dt = 1 is full speed; acceleration and jerk
    of s are bounded by the smallest a/v and j/v ratio over the joints (98 %).
    """
    s = np.concatenate([[0.0], np.cumsum(h)])
    otg, inp, out = Ruckig(1), InputParameter(1), RuckigTrajectory(1)
    inp.max_velocity = [1.0]
    inp.max_acceleration = [float(RUCKIG_SHARE * np.min(limits.acceleration / limits.velocity))]
    inp.max_jerk = [float(RUCKIG_SHARE * np.min(limits.jerk / limits.velocity))]
    inp.current_position, inp.target_position = [0.0], [float(s[-1])]
    otg.calculate(inp, out)
    speed = np.zeros(len(s))
    for k in range(1, len(s) - 1):
        tk = out.get_first_time_at_position(0, float(s[k]))
        if tk is not None:
            speed[k] = out.at_time(float(tk))[1][0]
    return np.clip(speed, 0.0, 1.0)


def through_velocities(qs: np.ndarray, hard: np.ndarray, limits, scale: float) -> np.ndarray:
    """Velocity at every pose of a chain (zero at both ends and next to hard steps); see the module doc."""
    velocity = limits.velocity
    m, dof = qs.shape
    V = np.zeros((m, dof))
    if m < 3:
        return V
    dq = np.diff(qs, axis=0)
    h = np.maximum((np.abs(dq) / (RUCKIG_SHARE * velocity)).max(axis=1), 1e-3)
    d = dq / h[:, None]
    hl, hr = h[:-1, None], h[1:, None]
    V[1:-1] = scale * (hr * d[:-1] + hl * d[1:]) / (hl + hr)
    V *= _path_speed(h, limits)[:, None]
    cap = V_CAP * RUCKIG_SHARE * velocity  # strictly inside ruckig's limits (round-off)
    V = np.clip(V, -cap, cap)
    soft = np.r_[False, ~hard[:-1] & ~hard[1:], False]
    V[~soft] = 0.0
    return V


def _remove_residual(times, q, qd, qdd, q_end, v_end) -> None:
    """Add the quintic from zero to ruckig's end residual (~1e-9) to every sample, in place.

    Overwriting only the last sample would put the residual into the last
    (possibly sub-ms) interval as a large jerk; spread over the move it is
    negligible, and cubic + quintic is still reproduced exactly by the Hermite.
    """
    T = times[-1]
    rq, rv, ra = q_end - q[-1], v_end - qd[-1], -qdd[-1]
    c = quintic_coefficients(np.zeros_like(rq), np.zeros_like(rq), np.zeros_like(rq), rq, rv * T, ra * T * T)
    u = (times / T)[:, None]
    q += c[0] + u * (c[1] + u * (c[2] + u * (c[3] + u * (c[4] + u * c[5]))))
    qd += (c[1] + u * (2 * c[2] + u * (3 * c[3] + u * (4 * c[4] + u * 5 * c[5])))) / T
    qdd += (2 * c[2] + u * (6 * c[3] + u * (12 * c[4] + u * 20 * c[5]))) / (T * T)


def _candidate(mover: RuckigMover, qs: np.ndarray, V: np.ndarray, dt_s: float):
    """One ruckig move per step through (qs, V); (t, q, qd, qdd, pose) or None if a move fails."""
    dof = qs.shape[1]
    out_t, out_q, out_qd, out_qdd, out_pose = [np.zeros(1)], [qs[:1]], [np.zeros((1, dof))], \
        [np.zeros((1, dof))], [np.zeros(1, int)]
    t_now = 0.0
    for k in range(len(qs) - 1):
        rest = not V[k].any() and not V[k + 1].any()
        try:
            traj = mover.move(qs[k], qs[k + 1], v0=V[k], v1=V[k + 1], phase=rest)
        except RuckigError:
            traj = None
        if traj is None or not mover.within_position_limits(traj):
            return None
        times = sample_times(traj, dt_s, min_gap_s=FLOW_MIN_GAP_S)
        q, qd, qdd = sample_move(traj, times)
        _remove_residual(times, q, qd, qdd, qs[k + 1], V[k + 1])
        q[-1], qd[-1], qdd[-1] = qs[k + 1], V[k + 1], 0.0
        pose = np.full(len(times), -1)
        pose[-1] = k + 1
        out_t.append(t_now + times[1:])
        out_q.append(q[1:])
        out_qd.append(qd[1:])
        out_qdd.append(qdd[1:])
        out_pose.append(pose[1:])
        t_now += traj.duration
    return (np.concatenate(out_t), np.concatenate(out_q), np.concatenate(out_qd),
            np.concatenate(out_qdd), np.concatenate(out_pose))


def flow_chain(mover: RuckigMover, qs: np.ndarray, hard: np.ndarray, dt_s: float = FREE_SAMPLE_S):
    """Time a free chain without stopping at its soft intermediate poses; same output as ``rest_to_rest_chain``.

    ``hard`` (len(qs) - 1,) marks steps that stay rest-to-rest. Returns the
    shortest candidate within the limits, the rest-to-rest chain if no
    through-velocity candidate is shorter.
    """
    qs = np.asarray(qs, float)
    best = rest_to_rest_chain(mover, qs, dt_s)
    # repeated poses are skipped (as rest_to_rest_chain does); pose indices refer to qs
    keep = np.r_[True, np.abs(np.diff(qs, axis=0)).max(axis=1) >= MIN_STEP] if len(qs) > 1 else np.ones(1, bool)
    idx = np.flatnonzero(keep)
    if len(idx) < 3:
        return best
    sub = qs[idx]
    # a step between kept poses is hard if any original step it covers is hard
    pos = np.cumsum(keep) - 1  # index in sub of the kept pose each original pose equals
    sub_hard = np.zeros(len(idx) - 1, bool)
    for i in np.flatnonzero(np.asarray(hard, bool)):
        if keep[i + 1]:
            sub_hard[pos[i + 1] - 1] = True
    if sub_hard.all():
        return best
    movers = [mover] + [RuckigMover(mover.limits, RUCKIG_SHARE * f) for f in RETRY_SHARES]
    for scale in SCALES:
        V = through_velocities(sub, sub_hard, mover.limits, scale)
        for m in movers:  # lower limits if a merged phase boundary lets a sample interval break one
            cap = V_CAP * np.asarray(m.inp.max_velocity)
            cand = _candidate(m, sub, np.clip(V, -cap, cap), dt_s)
            if cand is None or cand[0][-1] >= best[0][-1]:
                break
            if not mover.breaks_limits(cand[0], cand[1], cand[2], cand[3]).any():
                pose = cand[4]
                best = (cand[0], cand[1], cand[2], cand[3], np.where(pose >= 0, idx[np.maximum(pose, 0)], -1))
                break
    return best
