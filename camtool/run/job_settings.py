"""Every stage's settings of one job, read from the job once at the top of a run: below ``run/``
each stage takes its settings object (``camtool.settings``), never the raw job."""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import BadInput
from ..job import Job
from ..settings import (
    CheckSettings,
    FitSettings,
    PlannerSettings,
    PostSettings,
    ProcessSettings,
    RasterSettings,
    TimingSettings,
    WorkpieceSettings,
)

if TYPE_CHECKING:
    from ..collision import CellSettings


def home_q(job: Job, robot) -> np.ndarray | None:
    """``robot.home_deg`` in native joint units (rad / mm), or None when the job gives none."""
    values = job.robot.home_deg
    if not values:
        return None
    if len(values) != robot.dof:
        raise BadInput(f"{job.path}: robot.home_deg: {robot.name} needs {robot.dof} values, found {len(values)}")
    return robot.q_from_edge(values)


@dataclass(frozen=True)
class JobSettings:
    """Every stage's settings of one job."""

    workpiece: WorkpieceSettings
    fit: FitSettings
    raster: RasterSettings
    planner: PlannerSettings
    timing: TimingSettings
    post: PostSettings
    check: CheckSettings
    process: ProcessSettings | None = None
    cell: "CellSettings | None" = None   # obstacles, floor, clearance (camtool.collision); None = an empty cell
    segmented: bool = False  # [faces] select splits the workpiece into faces (camtool.part.faces)

    @classmethod
    def from_job(cls, job: Job, robot=None) -> "JobSettings":
        """All settings of ``job``; ``robot`` (for the home configuration's units) may be omitted."""
        q_home = home_q(job, robot) if robot is not None else None
        return cls(workpiece=WorkpieceSettings.from_section(job.workpiece), fit=FitSettings.from_section(job.fit),
                   raster=RasterSettings.from_section(job.raster),
                   planner=PlannerSettings.from_section(job.planner, q_home),
                   timing=TimingSettings.from_section(job.timing), post=PostSettings.from_section(job.post),
                   check=CheckSettings.from_section(job.check),
                   process=ProcessSettings.from_section(job.process, job.check.tool_radius_mm),
                   cell=_cell_settings(job), segmented=job.faces.select != "single")


def _cell_settings(job: Job) -> "CellSettings":
    """The job's collision cell (``camtool.collision.CellSettings``): its ``[cell]`` obstacles, floor,
    clearance and matrix overrides, and the ``[tool] mesh``."""
    from ..collision import CellSettings, obstacle_bodies
    from ..collision.shapes import mesh_points
    from ..collision.spec import obstacle_specs
    from ..transforms import matrix_from_xyz_rpy

    c = job.cell
    wp_T = matrix_from_xyz_rpy(c.workpiece_xyz_mm, c.workpiece_rpy_deg)
    obstacles = obstacle_bodies(obstacle_specs(c.obstacles), wp_T, job.dir, c.floor_z_mm)
    tool = mesh_points(job.resolve(job.tool.mesh), job.tool.mesh_units) if job.tool.mesh else None
    return CellSettings(obstacles, float(c.clearance_mm), tuple(map(tuple, c.allow_collision)),
                        tuple(map(tuple, c.check_collision)), tool)
