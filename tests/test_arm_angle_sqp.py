"""Arm-angle SQP planner (seed 002, on the paper's table sia20_paper) and the sequential_reach job kind."""
import json

import numpy as np
import pytest

from camtool.errors import PlanInfeasible
from camtool.job import load_job
from camtool.plan.arm_angle_sqp import LIMIT_MARGIN_RAD, optimise_arm_angles, path_length_rad, plan_arm_angle_sqp
from camtool.run.tasks.reach import reach_path, target_plane
from camtool.robots import get_robot
from camtool.robots.ik_srs import FAMILIES
from camtool.transforms import rotation_angle_rad

from conftest import SAMPLES, run_camtool

WALL_R = np.column_stack([[-1.0, 0, 0], [0, 0, 1.0], [0, 1.0, 0]])  # tool z into the wall, tool y up


def _targets(points_mm):
    T = np.tile(np.eye(4), (len(points_mm), 1, 1))
    T[:, :3, :3] = WALL_R
    T[:, :3, 3] = points_mm
    return T


@pytest.fixture(scope="module")
def small_task():
    pts = [(x, 500.0, z) for z in (450.0, 550.0, 650.0) for x in (-100.0, 0.0, 100.0)]
    robot = get_robot("sia20_paper")
    return robot, _targets(pts), optimise_arm_angles(robot, _targets(pts))


def test_every_family_reported_and_sqp_never_worse_when_fixed_is_feasible(small_task):
    robot, targets, res = small_task
    assert [f.family for f in res.families] == list(FAMILIES)
    lo, hi = robot.limits.lower + LIMIT_MARGIN_RAD, robot.limits.upper - LIMIT_MARGIN_RAD
    for f in res.families:
        assert np.isclose(f.fixed_E_rad, path_length_rad(f.q_fixed))
        assert np.isclose(f.opt_E_rad, path_length_rad(f.q_opt))
        assert f.fixed_feasible == bool(np.all(f.q_fixed >= lo - 1e-9) and np.all(f.q_fixed <= hi + 1e-9))
        assert f.opt_feasible == bool(np.all(f.q_opt >= lo - 1e-9) and np.all(f.q_opt <= hi + 1e-9))
        if f.fixed_feasible and f.opt_feasible:
            assert f.opt_E_rad <= f.fixed_E_rad + 1e-6
        # every optimised pose is an exact IK solution of its target
        for q, T in zip(f.q_opt, targets):
            Tq = robot.fk(q)
            assert np.linalg.norm(Tq[:3, 3] - T[:3, 3]) < 1e-6 and rotation_angle_rad(Tq, T) < 1e-9
    feasible = [(f.opt_E_rad, i) for i, f in enumerate(res.families) if f.opt_feasible] + \
               [(f.fixed_E_rad, i) for i, f in enumerate(res.families) if f.fixed_feasible]
    assert res.best == min(feasible)[1]
    assert any(f.opt_feasible and f.fixed_feasible and f.opt_E_rad < f.fixed_E_rad - 1e-3 for f in res.families)


def test_fixed_arm_angle_is_the_start_value(small_task):
    robot, targets, res = small_task
    from camtool.robots.ik_srs import SrsIK
    ik = SrsIK(robot)
    f = res.families[1]
    for q, T in zip(f.q_fixed, targets):
        assert abs(ik.arm_angle(q) - np.pi / 4) < 1e-9


def test_plan_arm_angle_sqp_gives_a_joint_path(small_task):
    robot, targets, _ = small_task
    job = load_job(SAMPLES / "sia20_paper_wall.toml", ["task.plane=job", "task.plane_point_mm=[0, 600, 0]",
                                                 "task.grid_columns=3", "task.grid_rows=2"])
    point, normal = target_plane(job)
    path = reach_path(job, point, normal, job.cell.base_xyz_mm)
    assert len(path) == 1 + 6 and path.zone_names()[0] == "approach"
    robot = robot.with_placement(base_T_mm=np.array([[1, 0, 0, 0], [0, 1, 0, 100.0], [0, 0, 1, 0], [0, 0, 0, 1]]))
    jp, res = plan_arm_angle_sqp(path, robot, 45.0, 100)
    assert jp.q.shape == (7, 7) and jp.reached.all() and robot.within_limits(jp.q.max(0))
    assert jp.position_error_mm.max() < 1e-6
    assert jp.events["arm_angle_sqp"]["best_family"] == list(res.families[res.best].family)


def test_unreachable_target_is_named():
    robot = get_robot("sia20_paper")
    with pytest.raises(PlanInfeasible, match="target 1: .*out of reach"):
        optimise_arm_angles(robot, _targets([(0.0, 500.0, 500.0), (350.0, 600.0, 950.0)]))


def test_reach_job_from_the_cli_vertical_route(tmp_path):
    out = tmp_path / "v"
    # a 4 x 4 corner of the sample's 8 x 8 wall grid (100 mm apart)
    r = run_camtool("run", SAMPLES / "sia20_paper_wall.toml", "-o", out, "--set", "task.route=vertical",
                    "--set", "task.grid_columns=4", "--set", "task.grid_rows=4")
    assert r.returncode == 0, r.stderr
    report = json.loads((out / "report.json").read_text())
    fam = report["arm_angle_sqp"]["families"]
    assert len(fam) == 8 and report["task"]["route"] == "vertical" and report["task"]["targets"] == 16
    assert abs(report["task"]["plane_point_mm"][1] - 600.0) < 1.0   # the RANSAC plane of wall.ply
    best = fam[report["arm_angle_sqp"]["best_family_number"] - 1]
    assert best["optimised_feasible"] or best["fixed_feasible"]
    assert (out / "SIAWALL.csv").is_file() and "arm_angle_families.txt" in r.stdout
    table = (out / "arm_angle_families.txt").read_text()
    assert "kept" in table and len(table.splitlines()) == 9


def test_reach_job_horizontal_small_grid_and_paper_placement(tmp_path):
    r = run_camtool("run", SAMPLES / "sia20_paper_wall.toml", "-o", tmp_path / "h", "--set", "task.grid_columns=3",
                    "--set", "task.grid_rows=2", "--set", "task.start_mm=[0, 600, 800]")
    assert r.returncode == 0, r.stderr
    report = json.loads((tmp_path / "h" / "report.json").read_text())
    assert report["task"]["route"] == "horizontal" and report["task"]["poses"] == 7
    # the paper's placement (base at the world origin): the corner is out of reach -> exit 3, clear line
    r = run_camtool("run", SAMPLES / "sia20_paper_wall.toml", "-o", tmp_path / "p", "--set", "cell.base_xyz_mm=[0, 0, 0]")
    assert r.returncode == 3 and "out of reach" in r.stderr and "target 0" in r.stderr
    assert (tmp_path / "h" / "SIAWALL.csv").is_file()   # the paper's table has no controller: joint values only


def test_raster_job_with_arm_angle_sqp_is_bad_input(tmp_path):
    r = run_camtool("run", SAMPLES / "sphere.toml", "-o", tmp_path / "s", "--set", "planner.method=arm-angle-sqp")
    assert r.returncode == 2 and "sequential_reach" in r.stderr
