"""Cartesian line / arc interpolation (seed 001) with closed-form IK, timing and the path check."""
import json

import numpy as np
import pytest

from camtool.settings import TimingSettings
from camtool.run.tasks.cartesian import arc_poses, arc_through_points, line_poses, solve_poses
from camtool.errors import BadInput
from camtool.robots import get_robot
from camtool.transforms import matrix_from_xyz_rpy, rotation_angle_rad

from conftest import SAMPLES, run_camtool


def test_line_with_slerp_orientation():
    T0 = matrix_from_xyz_rpy([900, -200, 1000], [0, 180, 0])
    T1 = matrix_from_xyz_rpy([900, 200, 600], [0, 150, 30])
    P, prim = line_poses(T0, T1, 300)
    assert len(P) == 300 and np.allclose(P[0], T0) and np.allclose(P[-1], T1)
    assert prim.distance_mm(P[:, :3, 3]).max() < 1e-9
    steps = [rotation_angle_rad(P[k], P[k + 1]) for k in range(299)]
    assert np.allclose(steps, rotation_angle_rad(T0, T1) / 299, atol=1e-9)  # slerp: constant angular step


def test_arc_by_centre_and_through_three_points_agree():
    T0 = matrix_from_xyz_rpy([900, 200, 600], [0, 180, 0])
    P, prim = arc_poses(T0, [800, 200, 600], [0, 0, 1], np.pi, 628)
    assert np.allclose(np.linalg.norm(P[:, :3, 3] - [800, 200, 600], axis=1), 100.0)
    assert np.allclose(P[-1, :3, 3], [700, 200, 600])
    Q, prim3 = arc_through_points(T0, [800, 300, 600], [700, 200, 600], 628)
    assert np.allclose(P[:, :3, 3], Q[:, :3, 3], atol=1e-9)
    assert prim3.distance_mm(np.array([[800, 300, 600.0], [800, 100, 600.0]])).tolist() == pytest.approx([0, 100 * np.sqrt(2)])
    with pytest.raises(BadInput, match="in line"):
        arc_through_points(T0, [900, 250, 600], [900, 300, 600], 10)


def test_solve_poses_closed_form_is_exact_and_continuous():
    robot = get_robot("irb2400")
    T0 = matrix_from_xyz_rpy([900, -200, 1000], [0, 180, 0])
    T1 = T0.copy()
    T1[:3, 3] += [0, 0, -400]
    P, _ = line_poses(T0, T1, 150)
    q = solve_poses(robot, P, np.zeros(6))
    assert max(np.linalg.norm(robot.fk(qk)[:3, 3] - T[:3, 3]) for qk, T in zip(q, P)) < 1e-6
    assert np.degrees(np.abs(np.diff(q, axis=0)).max()) < 2.0
    assert all(robot.within_limits(qk) for qk in q)


def test_sample_job_stays_on_the_line_and_arc(tmp_path):
    r = run_camtool("run", SAMPLES / "irb2400_line_arc.toml", "-o", tmp_path / "a")
    assert r.returncode == 0, r.stderr
    rep = json.loads((tmp_path / "a" / "report.json").read_text())
    c = rep["cartesian"]
    assert c["ik"] == "closed-form" and c["rounds"][-1]["points"] == [150, 150, 628]
    assert 0 < c["max_deviation_mm"] <= 0.01
    assert (tmp_path / "a" / "LINEARC.mod").is_file()


def test_coarse_points_are_densified_until_within_tolerance(tmp_path):
    r = run_camtool("run", SAMPLES / "irb2400_line_arc.toml", "-o", tmp_path / "c", "--set", "task.line_points=20",
                    "--set", "task.arc_points=40")
    assert r.returncode == 0, r.stderr
    c = json.loads((tmp_path / "c" / "report.json").read_text())["cartesian"]
    first, last = c["rounds"][0], c["rounds"][-1]
    assert max(first["max_deviation_mm"]) > 0.01          # the coarse path did leave the line / arc
    assert max(last["max_deviation_mm"]) <= 0.01 and len(c["rounds"]) > 1
    assert sum(last["points"]) > sum(first["points"])


def test_deviation_measure_is_independent_of_the_solver(tmp_path):
    """Re-measure the sample's timed trajectory against the analytic line / circle here."""
    from camtool.run.tasks.cartesian import build_moves, path_of_moves, seed001_moves
    from camtool.job import load_job
    from camtool.run.pipeline import robot_for_job
    from camtool.timing import time_trajectory
    from camtool.trajectory import JointPath

    job = load_job(SAMPLES / "irb2400_line_arc.toml", ["task.line_points=20", "task.arc_points=40"])
    robot = robot_for_job(job)
    poses, _ = build_moves(matrix_from_xyz_rpy(job.task.cart_start_mm, job.task.cart_start_rpy_deg),
                           seed001_moves(job), [1, 1, 1])
    path = path_of_moves(poses)
    q = solve_poses(robot, path.poses_mm, np.zeros(6))
    n = len(q)
    f = np.zeros(n, bool)
    jp = JointPath(q, np.arange(n), path.zone, np.zeros(n), np.zeros(n), f, f, f, f, ~f)
    tr = time_trajectory(jp, path, robot, TimingSettings.make(method="quintic", tcp_speed_mm_s=100.0, check_dt_ms=4.0))
    t, qs, *_ = tr.sample(0.004)
    p = np.array([robot.fk(x)[:3, 3] for x in qs])
    # distance to the union of: vertical line x=900,y=-200; line y in [-200,200] at z=600; circle r=100 about (800,200)
    d1 = np.hypot(p[:, 0] - 900, p[:, 1] + 200) + np.maximum(0, p[:, 2] - 1000) + np.maximum(0, 600 - p[:, 2])
    d2 = np.hypot(p[:, 0] - 900, p[:, 2] - 600) + np.maximum(0, p[:, 1] - 200) + np.maximum(0, -200 - p[:, 1])
    d3 = np.hypot(np.hypot(p[:, 0] - 800, p[:, 1] - 200) - 100, p[:, 2] - 600)
    d = np.minimum(np.minimum(d1, d2), d3)
    assert d.max() < 0.05   # the timed joint motion through the points follows the line and the circle
    # but a controller's straight moves between 40 points of a circle of r = 100 mm cut its chords:
    # the chord measure equals the analytic sagitta r (1 - cos(dtheta / 2)), the lines have none
    from camtool.run.tasks.cartesian import chord_deviation_mm
    _, prims = build_moves(matrix_from_xyz_rpy(job.task.cart_start_mm, job.task.cart_start_rpy_deg),
                           seed001_moves(job), [1, 1, 1])
    chord = chord_deviation_mm(poses, prims)
    assert chord[:2] == pytest.approx([0.0, 0.0], abs=1e-9)
    assert chord[2] == pytest.approx(100.0 * (1 - np.cos(np.radians(360.0 / 39) / 2)), rel=1e-6)
