"""Reconfigure off the surface: lift, reconfigure at a clearance, come back down.

The seed paper puts a reconfiguration "between segments, inside a self-motion
zone". Made literal, that zone lies on the part (the raster's transition poses
follow the surface), and a straight joint-space reconfiguration of 100-300 deg
sweeps the tool through it. Here every non-work stretch whose joint change is
larger than a small threshold becomes

    Cartesian lift along the tool axis  ->  reconfiguration at the clearance  ->  Cartesian descent

- the lift and the descent are straight TCP lines along the surface normal
  (``lift_steps`` poses each, solved by CWLN warm-started pose to pose, every
  joint moving together, the track included);
- the reconfiguration between the two lifted configurations is one joint move
  when every 4 ms-resolution sample of it keeps the link capsules clear of the
  part, else an RRT-Connect move (``camtool.plan.rrt``) between them;
- a stretch that cannot be made so raises ``PlanInfeasible`` naming the segment.

The same lift serves the retract fallback of the strategy (a reconfiguration
inside a run), so the retract leaves the part whatever the robot: with or
without a track, whatever the normal's direction.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import PlanInfeasible
from ..robots.model import Robot
from ..toolpath import ZONE_CODE, Path
from ..trajectory import JointPath
from .cwln import CwlnSolver
from .rrt import edge_valid, free_move

SURFACE = (ZONE_CODE["work"], ZONE_CODE["lead_in"], ZONE_CODE["lead_out"])
EDGE_RESOLUTION_RAD = 0.01  # joint-space step at which a reconfiguration edge is collision-checked


@dataclass(frozen=True)
class LiftSettings:
    """How a reconfiguration leaves the part: clearance (mm), poses per lift, what counts as a reconfiguration."""

    clearance_mm: float
    steps: int
    threshold_rad: float
    threshold_mm: float
    track_scale_mm: float
    seed: int


def cartesian_lift(solver: CwlnSolver, T_base_mm: np.ndarray, q_start: np.ndarray, height_mm: float,
                   steps: int) -> np.ndarray | None:
    """Joint rows (steps, dof) lifting the TCP from ``T_base_mm`` along -tool z by ``height_mm``; None if IK fails.

    ``T_base_mm`` is the TCP pose in the robot base frame; the tool z axis
    points into the surface, so -z leaves it.
    """
    out = np.empty((steps, len(q_start)))
    q = np.asarray(q_start, float)
    for i in range(1, steps + 1):
        T = T_base_mm.copy()
        T[:3, 3] = T_base_mm[:3, 3] - T_base_mm[:3, 2] * height_mm * i / steps
        res = solver.solve(T, q, max_iterations=300)
        if not res.converged:
            return None
        q = out[i - 1] = res.q
    return out


def is_reconfiguration(qa: np.ndarray, qb: np.ndarray, robot: Robot, settings: LiftSettings) -> bool:
    """Whether the change qa -> qb is larger than a small reconfiguration threshold on any joint."""
    thr = np.where(robot.prismatic, settings.threshold_mm, settings.threshold_rad)
    return bool(np.any(np.abs(np.asarray(qb) - np.asarray(qa)) > thr))


def lift_and_reconfigure(solver: CwlnSolver, robot: Robot, Ta: np.ndarray, qa: np.ndarray, Tb: np.ndarray,
                         qb: np.ndarray, settings: LiftSettings, valid=None) -> tuple[np.ndarray, dict]:
    """Rows strictly between (qa at Ta) and (qb at Tb): lift at a, reconfigure at the clearance, descend at b.

    ``Ta``, ``Tb``: TCP poses in the robot base frame. ``valid(q) -> bool``
    (optional) checks the reconfiguration; where the straight joint move fails
    it, RRT-Connect replaces it. Raises PlanInfeasible when a lift cannot be
    solved or no collision-free reconfiguration is found.
    """
    up = cartesian_lift(solver, Ta, qa, settings.clearance_mm, settings.steps)
    down = cartesian_lift(solver, Tb, qb, settings.clearance_mm, settings.steps)
    if up is None or down is None:
        raise PlanInfeasible(f"the tool cannot be lifted {settings.clearance_mm:g} mm off the surface to "
                             "reconfigure (out of reach); lower planner.lift_mm or move the part")
    down = down[::-1]
    info = {"lift_mm": settings.clearance_mm, "rrt": False}
    middle = np.zeros((0, len(qa)))
    if valid is not None:
        w = np.where(robot.prismatic, 1.0 / settings.track_scale_mm, 1.0)
        if not (valid(up[-1]) and valid(down[0])):
            raise PlanInfeasible(f"at {settings.clearance_mm:g} mm above the surface the arm still touches the "
                                 "part; raise planner.lift_mm")
        if not edge_valid(up[-1], down[0], valid, EDGE_RESOLUTION_RAD, w):
            q, figures = free_move(robot, up[-1], down[0], valid, seed=settings.seed,
                                   track_scale_mm=settings.track_scale_mm)
            middle = np.asarray(q)[1:-1]
            info.update(rrt=True, rrt_waypoints=int(len(q)))
    return np.concatenate([up, middle, down]), info


def lift_reconfigurations(joint_path: JointPath, path: Path, robot: Robot, settings: LiftSettings,
                          solver: CwlnSolver, valid=None) -> JointPath:
    """``joint_path`` with every reconfiguring connector between runs replaced by lift-reconfigure-descend rows.

    A connector is the stretch of non-surface rows between the last row of one
    run and the first row of the next. Inserted rows have path_index -1 and
    zone 'self_motion'. The joint path's events get ``lifted_connectors``.
    """
    jp = joint_path
    surface = np.isin(jp.zone, SURFACE) & (jp.path_index >= 0)
    rows = np.flatnonzero(surface)
    if len(rows) < 2:
        return jp
    base_inv = np.linalg.inv(robot.base_T_mm)
    keep = np.ones(len(jp.q), bool)
    inserts: dict[int, tuple[np.ndarray, dict]] = {}
    seg = np.asarray(path.segment)
    for r0, r1 in zip(rows[:-1], rows[1:]):
        same_run = r1 == r0 + 1 and seg[jp.path_index[r0]] == seg[jp.path_index[r1]]
        if same_run or not is_reconfiguration(jp.q[r0], jp.q[r1], robot, settings):
            continue
        Ta = base_inv @ path.poses_mm[jp.path_index[r0]]
        Tb = base_inv @ path.poses_mm[jp.path_index[r1]]
        try:
            new, info = lift_and_reconfigure(solver, robot, Ta, jp.q[r0], Tb, jp.q[r1], settings, valid)
        except PlanInfeasible as exc:
            raise PlanInfeasible(f"reconfiguration before segment {int(seg[jp.path_index[r1]])}: {exc}") from None
        keep[r0 + 1:r1] = False
        info.update(segment=int(seg[jp.path_index[r1]]), joint_change_deg=round(float(np.degrees(
            np.max(np.abs(jp.q[r1] - jp.q[r0])[~robot.prismatic], initial=0.0))), 3))
        inserts[int(r0)] = (new, info)
    if not inserts:
        return replace(jp, events={**jp.events, "lifted_connectors": []})
    order = []
    for r in range(len(jp.q)):
        if keep[r]:
            order.append(("row", r))
        if r in inserts:
            order.append(("new", r))
    q, pidx, zone, new_rows = [], [], [], []
    for kind, r in order:
        if kind == "row":
            q.append(jp.q[r][None]); pidx.append([jp.path_index[r]]); zone.append([jp.zone[r]])
            new_rows.append([False])
        else:
            block = inserts[r][0]
            q.append(block); pidx.append(np.full(len(block), -1)); zone.append(np.full(len(block), ZONE_CODE["self_motion"]))
            new_rows.append(np.ones(len(block), bool))
    q = np.concatenate(q)
    pidx = np.concatenate(pidx).astype(jp.path_index.dtype)
    zone = np.concatenate(zone).astype(jp.zone.dtype)
    inserted = np.concatenate(new_rows)
    src = np.array([r for kind, r in order for _ in range(1 if kind == "row" else len(inserts[r][0]))])

    def spread(a, fill):
        out = np.asarray(a)[src].copy()
        out[inserted] = fill
        return out

    jump = np.zeros(len(q), bool)
    jump[1:] = spread(jp.jump, False)[1:] & ~inserted[1:]
    pieces = [dict(info) for _, (_, info) in sorted(inserts.items())]
    return JointPath(q=q, path_index=pidx, zone=zone, position_error_mm=spread(jp.position_error_mm, 0.0),
                     orientation_error_rad=spread(jp.orientation_error_rad, 0.0), jump=jump,
                     reverse_planned=spread(jp.reverse_planned, False), retract=spread(jp.retract, False),
                     singular=spread(jp.singular, False), reached=spread(jp.reached, True),
                     events={**jp.events, "lifted_connectors": pieces})
