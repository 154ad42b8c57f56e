"""Settings objects: one frozen dataclass per stage, built once from the validated job.

The job file speaks the process engineer's units (degrees, ms); the stages
work in radians and seconds. This module is the one place where a job key
becomes a stage setting, so unit conversions happen here and nowhere else,
and the defaults live only in the job schema (``camtool.job.SCHEMA``)::

    job = load_job("job.toml")
    robot = robot_for_job(job)
    settings = JobSettings.from_job(job, robot)
    path = raster_path(surface, settings.raster)

``XSettings.make(**job_keys)`` builds one from job-file keys (schema defaults
for the rest, the same validation as a job file): handy in scripts and tests,
e.g. ``RasterSettings.make(step_over_mm=20)``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import ClassVar

import numpy as np

from .errors import BadInput
from .job import validate


def _section(name: str, keys: dict) -> dict:
    """Job keys of one section, checked against the schema, defaults filled."""
    return validate({name: dict(keys)}, f"[{name}]")[name]


class _FromSection:
    """Shared constructors: ``from_section`` (validated keys) and ``make`` (keys + defaults)."""

    SECTION: ClassVar[str] = ""

    @classmethod
    def from_section(cls, sec: dict):  # pragma: no cover - every subclass defines it
        raise NotImplementedError

    @classmethod
    def make(cls, **job_keys):
        """Settings from job-file keys of this section (unit as in the job file), schema defaults for the rest."""
        return cls.from_section(_section(cls.SECTION, job_keys))


@dataclass(frozen=True)
class WorkpieceSettings(_FromSection):
    """How the workpiece file is read."""

    SECTION: ClassVar[str] = "workpiece"
    file: str
    units: str
    sample_points: int
    normal_neighbours: int
    drop_nonfinite: bool
    scan: str = "auto"     # a mesh judged as a scan: "auto" (by its roughness), "yes" or "no"

    @classmethod
    def from_section(cls, sec):
        return cls(sec["file"], sec["units"], int(sec["sample_points"]), int(sec["normal_neighbours"]),
                   bool(sec["drop_nonfinite"]), str(sec.get("scan", "auto")))


@dataclass(frozen=True)
class FitSettings(_FromSection):
    """RANSAC plane / sphere fit and boundary extraction (mm)."""

    SECTION: ClassVar[str] = "fit"
    model: str
    threshold_mm: float
    iterations: int
    min_inlier_ratio: float
    seed: int
    boundary_cell_mm: float
    close_gaps_mm: float
    simplify_mm: float
    smoothing_mm: float = 0.0   # free-form faces of a scan: the smoothing sigma (0 = from the point spacing)

    @classmethod
    def from_section(cls, sec):
        return cls(**{f.name: sec[f.name] for f in fields(cls)})


@dataclass(frozen=True)
class RasterSettings(_FromSection):
    """S-path raster: lengths in mm on the surface, angles in rad."""

    SECTION: ClassVar[str] = "raster"
    step_over_mm: float
    pitch_mm: float
    angle_rad: float
    lead_mm: float
    lead_auto: bool
    lead_max_mm: float
    clearance_mm: float
    self_motion_lift_mm: float
    transition_points: int
    tool_x: str
    tool_x_world: tuple[float, float, float]
    lead_rad: float
    tilt_rad: float
    free_spin: bool
    step_over_auto: bool = False  # step_over_mm = "auto": chosen from the process map (camtool.process.stepover)
    cylinder_rows: str = "around"  # on a cylinder: rows around the axis or along it
    edge_margin: float = 0.25      # the first and last rows at least this share of a step-over inside the edges
    contour: str = "auto"          # a contour pass along the boundary: "auto" (where the rows leave slivers), "on", "off"
    lead_path: str = "surface"     # the leads: on the face's surface continued, or lifted clear of the row's tangent
    max_poses: int = 1_000_000     # the most poses a raster may have (estimated before any work)
    axis_tilt_max_rad: float = math.radians(30.0)   # free-form faces: the tool axis tilted clear of the part
    axis_tilt_turn_rad: float = math.radians(4.0)   # the most that tilt changes between neighbouring poses

    @classmethod
    def from_section(cls, sec):
        auto = sec["step_over_mm"] == "auto"
        return cls(step_over_mm=0.0 if auto else float(sec["step_over_mm"]), step_over_auto=auto, pitch_mm=float(sec["pitch_mm"]),
                   angle_rad=math.radians(sec["angle_deg"]), lead_mm=float(sec["lead_mm"]),
                   lead_auto=bool(sec["lead_auto"]), lead_max_mm=float(sec["lead_max_mm"]),
                   clearance_mm=float(sec["clearance_mm"]), self_motion_lift_mm=float(sec["self_motion_lift_mm"]),
                   transition_points=int(sec["transition_points"]),
                   tool_x=sec["tool_x"], tool_x_world=tuple(float(x) for x in sec["tool_x_world"]),
                   lead_rad=math.radians(sec["lead_deg"]), tilt_rad=math.radians(sec["tilt_deg"]),
                   free_spin=bool(sec["free_spin"]), cylinder_rows=sec["cylinder_rows"],
                   edge_margin=float(sec["edge_margin"]), contour=sec["contour"], lead_path=sec["lead_path"],
                   max_poses=int(sec["max_poses"]), axis_tilt_max_rad=math.radians(sec["axis_tilt_max_deg"]),
                   axis_tilt_turn_rad=math.radians(sec["axis_tilt_turn_deg"]))


@dataclass(frozen=True)
class PlannerSettings(_FromSection):
    """The redundant-arm planner: CWLN IK, jump detection, reverse planning, retracts.

    Angles in rad, lengths in mm; ``q_home`` is the start configuration in
    native joint units (rad / mm) or None.
    """

    SECTION: ClassVar[str] = "planner"
    method: str
    damping: float
    orientation_weight_mm: float
    position_tol_mm: float
    orientation_tol_rad: float
    max_iterations: int
    track_scale_mm: float
    posture_gain: float
    clamp_buffer_rad: float
    clamp_buffer_mm: float
    jump_threshold_rad: float
    jump_threshold_mm: float
    retract_mm: float
    chord_tol_mm: float
    smooth_runs: bool
    lift_mm: float
    lift_steps: int
    reconfigure_threshold_rad: float
    reconfigure_threshold_mm: float
    reverse_samples: int
    reverse_best_of: int
    seed: int
    ik_seeds: str
    q_home: tuple[float, ...] | None = None

    @classmethod
    def from_section(cls, sec, q_home=None):
        return cls(method=sec["method"], damping=float(sec["damping"]),
                   orientation_weight_mm=float(sec["orientation_weight_mm"]),
                   position_tol_mm=float(sec["position_tol_mm"]),
                   orientation_tol_rad=math.radians(sec["orientation_tol_deg"]),
                   max_iterations=int(sec["max_iterations"]), track_scale_mm=float(sec["track_scale_mm"]),
                   posture_gain=float(sec["posture_gain"]),
                   clamp_buffer_rad=math.radians(sec["clamp_buffer_deg"]),
                   clamp_buffer_mm=float(sec["clamp_buffer_mm"]),
                   jump_threshold_rad=math.radians(sec["jump_threshold_deg"]),
                   jump_threshold_mm=float(sec["jump_threshold_mm"]), retract_mm=float(sec["retract_mm"]),
                   chord_tol_mm=float(sec["chord_tol_mm"]), smooth_runs=bool(sec["smooth_runs"]),
                   lift_mm=float(sec["lift_mm"]), lift_steps=int(sec["lift_steps"]),
                   reconfigure_threshold_rad=math.radians(sec["reconfigure_threshold_deg"]),
                   reconfigure_threshold_mm=float(sec["reconfigure_threshold_mm"]),
                   reverse_samples=int(sec["reverse_samples"]), reverse_best_of=int(sec["reverse_best_of"]),
                   seed=int(sec["seed"]), ik_seeds=sec["ik_seeds"],
                   q_home=None if q_home is None else tuple(float(x) for x in q_home))

    @classmethod
    def make(cls, q_home=None, **job_keys):
        """Settings from [planner] keys (job-file units); ``q_home`` in native units (rad / mm)."""
        return cls.from_section(_section(cls.SECTION, job_keys), q_home)

    def jump_threshold(self, prismatic: np.ndarray) -> np.ndarray:
        """Per-joint jump threshold in native units (rad, or mm for prismatic joints)."""
        return np.where(prismatic, self.jump_threshold_mm, self.jump_threshold_rad)

    def with_method(self, method: str) -> "PlannerSettings":
        return replace(self, method=method)


@dataclass(frozen=True)
class TimingSettings(_FromSection):
    """Time parameterisation: TCP feed on work (mm/s), feed policy, check step (s), free-zone mode."""

    SECTION: ClassVar[str] = "timing"
    method: str
    tcp_speed_mm_s: float
    check_dt_s: float
    zones: str
    feed: str = "constant"
    slow_scope: str = "row"
    feed_factor: tuple[float, ...] | None = None  # per Path pose, <= 1: a cap on the feed (camtool.process.dwell)

    @classmethod
    def from_section(cls, sec):
        return cls(method=sec["method"], tcp_speed_mm_s=float(sec["tcp_speed_mm_s"]),
                   check_dt_s=float(sec["check_dt_ms"]) / 1000.0, zones=sec["zones"], feed=sec["feed"],
                   slow_scope=sec["slow_scope"])


@dataclass(frozen=True)
class PostSettings(_FromSection):
    """Post-processing: formats, program name, profiles, the shortest move (s), the programs'
    path (mm) and orientation (deg) tolerances."""

    SECTION: ClassVar[str] = "post"
    formats: tuple[str, ...]
    program_name: str
    profiles: dict
    min_move_s: float
    csv_angle_unit: str
    path_tol_mm: float = 0.1
    ori_tol_deg: float = 0.5

    @classmethod
    def from_section(cls, sec):
        return cls(formats=tuple(sec["formats"]), program_name=sec["program_name"], profiles=dict(sec["profiles"]),
                   min_move_s=float(sec["min_move_ms"]) / 1000.0, csv_angle_unit=sec["csv_angle_unit"],
                   path_tol_mm=float(sec["path_tol_mm"]), ori_tol_deg=float(sec["ori_tol_deg"]))


@dataclass(frozen=True)
class CheckSettings(_FromSection):
    """The independent motion check: sampling step (s), tolerances and body sizes (mm)."""

    SECTION: ClassVar[str] = "check"
    dt_s: float
    penetration_tol_mm: float
    clearance_mm: float
    path_tol_mm: float
    tool_radius_mm: float
    link_radius_mm: float
    tool_contact_exempt_mm: float

    @classmethod
    def from_section(cls, sec):
        return cls(dt_s=float(sec["dt_ms"]) / 1000.0, **{k: float(sec[k]) for k in (
            "penetration_tol_mm", "clearance_mm", "path_tol_mm", "tool_radius_mm", "link_radius_mm",
            "tool_contact_exempt_mm")})


@dataclass(frozen=True)
class ProcessSettings(_FromSection):
    """The process model (``[process]``): what the tool does to the part; lengths in mm, SI otherwise.

    ``diameter_mm`` and ``gaussian_sigma_mm`` are resolved here (0 = from the
    tool / the diameter); ``profile_table`` is ((r_mm, value), ...).
    """

    SECTION: ClassVar[str] = "process"
    kind: str
    diameter_mm: float
    profile: str
    gaussian_sigma_mm: float
    profile_table: tuple[tuple[float, float], ...]
    force_n: float
    preston_coefficient_per_pa: float
    relative_speed_m_s: float
    deposition_mm3_s: float
    contact_tol_mm: float
    grid_mm: float
    uniformity_target: float
    uniformity_band: float
    target_removal_file: str
    dwell_iterations: int
    feed_factor_min: float

    @property
    def enabled(self) -> bool:
        return self.kind != "none"

    @classmethod
    def from_section(cls, sec, tool_radius_mm: float = 25.0):
        d = float(sec["diameter_mm"]) or 2.0 * float(tool_radius_mm)
        r, v = list(sec["profile_radius_mm"]), list(sec["profile_value"])
        if sec["profile"] == "table" and (len(r) < 2 or len(r) != len(v) or not any(v)):
            raise BadInput("process.profile_radius_mm / profile_value: profile = 'table' needs at least 2 radii "
                           f"and as many values, not all 0 (found {len(r)} radii, {len(v)} values)")
        if sec["profile"] == "table" and r[-1] > d / 2:
            raise BadInput(f"process.profile_radius_mm: the table reaches {r[-1]:g} mm, beyond the footprint's "
                           f"radius {d / 2:g} mm (process.diameter_mm)")
        return cls(kind=sec["kind"], diameter_mm=d, profile=sec["profile"],
                   gaussian_sigma_mm=float(sec["gaussian_sigma_mm"]) or d / 6.0,
                   profile_table=tuple(zip(map(float, r), map(float, v))), force_n=float(sec["force_n"]),
                   preston_coefficient_per_pa=float(sec["preston_coefficient_per_pa"]),
                   relative_speed_m_s=float(sec["relative_speed_m_s"]), deposition_mm3_s=float(sec["deposition_mm3_s"]),
                   contact_tol_mm=float(sec["contact_tol_mm"]), grid_mm=float(sec["grid_mm"]) or d / 25.0,
                   uniformity_target=float(sec["uniformity_target"]),
                   uniformity_band=float(sec["uniformity_band_pct"]) / 100.0,
                   target_removal_file=sec["target_removal_file"], dwell_iterations=int(sec["dwell_iterations"]),
                   feed_factor_min=float(sec["feed_factor_min"]))

    @classmethod
    def make(cls, tool_radius_mm: float = 25.0, **job_keys):
        """Settings from [process] keys (job-file units); the tool's radius for the default diameter."""
        return cls.from_section(_section(cls.SECTION, job_keys), tool_radius_mm)
