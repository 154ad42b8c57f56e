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
from scipy.spatial.transform import Rotation

from ..robots.model import Robot
from ..path.toolpath import SURFACE_CODES, WORK, ZONE_CODE, Path
from ..trajectory import JointPath
from ..timing.feed import tcp_positions_world
from .cwln import CwlnSolver
from .row_orientations import RowOrientations, along_runs

MAX_SPLITS = 4  # a step is halved at most this many times (16 pieces)


def slerp_midposes(Ta: np.ndarray, Tb: np.ndarray) -> np.ndarray:
    """(m, 4, 4) midposes of m pose pairs: position midway, orientation slerped halfway.

    One batched scipy Rotation call for all pairs; per pair it is exactly
    ``Slerp([0, 1], [Ra, Rb])(0.5)`` (scipy's Slerp is ``Ra * exp(0.5 log(Ra^-1 Rb))``).
    """
    T = np.broadcast_to(np.eye(4), (len(Ta), 4, 4)).copy()
    T[:, :3, 3] = 0.5 * (Ta[:, :3, 3] + Tb[:, :3, 3])
    ra, rb = Rotation.from_matrix(Ta[:, :3, :3]), Rotation.from_matrix(Tb[:, :3, :3])
    T[:, :3, :3] = (ra * Rotation.from_rotvec(0.5 * (ra.inv() * rb).as_rotvec())).as_matrix()
    return T


def bisected(solver: CwlnSolver, Ta: np.ndarray, qa: np.ndarray, Tb: np.ndarray, qb: np.ndarray, levels: int,
             midposes, orient=None) -> dict[int, np.ndarray]:
    """{step: inserted q (k, dof) in order} for the steps (Ta[i], qa[i]) -> (Tb[i], qb[i]) (base frame), halved
    level by level (every interval of one depth at once), up to ``levels`` times.

    ``midposes(depth, Ta, qa, Tb, qb, q_mid)`` gives the intervals' midposes (m, 4, 4) and the indices of those to
    split; each is solved (CWLN without the clamp task, from the joint midpoint ``q_mid``: the least change),
    and one solved within the joint limits is inserted and its two halves go on to the next level.
    ``orient(step, share)`` ((m,) steps, (m,) shares of their way): (m,) where it decides, (m, 3, 3) the
    midposes' orientations there (``row_orientations``), or None: the midposes' own."""
    step = np.arange(len(Ta))
    key = np.full(len(Ta), 0.5)     # where the midpoint lies in its step (0..1): the order of the inserts
    half = 0.25
    found: dict[int, list] = {}
    for depth in range(levels):
        if not len(step):
            break
        q_mid = 0.5 * (qa + qb)
        T_mid, wanted = midposes(depth, Ta, qa, Tb, qb, q_mid)
        if orient is not None and len(wanted):   # the intervals split only (the others' midposes are not used)
            wanted = np.asarray(wanted, np.int64)
            ok, R = orient(step[wanted], key[wanted])
            T_mid[wanted[ok], :3, :3] = R[ok]
        keep, q_new = [], []
        for i in wanted:
            res = solver.solve(T_mid[i], q_mid[i], clamp=False)
            if not res.converged or np.any(res.q < solver.lo) or np.any(res.q > solver.hi):
                continue
            found.setdefault(int(step[i]), []).append((key[i], res.q))
            keep.append(i)
            q_new.append(res.q)
        if not keep:
            break
        keep = np.array(keep)
        q_new = np.array(q_new)
        # each kept interval becomes its two halves
        step = np.concatenate([step[keep], step[keep]])
        key = np.concatenate([key[keep] - half, key[keep] + half])
        Ta, Tb = np.concatenate([Ta[keep], T_mid[keep]]), np.concatenate([T_mid[keep], Tb[keep]])
        qa, qb = np.concatenate([qa[keep], q_new]), np.concatenate([q_new, qb[keep]])
        half *= 0.5
    return {s: np.array([q for _, q in sorted(v, key=lambda e: e[0])]) for s, v in found.items()}


def _split_steps(solver: CwlnSolver, robot: Robot, Ta: np.ndarray, qa: np.ndarray, Tb: np.ndarray, qb: np.ndarray,
                 tol_mm: float, orient=None) -> dict[int, np.ndarray]:
    """``bisected`` for the chord's bow: the joint midpoints' TCP by one vectorised FK, the midposes by one
    batched slerp; the intervals that bow more than ``tol_mm`` are split, up to ``MAX_SPLITS`` times."""
    base = np.asarray(robot.base_T_mm, float)

    def bowing(depth, Ta, qa, Tb, qb, q_mid):
        T_mid = slerp_midposes(Ta, Tb)
        tcp_base = (tcp_positions_world(robot, q_mid) - base[:3, 3]) @ base[:3, :3]  # = base^-1 world
        return T_mid, np.flatnonzero(np.linalg.norm(tcp_base - T_mid[:, :3, 3], axis=1) > tol_mm)

    return bisected(solver, Ta, qa, Tb, qb, MAX_SPLITS, bowing, orient)


def densify_work(joint_path: JointPath, path: Path, robot: Robot, solver: CwlnSolver, tol_mm: float,
                 orientations: RowOrientations | None = None) -> JointPath:
    """``joint_path`` with poses inserted where a surface step's joint-linear chord leaves the line by > ``tol_mm``.

    Inserted rows have path_index -1 and the zone of the step's first row (the self-motion zone
    on a step into or out of it, the lead's on a step between work and a lead); the events get
    ``densified_steps`` (how many steps were split, how many rows inserted). ``orientations``: the midposes'
    orientations on a free-form face's runs (``row_orientations``; None: slerped).
    """
    jp = joint_path
    base_inv = np.linalg.inv(robot.base_T_mm)
    on = np.isin(jp.zone, SURFACE_CODES + (ZONE_CODE["self_motion"],)) & (jp.path_index >= 0)
    neighbours = np.diff(jp.path_index) == 1  # consecutive poses of the Path (not a lifted connector)
    steps = np.flatnonzero(on[:-1] & on[1:] & neighbours)
    poses = base_inv @ path.poses_mm[jp.path_index[np.r_[steps, steps + 1]]] if len(steps) else np.zeros((0, 4, 4))
    q = np.asarray(jp.q, float)
    split = _split_steps(solver, robot, poses[:len(steps)], q[steps], poses[len(steps):], q[steps + 1], tol_mm,
                         along_runs(orientations, jp.path_index[steps]))
    inserts = {int(steps[i]): v for i, v in sorted(split.items())}
    events = {**jp.events, "densified_steps": {"steps": len(inserts),
                                               "rows": int(sum(len(v) for v in inserts.values())),
                                               "chord_tol_mm": tol_mm}}
    if not inserts:
        return replace(jp, events=events)
    return jp.with_rows_inserted(inserts, inserted_zones(jp.zone, inserts), events)


def inserted_zones(zone: np.ndarray, rows) -> dict[int, int]:
    """{r: the zone of a row inserted in the step from row r to r + 1} (the sag's, densify's and the spline's
    midposes): the step's own, except across a run end. A step between a lead and the self-motion zone lies in the
    self-motion zone (in the run it would bend the run's spline off the surface); a step between work and a lead
    lies in the lead (the work ends at its last work pose: on the lead's tangent past a convex rim a midpose is off
    the surface, and labelled work it read 0.1-1.2 mm off the Vito door on work)."""
    zone = np.asarray(zone)
    sm = ZONE_CODE["self_motion"]
    return {r: (sm if sm in (zone[r], zone[r + 1]) else zone[r + 1] if zone[r] == WORK else zone[r]) for r in rows}
