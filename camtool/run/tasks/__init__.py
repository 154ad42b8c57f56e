"""The task registry: what a job does, by ``task.kind``.

    TASKS[kind](job, settings, robot, outdir, log, compare=..., part=...) -> RunResult

(``part``: the job's workpiece and surface, ``part_stages.JobPart``.)

- ``raster`` (``tasks/raster.py``): the main seed's surface raster.
- ``sequential_reach`` (``tasks/reach.py``): seed 002's target grid by arm-angle SQP.
- ``cartesian`` (``tasks/cartesian.py``): seed 001's line and arc moves.

Every task composes the shared stage functions of ``camtool.run.stages``, which
import no task; adding a task touches this table and one new module.
"""
from __future__ import annotations

from typing import Callable

from . import cartesian, raster, reach

TASKS: dict[str, Callable] = {
    "raster": raster.run,
    "sequential_reach": reach.run,
    "cartesian": cartesian.run,
}

__all__ = ["TASKS"]
