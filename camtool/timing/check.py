"""Independent limit checker: only the Trajectory and the robot's limits are used.

It does not import any of the timing code; it resamples the trajectory with
``camtool.trajectory.sample_blocks`` (the quintic Hermite pieces a controller
would run), a block of waypoints at a time, or takes such samples ready-made,
and compares every joint's position, speed, acceleration and jerk to the
robot's limits. Findings are one line each, in user units (deg or mm, per s^k).
A pass finds nothing in bounded memory; only when a block breaks a limit is the
whole trajectory sampled at once, so that each finding spans its whole interval.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..trajectory import Trajectory, TrajectorySamples, sample_blocks, sample_trajectory

REL_TOL = 1e-9               # relative slack for round-off
MAX_LINES_PER_KIND = 20      # findings per joint and quantity before summarising

_KINDS = ("speed", "acceleration", "jerk")


def _unit(prismatic: bool, order: int) -> str:
    base = "mm" if prismatic else "deg"
    return base + ("", "/s", "/s^2", "/s^3")[order]


def _user(x, prismatic: bool):
    return x if prismatic else np.degrees(x)


def _intervals(bad: np.ndarray):
    """(start, stop) index pairs of runs of True in a 1-D bool array."""
    if not bad.any():
        return []
    d = np.diff(np.concatenate([[0], bad.astype(np.int8), [0]]))
    return list(zip(np.nonzero(d == 1)[0], np.nonzero(d == -1)[0]))


def _beyond(values, limit, lower=None) -> np.ndarray:
    """Where ``values`` break ``limit``: |values| above it, or with ``lower`` outside [lower, limit]; a
    relative slack of ``REL_TOL`` absorbs round-off (the one rule of the lines and of ``_breaks``)."""
    if lower is None:
        return np.abs(values) > limit + REL_TOL * (1.0 + np.abs(limit))
    return (values < lower - REL_TOL * (1.0 + np.abs(lower))) | (values > limit + REL_TOL * (1.0 + np.abs(limit)))


def _limit_lines(name, prismatic, t, values, limit, kind, order, lower=None):
    """Finding lines for one joint and one quantity (peak of each violating interval)."""
    bad = _beyond(values, limit, lower)
    lines = []
    spans = _intervals(bad)
    for a, b in spans[:MAX_LINES_PER_KIND]:
        seg = values[a:b]
        if lower is None:
            k = a + int(np.argmax(np.abs(seg)))
            what = f"|{kind}| {_user(abs(values[k]), prismatic):.6g} {_unit(prismatic, order)} exceeds the limit " \
                   f"{_user(limit, prismatic):.6g} {_unit(prismatic, order)}"
        else:
            k = a + int(np.argmax(np.maximum(lower - seg, seg - limit)))
            what = f"position {_user(values[k], prismatic):.6g} {_unit(prismatic, 0)} is outside " \
                   f"[{_user(lower, prismatic):.6g}, {_user(limit, prismatic):.6g}] {_unit(prismatic, 0)}"
        lines.append(f"joint {name}: {what} at t = {t[k]:.4f} s")
    if len(spans) > MAX_LINES_PER_KIND:
        lines.append(f"joint {name}: {kind} limit also broken in {len(spans) - MAX_LINES_PER_KIND} more intervals")
    return lines


def _breaks(robot, q, qd, qdd, qddd) -> bool:
    """True if any row of these joint values (waypoints, or a block of samples; no jerk: None) breaks a
    limit that ``_limit_lines`` (and, for coupled controller axes, ``_coupled_axis_speeds``) would report."""
    L = robot.limits
    if _beyond(q, L.upper, L.lower).any():
        return True
    if any(_beyond(x, limit).any() for x, limit in ((qd, L.velocity), (qdd, L.acceleration), (qddd, L.jerk))
           if x is not None):
        return True
    conv = robot.conventions
    return bool(conv.coupled) and any(_beyond(qd @ conv.matrix[k], L.velocity[conv.axis_joints[k]]).any()
                                      for k in conv.coupled_axes)


def check_trajectory(trajectory: Trajectory, robot, dt_s: float | None = None,
                     samples: TrajectorySamples | None = None,
                     each_block: Callable[[TrajectorySamples], None] | None = None) -> list[str]:
    """Findings (one line each) where ``trajectory`` breaks the robot's limits; empty if none.

    Checks array shapes, finite values, strictly increasing time stamps, the
    waypoints themselves, and position, speed, acceleration and jerk of every
    joint on a resampling: ``samples`` (from ``sample_trajectory(trajectory,
    dt_s)``) if given, else ``sample_blocks(trajectory, dt_s)`` one block at a
    time. Give ``dt_s`` or ``samples`` (or both: then they must agree).
    ``each_block`` is shown every block of samples checked, in order (once, the
    whole, when ``samples`` are given): a caller's figures from the very samples
    checked, with no second resampling.
    """
    if dt_s is None and samples is None:
        raise TypeError("check_trajectory: give dt_s (the resampling step, s) or samples")
    tr = trajectory
    L = robot.limits
    dof = robot.dof
    names = tuple(robot.joint_names)
    prism = np.asarray(robot.prismatic, bool)
    m = len(tr.t_s)
    findings: list[str] = []
    for label, arr, shape in (("t_s", tr.t_s, (m,)), ("q", tr.q, (m, dof)), ("qd", tr.qd, (m, dof)),
                              ("qdd", tr.qdd, (m, dof))):
        arr = np.asarray(arr)
        if arr.shape != shape:
            findings.append(f"{label} has shape {arr.shape}, expected {shape}")
        elif not np.all(np.isfinite(arr)):
            k = int(np.nonzero(~np.isfinite(arr).reshape(m, -1).all(axis=1))[0][0])
            findings.append(f"{label} has a non-finite value at waypoint {k}")
    if findings:
        return findings
    if m < 2:
        return [f"the trajectory has {m} waypoint(s); at least 2 are needed"]
    steps = np.diff(tr.t_s)
    if np.any(steps <= 0):
        k = int(np.nonzero(steps <= 0)[0][0])
        return [f"time stamps are not strictly increasing at waypoint {k + 1} (t = {tr.t_s[k + 1]:.6f} s "
                f"after {tr.t_s[k]:.6f} s)"]
    if samples is None:
        broken = _breaks(robot, tr.q, tr.qd, tr.qdd, None)
        for block in sample_blocks(tr, dt_s):
            if each_block is not None:
                each_block(block)
            broken = _breaks(robot, block.q, block.qd, block.qdd, block.qddd) or broken
        if not broken:
            return findings
        samples = sample_trajectory(tr, dt_s)  # the lines below: each interval whole, at its peak
    elif not samples.matches(tr, dt_s):
        raise ValueError(f"check_trajectory: the samples (dt {samples.dt_s} s, {samples.waypoints} waypoints) "
                         f"are not those of this trajectory ({m} waypoints) at dt {dt_s} s")
    elif each_block is not None:
        each_block(samples)
    # position, speed and acceleration: the waypoints and the samples, in time order; jerk: the samples
    t_all = np.concatenate([tr.t_s, samples.t_s])
    order = np.argsort(t_all, kind="stable")
    t_all = t_all[order]
    order_j = np.argsort(samples.t_s, kind="stable")
    t_j = samples.t_s[order_j]
    limit_of = {"speed": L.velocity, "acceleration": L.acceleration, "jerk": L.jerk}
    order_of = {"position": 0, "speed": 1, "acceleration": 2, "jerk": 3}
    for j in range(dof):
        for kind, wp, smp in (("position", tr.q, samples.q), ("speed", tr.qd, samples.qd),
                              ("acceleration", tr.qdd, samples.qdd), ("jerk", None, samples.qddd)):
            if wp is None:
                t, v = t_j, smp[order_j, j]
            else:
                t, v = t_all, np.concatenate([wp[:, j], smp[:, j]])[order]
            if kind == "position":
                findings += _limit_lines(names[j], prism[j], t, v, L.upper[j], kind, 0, lower=L.lower[j])
            else:
                findings += _limit_lines(names[j], prism[j], t, v, limit_of[kind][j], kind, order_of[kind])
    return findings + _coupled_axis_speeds(tr, robot, samples, t_all, order)


def _coupled_axis_speeds(tr: Trajectory, robot, samples: TrajectorySamples, t_all, order) -> list[str]:
    """Speed findings of the controller axes that sum joints (the IRB2400's axis 3 = j2 + j3): the
    controller limits that axis' speed, |q2' + q3'|, at the speed of the joint driving it."""
    conv = robot.conventions
    if not conv.coupled:
        return []
    out = []
    speeds = np.concatenate([tr.qd, samples.qd])[order]
    for k in conv.coupled_axes:
        j = conv.axis_joints[k]
        out += _limit_lines(f"{conv.controller_axis_names[k]} (controller axis)", bool(robot.prismatic[j]), t_all,
                            speeds @ conv.matrix[k], robot.limits.velocity[j], "speed", 1)
    return out
