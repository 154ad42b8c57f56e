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

import math
from abc import ABC, abstractmethod
from dataclasses import replace
from functools import partial

import numpy as np

from ..alongside import Alongside
from ..errors import CamtoolError
from ..part.faces import FacesSettings, segment_faces, select_faces
from ..part.segment import SegmentSettings
from ..part.workpiece import UNIT_TO_MM
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
    wp = replace(wp, scan=s.scan)   # the job's word on whether the mesh is a scan; its surfaces judge it once by it
    return wp.transformed(matrix_from_xyz_rpy(job.cell.workpiece_xyz_mm, job.cell.workpiece_rpy_deg))


def surface_for_job(job: Job, workpiece):
    """Fit the job's surface (world frame) to a placed workpiece; with [faces] select, the selected face's."""
    faces = faces_settings(job)
    if faces.segmented:
        return face_surface(job, faces, workpiece)
    return fit_surface(workpiece, FitSettings.from_section(job.fit))


def segment_settings(job: Job) -> SegmentSettings:
    """The segmentation settings of a job: [faces] keys, with [fit]'s threshold, seed and boundary keys."""
    f, fit = job.faces, job.fit
    return SegmentSettings(threshold_mm=float(fit.threshold_mm), normal_tol_rad=math.radians(f.normal_tol_deg),
                           min_area_mm2=float(f.min_area_mm2), small_faces=f.small_faces,
                           max_faces=int(f.max_faces), seed=int(fit.seed),
                           boundary_cell_mm=float(fit.boundary_cell_mm), close_gaps_mm=float(fit.close_gaps_mm),
                           simplify_mm=float(fit.simplify_mm), sharp_edge_deg=float(f.sharp_edge_deg))


def placement_mm(job: Job) -> np.ndarray:
    """The 4x4 pose (mm) that places the workpiece file's coordinates in the cell, units included."""
    T = matrix_from_xyz_rpy(job.cell.workpiece_xyz_mm, job.cell.workpiece_rpy_deg)
    S = np.eye(4)
    S[:3, :3] *= UNIT_TO_MM[job.workpiece.units]
    return T @ S


def faces_settings(job: Job) -> FacesSettings:
    """What the faces of ``job`` depend on (``camtool.part.faces``), read from the job once."""
    return FacesSettings(select=job.faces.select, segment=segment_settings(job),
                         workpiece_file=job.resolve(job.workpiece.file), placement_mm=placement_mm(job),
                         source=str(job.path))


def face_surface(job: Job, faces: FacesSettings, workpiece):
    """The surface of the job's selected face (world frame), or a ``surface.FaceSet`` of its selected faces,
    each with the raster keys ``[faces.raster.N]`` changes for it."""
    from ..part.surface import FaceSet
    from ..path.face_set import raster_changes

    chosen = select_faces(segment_faces(faces, workpiece), faces.select, workpiece, faces.source)
    if len(chosen) == 1:
        return chosen[0].surface
    job_keys = dict(job.sections["raster"])
    changes = tuple(raster_changes(job_keys, job.faces.raster.get(str(f.index), {})) for f in chosen)
    return FaceSet(tuple(f.surface for f in chosen), tuple(f.index for f in chosen), changes)


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
