"""The whole pipeline for one job, one stage after another, data flowing forward:

    load job -> workpiece -> fit -> raster -> plan -> time -> check -> post

``run_job`` checks the plugins, profiles and output folder first, builds the
job's settings once, and hands the job to its task (``camtool.tasks.TASKS``).
No program is ever written by a run that failed a stage or a check.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

from .job import Job
from .post import preflight
from .settings import JobSettings
from .stages import (RunResult, StageLog, path_for_job, plan_and_time, robot_for_job, surface_for_job,
                     workpiece_for_job)
from .tasks import TASKS

__all__ = ["RunResult", "run_job", "robot_for_job", "workpiece_for_job", "surface_for_job", "path_for_job",
           "plan_and_time"]


def run_job(job: Job, outdir: Path, compare: bool = False, on_stage: Callable | None = None) -> RunResult:
    """Run every stage of ``job``; programs, report.json, points.csv and plots go into ``outdir``.

    No program is written unless planning, timing, the independent trajectory
    check and every program check succeed.
    """
    robot = robot_for_job(job)
    preflight(robot, job, outdir)  # plugins, profiles and the output folder, before any work
    settings = JobSettings.from_job(job, robot)
    log = StageLog(on_stage=on_stage)
    return TASKS[job.task.kind](job, settings, robot, Path(outdir), log, compare=compare)
