"""Midposes on a C2 turn of the tool (plan/row_orientations.py): the feed near the wrist's singularity (issue #46)."""
import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from camtool.job import load_job
from camtool.path.toolpath import WORK, ZONE_CODE, Path
from camtool.plan.cwln import CwlnSolver
from camtool.plan.densify import densify_work
from camtool.plan.row_orientations import RowOrientations
from camtool.plan.strategy import ik_settings
from camtool.run.job_settings import JobSettings
from camtool.run.stages import robot_for_job
from camtool.timing.pathlaw import PathSpline, speed_bounds
from camtool.timing.runs import path_parameter
from camtool.trajectory import JointPath

from conftest import SAMPLES

FEED_MM_S = 100.0


def _turning_row(n: int, pitch_mm: float, wave_deg: float, R0=np.eye(3), p0=np.zeros(3), direction=(1.0, 0, 0)):
    """(poses (n, 4, 4), s (n,)): a straight row whose tool turns smoothly about two axes (two waves)."""
    s = np.arange(n) * pitch_mm
    a = np.radians(wave_deg)
    rx = Rotation.from_rotvec(a * np.sin(2 * np.pi * s / 60.0)[:, None] * [1.0, 0.0, 0.0])
    ry = Rotation.from_rotvec(a * np.cos(2 * np.pi * s / 80.0)[:, None] * [0.0, 1.0, 0.0])
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = R0 @ (rx * ry).as_matrix()
    T[:, :3, 3] = p0 + s[:, None] * np.asarray(direction)
    return T, s


def _true_turn(s, wave_deg):
    a = np.radians(wave_deg)
    return (Rotation.from_rotvec(a * np.sin(2 * np.pi * s / 60.0)[:, None] * [1.0, 0.0, 0.0])
            * Rotation.from_rotvec(a * np.cos(2 * np.pi * s / 80.0)[:, None] * [0.0, 1.0, 0.0]))


def test_midposes_follow_the_smooth_turn_closer_than_a_slerp_and_only_on_the_runs():
    n, pitch, wave = 34, 5.0, 8.0
    T, s = _turning_row(n, pitch, wave)
    zone = np.full(n, WORK)
    zone[24] = ZONE_CODE["retract"]             # a pose off the surface ends a run
    segment = np.r_[np.zeros(16, int), np.ones(n - 16, int)]   # a new segment starts a run
    only = np.ones(n, bool)
    only[29:] = False                           # an analytic face's poses: slerped
    ro = RowOrientations.build(Path(T, segment, np.arange(n), zone), only, np.eye(4))
    first = np.arange(n - 1)
    ok, R = ro.at(first, np.full(n - 1, 0.5))
    inside = np.ones(n - 1, bool)
    inside[[15, 23, 24]] = False                 # across a segment, into and out of the retract
    inside[28:] = False                         # into the analytic poses and beyond
    assert np.array_equal(ok, inside)
    k = np.flatnonzero(ok & (first >= 3) & (first <= 11))   # inside the first run, off its ends
    truth = _true_turn(s[k] + 0.5 * pitch, wave)
    slerp = np.array([Slerp([0, 1], Rotation.from_matrix(T[i:i + 2, :3, :3]))(0.5).as_matrix() for i in k])
    err_spline = (Rotation.from_matrix(R[k]) * truth.inv()).magnitude()
    err_slerp = (Rotation.from_matrix(slerp) * truth.inv()).magnitude()
    assert err_spline.max() < 0.1 * err_slerp.max()
    # through the poses themselves, at any share of a step by chord length
    ok0, R0 = ro.at(first[ok], np.zeros(ok.sum()))
    assert ok0.all() and np.allclose(R0, T[first[ok], :3, :3], atol=1e-9)


def _row_bound_mm_s(solver, robot, q):
    tcp = np.array([solver.tcp_pose(x)[:3, 3] for x in q])
    s = path_parameter(q, np.linalg.norm(np.diff(tcp, axis=0), axis=1), robot.limits, FEED_MM_S)
    return float(speed_bounds(*PathSpline(s, q).piece_bounds(), robot.limits)[0].min())


def test_densified_row_near_the_wrist_singularity_keeps_the_feed_of_its_own_poses():
    """A row of the IRB2400 with j5 at 12-18 deg, its tool turning by +-2 deg waves: densify splits the steps where
    the wrist's joint-linear motion bows off the chord. The time law's spline through the poses and the midposes
    holds the feed of the spline through the row's own poses (the reference) with the midposes on the rows' C2 turn;
    slerped step by step (before), their kinks near the singularity halved it (40.6 of 75.5 mm/s)."""
    job = load_job(SAMPLES / "irb2400_plate.toml", [])
    robot = robot_for_job(job)
    solver = CwlnSolver(robot, ik_settings(JobSettings.from_job(job, robot).planner))
    q0 = np.radians([0.0, 20.0, 10.0, 0.0, 15.0, 0.0])
    T0 = solver.tcp_pose(q0)
    n = 41
    poses, _ = _turning_row(n, 5.0, 2.0, T0[:3, :3], T0[:3, 3], T0[:3, 1])
    q = [q0]
    for T in poses:
        res = solver.solve(T, q[-1])
        assert res.converged
        q.append(res.q)
    q = np.array(q[1:])
    assert 10.0 < np.degrees(np.abs(q[:, 4])).min() and np.degrees(np.abs(q[:, 4])).max() < 20.0
    path = Path(robot.base_T_mm @ poses, np.zeros(n, int), np.arange(1, n + 1), np.full(n, WORK))
    f, b = np.zeros(n), np.zeros(n, bool)
    jp = JointPath(q, np.arange(n), np.full(n, WORK), f, f, b, b, b, b, ~b)
    own = _row_bound_mm_s(solver, robot, q)
    slerped = densify_work(jp, path, robot, solver, 0.05)
    turned = densify_work(jp, path, robot, solver, 0.05,
                          RowOrientations.build(path, ~b, np.linalg.inv(robot.base_T_mm)))
    assert turned.events["densified_steps"]["rows"] >= 5
    assert _row_bound_mm_s(solver, robot, turned.q) >= 0.95 * own
    assert _row_bound_mm_s(solver, robot, slerped.q) < 0.7 * own
