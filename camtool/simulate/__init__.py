"""Program simulator: re-execute a written program the way the controller interpolates it.

It reads what a program says (``ProgramMoves``, from the plugin's
``read_program``), never the planner's data, and shares no code with the
writers:

- **Targets.** Joint targets as written. A Cartesian target (MoveL / MOVL,
  MoveC / MOVC) is solved for the joints it leaves open by damped least squares,
  starting from the previous target (the controller keeps its configuration),
  and its configuration (ABB confdata) is compared with the program's.
- **Timing.** A move takes its written duration (``\\T``, or the VJ estimate), or
  its length over its TCP speed (the slower of TCP and reorientation speed);
  along a move the speed is constant (the controller's acceleration ramps are
  not modelled).
- **Interpolation** at ``dt_s`` (<= 4 ms): joint-linear for joint moves; a
  straight TCP line (orientation by slerp) for linear moves; a circle through
  the start, the circle point and the target for circular moves, with its joint
  values by batch Newton from the joint-linear guess.
- **Corners.** A target with a blend radius r (zone, PL) is cut by a parabolic
  blend: from ``tau`` before the target to ``tau`` after it, with
  ``tau = min(f_in T_in, f_out T_out)`` and ``f = min(1/2, r / L)`` of each move,
  the path is the quadratic curve with the target as its control point, so the
  velocity goes linearly from the incoming move's to the outgoing one's. It is
  computed in joint space for joint moves (L of a joint move: the larger of its
  TCP length and its largest joint travel in deg over 0.15 deg/mm) and in TCP
  space for Cartesian ones; r = 0 (``fine``, ``PL=0``) stops exactly at the
  target.
- **The surface** is where the program says the process runs: from the move
  after a row-start marker (``! Row`` comment, tool on) to the move before the
  row-end marker (tool off).

``simulate`` reports, against a planned path (``Reference``): the largest
distance of the simulated TCP from the planned path on work (mm), TCP feed
statistics on work, exact stops and module / job switches on the surface,
joint position and speed limit violations, and the program's time against the
plan's. ``SimReport.findings`` lists what breaks the acceptance rules; ``SimReport.deviation_s``
holds each move's largest deviation on work with its time span (the post stage writes the moves
farther than it aims for closer to the plan, ``camtool.program.post``).

The modules, one job each: ``reference`` (the planned path), ``interpolation`` (the
controller's interpolation at ``dt_s``), ``measures`` (limits, the surface, feed,
deviation, ``SimReport``); the targets' joint values and the moves' durations are the
program model's generic reading (``camtool.program.targets`` / ``durations``), which
the plugins' readers use too.
"""
from __future__ import annotations

import numpy as np

from camtool.program.durations import move_durations
from camtool.program.targets import _Chain, _robot_for, _target_poses, configuration_findings, target_joints

from .interpolation import interpolate
from .measures import SimReport, limit_findings, summary_lines, surface_of, unfollowed_moves, work_figures
from .reference import Reference, reference_from_path, reference_from_samples, reference_from_trajectory

SIM_DT_S = 0.004

__all__ = ["SIM_DT_S", "Reference", "SimReport", "move_durations", "reference_from_path", "reference_from_samples",
           "reference_from_trajectory", "simulate", "summary_lines", "target_joints"]


def simulate(prog, robot, reference: Reference | None = None, *, dt_s: float = SIM_DT_S,
             path_tol_mm: float | None = None, profile=None, world=None) -> SimReport:
    """Re-execute ``prog`` (a ``ProgramMoves``) at ``dt_s`` and measure it (module doc).

    ``reference`` (optional) is the planned path; without it there is no deviation and no
    time comparison. ``path_tol_mm`` makes a larger deviation a finding. ``world`` (a
    ``camtool.collision.CollisionWorld`` of the same robot, optional): every body pair of the
    cell (link x obstacle, link x link) is measured on the simulated motion too, and a pair
    that touches or overlaps is a finding.
    """
    robot = _robot_for(prog, robot)
    findings: list[str] = []
    M = len(prog)
    if M == 0:
        return SimReport(0, 0.0, None, 0, 0.0, 0.0, 0, None, None, {}, 0, 0, 0, 0, 0, 0, 0, ["no moves"])
    chain = _Chain(robot)
    q_t = target_joints(prog, robot, profile)
    bad_t = np.flatnonzero(~np.isfinite(q_t).all(axis=1))
    for k in bad_t[:20]:
        findings.append(f"{prog.where[k]}: no joint values reach this target")
    if len(bad_t):
        return SimReport(M, float("nan"), None, 0, 0.0, 0.0, 0, None, None, {}, 0, 0, 0, 0, 0, 0, 0, findings)
    findings += configuration_findings(prog, robot, q_t, profile)
    P_t, R_t = _target_poses(prog, robot, q_t)
    dur = move_durations(prog, robot, q_t)
    s = interpolate(prog, robot, chain, q_t, P_t, R_t, dur, dt_s)
    findings += s.findings
    n_lim, n_speed, found = limit_findings(prog, robot, chain, s)
    findings += found
    surf, found = surface_of(prog, s)
    findings += found
    work_len, feed, max_dev, p99, planned, found, moves_dev = work_figures(prog, chain, s, surf, reference, path_tol_mm)
    findings += found
    cell = None
    if world is not None and world.pairs:
        cell, found = _cell_pass(prog, world, s)
        findings += found
    t, S, on_work = s.t, len(s.t), surf.on_work
    stops = int(surf.blend_zero.sum())
    return SimReport(moves=M, duration_s=s.total, planned_duration_s=planned, rows=len(surf.rows),
                     work_length_mm=work_len, work_time_s=float(np.diff(t)[on_work[1:] & on_work[:-1]].sum())
                     if S > 1 else 0.0, moves_on_work=surf.moves_on_work, max_deviation_mm=max_dev,
                     p99_deviation_mm=p99, feed=feed, exact_stops=stops, exact_stops_on_surface=surf.stops_surface,
                     part_switches=int(surf.switch_after.sum()), part_switches_on_surface=surf.switches_surface,
                     limit_violations=n_lim, speed_violations=n_speed, samples=S, findings=findings, cell=cell,
                     unfollowed_s=unfollowed_moves(robot, chain, s) if n_lim or n_speed or len(s.unsolved) else (),
                     deviation_s=moves_dev)


def _cell_pass(prog, world, s) -> tuple[dict, list[str]]:
    """The world's pairs on the simulated samples (``camtool.motion.cell_check``): figures and findings."""
    from camtool.motion.cell_check import check_sampled_motion

    rep = check_sampled_motion(world, s.q, threshold_mm=0.0)
    found = []
    for a, b, d, k, pts in rep.collisions:
        i = min(int(k), len(s.t) - 1)
        near = " at ({:.0f}, {:.0f}, {:.0f}) mm".format(*pts[0]) if len(pts) else ""
        found.append(f"{prog.where[int(s.m[i])]}: {a} and {b} overlap by {-d:.3f} mm at t = {float(s.t[i]):.3f} s"
                     f"{near} (the program as the controller runs it)")
    figures = {"pairs": len(world.pairs), "threshold_mm": rep.threshold_mm, "evaluations": rep.evaluations,
               "seconds": round(rep.seconds, 4), "collisions": len(rep.collisions)}
    return figures, found
