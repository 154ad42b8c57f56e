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


def run_job(job: Job, outdir: Path) -> RunResult:
    """Run every stage of ``job``; programs and the report go into ``outdir``."""
    from .robots import get_robot
    from .transforms import matrix_from_xyz_rpy

    r = RunResult()

    def done(name, value):
        r.outputs[name] = value
        r.stages.append(name)
        return value

    cell = job.cell
    load = stage_function("workpiece", r.stages)
    wp = load(job.resolve(job.workpiece.file), units=job.workpiece.units,
              sample_points=job.workpiece.sample_points,
              normal_neighbours=job.workpiece.normal_neighbours, seed=job.fit.seed)
    wp = done("workpiece", wp.transformed(matrix_from_xyz_rpy(cell.workpiece_xyz_mm, cell.workpiece_rpy_deg)))

    surface = done("fit", stage_function("fit", r.stages)(wp, **job.fit))
    path = done("raster", stage_function("raster", r.stages)(surface, **job.raster))

    robot = get_robot(job.robot.name, job.robot.params, job.dir).with_placement(
        matrix_from_xyz_rpy(cell.base_xyz_mm, cell.base_rpy_deg),
        matrix_from_xyz_rpy(job.tool.tcp_xyz_mm, job.tool.tcp_rpy_deg))
    plan = stage_function("plan", r.stages)
    joint_path = done("plan", plan(path, robot, home_deg=job.robot.home_deg, **job.planner))
    time = stage_function("time", r.stages)
    trajectory = done("time", time(joint_path, path, robot, **job.timing))
    post = stage_function("post", r.stages)
    r.files = done("post", post(trajectory, robot, job, Path(outdir)))
    return r
