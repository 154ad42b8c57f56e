"""The whole pipeline for one job, one stage after another, data flowing forward:

    load job -> workpiece -> fit -> raster -> plan -> time -> check -> post

Each stage is one module with one entry function. A stage whose module this
camtool does not have stops the run with ``StageUnavailable`` (exit 4),
naming the last stage that ran; no program is ever written by a partial run.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from .errors import PlanInfeasible, StageUnavailable
from .job import Job

STAGES = (
    ("workpiece", "camtool.workpiece", "load_workpiece"),
    ("fit", "camtool.fit", "fit_surface"),
    ("raster", "camtool.raster", "raster_path"),
    ("plan", "camtool.plan", "plan_path"),
    ("time", "camtool.timing", "time_trajectory"),
    ("post", "camtool.post", "write_programs"),
)


def stage_function(stage: str, done: list[str]) -> Callable:
    """The entry function of a stage, or StageUnavailable naming the last stage run."""
    for name, module, func in STAGES:
        if name == stage:
            try:
                return getattr(importlib.import_module(module), func)
            except ModuleNotFoundError as exc:
                if exc.name != module:
                    raise
                after = f"after '{done[-1]}'" if done else "before the first stage"
                raise StageUnavailable(
                    f"stage '{stage}' is not available in this camtool yet; the run stopped {after} "
                    "and wrote no program") from None
    raise KeyError(stage)


def _optional(module: str):
    """A stage module if this camtool has it, else None (its stage raises later)."""
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name != module:
            raise
        return None


@dataclass
class RunResult:
    """What a run produced: the stages that ran, their outputs, and the files written."""

    stages: list[str] = field(default_factory=list)
    outputs: dict = field(default_factory=dict)
    files: list[Path] = field(default_factory=list)
    on_stage: Callable | None = None

    def done(self, name: str, value):
        """Record a finished stage's output, tell ``on_stage(name, value)``, and pass the value on."""
        self.outputs[name] = value
        self.stages.append(name)
        if self.on_stage is not None:
            self.on_stage(name, value)
        return value

    def post_checked(self, trajectory, robot, job: Job, outdir: Path) -> list[Path]:
        """The independent 4 ms limit check of the timed trajectory, then the post stage.

        PlanInfeasible on any finding: no program is written from a trajectory that
        breaks a limit."""
        from .timing import check_trajectory

        findings = check_trajectory(trajectory, robot, job.timing.check_dt_ms / 1000.0)
        if findings:
            raise PlanInfeasible(f"the timed trajectory breaks {len(findings)} limit(s); first: {findings[0]}")
        self.files = list(self.done("post", stage_function("post", self.stages)(trajectory, robot, job, outdir)))
        return self.files

    def finish(self, report: dict, path, joint_path, robot, trajectories: dict, outdir: Path,
               extra_files=()) -> "RunResult":
        """Write the plots, points.csv and report.json of a successful run; list them in ``files``."""
        from .report import plot_joints, write_json_atomic, write_points_csv

        outdir = Path(outdir)
        plots = plot_joints(trajectories, robot, outdir / "plots")
        write_points_csv(path, joint_path, robot, outdir / "points.csv")
        report["programs"] = [str(f) for f in self.files]
        report["plots"] = [str(f) for f in plots]
        write_json_atomic(report, outdir / "report.json")
        self.outputs["report"] = report
        self.files += [outdir / "report.json", *extra_files, outdir / "points.csv", *plots]
        return self


def workpiece_for_job(job: Job, done: list[str] | None = None):
    """Load the job's workpiece and place it in the world frame (cell.workpiece_*)."""
    from .transforms import matrix_from_xyz_rpy

    wp = stage_function("workpiece", done or [])(
        job.resolve(job.workpiece.file), units=job.workpiece.units,
        sample_points=job.workpiece.sample_points,
        normal_neighbours=job.workpiece.normal_neighbours, seed=job.fit.seed)
    return wp.transformed(matrix_from_xyz_rpy(job.cell.workpiece_xyz_mm, job.cell.workpiece_rpy_deg))


def surface_for_job(job: Job, workpiece, done: list[str] | None = None):
    """Fit the job's surface (world frame) to a placed workpiece."""
    return stage_function("fit", done or ["workpiece"])(workpiece, **job.fit)


def path_for_job(job: Job, surface, done: list[str] | None = None):
    """Raster the job's surface into a tool Path (world frame)."""
    return stage_function("raster", done or ["workpiece", "fit"])(surface, **job.raster)


def robot_for_job(job: Job):
    """The job's robot with its base placement and tool."""
    from .robots import get_robot
    from .transforms import matrix_from_xyz_rpy

    return get_robot(job.robot.name, job.robot.params, job.dir).with_placement(
        matrix_from_xyz_rpy(job.cell.base_xyz_mm, job.cell.base_rpy_deg),
        matrix_from_xyz_rpy(job.tool.tcp_xyz_mm, job.tool.tcp_rpy_deg))


FREE_MOVE_RADIUS_MM = 60.0   # link capsule radius of the approach / depart collision check
CONTACT_ALLOWANCE_MM = 20.0  # the exempt ball round the first / last tool contact: capsule radius + this


def free_move_checker(workpiece, robot, contact_xyz_mm):
    """Validity check of a free move: link capsules against the placed workpiece, the tool contact exempt.

    A mesh gives ``CapsuleChecker`` (signed distance if watertight), a point
    cloud ``CloudChecker`` (KD-tree distance to the points).
    """
    from .plan.rrt import CapsuleChecker, CloudChecker

    exempt = [(contact_xyz_mm, FREE_MOVE_RADIUS_MM + CONTACT_ALLOWANCE_MM)]
    if workpiece.faces is not None and workpiece.vertices_mm is not None and len(workpiece.faces):
        import trimesh

        mesh = trimesh.Trimesh(workpiece.vertices_mm, workpiece.faces, process=False)
        return CapsuleChecker(robot, mesh, FREE_MOVE_RADIUS_MM, exempt=exempt)
    return CloudChecker(robot, workpiece.points_mm, FREE_MOVE_RADIUS_MM, exempt=exempt)


def add_home_moves(job: Job, workpiece, path, robot, joint_path):
    """With ``robot.home_deg``: RRT-Connect approach (home -> first row) and depart (last row -> home).

    The moves are inserted as 'approach' / 'depart' rows (path_index -1);
    ``joint_path.events['free_moves']`` gets their figures. Without home_deg
    the joint path is returned unchanged.
    """
    import numpy as np

    from .plan.rrt import free_move, insert_home_moves

    if not job.robot.home_deg:
        return joint_path
    q_home = np.where(robot.prismatic, job.robot.home_deg, np.radians(job.robot.home_deg))
    pidx = joint_path.path_index
    first, last = path.poses_mm[pidx[pidx >= 0][0]][:3, 3], path.poses_mm[pidx[pidx >= 0][-1]][:3, 3]
    seed, scale = job.planner.seed, job.planner.track_scale_mm
    figures = {}
    moves = {}
    for name, contact, qa, qb in (("approach", first, q_home, joint_path.q[0]),
                                  ("depart", last, joint_path.q[-1], q_home)):
        valid = free_move_checker(workpiece, robot, contact)
        try:
            moves[name], info = free_move(robot, qa, qb, valid, seed=seed, track_scale_mm=scale)
        except PlanInfeasible as exc:
            raise PlanInfeasible(f"{name} move from/to robot.home_deg: {exc}") from None
        info["check"] = ("mesh capsules" if hasattr(valid, "mesh") else "point-cloud capsules (KD-tree)")
        info["capsule_radius_mm"] = FREE_MOVE_RADIUS_MM
        info["exempt_contact_radius_mm"] = FREE_MOVE_RADIUS_MM + CONTACT_ALLOWANCE_MM
        figures[name] = info
    out = insert_home_moves(joint_path, moves["approach"], moves["depart"])
    out.events["free_moves"] = figures
    return out


def plan_and_time(job: Job, path, robot, method: str | None = None, workpiece=None):
    """Plan and time ``path`` with the job's planner (or another ``method``).

    Given the placed ``workpiece`` and ``robot.home_deg``, approach and depart
    moves from and back to home are planned by RRT-Connect (``add_home_moves``).
    """
    planner = dict(job.planner)
    if method:
        planner["method"] = method
    joint_path = stage_function("plan", ["raster"])(path, robot, home_deg=job.robot.home_deg, **planner)
    if workpiece is not None:
        joint_path = add_home_moves(job, workpiece, path, robot, joint_path)
    trajectory = stage_function("time", ["plan"])(joint_path, path, robot, **job.timing)
    return joint_path, trajectory


def _report_unreachable(exc: PlanInfeasible, path, robot, job: Job, outdir: Path) -> None:
    """Write report.json and a PNG map of unreachable poses for an infeasible plan."""
    from .report import plot_unreachable, write_json_atomic

    unreachable = exc.report.get("unreachable", [])
    report = {"robot": robot.name, "method": job.planner.method, "status": "infeasible",
              "reason": str(exc), "points_total": len(path), "unreachable_count": len(unreachable),
              "unreachable": unreachable}
    if unreachable:
        report["unreachable_map"] = str(plot_unreachable(path, unreachable, outdir / "plots" / "unreachable.png"))
    write_json_atomic(report, outdir / "report.json")


def run_report(path, joint_path, trajectory, robot, job: Job, method: str) -> dict:
    """The planner's and the timing stage's figures of a run, for report.json."""
    from .report import plan_metrics

    report = plan_metrics(path, joint_path, robot, method, job.planner.jump_threshold_deg,
                          job.planner.jump_threshold_mm)
    report.update(timing_figures(trajectory, robot, job))
    return report


def timing_figures(trajectory, robot, job: Job) -> dict:
    """The timing stage's figures, its method named ``timing_method``."""
    from .timing import timing_report

    figures = timing_report(trajectory, robot, job.timing.check_dt_ms / 1000.0)
    figures["timing_method"] = figures.pop("method")
    return figures


def run_job(job: Job, outdir: Path, compare: bool = False, on_stage: Callable | None = None) -> RunResult:
    """Run every stage of ``job``; programs, report.json, points.csv and plots go into ``outdir``.

    No program is written unless planning, timing, the independent trajectory
    check and every program check succeed.
    """

    robot = robot_for_job(job)
    preflight = getattr(_optional("camtool.post"), "preflight", None)
    if preflight is not None:  # plugins, profiles and the output folder, before any work
        preflight(robot, job, outdir)
    if job.task.kind == "sequential_reach":  # seed 002's task: camtool/reach.py
        from .reach import run_reach_job
        return run_reach_job(job, outdir, on_stage)
    if job.planner.method == "arm-angle-sqp":
        from .errors import BadInput
        raise BadInput(f"{job.path}: planner.method: 'arm-angle-sqp' plans task.kind = 'sequential_reach', "
                       f"not {job.task.kind!r} jobs")
    if job.task.kind == "cartesian":  # seed 001's line and arc: camtool/cartesian.py
        from .cartesian import run_cartesian_job
        return run_cartesian_job(job, outdir, on_stage)
    outdir = Path(outdir)
    r = RunResult(on_stage=on_stage)
    done = r.done

    wp = done("workpiece", workpiece_for_job(job, r.stages))
    surface = done("fit", surface_for_job(job, wp, r.stages))
    path = done("raster", path_for_job(job, surface, r.stages))
    try:
        joint_path, trajectory = plan_and_time(job, path, robot, workpiece=wp)
    except PlanInfeasible as exc:
        _report_unreachable(exc, path, robot, job, outdir)
        raise
    done("plan", joint_path)
    done("time", trajectory)
    r.post_checked(trajectory, robot, job, outdir)
    report = run_report(path, joint_path, trajectory, robot, job, job.planner.method)
    if "free_moves" in joint_path.events:
        report["free_moves"] = joint_path.events["free_moves"]
    report["limits_ok"] = True  # post_checked passed the independent check
    report["status"] = "ok"
    trajectories = {job.planner.method: trajectory}
    if compare:
        other = "general" if job.planner.method == "seed" else "seed"
        try:
            jp2, tr2 = plan_and_time(job, path, robot, other, workpiece=wp)
            trajectories[other] = tr2
            report["compare"] = run_report(path, jp2, tr2, robot, job, other)
        except PlanInfeasible as exc:
            report["compare"] = {"method": other, "status": "infeasible", "reason": str(exc)}
    return r.finish(report, path, joint_path, robot, trajectories, outdir)
