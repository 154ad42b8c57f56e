"""What the stage commands (fit, raster, plan, time, post) share: reading the input box of a stage.

Each stage command runs its stage on a JOB. With ``--from FILE`` it takes the
previous stage's saved output (``camtool.run.stage_files``); without it, it runs
the stages before it first. Either way the same settings of the same job are
used, so resumed stages reproduce ``camtool run`` byte for byte.
"""
from __future__ import annotations

from pathlib import Path

import click

from ..errors import BadInput

SURFACE_FILE, PATH_FILE, JOINT_PATH_FILE, TRAJECTORY_FILE = "surface.json", "path.npz", "joint_path.npz", \
    "trajectory.npz"


def workpiece(job):
    """The job's placed workpiece; its warnings go to stderr."""
    from ..run.stages import workpiece_for_job

    wp = workpiece_for_job(job)
    for w in wp.warnings:
        click.echo(f"camtool: warning: {w}", err=True)
    return wp


def surface_of(job, from_file: Path | None):
    """The fitted surface: from ``from_file`` (surface.json) or fitted now."""
    from ..run.stages import surface_for_job
    from ..part.surface import load_surface

    return load_surface(from_file) if from_file is not None else surface_for_job(job, workpiece(job))


def path_of(job, from_file: Path | None):
    """The tool Path: from ``from_file`` (path.npz) or rastered now."""
    from ..run.stage_files import load_stage
    from ..run.stages import path_for_job

    if from_file is not None:
        return load_stage(from_file, expect=("Path",))
    return path_for_job(job, surface_of(job, None))


def sibling(from_file: Path | None, given: Path | None, name: str, what: str) -> Path | None:
    """``given``, else ``name`` beside ``from_file`` (where the stage commands put it), else None."""
    if given is not None:
        return given
    if from_file is None:
        return None
    guess = Path(from_file).parent / name
    if not guess.is_file():
        raise BadInput(f"{from_file}: resuming needs the {what} too: give --path, or keep {name} beside it")
    return guess


def joint_path_of(job, settings, robot, from_file: Path | None, path_file: Path | None):
    """(Path, JointPath): from saved files, or planned now (with home moves when the job has a home)."""
    from ..run.stage_files import load_stage
    from ..run.stages import part_for_checks, path_for_job, plan_with_sized_leads, surface_for_job

    path_file = sibling(from_file, path_file, PATH_FILE, "path")
    if from_file is not None:
        return load_stage(path_file, expect=("Path",)), load_stage(from_file, expect=("JointPath",))
    wp = workpiece(job)
    surface = surface_for_job(job, wp)
    path = load_stage(path_file, expect=("Path",)) if path_file is not None else path_for_job(job, surface, wp)
    return plan_with_sized_leads(settings, surface, path, robot, part_for_checks(settings, wp, surface))


def trajectory_of(job, settings, robot, from_file: Path | None, path_file: Path | None = None):
    """(Path, timed trajectory): from saved files (the Path beside the trajectory), or planned and timed now."""
    from ..run.stage_files import load_stage
    from ..run.stages import time_for_job

    if from_file is not None:
        path = load_stage(sibling(from_file, path_file, PATH_FILE, "path"), expect=("Path",))
        return path, load_stage(from_file, expect=("TimedTrajectory", "Trajectory"))
    from ..timing.pathlaw import remembered_runs

    with remembered_runs():   # lead sizing plans each run's time law; the timing takes it
        path, joint_path = joint_path_of(job, settings, robot, None, None)
        return path, time_for_job(settings, joint_path, path, robot)
