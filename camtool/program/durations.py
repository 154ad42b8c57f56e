"""The duration of each move of a program: as written, or its length over its TCP speed."""
from __future__ import annotations

import numpy as np

from .arcs import circle_through
from .targets import _robot_for, _rotvec, _target_poses, target_joints


def move_durations(prog, robot, q=None, profile=None) -> np.ndarray:
    """(M,) each move's duration (s): as written, else its length over its TCP speed (the
    slower of TCP and reorientation); NaN for the first move (from wherever the robot is)."""
    robot = _robot_for(prog, robot)
    q = target_joints(prog, robot, profile) if q is None else q
    M = len(prog)
    P, R = _target_poses(prog, robot, q)
    dur = np.array(prog.duration_s, float)
    need = np.isnan(dur) & np.isfinite(prog.speed_mm_s)
    need[0] = False
    for k in np.flatnonzero(need):
        if prog.kind[k] == "C" and np.isfinite(prog.via[k]).all():
            c, rad, n, r0, sweep, ok = circle_through(P[k - 1][None], prog.via[k][None, :3, 3], P[k][None])
            L = float(rad[0] * sweep[0]) if ok[0] else float(np.linalg.norm(P[k] - P[k - 1]))
        else:
            L = float(np.linalg.norm(P[k] - P[k - 1]))
        t = L / prog.speed_mm_s[k] if prog.speed_mm_s[k] > 0 else np.inf
        if np.isfinite(prog.ori_speed_deg_s[k]) and prog.ori_speed_deg_s[k] > 0:
            ang = np.degrees(np.linalg.norm(_rotvec((R[k] @ R[k - 1].T)[None])[0]))
            t = max(t, ang / prog.ori_speed_deg_s[k])
        dur[k] = t
    if M:
        dur[0] = np.nan
    return dur
