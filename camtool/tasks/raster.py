"""The main seed's task (``task.kind = "raster"``): a surface raster planned for a redundant arm.

    workpiece -> fit -> raster -> plan (+ home moves) -> time -> check -> post -> report
"""
from __future__ import annotations

from pathlib import Path

from ..errors import BadInput, PlanInfeasible
from ..job import Job
from ..settings import JobSettings
from ..stages import (StageLog, RunResult, finish_run, path_for_job, plan_and_time, post_checked,
                      report_unreachable, run_report, surface_for_job, workpiece_for_job)


def run(job: Job, settings: JobSettings, robot, outdir: Path, log: StageLog, compare: bool = False) -> RunResult:
    """Run a raster job; programs, report.json, points.csv and plots go into ``outdir``."""
    if settings.planner.method == "arm-angle-sqp":
        raise BadInput(f"{job.path}: planner.method: 'arm-angle-sqp' plans task.kind = 'sequential_reach', "
                       f"not {job.task.kind!r} jobs")
    outdir = Path(outdir)
    wp = log.done("workpiece", workpiece_for_job(job))
    surface = log.done("fit", surface_for_job(job, wp))
    path = log.done("raster", path_for_job(job, surface))
    try:
        joint_path, trajectory = plan_and_time(settings, path, robot, workpiece=wp)
    except PlanInfeasible as exc:
        report_unreachable(exc, path, robot, job, outdir, wp, surface)
        raise
    log.done("plan", joint_path)
    log.done("time", trajectory)
    programs = log.done("post", post_checked(trajectory, robot, job, outdir))
    report = run_report(path, joint_path, trajectory, robot, job, settings.planner.method)
    if "free_moves" in joint_path.events:
        report["free_moves"] = joint_path.events["free_moves"]
    report["limits_ok"] = True  # post_checked passed the independent check
    report["status"] = "ok"
    trajectories = {settings.planner.method: trajectory}
    if compare:
        other = "general" if settings.planner.method == "seed" else "seed"
        try:
            jp2, tr2 = plan_and_time(settings, path, robot, other, workpiece=wp)
            trajectories[other] = tr2
            report["compare"] = run_report(path, jp2, tr2, robot, job, other)
        except PlanInfeasible as exc:
            report["compare"] = {"method": other, "status": "infeasible", "reason": str(exc)}
    return finish_run(log, programs, report, path, joint_path, robot, trajectories, outdir)
