"""Seed 002's sequential reaching task on a plane (``task.kind = "sequential_reach"``).

    load job -> workpiece -> fit (plane) -> targets -> arm-angle SQP -> time -> check -> post

Targets: the grid ``grid_origin_mm + grid_step_mm * (m * h + n * v)`` with
``v`` = ``task.tool_y_world`` and ``h`` along the plane, projected onto the
target plane: by default the RANSAC plane fitted to the workpiece scan (as in
seed 002), or ``task.plane_point_mm`` / ``task.plane_normal``. The tool z axis
is the plane normal pointing away from the robot base, the tool y axis follows
``tool_y_world``. The route is an S-shaped sweep over rows (horizontal) or
columns (vertical), starting at the grid corner nearest to the start point.

The Path: the start pose (zone ``approach``), then one single-pose ``work``
run per target (each its own segment), so the timing stage times every move
between targets as a rest-to-rest ruckig move (docs/timing.md). A start point
on the first target (seed 002's start is the grid corner (350, 600, 950)) is
that target: the robot starts there.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path as FsPath

import numpy as np

from ...errors import BadInput, PlanInfeasible
from ...job import Job
from ..part_stages import JobPart
from ...plan.arm_angle_sqp import plan_arm_angle_sqp
from ...report.run_report import write_json_atomic
from ...collision.stage import collision_world
from ..job_settings import JobSettings
from ..stages import (RunResult, StageLog, finish_run, lift_connectors, motion_check, part_for_checks, post_checked,
                      report_failure, run_report, time_for_job)
from ...path.toolpath import ZONE_CODE, Path

FAMILY_TABLE_FILE = "arm_angle_families.txt"
START_MERGE_MM = 1e-3  # a start point this close to the first target is that target


def _unit(v, what: str) -> np.ndarray:
    v = np.asarray(v, float)
    n = np.linalg.norm(v)
    if n < 1e-9:
        raise BadInput(f"{what}: expected a non-zero vector, found {v.tolist()}")
    return v / n


def target_plane(job: Job, surface=None) -> tuple[np.ndarray, np.ndarray]:
    """(point, unit normal) of the target plane in the world frame, mm."""
    if job.task.plane == "fit":
        if surface is None or not hasattr(surface, "u_axis"):
            kind = type(surface).__name__ if surface is not None else "nothing"
            raise BadInput(f"{job.path}: task.plane = 'fit' needs a plane fitted to the workpiece, found {kind}; "
                           "set fit.model = 'plane' or task.plane = 'job'")
        return np.asarray(surface.origin_mm, float), _unit(surface.normal, "fitted plane normal")
    return np.asarray(job.task.plane_point_mm, float), _unit(job.task.plane_normal, f"{job.path}: task.plane_normal")


def reach_path(job: Job, point_mm: np.ndarray, normal: np.ndarray, base_xyz_mm) -> Path:
    """The start pose and the S-ordered grid targets as a Path (world frame TCP poses)."""
    t = job.task
    base = np.asarray(base_xyz_mm, float)
    z = normal if normal @ (point_mm - base) > 0 else -normal       # tool z points away from the robot
    yw = np.asarray(t.tool_y_world, float)
    y = yw - (yw @ z) * z
    if np.linalg.norm(y) < 1e-6:
        raise BadInput(f"{job.path}: task.tool_y_world is perpendicular to the target plane")
    y /= np.linalg.norm(y)
    x = np.cross(y, z)
    R = np.column_stack([x, y, z])

    def project(p):
        p = np.asarray(p, float)
        return p - ((p - point_mm) @ z) * z

    h = -x  # grid m direction: for the paper's wall (z = +y world) -x tool is +x world
    origin = project(t.grid_origin_mm)
    step = t.grid_step_mm
    grid = {(m, n): origin + step * (m * h + n * y) for m in range(t.grid_columns) for n in range(t.grid_rows)}
    start = project(t.start_mm)
    m0, n0 = min(grid, key=lambda k: float(np.linalg.norm(grid[k] - start)))
    ms = list(range(t.grid_columns)) if m0 == 0 else list(range(t.grid_columns - 1, -1, -1))
    ns = list(range(t.grid_rows)) if n0 == 0 else list(range(t.grid_rows - 1, -1, -1))
    order = []
    if t.route == "horizontal":
        for i, n in enumerate(ns):
            order += [(m, n) for m in (ms if i % 2 == 0 else ms[::-1])]
    else:
        for i, m in enumerate(ms):
            order += [(m, n) for n in (ns if i % 2 == 0 else ns[::-1])]
    pts = [grid[k] for k in order]
    has_start = np.linalg.norm(start - pts[0]) > START_MERGE_MM
    if has_start:
        pts.insert(0, start)
    poses = np.tile(np.eye(4), (len(pts), 1, 1))
    poses[:, :3, :3] = R
    poses[:, :3, 3] = pts
    zone = np.full(len(pts), ZONE_CODE["work"])
    point = np.ones(len(pts), int)
    if has_start:
        zone[0] = ZONE_CODE["approach"]
        point[0] = 0
    return Path(poses, np.arange(len(pts)), point, zone, step_over_mm=step, pitch_mm=step)


def family_table_text(res) -> str:
    """The per-family table as fixed-width text (E in rad)."""
    lines = ["family  g1 g2 g3  E_fixed_rad  fixed_ok  E_opt_rad  opt_ok  sqp_it"]
    for i, f in enumerate(res.families):
        mark = "  <- kept (" + res.best_source + ")" if i == res.best else ""

        def e(x):
            return f"{x:11.4f}" if np.isfinite(x) else "        nan"
        lines.append(f"{i + 1:6d}  {f.family[0]:+d} {f.family[1]:+d} {f.family[2]:+d}  {e(f.fixed_E_rad)}  "
                     f"{'yes' if f.fixed_feasible else 'no':>8}  {e(f.opt_E_rad)[1:]}  "
                     f"{'yes' if f.opt_feasible else 'no':>6}  {f.iterations:6d}{mark}")
    return "\n".join(lines) + "\n"


def run(job: Job, settings: JobSettings, robot, outdir, log: StageLog, compare: bool = False, *,
        part: JobPart) -> RunResult:
    """Run a sequential_reach job (see module doc). ``compare`` does not apply and is ignored; ``part``: its
    workpiece and surface (``part_stages.JobPart``)."""
    if settings.planner.method != "arm-angle-sqp":
        raise BadInput(f"{job.path}: planner.method: task.kind = 'sequential_reach' is planned by "
                       f"'arm-angle-sqp', found {job.planner.method!r}")
    outdir = FsPath(outdir)
    done = log.done

    surface = wp = None
    if job.task.plane == "fit":
        wp = done("workpiece", part.workpiece())
        surface = done("fit", part.surface())
    point, normal = target_plane(job, surface)
    path = done("raster", reach_path(job, point, normal, job.cell.base_xyz_mm))
    try:
        joint_path, res = plan_arm_angle_sqp(path, robot, job.task.arm_angle0_deg, job.task.sqp_max_iterations,
                                             job.task.track_mm)
    except PlanInfeasible as exc:
        write_json_atomic({"robot": robot.name, "method": job.planner.method, "status": "infeasible",
                           "reason": str(exc), **exc.report}, outdir / "report.json")
        raise
    if wp is not None:  # the tool leaves the wall between targets (a joint move between them grazes it)
        joint_path = lift_connectors(replace(settings.planner, lift_mm=float(job.task.hop_mm), lift_steps=1),
                                     part_for_checks(settings, wp, surface), path, robot, joint_path, every=True)
    done("plan", joint_path)
    trajectory = done("time", time_for_job(settings, joint_path, path, robot))
    motion = None
    if wp is not None:  # the scanned wall: no move may go behind it
        try:
            motion = done("check", motion_check(settings, trajectory, robot, wp, path, surface))
        except PlanInfeasible as exc:
            report_failure(exc, path, joint_path, robot, job, outdir, wp, surface,
                           world=collision_world(settings, robot))
            raise
    simulated: dict = {}
    programs = done("post", post_checked(trajectory, robot, job, outdir, path=path, report=simulated))
    report = run_report(path, joint_path, trajectory, robot, job, job.planner.method)
    best = res.families[res.best]
    if motion is not None:
        report["motion_check"] = motion
    report["programs_simulated"] = simulated
    report["limits_ok"] = True
    report["status"] = "ok"
    report["task"] = {"kind": "sequential_reach", "route": job.task.route, "plane": job.task.plane,
                      "plane_point_mm": point.tolist(), "plane_normal": normal.tolist(),
                      "targets": int(np.count_nonzero(path.zone == ZONE_CODE["work"])),
                      "poses": int(len(path))}
    report["arm_angle_sqp"] = {
        "theta0_deg": float(np.degrees(res.theta0_rad)),
        "best_family": list(best.family), "best_family_number": res.best + 1, "best_source": res.best_source,
        "best_E_rad": float(best.opt_E_rad if res.best_source == "optimised" else best.fixed_E_rad),
        "families": res.table()}
    table = outdir / FAMILY_TABLE_FILE
    table.write_text(family_table_text(res))
    return finish_run(log, programs, report, path, joint_path, robot, {job.planner.method: trajectory}, outdir,
                      [table], world=collision_world(settings, robot))
