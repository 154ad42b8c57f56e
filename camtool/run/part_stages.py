"""The workpiece and fit stages of a job, and the same made ahead in a forked process.

``workpiece_for_job`` loads and places the job's workpiece; ``surface_for_job`` fits its surface
(or the selected face's). Both need only the workpiece readers and the fit, so this module
imports nothing else heavy (``camtool.run.stages`` re-exports them).

A task takes them through a ``JobPart``, each at its own stage: ``PartHere`` makes them in the
run's process when asked; ``PartAhead`` makes both in a child forked as ``camtool run`` starts (``alongside.Alongside``),
while the run's own process imports the pipeline: for most of a second that process uses one
core, and the child's imports, reading and fitting take the other. The run then takes the
workpiece and the surface from the child, each at its own stage (``workpiece()``, ``surface()``):
a file that cannot be read is refused at the workpiece stage, and a fit that fails at the fit
stage, with the same message as when they are made in the run's process.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from functools import partial

from .alongside import Alongside
from ..errors import CamtoolError
from ..part.faces import face_surface_for_job, segmented
from ..part.fit import fit_surface
from ..job import Job
from ..settings import FitSettings, WorkpieceSettings
from ..transforms import matrix_from_xyz_rpy
from ..part.workpiece import load_workpiece


def workpiece_for_job(job: Job):
    """Load the job's workpiece and place it in the world frame (cell.workpiece_*)."""
    s = WorkpieceSettings.from_section(job.workpiece)
    wp = load_workpiece(job.resolve(s.file), units=s.units, sample_points=s.sample_points,
                        normal_neighbours=s.normal_neighbours, seed=job.fit.seed, drop_nonfinite=s.drop_nonfinite)
    return wp.transformed(matrix_from_xyz_rpy(job.cell.workpiece_xyz_mm, job.cell.workpiece_rpy_deg))


def surface_for_job(job: Job, workpiece):
    """Fit the job's surface (world frame) to a placed workpiece; with [faces] select, the selected face's."""
    if segmented(job):
        return face_surface_for_job(job, workpiece)
    return fit_surface(workpiece, FitSettings.from_section(job.fit))


def _workpiece_and_surface(job: Job) -> tuple:
    """(workpiece, surface or the CamtoolError its fit raised): what ``PartAhead``'s child makes."""
    wp = workpiece_for_job(job)
    try:
        return wp, surface_for_job(job, wp)
    except CamtoolError as exc:   # the fit stage's error: raised there, after the workpiece stage
        return wp, exc


class JobPart(ABC):
    """The job's workpiece and fitted surface, each taken at its own stage, the workpiece first."""

    @abstractmethod
    def workpiece(self):
        """The placed workpiece (what reading it raised is raised here)."""

    @abstractmethod
    def surface(self):
        """The fitted surface (what the fit raised is raised here)."""


class PartHere(JobPart):
    """The job's workpiece and surface made in this process when asked (the workpiece once)."""

    def __init__(self, job: Job):
        self._job, self._workpiece = job, None

    def workpiece(self):
        if self._workpiece is None:
            self._workpiece = workpiece_for_job(self._job)
        return self._workpiece

    def surface(self):
        return surface_for_job(self._job, self.workpiece())


class PartAhead(JobPart):
    """The job's workpiece and surface, made in a forked child (``Alongside``; a context manager: the child
    is killed if the run ends first)."""

    def __init__(self, job: Job):
        self._child = Alongside(partial(_workpiece_and_surface, job))

    def workpiece(self):
        return self._child.result()[0]

    def surface(self):
        surface = self._child.result()[1]
        if isinstance(surface, CamtoolError):
            raise surface
        return surface

    def __enter__(self) -> "PartAhead":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self._child.__exit__(exc_type, exc, tb)
