"""The whole pipeline for one job, one stage after another, data flowing forward:

    load job -> workpiece -> fit -> raster -> plan -> time -> check -> post

Each stage is one module with one entry function. A stage whose module this
camtool does not have stops the run with ``StageUnavailable`` (exit 4),
naming the last stage that ran; no program is ever written by a partial run.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from .errors import StageUnavailable
from .job import Job

STAGES = (
    ("workpiece", "camtool.workpiece", "load_workpiece"),
    ("fit", "camtool.fit", "fit_surface"),
    ("raster", "camtool.raster", "raster_path"),
    ("plan", "camtool.plan", "plan_path"),
    ("time", "camtool.timing", "time_trajectory"),
    ("post", "camtool.post", "write_programs"),
)


def stage_function(stage: str, done: list[str]) -> Callable:
    """The entry function of a stage, or StageUnavailable naming the last stage run."""
    for name, module, func in STAGES:
        if name == stage:
            try:
                return getattr(importlib.import_module(module), func)
            except ModuleNotFoundError as exc:
                if exc.name != module:
                    raise
                after = f"after '{done[-1]}'" if done else "before the first stage"
                raise StageUnavailable(
                    f"stage '{stage}' is not available in this camtool yet; the run stopped {after} "
                    "and wrote no program") from None
    raise KeyError(stage)


@dataclass
class RunResult:
    """What a run produced: the stages that ran, their outputs, and the files written."""

    stages: list[str] = field(default_factory=list)
    outputs: dict = field(default_factory=dict)
    files: list[Path] = field(default_factory=list)


def workpiece_for_job(job: Job, done: list[str] | None = None):
    """Load the job's workpiece and place it in the world frame (cell.workpiece_*)."""
    from .transforms import matrix_from_xyz_rpy

    wp = stage_function("workpiece", done or [])(
        job.resolve(job.workpiece.file), units=job.workpiece.units,
        sample_points=job.workpiece.sample_points,
        normal_neighbours=job.workpiece.normal_neighbours, seed=job.fit.seed)
    return wp.transformed(matrix_from_xyz_rpy(job.cell.workpiece_xyz_mm, job.cell.workpiece_rpy_deg))


def surface_for_job(job: Job, workpiece, done: list[str] | None = None):
    """Fit the job's surface (world frame) to a placed workpiece."""
    return stage_function("fit", done or ["workpiece"])(workpiece, **job.fit)


def path_for_job(job: Job, surface, done: list[str] | None = None):
    """Raster the job's surface into a tool Path (world frame)."""
    return stage_function("raster", done or ["workpiece", "fit"])(surface, **job.raster)


def robot_for_job(job: Job):
    """The job's robot with its base placement and tool."""
    from .robots import get_robot
    from .transforms import matrix_from_xyz_rpy

    return get_robot(job.robot.name, job.robot.params, job.dir).with_placement(
        matrix_from_xyz_rpy(job.cell.base_xyz_mm, job.cell.base_rpy_deg),
        matrix_from_xyz_rpy(job.tool.tcp_xyz_mm, job.tool.tcp_rpy_deg))


def run_job(job: Job, outdir: Path) -> RunResult:
    """Run every stage of ``job``; programs and the report go into ``outdir``."""
    r = RunResult()

    def done(name, value):
        r.outputs[name] = value
        r.stages.append(name)
        return value

    wp = done("workpiece", workpiece_for_job(job, r.stages))
    surface = done("fit", surface_for_job(job, wp, r.stages))
    path = done("raster", path_for_job(job, surface, r.stages))
    robot = robot_for_job(job)
    plan = stage_function("plan", r.stages)
    joint_path = done("plan", plan(path, robot, home_deg=job.robot.home_deg, **job.planner))
    time = stage_function("time", r.stages)
    trajectory = done("time", time(joint_path, path, robot, **job.timing))
    post = stage_function("post", r.stages)
    r.files = done("post", post(trajectory, robot, job, Path(outdir)))
    return r
