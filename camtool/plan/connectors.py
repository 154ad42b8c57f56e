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
from ..path.toolpath import ZONE_CODE, Path, row_segments, run_bounds
from ..trajectory import JointPath
from ..collision.world import WorldChecker
from .cwln import CwlnSolver
from .rrt import edge_valid, free_move

EDGE_RESOLUTION_RAD = 0.01  # joint-space step at which a reconfiguration edge is collision-checked
LIFT_FRACTIONS = (1.0, 0.75, 0.5, 0.25, 0.15, 0.1)  # of planner.lift_mm, tried in turn where the higher lifts are out of reach or collide
SEARCH_TRACK_SCALE_MM = 500.0  # RRT metric: 1 rad weighs as this much track travel (not the IK's metric)


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
                   steps: int, away: np.ndarray | None = None) -> np.ndarray | None:
    """Joint rows (steps, dof) lifting the TCP from ``T_base_mm`` along -tool z by ``height_mm``; None if IK fails.

    ``T_base_mm`` is the TCP pose in the robot base frame; the tool z axis
    points into the surface, so -z leaves it. ``away`` (unit, base frame): lift along it instead, the
    tool's orientation kept.
    """
    out = np.empty((steps, len(q_start)))
    q = np.asarray(q_start, float)
    d = -T_base_mm[:3, 2] if away is None else np.asarray(away, float)
    for i in range(1, steps + 1):
        T = T_base_mm.copy()
        T[:3, 3] = T_base_mm[:3, 3] + d * height_mm * i / steps
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
                         qb: np.ndarray, settings: LiftSettings, valid=None,
                         away: np.ndarray | None = None) -> tuple[np.ndarray, dict]:
    """Rows strictly between (qa at Ta) and (qb at Tb): lift at a, reconfigure at the clearance, descend at b.

    ``Ta``, ``Tb``: TCP poses in the robot base frame. ``valid(q) -> bool``
    (optional) checks the reconfiguration; where the straight joint move fails
    it, RRT-Connect replaces it. ``away`` (unit, base frame; optional): where no lift along the tool
    axis is free (a tool steep in a pocket, whose back end a lift along its axis drives into the rim),
    the lifts along it are tried too (the part's mean outward normal). Raises PlanInfeasible when a
    lift cannot be solved or no collision-free reconfiguration is found.
    """
    touches, chosen, direction = [], None, None
    for direction in (None, away):
        chosen = _first_free_lift(solver, robot, Ta, qa, Tb, qb, settings, valid, direction, touches)
        if chosen is not None or away is None:
            break
    if chosen is None:
        if touches:
            # a lift that only ever meets a joint limit is at the edge of reach: a higher one goes further past it
            advice = ("every lift is past a joint limit: the part is at the edge of the robot's reach; move it "
                      "closer (camtool place)" if all(BEYOND in t for t in touches)
                      else "raise planner.lift_mm or move the part (camtool place)")
            raise PlanInfeasible(f"{touches[0]}; {advice}"
                                 + (f" (lower lifts: {'; '.join(touches[1:])})" if len(touches) > 1 else ""))
        raise PlanInfeasible(f"the tool cannot be lifted {LIFT_FRACTIONS[-1] * settings.clearance_mm:g}-"
                             f"{settings.clearance_mm:g} mm "
                             "off the surface to reconfigure: the part is at the edge of the robot's reach; move "
                             "it closer (camtool place)")
    height, up, down = chosen
    info = {"lift_mm": float(height), "rrt": False}
    if direction is not None:
        info["lift_along"] = "mean_normal"   # every lift along the tool axis failed
    middle = np.zeros((0, len(qa)))
    if valid is not None:
        w = np.where(robot.prismatic, 1.0 / SEARCH_TRACK_SCALE_MM, 1.0)
        if not edge_valid(up[-1], down[0], valid, EDGE_RESOLUTION_RAD, w):
            q, figures = free_move(robot, up[-1], down[0], valid, seed=settings.seed,
                                   track_scale_mm=SEARCH_TRACK_SCALE_MM)
            middle = np.asarray(q)[1:-1]
            info.update(rrt=True, rrt_waypoints=int(len(q)))
    info["straight_from"] = len(up)  # rows from here to the first descent row are reached by straight joint moves
    info["straight_to"] = len(up) + len(middle)
    return np.concatenate([up, middle, down]), info


def _first_free_lift(solver, robot, Ta, qa, Tb, qb, settings: LiftSettings, valid, away, touches: list):
    """(height, up rows, down rows) of the highest free lift along ``away`` (None: the tool axis), or None;
    each refused height's reason appended to ``touches``."""
    world = valid.world if isinstance(valid, WorldChecker) else None
    along = "" if away is None else " along the part's mean normal"
    for height in settings.clearance_mm * np.array(LIFT_FRACTIONS):
        up = cartesian_lift(solver, Ta, qa, height, settings.steps, away)
        down = cartesian_lift(solver, Tb, qb, height, settings.steps, away) if up is not None else None
        if up is None or down is None:
            continue
        down = down[::-1]
        if valid is not None and not (valid(up[-1]) and valid(down[0])):
            beyond = _beyond_limits(robot, [up[-1], down[0]])
            hit = _world_hit(world, [up[-1], down[0]]) if world is not None and beyond is None else None
            touches.append(f"at {height:g} mm above the surface{along} " + (
                beyond or hit or "the arm still touches the part"))
            continue
        hit = _world_hit(world, np.concatenate([up, down])) if world is not None else None
        if hit is not None:
            touches.append(f"the {height:g} mm lift{along} brings {hit}")
            continue   # a lower lift may pass under the obstacle
        return height, up, down
    return None


BEYOND = "is beyond its limits"   # _beyond_limits' words (and the controller conventions')


def _beyond_limits(robot: Robot, rows) -> str | None:
    """'<axis> = v deg is beyond its limits [..]' for the first row outside the joint or controller limits."""
    for q in rows:
        if robot.within_limits(q):
            continue
        lines = robot.conventions.check_controller_limits(robot.conventions.controller_from_model(q))
        if lines:
            return lines[0]
        k = int(np.argmax(np.maximum(robot.limits.lower - q, q - robot.limits.upper)))
        v = robot.q_to_edge(q)[k]
        lo, hi = robot.q_to_edge(robot.limits.lower)[k], robot.q_to_edge(robot.limits.upper)[k]
        return f"joint {robot.joint_names[k]} = {v:.2f} {BEYOND} [{lo:g}, {hi:g}]"
    return None


def _world_hit(world, rows) -> str | None:
    """'<body> within d mm of <body>' for the first row of a lift that breaks the world's clearance, else None."""
    for q in rows:
        d, pair = world.clearance_mm_at(q)
        if d < world.clearance_mm:
            a, b = world.pair_name(pair)
            return f"{a} within {d:.1f} mm of {b} (cell.clearance_mm {world.clearance_mm:g} mm)"
    return None


def lift_reconfigurations(joint_path: JointPath, path: Path, robot: Robot, settings: LiftSettings,
                          solver: CwlnSolver, valid=None, touch_points: bool = False,
                          every_failure: bool = False) -> JointPath:
    """``joint_path`` with every reconfiguring connector between runs replaced by lift-reconfigure-descend rows.

    A connector is the stretch of non-surface rows between the last row of one
    run and the first row of the next. With ``touch_points`` every path pose is
    a contact of its own (seed 002's targets and its start point): the tool
    lifts between any two of them. Inserted rows have path_index -1 and zone
    'self_motion'. The joint path's events get ``lifted_connectors``.

    A connector that cannot be lifted raises ``PlanInfeasible`` naming it; its report's
    ``unliftable_path_indices`` holds the path indices of the two poses it joins (the end of one run, the start
    of the next). With ``every_failure`` every connector is tried first and the report holds those pairs of each
    one that fails, in path order (a partial plan leaves them out, ``run/tasks/raster.py``).
    """
    jp = joint_path
    seg = np.asarray(path.segment)
    base_inv = np.linalg.inv(robot.base_T_mm)
    away = _mean_outward(path, base_inv)
    keep = np.ones(len(jp.q), bool)
    inserts: dict[int, tuple[np.ndarray, dict]] = {}
    failed: list[tuple[str, int, int]] = []   # (message, path index before, path index after)
    for r0, r1 in _connectors(jp, seg, touch_points):
        # two runs with no connector poses between them (a row cut at unreachable poses, --allow-partial)
        # are joined off the part too: a direct move between two surface points cuts through a convex part
        if r1 > r0 + 1 and not is_reconfiguration(jp.q[r0], jp.q[r1], robot, settings):
            continue
        Ta = base_inv @ path.poses_mm[jp.path_index[r0]]
        Tb = base_inv @ path.poses_mm[jp.path_index[r1]]
        try:
            new, info = lift_and_reconfigure(solver, robot, Ta, jp.q[r0], Tb, jp.q[r1], settings, valid, away)
        except PlanInfeasible as exc:
            failed.append((f"reconfiguration before {path.segment_text(int(jp.path_index[r1]))}: {exc}",
                           int(jp.path_index[r0]), int(jp.path_index[r1])))
            if every_failure:
                continue
            break
        keep[r0 + 1:r1] = False
        info["retract"] = bool(np.any(jp.retract[r0 + 1:r1]))  # a strategy retract, re-planned here
        info.update(segment=int(seg[jp.path_index[r1]]), joint_change_deg=round(float(np.degrees(
            np.max(np.abs(jp.q[r1] - jp.q[r0])[~robot.prismatic], initial=0.0))), 3))
        inserts[int(r0)] = (new, info)
    if failed:
        raise PlanInfeasible(failed[0][0] + (f" (and {len(failed) - 1} more connector(s))" if len(failed) > 1 else ""),
                             report={"unliftable_path_indices": [i for _, a, b in failed for i in (a, b)]})
    if not inserts:
        return replace(jp, events={**jp.events, "lifted_connectors": []})
    return _spliced(jp, keep, inserts)


def _mean_outward(path: Path, base_inv: np.ndarray) -> np.ndarray | None:
    """The part's mean outward normal (base frame): the mean of the work poses' -tool z, or None where they
    cancel out (a closed part worked all round)."""
    work = path.poses_mm[path.is_work] if path.is_work.any() else path.poses_mm
    m = -work[:, :3, 2].mean(axis=0) if len(work) else np.zeros(3)
    n = float(np.linalg.norm(m))
    return None if n < 0.5 else base_inv[:3, :3] @ (m / n)


def _connectors(jp: JointPath, seg: np.ndarray, touch_points: bool):
    """(last row of a run, first row of the next) of each connector (with ``touch_points``: of every two path poses)."""
    _surface, start, end = run_bounds(jp.zone, row_segments(jp.path_index, jp.zone, seg))
    if touch_points:
        start = end = np.asarray(jp.path_index) >= 0
    return zip(np.flatnonzero(end)[:-1], np.flatnonzero(start)[1:])


def _spliced(jp: JointPath, keep: np.ndarray, inserts: dict[int, tuple[np.ndarray, dict]]) -> JointPath:
    """``jp``'s kept rows with each lift's rows (``inserts``, by the row they follow) after the row they follow."""
    order = _row_order(keep, inserts)
    q, pidx, zone, inserted = _stacked_rows(jp, order, inserts)
    src = np.array([r for kind, r in order for _ in range(1 if kind == "row" else len(inserts[r][0]))])

    def spread(a, fill):
        out = np.asarray(a)[src].copy()
        out[inserted] = fill
        return out

    jump = np.zeros(len(q), bool)
    jump[1:] = spread(jp.jump, False)[1:] & ~inserted[1:]
    _mark_straight_moves(jump, order, inserts)
    pieces = [dict(info) for _, (_, info) in sorted(inserts.items())]
    retract = spread(jp.retract, False)
    retract[inserted] = zone[inserted] == ZONE_CODE["retract"]
    return JointPath(q=q, path_index=pidx, zone=zone, position_error_mm=spread(jp.position_error_mm, 0.0),
                     orientation_error_rad=spread(jp.orientation_error_rad, 0.0), jump=jump,
                     reverse_planned=spread(jp.reverse_planned, False), retract=retract,
                     singular=spread(jp.singular, False), reached=spread(jp.reached, True),
                     events={**jp.events, "lifted_connectors": pieces})


def _row_order(keep: np.ndarray, inserts: dict) -> list[tuple[str, int]]:
    """The rows of the new joint path in order: ("row", r) a kept row, ("new", r) the lift inserted after row r."""
    order = []
    for r in range(len(keep)):
        if keep[r]:
            order.append(("row", r))
        if r in inserts:
            order.append(("new", r))
    return order


def _stacked_rows(jp: JointPath, order: list[tuple[str, int]], inserts: dict):
    """(q, path_index, zone, inserted) of the rows in ``order``: a lift's rows have path_index -1 and zone
    'retract' (a strategy retract re-planned) or 'self_motion'."""
    q, pidx, zone, new_rows = [], [], [], []
    for kind, r in order:
        if kind == "row":
            q.append(jp.q[r][None]); pidx.append([jp.path_index[r]]); zone.append([jp.zone[r]])
            new_rows.append([False])
        else:
            block, info = inserts[r]
            code = ZONE_CODE["retract"] if info["retract"] else ZONE_CODE["self_motion"]
            q.append(block); pidx.append(np.full(len(block), -1)); zone.append(np.full(len(block), code))
            new_rows.append(np.ones(len(block), bool))
    return (np.concatenate(q), np.concatenate(pidx).astype(jp.path_index.dtype),
            np.concatenate(zone).astype(jp.zone.dtype), np.concatenate(new_rows))


def _mark_straight_moves(jump: np.ndarray, order: list[tuple[str, int]], inserts: dict) -> None:
    """Flag each reconfiguration's own rows in ``jump``: they were collision-checked as straight joint moves, so
    the timing runs them rest to rest along exactly those lines (a blend would cut the checked corners)."""
    at = 0
    for kind, r in order:
        if kind == "row":
            at += 1
            continue
        block, info = inserts[r]
        jump[at + info["straight_from"]:at + info["straight_to"] + 1] = True
        at += len(block)
