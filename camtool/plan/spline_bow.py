"""Keep the timed spline out of the part: poses where a surface run's cubic spline bows into it.

The time stage runs every surface run (consecutive work and lead poses of one segment,
``timing.assemble.run_layout``) along a not-a-knot cubic spline q(s) through its poses, s the
TCP chord length (``timing.pathlaw.PathSpline`` at ``timing.runs.path_parameter``'s knots).
``densify`` keeps the joint-linear motion of each step within ``chord_tol_mm`` of its chord; the
spline is another curve. Where the path bends sharply over a few poses (a free-form face's lead
lifted clear of the part, ``path.lead_clearance``: 4 mm within its first 7.5 mm, next to straight
work) the spline overshoots into the steps beside the bend: on the Vito door's lower skin it ran up
to 0.11 mm behind the surface in the last work step before such a lead-out (0.16 mm in a lead-in
step), and the trajectory's samples there (where the feed changes, or taken by the post's closer
rounds) put the tool into the part.

Here each run's spline is sampled inside every step (``DEPTH_SHARES``) and measured against the
part itself (its signed distance, as the motion check measures it); a step whose spline runs
deeper than the tolerance gets a midpose (the sag's: on the surface's arc, on a free-form face's
own surface, on a lead's chord; ``sag.step_midposes``), solved from the joint midpoint, and the
runs are measured again, ``MAX_ROUNDS`` times at most. Only where the spline goes into the part:
splitting every step whose spline leaves its chord by the tolerance (673 of the door's 6 329 steps,
up to 1.2 mm on the lifted leads high above the part) made the knots uneven next to the rolled rim's
short steps, the jerk bounds fell and the door's cycle grew by 6.5 %; splitting where it goes into
the part takes 84 poses in two rounds and 0.2 s. A work step (both its poses work) shorter than
``WORK_STEP_MM`` is not split (issue #46): where a free-form face's poses lie on its facets, at a crest between
two facets the spline cuts the corner however short the steps (its depth falls with the step, h, its third
derivative grows as 1 / h^2); on the wavy sheet four rounds halved 1.25 mm steps down to 0.02-0.08 mm and the
joint jerk there set the work feed of 58 of its 72 rows (median 5.6 mm/s; its pieces of 2 mm and more hold
100 mm/s on 92 % of their length). The motion check still measures what is left. The spline is the time stage's own (scipy's
CubicSpline), so what is measured is what is timed; the depth is written here: no library measures a
joint spline's TCP against a part.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from ..path.toolpath import WORK, Path
from ..robots.model import Robot
from ..timing.assemble import run_layout, tcp_positions_mm
from ..timing.feed import tcp_positions_world
from ..timing.pathlaw import PathSpline
from ..timing.runs import path_parameter
from ..trajectory import JointPath
from .cwln import CwlnSolver
from .densify import inserted_zones
from .sag import in_frame, step_midposes

DEPTH_SHARES = np.arange(1, 8) / 8.0   # where inside each step the spline is measured (shares of its length)
MAX_ROUNDS = 4                          # rounds of splitting the steps that go in and measuring the runs again
WORK_STEP_MM = 1.0                      # a work step shorter than this is not split (its halves would be < 0.5 mm)


@dataclass(frozen=True)
class SplineDepthSettings:
    """How deep the timed spline may run into the part (mm: ``planner.chord_tol_mm``, a scan's noise band on
    top), and the commanded feed (mm/s) its knots are placed with (``timing.runs.path_parameter``)."""

    depth_tol_mm: float
    feed_mm_s: float


def spline_depths_mm(joint_path: JointPath, path: Path, robot: Robot, feed_mm_s: float,
                     signed_distance: Callable[[np.ndarray], np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(rows r, depth (mm) of each): every surface step r -> r + 1 of ``joint_path`` and how deep the time stage's
    spline of its run goes into the part there (``DEPTH_SHARES`` of the step; <= 0: in front of it).
    ``signed_distance(points_mm)``: world points' distance in front of the part (+) or inside it (-)."""
    rows, depth, _ = _spline_steps(joint_path, path, robot, feed_mm_s, signed_distance)
    return rows, depth


def _spline_steps(joint_path: JointPath, path: Path, robot: Robot, feed_mm_s: float,
                  signed_distance: Callable) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``spline_depths_mm``'s rows and depths, and each step's TCP chord (mm)."""
    q = np.asarray(joint_path.q, float)
    pos = tcp_positions_mm(joint_path, path, robot)
    rows, qs, steps = [], [], []
    for a, b in run_layout(joint_path, path).runs():
        if b == a:
            continue
        step = np.linalg.norm(np.diff(pos[a:b + 1], axis=0), axis=1)
        s = path_parameter(q[a:b + 1], step, robot.limits, feed_mm_s)
        x = (s[:-1, None] + DEPTH_SHARES[None] * np.diff(s)[:, None]).ravel()
        qs.append(PathSpline(s, q[a:b + 1]).derivatives(x)[0])
        rows.append(np.arange(a, b))
        steps.append(step)
    if not rows:
        return np.zeros(0, int), np.zeros(0), np.zeros(0)
    sd = np.nan_to_num(signed_distance(tcp_positions_world(robot, np.vstack(qs))), nan=np.inf)
    return np.concatenate(rows), -sd.reshape(-1, len(DEPTH_SHARES)).min(axis=1), np.concatenate(steps)


def _step_poses(joint_path: JointPath, path: Path, solver: CwlnSolver, rows: np.ndarray, base_inv) -> np.ndarray:
    """(m, 4, 4) the base-frame poses of JointPath rows: the Path's, or the TCP's (forward kinematics) for an
    inserted row."""
    pidx = np.asarray(joint_path.path_index)[rows]
    T = np.einsum("ij,njk->nik", base_inv, np.asarray(path.poses_mm)[np.maximum(pidx, 0)])
    for i in np.flatnonzero(pidx < 0):
        T[i] = solver.tcp_pose(np.asarray(joint_path.q, float)[rows[i]])
    return T


def _midpose_q(solver: CwlnSolver, T_mid: np.ndarray, qa: np.ndarray, qb: np.ndarray) -> np.ndarray | None:
    """The joints of one midpose, solved from the joint midpoint (the least change; no clamp task), or None where
    it does not converge within the joint limits."""
    res = solver.solve(T_mid, 0.5 * (qa + qb), clamp=False)
    if not res.converged or np.any(res.q < solver.lo) or np.any(res.q > solver.hi):
        return None
    return res.q


def _splittable(joint_path: JointPath, rows: np.ndarray, step_mm: np.ndarray) -> np.ndarray:
    """(len(rows),) whether each surface step r -> r + 1 (its TCP chord ``step_mm``) may get a midpose: a lead's
    step always, a work step (both poses work) of ``WORK_STEP_MM`` or longer (module doc)."""
    zone = np.asarray(joint_path.zone)
    work = (zone[rows] == WORK) & (zone[rows + 1] == WORK)
    return ~work | (step_mm >= WORK_STEP_MM)


def add_spline_poses(joint_path: JointPath, path: Path, robot: Robot, solver: CwlnSolver,
                     settings: SplineDepthSettings, signed_distance: Callable, project=None) -> JointPath:
    """``joint_path`` with a midpose in every surface step whose timed spline runs deeper into the part than
    ``settings.depth_tol_mm`` (module doc), again for the runs so changed, up to ``MAX_ROUNDS`` times.
    ``signed_distance``: world points' distance in front of the part (``spline_depths_mm``); ``project``: world
    points onto a free-form face (``FreeformSurface.project_mm``), the sag's. Inserted rows have path_index -1 and
    the zone of their step (of its lead, on a step between work and a lead); the events get ``spline_steps``
    (rows inserted, rounds, the tolerance, the deepest the spline goes in after them)."""
    jp = joint_path
    base_inv = np.linalg.inv(robot.base_T_mm)
    base_project = None if project is None else in_frame(project, np.asarray(robot.base_T_mm, float))
    tol = settings.depth_tol_mm
    rounds = inserted = 0
    rows, depth, step_mm = _spline_steps(jp, path, robot, settings.feed_mm_s, signed_distance)
    while rounds < MAX_ROUNDS and (depth > tol).any():
        split = rows[(depth > tol) & _splittable(jp, rows, step_mm)]
        if not len(split):
            break
        q = np.asarray(jp.q, float)
        Ta, Tb = _step_poses(jp, path, solver, split, base_inv), _step_poses(jp, path, solver, split + 1, base_inv)
        T_mid = step_midposes(Ta, Tb, base_project)
        inserts = {}
        for i, r in enumerate(split):
            q_new = _midpose_q(solver, T_mid[i], q[r], q[r + 1])
            if q_new is not None:
                inserts[int(r)] = q_new[None]
        if not inserts:
            break
        jp = jp.with_rows_inserted(inserts, inserted_zones(jp.zone, inserts), jp.events)
        rounds, inserted = rounds + 1, inserted + len(inserts)
        rows, depth, step_mm = _spline_steps(jp, path, robot, settings.feed_mm_s, signed_distance)
    events = {**jp.events, "spline_steps": {"rows": inserted, "rounds": rounds, "depth_tol_mm": tol,
                                            "max_depth_mm": round(max(float(depth.max(initial=0.0)), 0.0), 4)}}
    return replace(jp, events=events)
