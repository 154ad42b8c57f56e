"""Keep the controller's joint-linear motion on the surface: densify surface steps whose chord bows too far.

A controller runs joint moves linearly in joint space; between two planned
poses the TCP then follows a curve, not the straight line. At 5 mm pitch that
bow is a few hundredths of a millimetre, but where the joints change fast (a
joint turning round near a singularity or a clamped limit) it can reach tenths.
For every step between two consecutive Path poses on the surface or in the
self-motion zone (which runs just above it), the TCP at the joint midpoint is
compared with the midpoint of the two poses; where they are farther apart than
``chord_tol_mm`` an intermediate pose is solved (position midway, orientation
slerped halfway, warm-started from the joint midpoint) and inserted, and the
two halves are checked again, up to ``MAX_SPLITS`` times.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from ..robots.model import Robot
from ..toolpath import SURFACE_CODES, ZONE_CODE, Path
from ..trajectory import JointPath
from .cwln import CwlnSolver

MAX_SPLITS = 4  # a step is halved at most this many times (16 pieces)


def _midpose(Ta: np.ndarray, Tb: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = 0.5 * (Ta[:3, 3] + Tb[:3, 3])
    T[:3, :3] = Slerp([0.0, 1.0], Rotation.from_matrix([Ta[:3, :3], Tb[:3, :3]]))(0.5).as_matrix()
    return T


def _split(solver: CwlnSolver, Ta, qa, Tb, qb, tol_mm: float, depth: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Inserted (pose, q) pairs strictly between a and b (base frame), in order."""
    q_mid = 0.5 * (qa + qb)
    T_mid = _midpose(Ta, Tb)
    if depth >= MAX_SPLITS or np.linalg.norm(solver.tcp_pose(q_mid)[:3, 3] - T_mid[:3, 3]) <= tol_mm:
        return []
    res = solver.solve(T_mid, q_mid, clamp=False)  # the least change from the joint midpoint: no spike in the joint path
    if not res.converged or np.any(res.q < solver.lo) or np.any(res.q > solver.hi):
        return []
    return (_split(solver, Ta, qa, T_mid, res.q, tol_mm, depth + 1) + [(T_mid, res.q)]
            + _split(solver, T_mid, res.q, Tb, qb, tol_mm, depth + 1))


def densify_work(joint_path: JointPath, path: Path, robot: Robot, solver: CwlnSolver, tol_mm: float) -> JointPath:
    """``joint_path`` with poses inserted where a surface step's joint-linear chord leaves the line by > ``tol_mm``.

    Inserted rows have path_index -1 and the zone of the step's first row (the self-motion zone
    on a step into or out of it); the events get
    ``densified_steps`` (how many steps were split, how many rows inserted).
    """
    jp = joint_path
    base_inv = np.linalg.inv(robot.base_T_mm)
    on = np.isin(jp.zone, SURFACE_CODES + (ZONE_CODE["self_motion"],)) & (jp.path_index >= 0)
    neighbours = np.diff(jp.path_index) == 1  # consecutive poses of the Path (not a lifted connector)
    steps = np.flatnonzero(on[:-1] & on[1:] & neighbours)
    inserts = {}
    for r in steps:
        Ta = base_inv @ path.poses_mm[jp.path_index[r]]
        Tb = base_inv @ path.poses_mm[jp.path_index[r + 1]]
        extra = _split(solver, Ta, jp.q[r], Tb, jp.q[r + 1], tol_mm, 0)
        if extra:
            inserts[int(r)] = np.array([q for _, q in extra])
    events = {**jp.events, "densified_steps": {"steps": len(inserts),
                                               "rows": int(sum(len(v) for v in inserts.values())),
                                               "chord_tol_mm": tol_mm}}
    if not inserts:
        return replace(jp, events=events)
    src, new = [], []
    for r in range(len(jp.q)):
        src.append(r)
        new.append(False)
        for _ in inserts.get(r, ()):
            src.append(r)
            new.append(True)
    src, new = np.array(src), np.array(new)
    q = jp.q[src].copy()
    q[new] = np.concatenate([inserts[r] for r in sorted(inserts)])

    def spread(a, fill):
        out = np.asarray(a)[src].copy()
        out[new] = fill
        return out

    # an inserted row takes the zone of its step, except across a run end: a step between a lead and the
    # self-motion zone lies in the self-motion zone (in the run it would bend the run's spline off the surface)
    zone = np.asarray(jp.zone)
    sm = ZONE_CODE["self_motion"]
    step_zone = {r: (sm if sm in (zone[r], zone[r + 1]) else zone[r]) for r in inserts}
    new_zone = zone[src].copy()
    new_zone[new] = np.concatenate([np.full(len(inserts[r]), step_zone[r]) for r in sorted(inserts)])
    return JointPath(q=q, path_index=spread(jp.path_index, -1), zone=new_zone,
                     position_error_mm=spread(jp.position_error_mm, 0.0),
                     orientation_error_rad=spread(jp.orientation_error_rad, 0.0), jump=spread(jp.jump, False),
                     reverse_planned=spread(jp.reverse_planned, False), retract=spread(jp.retract, False),
                     singular=spread(jp.singular, False), reached=spread(jp.reached, True), events=events)
