"""The seed strategy against the baseline: accuracy and smoothness on the seed sphere
job, reverse planning and fallback on a path that provokes jumps, unreachable poses."""
import numpy as np
import pytest

from camtool.errors import BadInput, PlanInfeasible
from camtool.job import load_job
from camtool.run.pipeline import path_for_job, robot_for_job, surface_for_job, workpiece_for_job
from camtool.plan import plan_path
from camtool.plan.strategy import split_runs
from camtool.report.run_report import plan_metrics
from camtool.robots import get_robot
from camtool.path.toolpath import ZONE_CODE
from camtool.transforms import rotation_angle_rad

from conftest import SAMPLES
from plan_fixtures import sphere_rows
from camtool.settings import PlannerSettings


@pytest.fixture(scope="module")
def sphere_job():
    job = load_job(SAMPLES / "sphere.toml")
    path = path_for_job(job, surface_for_job(job, workpiece_for_job(job)))
    return job, path, robot_for_job(job)


@pytest.fixture(scope="module")
def seed_plan(sphere_job):
    job, path, robot = sphere_job
    return plan_path(path, robot, PlannerSettings.make(**job.planner))


def test_every_work_point_within_1um_and_0001deg(sphere_job, seed_plan):
    """Accuracy checked by an independent FK of the planned joints, not the planner's own errors."""
    job, path, robot = sphere_job
    jp = seed_plan
    rows = np.flatnonzero((jp.zone == ZONE_CODE["work"]) & (jp.path_index >= 0))
    assert len(rows) > 9000
    base_inv = np.linalg.inv(robot.base_T_mm)
    worst_mm = worst_deg = 0.0
    for k in rows[::7]:
        T = robot.fk_tcp(jp.q[k])
        target = base_inv @ path.poses_mm[jp.path_index[k]]
        worst_mm = max(worst_mm, np.linalg.norm(T[:3, 3] - target[:3, 3]))
        worst_deg = max(worst_deg, np.degrees(rotation_angle_rad(T, target)))
        assert robot.within_limits(jp.q[k])
    assert worst_mm <= 1e-3 and worst_deg <= 1e-3
    assert jp.position_error_mm[rows].max() <= 1e-3
    assert np.degrees(jp.orientation_error_rad[rows].max()) <= 1e-3


def test_seed_is_smooth_on_the_surface(sphere_job, seed_plan):
    job, path, robot = sphere_job
    m = plan_metrics(path, seed_plan, robot, "seed", 50, 100)
    assert m["on_surface_jumps"] == 0
    assert m["max_joint_step_work_deg"] <= 2.0
    assert m["retracts"] == 0


def test_general_baseline_runs_and_is_rougher(sphere_job, seed_plan):
    job, path, robot = sphere_job
    general = plan_path(path, robot, PlannerSettings.make(**{**job.planner, "method": "general"}))
    mg = plan_metrics(path, general, robot, "general", 50, 100)
    ms = plan_metrics(path, seed_plan, robot, "seed", 50, 100)
    assert mg["max_joint_step_work_deg"] > ms["max_joint_step_work_deg"]


def test_deterministic(sphere_job, seed_plan):
    job, path, robot = sphere_job
    again = plan_path(path, robot, PlannerSettings.make(**job.planner))
    assert np.array_equal(again.q, seed_plan.q)


def test_reverse_planning_and_fallback_move_jumps_off_the_surface():
    """A path that makes plain CWLN jump on the surface (a costly track, no posture term):
    the general method keeps the jumps; the seed strategy reverse-plans them away."""
    path = sphere_rows(rows=4)
    robot = get_robot("seed8")
    kw = dict(track_scale_mm=1.0, posture_gain=0.0)
    general = plan_path(path, robot, PlannerSettings.make(method="general", **kw))
    seed = plan_path(path, robot, PlannerSettings.make(method="seed", **kw))
    mg = plan_metrics(path, general, robot, "general", 50, 100)
    ms = plan_metrics(path, seed, robot, "seed", 50, 100)
    assert mg["on_surface_jumps"] >= 1
    assert ms["on_surface_jumps"] == 0
    assert ms["reverse_plans"] >= 1
    for ev in seed.events["reverse_plans"]:
        seg = path.segment[ev["index"]]
        first = np.flatnonzero((path.segment == seg) & (path.zone == ZONE_CODE["work"]))[0]
        assert np.all(seed.reverse_planned[np.isin(seed.path_index, np.arange(first, ev["index"] + 1))])
    # every fallback point is listed and preceded by inserted retract poses: a straight lift off the
    # surface along its normal, and a straight descent onto the point
    for ev in seed.events["retracts"]:
        row = int(np.flatnonzero(seed.path_index == ev["index"])[0])
        lift = np.flatnonzero(seed.retract[:row])[-10:]
        assert len(lift) == 10 and seed.singular[row] and lift[-1] == row - 1
        tcp = np.array([(robot.base_T_mm @ robot.fk_tcp(q))[:3, 3] for q in seed.q[lift]])
        normal_out = -path.poses_mm[ev["index"]][:3, 2]
        p0, p1 = path.poses_mm[ev["index"] - 1][:3, 3], path.poses_mm[ev["index"]][:3, 3]
        assert (tcp[4] - p0) @ normal_out > 199.0 and (tcp[5] - p1) @ normal_out > 199.0
    # the path stays exact at every pose, fallback points included
    assert seed.position_error_mm[seed.path_index >= 0].max() <= 1e-4


def test_unreachable_poses_raise_with_a_list():
    path = sphere_rows(center=(2400.0, 0.0, 100.0), rows=2, pitch_mm=40.0)
    with pytest.raises(PlanInfeasible) as info:
        plan_path(path, get_robot("seed8"), PlannerSettings.make(reverse_samples=5))
    unreachable = info.value.report["unreachable"]
    assert len(unreachable) > 0
    assert {"index", "segment", "point", "xyz_mm"} <= set(unreachable[0])
    assert "out of reach of seed8" in str(info.value)


def test_runs_split_at_segments():
    path = sphere_rows(rows=3)
    runs = split_runs(path)
    assert len(runs) == 3
    for a, b in runs:
        assert np.all(path.zone[a:b + 1] == ZONE_CODE["work"]) and len(set(path.segment[a:b + 1])) == 1


def test_bad_method_and_home():
    path = sphere_rows(rows=1, pitch_mm=50.0)
    with pytest.raises(BadInput, match="planner.method"):
        plan_path(path, get_robot("seed8"), PlannerSettings.make(method="magic"))
    with pytest.raises(BadInput, match="home_deg"):
        plan_path(path, get_robot("seed8"), PlannerSettings.make(q_home=[0, 0]))


def test_irb2400_plans_inside_the_coupled_axis_3_or_says_which_axis():
    """CWLN clamps the joint box; the IRB2400's controller limits axis 3 = j2 + j3. A plan never
    keeps a pose beyond it: a low plate close to the robot (its forearm would point 100 deg down)
    is refused naming rax_3, and a reachable one plans inside every controller limit."""
    robot = get_robot("irb2400")
    assert robot.conventions.coupled and not get_robot("sia20").conventions.coupled
    low = load_job(SAMPLES / "irb2400_plate.toml", ["raster.step_over_mm=60", "raster.pitch_mm=10",
                                                    "cell.workpiece_xyz_mm=[850.0, 0.0, 450.0]"])
    path = path_for_job(low, surface_for_job(low, workpiece_for_job(low)))
    with pytest.raises(PlanInfeasible) as info:
        plan_path(path, robot_for_job(low), PlannerSettings.make(reverse_samples=5))
    assert "rax_3" in str(info.value) and "beyond its limits" in str(info.value)
    assert "rax_3" in info.value.report["unreachable"][0]["reason"]
    ok = load_job(SAMPLES / "irb2400_plate.toml", ["raster.step_over_mm=60", "raster.pitch_mm=10"])
    jp = plan_path(path_for_job(ok, surface_for_job(ok, workpiece_for_job(ok))), robot_for_job(ok),
                   PlannerSettings.make())
    assert np.all(robot.conventions.within_limits(jp.q))


def _ball(centre, radius_mm):
    from camtool.collision.shapes import WORLD, Body

    T = np.eye(4)
    T[:3, 3] = centre
    return Body("ball", "obstacle", WORLD, "sphere", (float(radius_mm),), T)


def test_an_obstacle_at_the_elbow_is_planned_around_with_another_arm_angle():
    """The sia20's planned elbow is where a ball is put; with the cell the planner takes other
    configurations, every work pose reached and clear of the ball (measured by the world itself)."""
    from camtool.collision import CellSettings, CollisionWorld

    robot = get_robot("sia20")
    path = sphere_rows(center=(1000.0, 0.0, 400.0), radius=300.0, rows=3, pitch_mm=20.0, el_deg=(-10, 30),
                       az_deg=(-30, 30))
    plain = plan_path(path, robot, PlannerSettings.make())
    work = np.flatnonzero(plain.path_index >= 0)
    elbow = CollisionWorld(robot).joint_frames_mm(plain.q[work[len(work) // 2]])[3][:3, 3]
    world = CollisionWorld(robot, CellSettings(obstacles=(_ball(elbow, 100.0),)))
    assert not world.valid_many(plain.q[work]).all()      # the plain plan runs the elbow through the ball
    jp = plan_path(path, robot, PlannerSettings.make(), world)
    runs = np.zeros(len(path), bool)   # work rows and their leads (connectors are the lift stage's)
    for a, b in split_runs(path):
        runs[a:b + 1] = True
    work = np.flatnonzero((jp.path_index >= 0) & runs[np.maximum(jp.path_index, 0)])
    assert jp.reached[work].all() and world.valid_many(jp.q[work]).all()
    assert all(world.clearance_mm_at(q)[0] >= world.clearance_mm for q in jp.q[work[::5]])


def test_a_pose_every_configuration_of_which_collides_is_refused_naming_the_bodies():
    from camtool.collision import CellSettings, CollisionWorld

    robot = get_robot("sia20")
    path = sphere_rows(center=(1000.0, 0.0, 400.0), radius=300.0, rows=2, pitch_mm=20.0, el_deg=(-10, 30),
                       az_deg=(-30, 30))
    tcp = path.poses_mm[np.flatnonzero(path.zone == ZONE_CODE["work"])[0]][:3, 3]
    world = CollisionWorld(robot, CellSettings(obstacles=(_ball(tcp, 40.0),)))   # round the first work pose
    with pytest.raises(PlanInfeasible) as exc:
        plan_path(path, robot, PlannerSettings.make(), world)
    first = exc.value.report["unreachable"][0]
    assert "every configuration tried collides" in first["reason"] and "ball" in first["reason"]
    assert "every configuration tried collides" in str(exc.value)
