"""The stages of a job, one function each, shared by every task kind.

    job -> robot, workpiece -> surface -> path -> joint path -> trajectory -> programs + report

Each function takes the job (or its settings) and the previous stage's box and
returns the next box; none of them writes files except ``post_checked`` and
``finish_run``. Task modules (``camtool.run.tasks``) compose these; this module
imports no task, so the import graph stays acyclic.
"""
from __future__ import annotations

import math
import time
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import Callable

import numpy as np
import trimesh

from ..errors import PlanInfeasible
from ..job import Job
from ..motion import MotionCheckSettings, WaypointIndex, check_motion, part_from_path
from ..motion.tool_bodies import tool_axis_bodies
from .part_stages import surface_for_job, workpiece_for_job  # noqa: F401  (the stages of every task)
from ..placement.margins import reach_margins
from ..plan import plan_path
from ..plan.connectors import LiftSettings, lift_reconfigurations
from ..plan.cwln import CwlnSolver
from ..plan.densify import densify_work
from ..plan.row_orientations import RowOrientations
from ..plan.sag import add_surface_poses, nearest_of
from ..plan.spline_bow import SplineDepthSettings, add_spline_poses
from ..plan.smooth import SmoothSettings, smooth_runs
from ..plan.rrt import CapsuleChecker, CloudChecker, free_move, insert_home_moves
from ..plan.strategy import ik_settings
from ..collision.stage import collision_world, with_world
from ..program.post import thin_waypoints
from .post_inputs import write_job_programs
from ..path.axis_tilt import AxisTiltSettings, TiltRefused, tilted_axes
from ..path.turn_split import split_turns
from ..path.axis_lowpass import AxisLowpassSettings, lowpassed_axes
from ..path.lead_clearance import cleared_leads
from ..path.raster import raster_path
from ..report.run_report import (
    plan_metrics,
    plot_joints,
    plot_unreachable,
    stage_seconds,
    write_json_atomic,
    write_points_csv,
)
from ..report.html import write_run_html
from ..robots import get_robot
from ..settings import PlannerSettings, RasterSettings, TimingSettings
from .job_settings import JobSettings
from ..part.roughness import judged_before, mesh_is_scan, mesh_roughness
from ..part.surface import FaceSet
from ..part.surface_base import Surface
from .check_left_out import failing_path_poses
from ..timing import lead_needed_mm, limit_findings, sampled_for, time_trajectory, timing_report
from ..path.toolpath import row_segments
from ..transforms import matrix_from_xyz_rpy

FREE_MOVE_RADIUS_MM = 60.0   # link capsule radius of the approach / depart collision check
CONTACT_ALLOWANCE_MM = 20.0  # the exempt ball round the first / last tool contact: capsule radius + this
ALONE_SPACINGS = 3.0         # a free-form scan's point with no other within this many spacings is no surface
SCAN_NOISE_FACTOR = 3.0      # a cloud's tolerances grow by this many times the fit's RMS residual
CONNECTOR_RADIUS_MM = 20.0   # default link capsule radius of the planner's reconfiguration check (raster jobs
                             # use check.link_radius_mm, the size the independent motion check measures)


@dataclass(frozen=True)
class RunResult:
    """What a run produced: the stages that ran (in order), their outputs, and the files written."""

    stages: tuple[str, ...]
    outputs: MappingProxyType
    files: tuple[Path, ...]


@dataclass
class StageLog:
    """Records finished stages while a run goes on and tells ``on_stage(name, value)`` of each.

    The log is the runner's notebook; the stage boxes it records are immutable.
    ``result()`` freezes it into a RunResult. ``seconds``: wall seconds per stage
    (report.json's ``stage_seconds``), ``cpu_seconds`` this process's CPU seconds
    (``stage_cpu_seconds``; on a shared machine the steadier figure): the time since
    the previous mark goes to the stage ``done`` records, or to the one a ``clock``
    block measures.
    """

    on_stage: Callable | None = None
    stages: list[str] = field(default_factory=list)
    outputs: dict = field(default_factory=dict)
    seconds: dict = field(default_factory=dict)
    cpu_seconds: dict = field(default_factory=dict)
    alongside_seconds: dict = field(default_factory=dict)       # stages run in a forked process: their own
    alongside_cpu_seconds: dict = field(default_factory=dict)   # wall and CPU seconds there
    _mark: tuple = field(default_factory=lambda: (time.perf_counter(), time.process_time()), repr=False)

    def lap(self, name: str) -> None:
        """Add the wall (and this process's CPU) time since the previous mark to stage ``name``; mark now."""
        now = (time.perf_counter(), time.process_time())
        self.seconds[name] = self.seconds.get(name, 0.0) + (now[0] - self._mark[0])
        self.cpu_seconds[name] = self.cpu_seconds.get(name, 0.0) + (now[1] - self._mark[1])
        self._mark = now

    def _restart(self) -> None:
        self._mark = (time.perf_counter(), time.process_time())

    @contextmanager
    def clock(self, name: str):
        """Time the block as (part of) stage ``name``; what came before it goes to no stage."""
        self._restart()
        try:
            yield
        finally:
            self.lap(name)

    def done(self, name: str, value):
        """Record a finished stage's output and pass the value on."""
        self.lap(name)
        self.outputs[name] = value
        self.stages.append(name)
        if self.on_stage is not None:
            self.on_stage(name, value)
        self._restart()  # the listener's time is no stage's
        return value

    def result(self, files=()) -> RunResult:
        return RunResult(tuple(self.stages), MappingProxyType(dict(self.outputs)), tuple(Path(f) for f in files))


# --------------------------------------------------------------------------- job -> stage inputs


def robot_for_job(job: Job):
    """The job's robot with its base placement and tool."""
    return get_robot(job.robot.name, job.robot.params, job.dir).with_placement(
        matrix_from_xyz_rpy(job.cell.base_xyz_mm, job.cell.base_rpy_deg),
        matrix_from_xyz_rpy(job.tool.tcp_xyz_mm, job.tool.tcp_rpy_deg))


def path_for_job(job: Job, surface, workpiece=None):
    """Raster the job's surface into a tool Path (world frame); given the job's ``workpiece`` (as loaded), with its
    free-form faces' tool axes tilted and leads lifted clear of it (``shaped_for_part``), as ``camtool run`` rasters
    it."""
    path = raster_path(surface, RasterSettings.from_section(job.raster))
    if workpiece is None:
        return path
    settings = JobSettings.from_job(job)
    return shaped_for_part(settings, surface, path, clearance_part(settings, workpiece, surface), robot_for_job(job))[0]


# --------------------------------------------------------------------------- plan and time


def free_move_checker(workpiece, robot, contact_xyz_mm=None, radius_mm: float = FREE_MOVE_RADIUS_MM, path=None,
                      clearance_mm: float = 0.0, world=None, tip_exempt_mm: float = 0.0):
    """Validity check of a free move: link capsules against the placed workpiece, the tool contact exempt.

    A mesh gives ``CapsuleChecker`` (signed distance if watertight; with the
    ``path``, an open patch is signed too: behind its surface, as the work
    poses' tool axes say, is inside), a point cloud ``CloudChecker`` (KD-tree
    distance to the points).
    """
    exempt = [] if contact_xyz_mm is None else [(contact_xyz_mm, radius_mm + CONTACT_ALLOWANCE_MM)]
    if workpiece.faces is not None and workpiece.vertices_mm is not None and len(workpiece.faces):
        mesh = trimesh.Trimesh(workpiece.vertices_mm, workpiece.faces, process=False)
        outward = None
        if path is not None and path.is_work.any():
            work = path.poses_mm[path.is_work]
            outward = (work[:, :3, 3], -work[:, :3, 2])
        return with_world(CapsuleChecker(robot, mesh, radius_mm, clearance_mm, exempt=exempt, outward=outward,
                                         tip_exempt_mm=tip_exempt_mm), world)
    return with_world(CloudChecker(robot, workpiece.points_mm, radius_mm, clearance_mm, exempt=exempt,
                                   tip_exempt_mm=tip_exempt_mm), world)


def lift_connectors(settings: PlannerSettings, workpiece, path, robot, joint_path, every: bool = False,
                    link_radius_mm: float | None = None, clearance_mm: float = 0.0, solver: CwlnSolver | None = None,
                    world=None, tip_exempt_mm: float = 0.0, every_failure: bool = False):
    """Every reconfiguring connector between runs made a lift - reconfigure - descend (``plan/connectors.py``;
    ``every_failure``: its ``lift_reconfigurations``'s).

    The reconfiguration at the lift height is checked against the placed
    workpiece (link capsules) and re-planned by RRT-Connect where needed.
    ``every``: lift between all runs, however small the joint change (touch
    tasks such as seed 002's, whose moves between targets would graze the part).
    """
    lift = LiftSettings(clearance_mm=settings.lift_mm, steps=settings.lift_steps,
                        threshold_rad=0.0 if every else settings.reconfigure_threshold_rad,
                        threshold_mm=0.0 if every else settings.reconfigure_threshold_mm,
                        track_scale_mm=settings.track_scale_mm, seed=settings.seed)
    # the bodies the motion check measures (raster jobs), or small ones that leave room for a short hop
    radius = link_radius_mm if link_radius_mm is not None else min(CONNECTOR_RADIUS_MM, 0.5 * settings.lift_mm)
    valid = with_world(None, world) if workpiece is None else free_move_checker(
        workpiece, robot, radius_mm=radius, path=path, clearance_mm=clearance_mm, world=world,
        tip_exempt_mm=tip_exempt_mm)
    solver = solver or CwlnSolver(robot, ik_settings(settings), free_spin=path.free_spin)
    return lift_reconfigurations(joint_path, path, robot, lift, solver, valid, touch_points=every,
                                 every_failure=every_failure)


def add_home_moves(settings: PlannerSettings, workpiece, path, robot, joint_path, world=None):
    """With a home configuration: RRT-Connect approach (home -> first row) and depart (last row -> home).

    The moves are inserted as 'approach' / 'depart' rows (path_index -1); the
    returned joint path's ``events['free_moves']`` has their figures. Without
    ``settings.q_home`` the joint path is returned unchanged.
    """
    if settings.q_home is None:
        return joint_path
    q_home = np.asarray(settings.q_home, float)
    pidx = joint_path.path_index
    first, last = path.poses_mm[pidx[pidx >= 0][0]][:3, 3], path.poses_mm[pidx[pidx >= 0][-1]][:3, 3]
    figures, moves = {}, {}
    for name, contact, qa, qb in (("approach", first, q_home, joint_path.q[0]),
                                  ("depart", last, joint_path.q[-1], q_home)):
        valid = free_move_checker(workpiece, robot, contact, world=world)
        try:
            moves[name], info = free_move(robot, qa, qb, valid, seed=settings.seed,
                                          track_scale_mm=settings.track_scale_mm)
        except PlanInfeasible as exc:
            raise PlanInfeasible(f"{name} move from/to robot.home_deg: {exc}") from None
        info["check"] = ("mesh capsules" if hasattr(valid, "mesh") else "point-cloud capsules (KD-tree)")
        info["capsule_radius_mm"] = FREE_MOVE_RADIUS_MM
        info["exempt_contact_radius_mm"] = FREE_MOVE_RADIUS_MM + CONTACT_ALLOWANCE_MM
        figures[name] = info
    return insert_home_moves(joint_path, moves["approach"], moves["depart"], {"free_moves": figures})


def face_projector(surface, workpiece):
    """What the sag takes its midposes onto (``plan.sag``): a free-form face's own surface when it is a CAD mesh's
    facets (``FreeformSurface.project_mm``); None for an analytic face, a scan's smoothed surface or a scanned
    mesh (the face's own verdict, ``FreeformSurface.from_scan``): taken onto those, the midposes would follow their
    noise, and the time law slows for it (the shell sample's cycle 214 -> 361 s at its former placement), so they
    stay on the arc through the tool axes. Several faces (``FaceSet``): each point onto the nearest of its CAD
    free-form faces (``plan.sag.nearest_of``)."""
    if isinstance(surface, FaceSet):
        own = [p for p in (face_projector(f, workpiece) for f in surface.surfaces) if p is not None]
        return nearest_of(own) if own else None
    if not isinstance(surface, Surface) or not surface.on_mesh_facets or workpiece is None or workpiece.faces is None:
        return None
    return None if surface.from_scan else surface.project_mm


def plan_for_job(settings: JobSettings, path, robot, workpiece=None, method: str | None = None, planned=None,
                 surface=None, every_failure: bool = False):
    """Plan ``path`` with the job's planner (or another ``method``), plus home moves when a workpiece is given.
    ``every_failure``: every connector's lift is tried before one that fails is raised (``lift_connectors``).

    ``workpiece``: the part the free motion keeps clear of (``part_for_checks``).
    ``planned``: ``plan_path``'s joint path of this very ``path`` and planner, when the
    caller has it already (lead sizing); it is then not planned again. ``surface``: the face rastered; a CAD
    mesh's free-form one takes the sag's midposes onto itself (``face_projector``)."""
    planner = settings.planner if method is None else settings.planner.with_method(method)
    solver = CwlnSolver(robot, ik_settings(planner), free_spin=path.free_spin)  # lifts and densified poses
    world = collision_world(settings, robot)
    joint_path = plan_path(path, robot, planner, world) if planned is None else planned
    if planner.smooth_runs:
        smooth = SmoothSettings(feed_mm_s=settings.timing.tcp_speed_mm_s)
        joint_path = smooth_runs(joint_path, path, robot, solver, smooth)
    joint_path = lift_connectors(planner, workpiece, path, robot, joint_path,
                                 link_radius_mm=settings.check.link_radius_mm,
                                 clearance_mm=settings.check.clearance_mm, solver=solver, world=world,
                                 tip_exempt_mm=settings.check.tool_contact_exempt_mm, every_failure=every_failure)
    project = face_projector(surface, workpiece)
    only = None if surface is None else _freeform_poses(surface, path)
    turns = None if only is None else RowOrientations.build(path, only, np.linalg.inv(robot.base_T_mm))
    joint_path = add_surface_poses(joint_path, path, robot, solver, planner.chord_tol_mm, project, turns)
    joint_path = densify_work(joint_path, path, robot, solver, planner.chord_tol_mm, turns)
    kept_out = _spline_kept_out(settings, surface, path, workpiece)
    if kept_out is not None:   # the timed spline kept out of the part (its lifted leads bend the runs sharply)
        joint_path = add_spline_poses(joint_path, path, robot, solver, kept_out[0], kept_out[1], project)
    if workpiece is not None:
        joint_path = add_home_moves(planner, workpiece, path, robot, joint_path, world=world)
    return joint_path


def _spline_kept_out(settings: JobSettings, surface, path, workpiece) -> tuple | None:
    """(``plan.spline_bow``'s settings, the part's signed distance) for a path of free-form faces whose leads may
    meet ``workpiece`` (``part_for_checks``, as ``shaped_for_part``: their leads are lifted clear of it and bend
    the runs sharply), or None: an analytic face's leads follow its surface, and a scanned cloud worked as one
    face is not measured here (its geometry costs seconds; the motion check still measures every lead)."""
    only = None if surface is None else _freeform_poses(surface, path)
    if not _leads_may_meet(settings, workpiece) or only is None or not only.any():
        return None
    band = max(_lead_band_mm(surface), _scanned_mesh_band(settings, workpiece))
    depth = SplineDepthSettings(depth_tol_mm=settings.planner.chord_tol_mm + band,
                                feed_mm_s=settings.timing.tcp_speed_mm_s)
    return depth, part_from_path(workpiece, path).signed_distance


def _scanned_mesh_band(settings: JobSettings, workpiece) -> float:
    """A scanned mesh's noise band (``scanned_mesh_band_mm``, which the motion check allows the TCP), 0 for a CAD
    mesh or a cloud (judged once: ``mesh_is_scan``). Measured against a scan's triangles with the CAD's 0.05 mm,
    the spline went "into" its bumps at every other step: the bezier dac scan took 830 poses more, slerped
    between neighbours 5 mm apart over its rough skin (its tool axis p95 1.89 -> 3.40 deg off the part's normal)."""
    if workpiece is None or workpiece.faces is None or workpiece.vertices_mm is None:
        return 0.0
    if not mesh_is_scan(workpiece.vertices_mm, settings.workpiece.scan, workpiece.faces):
        return 0.0
    return scanned_mesh_band_mm(workpiece, settings.fit.smoothing_mm, settings.workpiece.scan)


LEAD_SIZING_ROUNDS = 2   # re-raster and re-plan at most this many times for longer leads
LEAD_MARGIN = 1.05       # the chosen lead is this much longer than the longest ramp needs (before rounding)


@dataclass
class _Leads:
    """Lead sizing under way: the path, its plan, the lead it was rastered with, and report.json's record."""

    path: object
    joint_path: object
    lead_mm: float
    record: dict
    rounds_used: int = 0

    def grow(self, settings: JobSettings, surface, robot, plan: Callable, rounds: int, workpiece=None) -> bool:
        """Up to ``rounds`` times: measure the ramps on the plan, re-raster with a longer lead and ``plan`` it.

        True when the leads are long enough for the plan in hand; False when capped
        at ``raster.lead_max_mm``, out of rounds, or the longer lead cannot be planned
        (the last plan is kept)."""
        raster = settings.raster
        for round_ in range(rounds + 1):
            need = lead_needed_mm(self.joint_path, self.path, robot, settings.timing)
            needed = max(need["lead_in_mm"], need["lead_out_mm"])
            self.record["needed_mm"] = round(float(needed), 3)
            have = min([min(r["lead_in_mm"], r["lead_out_mm"]) for r in need["per_run"]], default=self.lead_mm)
            if needed <= have + 1e-6:
                return True
            if round_ == rounds:
                return False
            longer = min(float(math.ceil(LEAD_MARGIN * needed - 1e-9)), raster.lead_max_mm)
            if longer <= self.lead_mm:
                self.record["capped"] = True
                return False
            try:
                new_path, tilt = shaped_for_part(settings, surface, raster_path(surface, replace(raster, lead_mm=longer)),
                                                 workpiece, robot)
                new_joint_path = plan(new_path)
            except PlanInfeasible as exc:
                self.record["kept_because"] = f"a {longer:g} mm lead cannot be planned: {exc}"
                return False
            self.path, self.joint_path, self.lead_mm = new_path, new_joint_path, longer
            if tilt is not None:
                self.record["axis_tilt"] = tilt   # the tilt of the path rastered again, for report.json
            self.record["lead_mm_used"] = longer
            self.rounds_used += 1
        return False


def plan_with_sized_leads(settings: JobSettings, surface, path, robot, workpiece=None):
    """(path, joint path): ``plan_for_job``, with ``raster.lead_auto`` on leads long enough for the ramps.

    The length the ramps to and from the feed need (``timing.lead_needed_mm``: the
    limits, the feed and the planned joint path) is measured on ``plan_path``'s plan,
    before smoothing, lifts and densifying, which leave the runs' ends as they are;
    where a run needs more than it has, ``surface`` is rastered again with a lead of
    that length (times ``LEAD_MARGIN``, rounded up to whole mm, at most
    ``raster.lead_max_mm``) and ``plan_path`` runs again. The whole plan is then made
    once, on the path with the leads chosen, and measured again; should it need
    longer leads still, the sizing goes on with whole plans (``LEAD_SIZING_ROUNDS``
    in all). ``events['leads']`` records the lead set, the lead used and the length
    needed. A longer lead that cannot be planned is not taken (``kept_because``).
    """
    raster = settings.raster
    world = collision_world(settings, robot)
    raw = plan_path(path, robot, settings.planner, world)
    if not raster.lead_auto or raster.lead_mm <= 0:
        return path, plan_for_job(settings, path, robot, workpiece, planned=raw, surface=surface)
    lead = raster.lead_mm
    sizing = _Leads(path, raw, lead, {"lead_mm_set": lead, "lead_mm_used": lead, "max_mm": raster.lead_max_mm})
    kernel_only = sizing.grow(settings, surface, robot, lambda p: plan_path(p, robot, settings.planner, world),
                              LEAD_SIZING_ROUNDS, workpiece)
    try:
        sizing.joint_path = plan_for_job(settings, sizing.path, robot, workpiece, planned=sizing.joint_path,
                                         surface=surface)
    except PlanInfeasible as exc:
        if sizing.lead_mm == lead:
            raise
        sizing.record["kept_because"] = f"a {sizing.lead_mm:g} mm lead cannot be planned: {exc}"
        sizing.path, sizing.lead_mm, sizing.record["lead_mm_used"] = path, lead, lead
        sizing.joint_path = plan_for_job(settings, path, robot, workpiece, planned=raw, surface=surface)
        kernel_only = False
    rounds_left = LEAD_SIZING_ROUNDS - sizing.rounds_used if kernel_only else 0  # else: capped, or kept
    sizing.grow(settings, surface, robot, lambda p: plan_for_job(settings, p, robot, workpiece, surface=surface),
                rounds_left, workpiece)
    return sizing.path, replace(sizing.joint_path, events={**sizing.joint_path.events, "leads": sizing.record})


def time_for_job(settings: JobSettings, joint_path, path, robot, before_check: Callable | None = None):
    """Time a joint path with the job's timing settings (``before_check``: ``time_trajectory``'s)."""
    return time_trajectory(joint_path, path, robot, settings.timing, before_check=before_check)


def plan_and_time(settings: JobSettings, path, robot, method: str | None = None, workpiece=None, surface=None,
                  every_failure: bool = False):
    """(joint path, trajectory) of ``path``: ``plan_for_job`` then ``time_for_job``. ``surface``: the face rastered
    (a CAD mesh's free-form face takes the sag's midposes onto itself, ``face_projector``); ``every_failure``:
    ``plan_for_job``'s."""
    joint_path = plan_for_job(settings, path, robot, workpiece, method, surface=surface, every_failure=every_failure)
    return joint_path, time_for_job(settings, joint_path, path, robot)


def plan_and_time_sized(settings: JobSettings, surface, path, robot, workpiece=None):
    """(path, joint path, trajectory): ``plan_with_sized_leads`` then ``time_for_job``."""
    path, joint_path = plan_with_sized_leads(settings, surface, path, robot, workpiece)
    return path, joint_path, time_for_job(settings, joint_path, path, robot)


# --------------------------------------------------------------------------- check, post, report


def part_for_checks(settings: JobSettings, workpiece, surface):
    """The part that collision and motion checks measure against: a mesh as loaded; a scanned cloud without
    the points off its fitted surface (outliers, clutter), those within 3x fit.threshold_mm of it."""
    if workpiece.faces is not None or surface is None or settings.segmented:
        return workpiece  # a face of a segmented scan: the other faces' points stay obstacles
    P = np.asarray(workpiece.points_mm, float)
    on = np.linalg.norm(surface.point_mm(*surface.uv_from_points(P).T) - P, axis=1) <= 3.0 * settings.fit.threshold_mm
    if getattr(surface, "model", "") == "freeform":
        on[on] = _not_alone(P[on])
    return replace(workpiece, points_mm=P[on], normals=np.asarray(workpiece.normals)[on])


def _freeform_poses(surface, path) -> np.ndarray | None:
    """Which poses of ``path`` are a free-form face's (None: none is)."""
    if isinstance(surface, FaceSet):
        free = [i for f, i in zip(surface.surfaces, surface.indices) if getattr(f, "model", "") == "freeform"]
        return np.isin(path.face, free) if free and path.face is not None else None
    return np.ones(len(path), bool) if getattr(surface, "model", "") == "freeform" else None


def _leads_may_meet(settings: JobSettings, part) -> bool:
    """Whether a free-form face's leads may meet ``part`` (the workpiece, or its ``part_for_checks``): a mesh or a
    segmented scan holds more than the face; a scanned cloud worked as one face is checked against its own points
    on that face, which the leads, on its tangent and above its noise band, leave behind."""
    return part is not None and (part.faces is not None or settings.segmented)


def clearance_part(settings: JobSettings, workpiece, surface):
    """What ``shaped_for_part`` measures against: ``part_for_checks``, or None where the leads cannot meet the
    part (``_leads_may_meet``; a 1 M-point scan's filtered points cost 2 s for nothing, its geometry 20 s; the
    motion check still measures every lead against it)."""
    return part_for_checks(settings, workpiece, surface) if _leads_may_meet(settings, workpiece) else None


def shaped_for_part(settings: JobSettings, surface, path, part, robot=None) -> tuple:
    """(``path`` shaped to ``part`` (``part_for_checks``), the tilt's figures for report.json or None): its
    free-form faces' tool orientations low-passed along their rows (``path.axis_lowpass``: the wrist's jerk
    follows their wobble; a CAD mesh's facets and a scan's bumps alike), then their tool axes tilted clear of the part where the tool or the wrist would be in it (with
    ``robot``: ``_tilted``), then their leads lifted clear of it (``_leads_cleared``), then their work steps that
    turn the tool axis by more than 5 deg cut into pieces on the face (``path.turn_split``, whatever the part). A
    path of no free-form face comes back as it was, one of a part its poses cannot meet (``_leads_may_meet``)
    only cut where it turns."""
    only = _freeform_poses(surface, path)
    if only is None or not only.any():
        return path, None
    path = lowpassed_axes(path, only, AxisLowpassSettings())
    figures = None
    if _leads_may_meet(settings, part):
        geometry = part_from_path(part, path)
        if robot is not None and settings.raster.axis_tilt_max_rad > 0:
            path, figures = _tilted(settings, path, geometry, robot, only)
        path = _leads_cleared(settings, surface, path, geometry, only)
    return split_turns(path, _freeform_projectors(surface, path))[0], figures


def _freeform_projectors(surface, path) -> list:
    """(the mask of ``path``'s poses on it, its ``project_mm``) for each free-form face of ``surface``."""
    if isinstance(surface, FaceSet):
        return [(path.face == i, f.project_mm) for f, i in zip(surface.surfaces, surface.indices)
                if f.model == "freeform" and path.face is not None]
    return [(np.ones(len(path), bool), surface.project_mm)] if surface.model == "freeform" else []


def _tilted(settings: JobSettings, path, geometry, robot, only) -> tuple:
    """(``path`` with its tool axes tilted clear of ``geometry`` (``path.axis_tilt``: the motion check's capsules
    rigid with the TCP, its penetration tolerance), the tilt's figures); PlanInfeasible where the largest tilt
    does not clear a pose."""
    c = settings.check
    bodies = tool_axis_bodies(robot, MotionCheckSettings(tool_radius_mm=c.tool_radius_mm,
                                                         link_radius_mm=c.link_radius_mm,
                                                         tool_contact_exempt_mm=c.tool_contact_exempt_mm))
    tilt = AxisTiltSettings(max_rad=settings.raster.axis_tilt_max_rad, turn_rad=settings.raster.axis_tilt_turn_rad,
                            clear_mm=1.0 + c.clearance_mm, inside_mm=c.penetration_tol_mm)
    try:
        path, figures = tilted_axes(path, geometry.signed_distance, bodies, tilt, only)
    except TiltRefused as exc:
        raise PlanInfeasible(f"the tool axis cannot be tilted clear of the part: {exc}") from None
    return path, figures.to_dict()


def _leads_cleared(settings: JobSettings, surface, path, geometry, only):
    """``path`` with its free-form faces' leads (``only``) lifted clear of the part's ``geometry``
    (``part_from_path``; the modifier ``path.lead_clearance``): their straight leads run on past the face's edge,
    where the part may go on and turn up towards the tool (a door's handle recess, a flange). An analytic face's
    leads follow its surface (or its tangent, ``raster.lead_path``) and stay as they are, as does every lead
    already clear."""
    return cleared_leads(path, geometry.signed_distance, settings.raster.lead_mm, only,
                         inside_mm=_lead_band_mm(surface))   # a scan's leads may run in its noise band, as the check allows


def _lead_band_mm(surface) -> float:
    """How deep a free-form face's leads may run into the part: a scan's noise band (the motion check allows it),
    0 on a mesh's facets."""
    faces = surface.surfaces if isinstance(surface, FaceSet) else (surface,)
    return max((f.lead_band_mm for f in faces if f.scanned), default=0.0)


def _not_alone(P: np.ndarray) -> np.ndarray:
    """Which points of a scan have another within ALONE_SPACINGS median spacings. A free-form face's band reaches
    over its holes' fill and past its edge, and a scan's outliers that fall in it there stand alone: no surface,
    yet the motion check would read the tool beside one as behind it (the shell scan's hole)."""
    from scipy.spatial import cKDTree

    if len(P) < 3:
        return np.ones(len(P), bool)
    d = cKDTree(P).query(P, k=2)[0][:, 1]
    return d <= ALONE_SPACINGS * float(np.median(d))


def _fit_rms_mm(surface) -> float:
    """The fit's RMS (mm) of a surface, the largest of its faces' for several faces; 0 where none is known."""
    faces = surface.surfaces if isinstance(surface, FaceSet) else (surface,)
    return max((f.stats.rms_mm for f in faces if getattr(f, "stats", None) is not None), default=0.0)


def scanned_mesh_band_mm(workpiece, smoothing_mm: float = 0.0, scan: str = "auto") -> float:
    """A mesh's noise band (mm, over two ``smoothing_mm`` sigmas) when it is a scan (``workpiece.scan``: "yes", or
    "auto" and its vertices are rough, ``part.roughness``), else 0 (a CAD mesh keeps the strict check). The TCP's tolerances on work, leads and contacts
    grow by it, as a cloud's do by its noise; the tool's and the links' capsules keep the strict penetration and
    clearance rules."""
    if workpiece.faces is None or workpiece.vertices_mm is None or scan == "no":
        return 0.0
    rough = mesh_roughness(workpiece.vertices_mm, smoothing_mm, scan, workpiece.faces)
    return rough.band_mm if rough.is_scan else 0.0


def with_scan_verdict(settings: JobSettings, workpiece) -> JobSettings:
    """``settings`` with ``workpiece.scan`` "yes" or "no" where this process has judged the mesh already
    (``_scanned_mesh_band``, "auto"): the motion check, in its own process, takes that verdict for its noise band
    (``scanned_mesh_band_mm``) instead of judging the mesh again (a second on a 200 k-vertex scan)."""
    if settings.workpiece.scan != "auto" or workpiece is None or workpiece.faces is None \
            or workpiece.vertices_mm is None:
        return settings
    verdict = judged_before(workpiece.vertices_mm, "auto", workpiece.faces)
    if verdict is None:
        return settings
    return replace(settings, workpiece=replace(settings.workpiece, scan="yes" if verdict else "no"))


def motion_check_part(settings: JobSettings, workpiece, path, surface=None):
    """The part the independent motion check measures against (``motion.PartGeometry``): ``part_for_checks``,
    oriented by the path's work poses. Made as soon as the raster is (a process on standby builds it while the
    run plans); the path's later leads do not change it (its work poses only orient the part's normals)."""
    return part_from_path(part_for_checks(settings, workpiece, surface), path)


def motion_check(settings: JobSettings, trajectory, robot, workpiece, path, surface=None, part=None,
                 locate: bool = False) -> dict:
    """The independent motion check of what the controller will run; its figures for report.json.

    The program's waypoints (thinned as the post-processors write them) are
    interpolated joint-linearly at ``check.dt_ms`` and measured against the
    placed workpiece: penetration, clearance off work, deviation on work, joint
    steps per mm (``camtool.motion``, which shares no code with the planner).
    ``part``: ``motion_check_part``'s, when made ahead. PlanInfeasible (exit 3)
    naming the first finding when anything fails; the figures are in the
    exception's report, with ``locate`` also ``failing_path_poses`` (``check_left_out``:
    where each failing sample lies on ``path``).
    """
    c = settings.check
    noise = 0.0
    if workpiece.faces is None and surface is not None:
        noise = SCAN_NOISE_FACTOR * _fit_rms_mm(surface)  # a scan is only as exact as its noise
    path_tol, penetration_tol = c.path_tol_mm + noise, c.penetration_tol_mm + noise
    band = scanned_mesh_band_mm(workpiece, settings.fit.smoothing_mm, settings.workpiece.scan)
    if part is None:
        part = motion_check_part(settings, workpiece, path, surface)
    program = thin_waypoints(trajectory, settings.post.min_move_s)
    report = check_motion(program.t_s, program.q, program.zone, robot, part,
                          MotionCheckSettings(dt_s=c.dt_s, penetration_tol_mm=penetration_tol,
                                              clearance_mm=c.clearance_mm, path_tol_mm=path_tol,
                                              tool_radius_mm=c.tool_radius_mm, link_radius_mm=c.link_radius_mm,
                                              tool_contact_exempt_mm=c.tool_contact_exempt_mm,
                                              scan_band_mm=band),
                          WaypointIndex(row_segments(program.path_index, program.zone, path.segment), "segment"),
                          world=collision_world(settings, robot))
    figures = report.to_dict()
    if noise > 0 or band > 0:
        figures["scan_noise_band_mm"] = round(noise or band, 4)
    if not report.ok:
        failed = {"motion_check": figures}
        if locate:
            failed["failing_path_poses"] = failing_path_poses(program.path_index, report.failing_intervals)
        raise PlanInfeasible(f"the motion check failed ({len(report.findings)} finding(s)); first: "
                             f"{report.findings[0]}; no program written{_lead_hint(settings, report.findings)}",
                             report=failed)
    return figures


def leads_into_part(settings: JobSettings, failed: PlanInfeasible) -> bool:
    """Whether a motion check's refusal is only the tool in the part in leads that run on a segmented face's
    surface continued: a neighbouring face that goes on tangentially (a dome on a cylinder) is in their way, and
    leads lifted clear of the row's tangent (``raster.lead_path = "tangent"``) would miss it."""
    findings = failed.report.get("motion_check", {}).get("findings", [])
    more = "more intervals for body tcp"   # (the check lists the first intervals and counts the rest)
    return (bool(findings) and all(_tool_in_lead(f) or more in f for f in findings)
            and _leads_in_part(settings, findings))


def _tool_in_lead(finding: str) -> bool:
    """A finding of the tool in the part in a lead, or in the self-motion zone that leaves from one."""
    return "penetrated" in finding and "body: tcp" in finding and (" lead_" in finding or " self_motion " in finding)


def _leads_in_part(settings: JobSettings, findings: list[str]) -> bool:
    in_lead = any(_tool_in_lead(f) and " lead_" in f for f in findings)
    return in_lead and settings.segmented and settings.raster.lead_path == "surface"


def _lead_hint(settings: JobSettings, findings: list[str]) -> str:
    """What would work where ``leads_into_part``: the leads lifted clear."""
    if not _leads_in_part(settings, findings):
        return ""
    return ("; the tool goes into the part in a lead, which runs on the face's surface continued: where a "
            "neighbouring face goes on tangentially, raster.lead_path = \"tangent\" lifts the leads clear of it")


def post_checked(trajectory, robot, job: Job, outdir: Path, path=None, report: dict | None = None,
                 before_placing: Callable | None = None) -> list[Path]:
    """The independent 4 ms limit check of the timed trajectory (``time_trajectory`` made it already of
    one it timed: ``timing.limit_findings``), then the post stage.

    PlanInfeasible on any finding: no program is written from a trajectory that
    breaks a limit. Every program is simulated the way its controller runs it
    (against ``path``) and its simulated motion measured against the job's cell:
    no robot or tool body may touch an obstacle, the floor or another link
    (the acceptance of the written program, not only of the plan); ``report``
    receives the simulation figures; ``before_placing`` is called once they all pass, before any is
    placed (``post.write_programs``).
    """
    timing = TimingSettings.from_section(job.timing)
    findings = limit_findings(trajectory, robot, timing.check_dt_s)  # [] when time_trajectory checked it
    if findings:
        raise PlanInfeasible(f"the timed trajectory breaks {len(findings)} limit(s); first: {findings[0]}")
    world = collision_world(JobSettings.from_job(job, robot), robot)   # the written programs against the cell
    return list(write_job_programs(trajectory, robot, job, outdir, path=path, report=report, world=world,
                                   before_placing=before_placing))


def timing_figures(trajectory, robot, job: Job) -> dict:
    """The timing stage's figures, its method named ``timing_method``."""
    figures = timing_report(trajectory, robot,
                            sampled_for(trajectory, robot, TimingSettings.from_section(job.timing).check_dt_s))
    figures["timing_method"] = figures.pop("method")
    return figures


def run_report(path, joint_path, trajectory, robot, job: Job, method: str) -> dict:
    """The planner's and the timing stage's figures of a run, for report.json."""
    report = plan_metrics(path, joint_path, robot, method, job.planner.jump_threshold_deg,
                          job.planner.jump_threshold_mm)
    report.update(timing_figures(trajectory, robot, job))
    report["margins"] = reach_margins(path, joint_path, robot, orientation_mm=job.planner.orientation_weight_mm,
                                      track_scale_mm=job.planner.track_scale_mm)
    return report


def report_unreachable(exc: PlanInfeasible, path, robot, job: Job, outdir: Path, workpiece=None,
                       surface=None, shift: dict | None = None, world=None) -> None:
    """Write report.json, report.html (failing poses marked, with the redundancy map) and a PNG map of
    unreachable poses for an infeasible plan."""
    unreachable = exc.report.get("unreachable", [])
    report = {"robot": robot.name, "method": job.planner.method, "status": "infeasible",
              "reason": str(exc), "points_total": len(path), "unreachable_count": len(unreachable),
              "unreachable": unreachable}
    if shift is not None:
        report["nearest_feasible_shift"] = shift
    if exc.report.get("joint_path") is not None:
        report["margins"] = reach_margins(path, exc.report["joint_path"], robot,
                                          orientation_mm=job.planner.orientation_weight_mm,
                                          track_scale_mm=job.planner.track_scale_mm)
    if unreachable:
        report["unreachable_map"] = str(plot_unreachable(path, unreachable, Path(outdir) / "plots" / "unreachable.png"))
    write_json_atomic(report, Path(outdir) / "report.json")
    write_run_html(outdir, report=report, robot=robot, workpiece=workpiece, surface=surface, path=path,
                   joint_path=exc.report.get("joint_path"), failing_indices=[u["index"] for u in unreachable],
                   world=world)


def report_failure(exc: PlanInfeasible, path, joint_path, robot, job: Job, outdir: Path, workpiece=None,
                   surface=None, world=None, redundancy=None) -> None:
    """report.json (status "unsafe", the reason and the motion-check figures) and report.html for a plan
    that failed a check after planning; no program is written."""
    report = {"robot": robot.name, "method": job.planner.method, "status": "unsafe", "reason": str(exc),
              "points_total": len(path), **exc.report}
    write_json_atomic(report, Path(outdir) / "report.json")
    write_run_html(outdir, report=report, robot=robot, workpiece=workpiece, surface=surface, path=path,
                   joint_path=joint_path, world=world, redundancy=redundancy)


def finish_run(log: StageLog, programs, report: dict, path, joint_path, robot, trajectories: dict, outdir: Path,
               extra_files=(), world=None, figures=None, mapping=None, html_figures=None) -> RunResult:
    """Write the plots, points.csv and report.json of a successful run; the RunResult lists every file.

    ``world``: the job's collision world (the redundancy map's collision layer).
    ``figures``: a process (``camtool.run.alongside``) drawing ``figures.draw_run_figures``
    while the run went on, and ``mapping`` one whose ``result()`` is
    ``run_figures.draw_redundancy_map``'s (or None: not drawn ahead) (the raster task);
    their files are taken here, the wait for them is the stage ``figures`` and their own
    time is report.json's ``stage_seconds_alongside``. Without them the joint plots and
    the redundancy map are drawn here. ``html_figures``: report.html's figures, rendered while
    the motion check finished (``report_html.figure_sections``)."""
    outdir = Path(outdir)
    write_points_csv(path, joint_path, robot, outdir / "points.csv")
    log.lap("report")
    redundancy = None
    if figures is None:
        plots = plot_joints(trajectories, robot, outdir / "plots")
        log.lap("plots")
    else:
        drawn = figures.result()
        plots, extra_files = list(drawn.joint_plots), (drawn.feed_png, *extra_files)
        log.alongside_seconds.update(drawn.seconds)
        log.alongside_cpu_seconds.update(drawn.cpu_seconds)
    mapped = None if mapping is None else mapping.result()
    if mapped is not None:
        redundancy = mapped.redundancy
        log.alongside_seconds.update(mapped.seconds)
        log.alongside_cpu_seconds.update(mapped.cpu_seconds)
    if figures is not None or mapping is not None:
        log.lap("figures")
    if log.alongside_seconds:
        report["stage_seconds_alongside"] = stage_seconds(log.alongside_seconds)
        report["stage_cpu_seconds_alongside"] = stage_seconds(log.alongside_cpu_seconds)
    report["programs"] = [str(f) for f in programs]
    report["plots"] = [str(f) for f in plots]
    report["stage_seconds"], report["stage_cpu_seconds"] = stage_seconds(log.seconds), stage_seconds(log.cpu_seconds)
    write_json_atomic(report, outdir / "report.json")
    log.outputs["report"] = report
    html = write_run_html(outdir, report=report, robot=robot, workpiece=log.outputs.get("workpiece"),
                          surface=log.outputs.get("fit"), path=path, joint_path=joint_path,
                          trajectory=next(iter(trajectories.values())), faces=log.outputs.get("faces"),
                          world=world, redundancy=redundancy, figures=html_figures)
    log.lap("report_html")
    report["stage_seconds"], report["stage_cpu_seconds"] = stage_seconds(log.seconds), stage_seconds(log.cpu_seconds)
    write_json_atomic(report, outdir / "report.json")  # again, with the page's own time (11 kB)
    return log.result([*programs, outdir / "report.json", *extra_files, outdir / "points.csv", *plots, *html])
