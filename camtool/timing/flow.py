"""Free chains timed as one continuous motion (``timing.zones = "flow"``, the default).

A free chain (self-motion between two runs, approach, depart, a lift connector)
starts and ends at rest, because runs do. With ``zones = "stop"`` every step of
it is a rest-to-rest ruckig move (``ruckig_moves.rest_to_rest_chain``): the tool
stops at every free pose. Here the chain is split at the poses where it must
rest, and every *soft group* between them is one section of ``pathlaw``:

- **Rest poses.** The chain's ends, both ends of every *hard* step, and every
  *corner* of an inserted free move. Hard steps stay rest-to-rest,
  phase-synchronised ruckig moves on the straight joint-space line:
  reconfiguration jumps (a revolute step above ``JUMP_DEG``, or the planner's jump
  flag) and every step into or out of a retract pose (a retract must stay a pure
  lift). A corner is an inserted pose (``path_index`` -1: lift connectors, RRT
  approach and depart) where the joint-space direction turns by more than
  ``CORNER_DEG``: those moves were checked for collisions on their straight
  joint-space edges, so the motion keeps to them there.
- **Soft groups.** A cubic spline through the group's poses, in the chord length
  of the joint steps scaled by the speed limits (``u``, in s); one plateau at the
  highest constant speed every piece allows, or every piece at its own highest
  speed rounded down to a 2^(k/4) level (the shorter of the two is kept), jerk-limited S-curves from and to
  rest, lowered until they fit (``pathlaw.plan_section``); samples at every pose,
  every S-curve phase boundary and every ``FREE_SAMPLE_S``; every Hermite piece
  bounded exactly at 99.5 % of each limit and inside the joint range
  (``pathlaw.time_section``). A group that cannot be so (the spline leaves the
  joint range) falls back to the rest-to-rest chain.
- **Choice.** The chain keeps the flow timing only if it is shorter than the
  rest-to-rest chain (it always was on the sample jobs). Deterministic.

Between poses the joints do not move on the straight joint-space line (they pass
every pose exactly; the spline is checked against the joint range).
"""
from __future__ import annotations

import numpy as np

from .pathlaw import PathSpline, speed_bounds, time_section
from .ruckig_moves import FREE_SAMPLE_S, RuckigMover, rest_to_rest_chain

JUMP_DEG = 20.0          # a revolute step above this between free poses is a reconfiguration jump
CORNER_DEG = 10.0        # an inserted pose where the joint-space direction turns more than this is a rest pose
SPEED_LEVELS_PER_OCTAVE = 4  # per-piece speeds of a soft group: rounded down to 2^(k/4) of the slowest piece
MIN_STEP = 1e-12         # steps shorter than this (a repeated pose) are skipped, as in "stop"


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


def corner_poses(qs: np.ndarray, inserted: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """Per pose of a chain: True for an inserted pose where the step direction turns by more than CORNER_DEG."""
    out = np.zeros(len(qs), bool)
    if len(qs) < 3:
        return out
    d = np.diff(qs, axis=0) / velocity
    n = np.linalg.norm(d, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.einsum("ij,ij->i", d[:-1], d[1:]) / (n[:-1] * n[1:])
    turn = ~(cos >= np.cos(np.radians(CORNER_DEG)))  # nan (a repeated pose) counts as a corner
    out[1:-1] = turn & np.asarray(inserted, bool)[1:-1]
    return out


def _group(qs: np.ndarray, limits, dt_s: float):
    """(t, q, qd, qdd, pose) of one soft group (rest at both ends), or None if it cannot be timed so."""
    d = np.diff(qs, axis=0) / limits.velocity
    u = np.concatenate([[0.0], np.cumsum(np.linalg.norm(d, axis=1))])
    spline = PathSpline(u, qs)
    bound, _, _ = speed_bounds(*spline.piece_bounds(), limits)
    best = None
    # one plateau at the speed every piece allows, or each piece at its own highest speed (faster where
    # the chain's curvature is uneven, e.g. a self-motion arc between two rows): the shorter one is kept
    v_min = float(bound.min())
    levels = v_min * 2.0 ** (np.floor(SPEED_LEVELS_PER_OCTAVE * np.log2(bound / v_min)) / SPEED_LEVELS_PER_OCTAVE)
    candidates = [np.full(len(bound), v_min)] + ([levels] if np.any(levels > v_min) else [])
    for target in candidates:
        try:
            _, smp, _ = time_section(spline, target, limits, fill_s=dt_s)
        except RuntimeError:
            continue
        if best is None or smp.t_s[-1] < best.t_s[-1]:
            best = smp
    if best is None:
        return None
    return best.t_s, best.q, best.qd, best.qdd, best.knot


def flow_chain(mover: RuckigMover, qs: np.ndarray, hard: np.ndarray, rest=None, dt_s: float = FREE_SAMPLE_S):
    """Time a free chain without stopping at its soft poses; same output as ``rest_to_rest_chain``.

    ``hard`` (len(qs) - 1,) marks steps that stay rest-to-rest; ``rest`` (len(qs),)
    optional extra rest poses (corners). Returns (t, q, qd, qdd, pose) with ``pose`` the
    index into ``qs`` of a sample at a pose, else -1; the rest-to-rest chain if that is
    not longer.
    """
    qs = np.asarray(qs, float)
    best = rest_to_rest_chain(mover, qs, dt_s)
    if len(qs) < 3:
        return best
    keep = np.r_[True, np.abs(np.diff(qs, axis=0)).max(axis=1) >= MIN_STEP]
    idx = np.flatnonzero(keep)
    if len(idx) < 3:
        return best
    sub = qs[idx]
    pos = np.cumsum(keep) - 1  # index in sub of the kept pose each original pose equals
    sub_hard = np.zeros(len(idx) - 1, bool)
    for i in np.flatnonzero(np.asarray(hard, bool)):
        if keep[i + 1]:
            sub_hard[pos[i + 1] - 1] = True
    sub_rest = np.zeros(len(idx), bool)
    if rest is not None:
        sub_rest[pos[np.flatnonzero(np.asarray(rest, bool))]] = True
    cut = np.zeros(len(idx), bool)
    cut[[0, -1]] = True
    cut[np.flatnonzero(sub_hard)] = True
    cut[np.flatnonzero(sub_hard) + 1] = True
    cut |= sub_rest
    stops = np.flatnonzero(cut)
    parts, t_now = [], 0.0
    for a, b in zip(stops[:-1], stops[1:]):
        part = None
        if b - a >= 2 or not sub_hard[a:b].any():
            part = _group(sub[a:b + 1], mover.limits, dt_s) if b - a >= 1 else None
        if part is None:  # a hard step, or a group the flow timing cannot take
            part = rest_to_rest_chain(mover, sub[a:b + 1], dt_s)
        t, q, qd, qdd, pose = part
        pose = np.where(pose >= 0, pose + a, -1)
        first = 1 if parts else 0
        parts.append((t_now + t[first:], q[first:], qd[first:], qdd[first:], pose[first:]))
        t_now += float(t[-1])
    t, q, qd, qdd, pose = (np.concatenate([p[k] for p in parts]) for k in range(5))
    if t[-1] >= best[0][-1]:
        return best
    return t, q, qd, qdd, np.where(pose >= 0, idx[np.maximum(pose, 0)], -1)
