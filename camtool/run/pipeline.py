"""The whole pipeline for one job, one stage after another, data flowing forward:

    load job -> workpiece -> fit -> raster -> plan -> time -> check -> post

``run_job`` checks the plugins, profiles and output folder first, builds the
job's settings once, and hands the job to its task (``camtool.run.tasks.TASKS``).
No program is ever written by a run that failed a stage or a check, and the
output folder always holds one consistent run (``camtool/run/output.py``).
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from types import MappingProxyType
from typing import Callable

from .. import safe_io
from ..errors import CamtoolError
from ..job import Job
from ..report.run_report import write_json_atomic
from .output import final_path, place, staged_output
from .post_inputs import preflight, prepare_outdir
from .job_settings import JobSettings
from .part_stages import JobPart, PartHere
from .stages import (RunResult, StageLog, path_for_job, plan_and_time, robot_for_job, surface_for_job,
                     workpiece_for_job)
from .tasks import TASKS

__all__ = ["RunResult", "run_job", "robot_for_job", "workpiece_for_job", "surface_for_job", "path_for_job",
           "plan_and_time"]


def failure_report(job: Job, exc: BaseException, stage: Path, outdir: Path) -> dict:
    """report.json of a run that failed at a stage that writes no report of its own (bad input, a timing
    or post failure, an internal error, an interrupt): its status, exit code and reason, so the folder
    never shows the previous run's report as if it were this one's (issue #48)."""
    if isinstance(exc, KeyboardInterrupt):
        code, reason = 130, "interrupted"
    else:
        code = getattr(exc, "exit_code", 1) if isinstance(exc, CamtoolError) else 1
        reason = (str(exc) or type(exc).__name__).replace(str(stage), str(outdir))
    status = {2: "bad_input", 3: "infeasible", 4: "unavailable"}.get(code, "failed")
    return {"robot": getattr(getattr(job, "robot", None), "name", None), "job": str(getattr(job, "path", "")),
            "status": status, "exit_code": code, "reason": reason}


def run_job(job: Job, outdir: Path, compare: bool = False, on_stage: Callable | None = None,
            part: JobPart | None = None) -> RunResult:
    """Run every stage of ``job``; programs, report.json, points.csv and plots go into ``outdir``.

    No program is written unless planning, timing, the independent trajectory
    check and every program check succeed. ``part``: the job's workpiece and surface (``part_stages``:
    ``camtool run`` makes them ahead, ``PartAhead``); by default they are made here (``PartHere``).
    """
    outdir = Path(outdir)
    prepare_outdir(outdir)  # a folder camtool may not write into is refused before anything in it changes
    with staged_output(outdir) as stage:
        try:
            robot = robot_for_job(job)
            preflight(robot, job, outdir)  # plugins, profiles and the output folder, before any work
            settings = JobSettings.from_job(job, robot)
            log = StageLog(on_stage=on_stage)
            result = TASKS[job.task.kind](job, settings, robot, stage, log, compare=compare,
                                          part=part if part is not None else PartHere(job))
        except BaseException as exc:
            if not (stage / "report.json").is_file():  # a stage that writes no report: a report of this failure
                write_json_atomic(failure_report(job, exc, stage, outdir), stage / "report.json")
            place(stage, outdir)  # the failure report placed; the previous run's programs and report go
            if isinstance(exc, CamtoolError):
                exc.args = tuple(a.replace(str(stage), str(outdir)) if isinstance(a, str) else a for a in exc.args)
            raise
        # read in the private staging folder, before placing, with the paths as placed: never OUT/report.json again
        report = safe_io.load_json(safe_io.read_input_bytes(stage / "report.json", "manifest", follow=False)
                                   .replace(str(stage).encode(), str(outdir).encode()), stage / "report.json")
        place(stage, outdir)
    outputs = dict(result.outputs)
    outputs["report"] = report
    return replace(result, files=tuple(final_path(f, stage, outdir) for f in result.files),
                   outputs=MappingProxyType(outputs))
