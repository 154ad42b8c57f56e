"""The whole pipeline for one job, one stage after another, data flowing forward:

    load job -> workpiece -> fit -> raster -> plan -> time -> check -> post

``run_job`` checks the plugins, profiles and output folder first, builds the
job's settings once, and hands the job to its task (``camtool.run.tasks.TASKS``).
No program is ever written by a run that failed a stage or a check, and the
output folder always holds one consistent run (``camtool/run/output.py``).
"""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from types import MappingProxyType
from typing import Callable

from ..errors import CamtoolError
from ..job import Job
from .output import final_path, place, staged_output
from .post_inputs import preflight
from .job_settings import JobSettings
from .part_stages import JobPart, PartHere
from .stages import (RunResult, StageLog, path_for_job, plan_and_time, robot_for_job, surface_for_job,
                     workpiece_for_job)
from .tasks import TASKS

__all__ = ["RunResult", "run_job", "robot_for_job", "workpiece_for_job", "surface_for_job", "path_for_job",
           "plan_and_time"]


def run_job(job: Job, outdir: Path, compare: bool = False, on_stage: Callable | None = None,
            part: JobPart | None = None) -> RunResult:
    """Run every stage of ``job``; programs, report.json, points.csv and plots go into ``outdir``.

    No program is written unless planning, timing, the independent trajectory
    check and every program check succeed. ``part``: the job's workpiece and surface (``part_stages``:
    ``camtool run`` makes them ahead, ``PartAhead``); by default they are made here (``PartHere``).
    """
    robot = robot_for_job(job)
    outdir = Path(outdir)
    preflight(robot, job, outdir)  # plugins, profiles and the output folder, before any work
    settings = JobSettings.from_job(job, robot)
    log = StageLog(on_stage=on_stage)
    with staged_output(outdir) as stage:
        try:
            result = TASKS[job.task.kind](job, settings, robot, stage, log, compare=compare,
                                          part=part if part is not None else PartHere(job))
        except CamtoolError as exc:
            if (stage / "report.json").is_file():  # a failure report: placed, and the old programs go
                place(stage, outdir)
            exc.args = tuple(a.replace(str(stage), str(outdir)) if isinstance(a, str) else a for a in exc.args)
            raise
        place(stage, outdir)
    outputs = dict(result.outputs)
    outputs["report"] = json.loads((outdir / "report.json").read_text())  # the paths as placed
    return replace(result, files=tuple(final_path(f, stage, outdir) for f in result.files),
                   outputs=MappingProxyType(outputs))
