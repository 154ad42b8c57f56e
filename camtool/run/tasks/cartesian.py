"""Cartesian line and arc interpolation (seed 001), solved by closed-form IK, timed, and checked.

- ``line_poses(T0, T1, n)``: n poses on the straight line from T0 to T1, the
  orientation interpolated by scipy's ``Slerp``.
- ``arc_poses(T0, centre, axis, angle, n)``: n poses on the circular arc that
  starts at T0, turns ``angle`` rad about ``axis`` through ``centre``;
  ``arc_through_points(T0, p_mid, p_end, n)``: the arc through three points.
  The tool keeps T0's orientation unless ``R_end`` is given (then slerp).
- ``solve_poses(robot, poses, q_ref)``: joint values per pose, closed-form
  (``ik_spherical_wrist``, least change from the previous pose) when the robot
  is of the IRB2400 family, else CWLN warm-started from the previous pose.
- ``run``: ``task.kind = "cartesian"`` in the pipeline: seed
  001's test moves (a line 0.4 m down the tool z axis, then 0.4 m along +y,
  then a circle), each move a work run of its own; the timed trajectory is
  sampled every ``timing.check_dt_ms`` and the TCP's distance from the line or
  arc is measured between the solved points too, and so is the straight line
  a controller's linear move draws between two points (the chord of an arc). A move that leaves its
  primitive by more than ``task.path_tol_mm`` gets twice the points, up to
  ``MAX_DENSIFY`` times.

Lengths mm, angles rad inside (deg in the job).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from pathlib import Path as FsPath

from ...errors import BadInput, PlanInfeasible
from ...job import Job
from ..part_stages import JobPart
from ...plan.cwln import CwlnSolver, IkSettings
from ...robots.ik_spherical_wrist import SphericalWristIK
from ...collision.stage import collision_world
from ..job_settings import JobSettings
from ..stages import RunResult, StageLog, finish_run, post_checked, run_report, time_for_job
from ...path.toolpath import ZONE_CODE, Path
from ...trajectory import JointPath
from ...transforms import matrix_from_xyz_rpy

MAX_DENSIFY = 8


@dataclass(frozen=True)
class Primitive:
    """A line (a -> b) or an arc (centre, unit axis, radius, start point, angle) in mm / rad."""

    kind: str
    a: np.ndarray
    b: np.ndarray | None = None
    centre: np.ndarray | None = None
    axis: np.ndarray | None = None
    angle_rad: float = 0.0

    def distance_mm(self, p: np.ndarray) -> np.ndarray:
        """Distance of points (N, 3) from the line segment or the arc (its circle, clamped to the arc)."""
        p = np.atleast_2d(p)
        if self.kind == "line":
            d = self.b - self.a
            s = np.clip((p - self.a) @ d / (d @ d), 0.0, 1.0)
            return np.linalg.norm(p - (self.a + s[:, None] * d), axis=1)
        r0 = self.a - self.centre
        radius = np.linalg.norm(r0)
        e1 = r0 / radius
        e2 = np.cross(self.axis, e1)
        rel = p - self.centre
        x, y = rel @ e1, rel @ e2
        phi = np.arctan2(y, x)
        if self.angle_rad >= 0:
            phi = np.where(phi < 0, phi + 2 * np.pi, phi)
            phi = np.clip(phi, 0.0, self.angle_rad)
        else:
            phi = np.where(phi > 0, phi - 2 * np.pi, phi)
            phi = np.clip(phi, self.angle_rad, 0.0)
        near = self.centre + radius * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
        return np.linalg.norm(p - near, axis=1)

    @property
    def length_mm(self) -> float:
        if self.kind == "line":
            return float(np.linalg.norm(self.b - self.a))
        return float(abs(self.angle_rad) * np.linalg.norm(self.a - self.centre))


def slerp_rotations(R0: np.ndarray, R1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Rotations (N, 3, 3) slerped from R0 to R1 at fractions s in [0, 1]."""
    return Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([R0[:3, :3], R1[:3, :3]])))(s).as_matrix()


def line_poses(T0: np.ndarray, T1: np.ndarray, n: int) -> tuple[np.ndarray, Primitive]:
    """n >= 2 poses from T0 to T1 on a straight line, orientation by slerp."""
    if n < 2:
        raise BadInput(f"a line needs at least 2 points, got {n}")
    s = np.linspace(0.0, 1.0, n)
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = slerp_rotations(T0, T1, s)
    T[:, :3, 3] = T0[:3, 3] + s[:, None] * (T1[:3, 3] - T0[:3, 3])
    return T, Primitive("line", T0[:3, 3].copy(), T1[:3, 3].copy())


def arc_poses(T0: np.ndarray, centre_mm, axis, angle_rad: float, n: int,
              R_end: np.ndarray | None = None) -> tuple[np.ndarray, Primitive]:
    """n >= 2 poses on the arc from T0's position, ``angle_rad`` about ``axis`` through ``centre_mm``."""
    if n < 2:
        raise BadInput(f"an arc needs at least 2 points, got {n}")
    c = np.asarray(centre_mm, float)
    u = np.asarray(axis, float)
    u = u / np.linalg.norm(u)
    r0 = T0[:3, 3] - c
    r0 = r0 - (r0 @ u) * u
    if np.linalg.norm(r0) < 1e-9:
        raise BadInput("arc: the start point lies on the arc's axis")
    if not np.isclose((T0[:3, 3] - c) @ u, 0.0, atol=1e-6):
        raise BadInput("arc: the centre is not in the plane of the start point normal to the axis")
    s = np.linspace(0.0, 1.0, n)
    rot = Rotation.from_rotvec(np.outer(s * angle_rad, u))
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, 3] = c + rot.apply(r0)
    T[:, :3, :3] = T0[:3, :3] if R_end is None else slerp_rotations(T0, R_end, s)
    return T, Primitive("arc", T0[:3, 3].copy(), centre=c, axis=u, angle_rad=float(angle_rad))


def arc_through_points(T0: np.ndarray, p_mid, p_end, n: int) -> tuple[np.ndarray, Primitive]:
    """n poses on the circular arc from T0's position through ``p_mid`` to ``p_end``."""
    a, b, e = T0[:3, 3], np.asarray(p_mid, float), np.asarray(p_end, float)
    u = np.cross(b - a, e - a)
    if np.linalg.norm(u) < 1e-9 * max(1.0, np.linalg.norm(b - a) * np.linalg.norm(e - a)):
        raise BadInput("arc: the three points are in line")
    u /= np.linalg.norm(u)
    # circumcentre
    ab, ae = b - a, e - a
    c = a + (np.cross(u, ab) * (ae @ ae) - np.cross(u, ae) * (ab @ ab)) / (2 * np.cross(ab, ae) @ u)
    ang_e = np.arctan2(np.cross(a - c, e - c) @ u, (a - c) @ (e - c))
    ang_e = ang_e if ang_e > 0 else ang_e + 2 * np.pi
    return arc_poses(T0, c, u, float(ang_e), n)


def solve_poses(robot, poses_tcp_base: np.ndarray, q_ref: np.ndarray) -> np.ndarray:
    """Joint values per TCP pose (base frame): closed-form where the robot allows, else CWLN."""
    tool_inv = np.linalg.inv(robot.tool_T_mm)
    q = np.empty((len(poses_tcp_base), robot.dof))
    prev = np.asarray(q_ref, float)
    try:
        ik = SphericalWristIK(robot)
    except BadInput:
        ik = None
    if ik is not None:
        for k, T in enumerate(poses_tcp_base):
            try:
                prev = q[k] = ik.best(T @ tool_inv, prev)
            except PlanInfeasible as exc:
                raise PlanInfeasible(f"cartesian pose {k}: {exc}") from None
        return q
    solver = CwlnSolver(robot, IkSettings(max_iterations=300))
    for k, T in enumerate(poses_tcp_base):
        res = solver.solve(T, prev)
        if not res.converged:
            raise PlanInfeasible(f"cartesian pose {k}: CWLN did not converge "
                                 f"({res.position_error_mm:.3g} mm, {np.degrees(res.orientation_error_rad):.3g} deg)")
        prev = q[k] = res.q
    return q


def ik_method(robot) -> str:
    """'closed-form' if ``solve_poses`` uses the closed-form IK for this robot, else 'cwln'."""
    try:
        SphericalWristIK(robot)
        return "closed-form"
    except BadInput:
        return "cwln"


def seed001_moves(job) -> list[tuple[str, dict]]:
    """The job's moves as (kind, args): the line down the tool z, the line along +y, the arc."""
    t = job.task
    return [("line", {"tool_mm": [0.0, 0.0, t.line_down_mm], "n": t.line_points // 2}),
            ("line", {"world_mm": [0.0, t.line_side_mm, 0.0], "n": t.line_points - t.line_points // 2}),
            ("arc", {"radius_mm": t.arc_radius_mm, "angle_deg": t.arc_angle_deg, "n": t.arc_points})]


def build_moves(T_start: np.ndarray, moves, scale: list[int]) -> tuple[list[np.ndarray], list[Primitive]]:
    """Poses and primitives of consecutive moves (world frame); move i gets ``n * scale[i]`` points."""
    out, prims = [], []
    T = T_start
    for (kind, a), f in zip(moves, scale):
        n = (a["n"] - 1) * f + 1
        if kind == "line":
            T1 = T.copy()
            if "tool_mm" in a:
                T1[:3, 3] = T[:3, 3] + T[:3, :3] @ np.asarray(a["tool_mm"], float)
            else:
                T1[:3, 3] = T[:3, 3] + np.asarray(a["world_mm"], float)
            P, prim = line_poses(T, T1, n)
        else:  # a horizontal circle-arc starting at T, centre on the -x side of the tool's travel
            centre = T[:3, 3] - np.array([a["radius_mm"], 0.0, 0.0])
            P, prim = arc_poses(T, centre, [0.0, 0.0, 1.0], np.radians(a["angle_deg"]), n)
        out.append(P)
        prims.append(prim)
        T = P[-1]
    return out, prims


def path_of_moves(pose_lists: list[np.ndarray]) -> Path:
    """One work segment per move (each run starts and ends at rest)."""
    poses = np.concatenate(pose_lists)
    seg = np.concatenate([np.full(len(p), i) for i, p in enumerate(pose_lists)])
    point = np.concatenate([np.arange(1, len(p) + 1) for p in pose_lists])
    zone = np.full(len(poses), ZONE_CODE["work"])
    return Path(poses, seg, point, zone)


def chord_deviation_mm(pose_lists: list[np.ndarray], prims: list[Primitive]) -> np.ndarray:
    """Per move: the largest distance (mm) of a straight line between consecutive points from the line or arc
    (a controller's linear moves, MoveL / MOVL, between the program's points; at most the chord's sagitta)."""
    worst = np.zeros(len(prims))
    for i, (P, prim) in enumerate(zip(pose_lists, prims)):
        p = P[:, :3, 3]
        if len(p) > 1:
            worst[i] = float(prim.distance_mm(0.5 * (p[1:] + p[:-1])).max())
    return worst


def trajectory_deviation_mm(trajectory, robot, path: Path, prims: list[Primitive], dt_s: float) -> np.ndarray:
    """Per move: the largest distance (mm) of the sampled TCP from its line or arc."""
    t, q, *_ = trajectory.sample(dt_s)
    k = np.clip(np.searchsorted(trajectory.t_s, t, side="right") - 1, 0, len(trajectory.t_s) - 2)
    pi = trajectory.path_index
    a, b = pi[k], pi[k + 1]
    worst = np.zeros(len(prims))
    same = (a >= 0) & (b >= 0) & (path.segment[np.maximum(a, 0)] == path.segment[np.maximum(b, 0)])
    for i, prim in enumerate(prims):
        sel = np.nonzero(same & (path.segment[np.maximum(a, 0)] == i))[0]
        if not len(sel):
            continue
        p = np.array([(robot.base_T_mm @ robot.fk_tcp(q[j]))[:3, 3] for j in sel])
        worst[i] = float(prim.distance_mm(p).max())
    return worst


def run(job: Job, settings: JobSettings, robot, outdir, log: StageLog, compare: bool = False, *,
        part: JobPart) -> RunResult:
    """Run a ``task.kind = "cartesian"`` job (see module doc). ``compare`` and ``part`` (a workpiece) do not
    apply and are ignored."""
    outdir = FsPath(outdir)
    T_start = matrix_from_xyz_rpy(job.task.cart_start_mm, job.task.cart_start_rpy_deg)
    moves = seed001_moves(job)
    scale = [1] * len(moves)
    base_inv = np.linalg.inv(robot.base_T_mm)
    q_home = np.zeros(robot.dof) if settings.planner.q_home is None else np.asarray(settings.planner.q_home)
    history = []
    for _round in range(MAX_DENSIFY + 1):
        poses, prims = build_moves(T_start, moves, scale)
        path = path_of_moves(poses)
        q = solve_poses(robot, np.array([base_inv @ T for T in path.poses_mm]), q_home)
        n = len(q)
        err = np.array([np.linalg.norm((robot.base_T_mm @ robot.fk_tcp(qk))[:3, 3] - T[:3, 3])
                        for qk, T in zip(q, path.poses_mm)])
        f = np.zeros(n, bool)
        jp = JointPath(q, np.arange(n), path.zone.copy(), err, np.zeros(n), f, f.copy(), f.copy(), f.copy(),
                       err < 1e-6, {"cartesian": {}})
        trajectory = time_for_job(settings, jp, path, robot)
        dev = np.maximum(trajectory_deviation_mm(trajectory, robot, path, prims, settings.timing.check_dt_s),
                         chord_deviation_mm(poses, prims))
        history.append({"points": [len(p) for p in poses], "max_deviation_mm": dev.tolist()})
        bad = dev > job.task.path_tol_mm
        if not bad.any():
            break
        scale = [s * 2 if b_ else s for s, b_ in zip(scale, bad)]
    else:
        raise PlanInfeasible(f"cartesian moves leave their line/arc by {dev.max():.4g} mm > task.path_tol_mm = "
                             f"{job.task.path_tol_mm:g} even after {MAX_DENSIFY} densifications")
    for name, value in (("raster", path), ("plan", jp), ("time", trajectory)):
        log.done(name, value)
    simulated: dict = {}
    programs = log.done("post", post_checked(trajectory, robot, job, outdir, path=path, report=simulated))
    report = run_report(path, jp, trajectory, robot, job, "cartesian")
    report["programs_simulated"] = simulated
    report["limits_ok"] = True
    report["status"] = "ok"
    report["cartesian"] = {"moves": [{"kind": p.kind, "length_mm": p.length_mm} for p in prims],
                           "path_tol_mm": job.task.path_tol_mm, "rounds": history,
                           "max_deviation_mm": float(max(history[-1]["max_deviation_mm"])),
                           "ik": ik_method(robot)}
    return finish_run(log, programs, report, path, jp, robot, {"cartesian": trajectory}, outdir,
                      world=collision_world(settings, robot))
