"""Reconfigure off the surface: Cartesian lifts, reconfiguration at a clearance, collision-checked connectors."""
import re

import numpy as np
import pytest

from camtool.job import load_job
from camtool.plan.connectors import cartesian_lift, is_reconfiguration, LiftSettings
from camtool.plan.cwln import CwlnSolver, IkSettings
from camtool.robots import get_robot
from camtool.run.job_settings import JobSettings
from camtool.run.stages import path_for_job, plan_for_job, robot_for_job, surface_for_job, workpiece_for_job
from camtool.path.toolpath import ZONE_CODE

from conftest import SAMPLES

# the forcing settings: a costly track and no posture term make the seed planner reconfigure
# (#24: with posture_gain = 0 the least-norm drift folds seed8's forearm through its column and carriage,
# a self-collision the cell check refuses naming j6-j7 and the carriage; these tests are about the
# reconfigurations off the part, so those two pairs are allowed)
FORCING = ["raster.step_over_mm=40", "raster.pitch_mm=10", "planner.track_scale_mm=1", "planner.posture_gain=0",
           'cell.allow_collision=[["carriage", "j6-j7"], ["track-j2", "j6-j7"]]']


def test_cartesian_lift_is_a_straight_line_along_minus_tool_z():
    robot = get_robot("sia20")
    solver = CwlnSolver(robot, IkSettings(max_iterations=300))
    q0 = np.radians([10, 40, 0, -60, 0, 50, 0])
    T0 = robot.fk_tcp(q0)
    rows = cartesian_lift(solver, T0, q0, 80.0, 4)
    assert rows.shape == (4, 7)
    tcp = np.array([robot.fk_tcp(q)[:3, 3] for q in rows])
    expected = T0[:3, 3] - np.outer([20, 40, 60, 80], T0[:3, 2])
    assert np.allclose(tcp, expected, atol=1e-3)
    assert cartesian_lift(solver, T0, q0, 5000.0, 4) is None  # out of reach: None, not a wrong pose


def test_reconfiguration_threshold_per_joint_type():
    robot = get_robot("seed8")
    s = LiftSettings(100.0, 5, np.radians(10), 50.0, 500.0, 0)
    q = np.zeros(8)
    assert not is_reconfiguration(q, q + np.r_[49.0, np.full(7, np.radians(9))], robot, s)
    assert is_reconfiguration(q, q + np.r_[51.0, np.zeros(7)], robot, s)
    assert is_reconfiguration(q, q + np.r_[0.0, np.radians(11), np.zeros(6)], robot, s)


@pytest.fixture(scope="module")
def forced():
    job = load_job(SAMPLES / "sphere.toml", FORCING)
    robot = robot_for_job(job)
    settings = JobSettings.from_job(job, robot)
    wp = workpiece_for_job(job)
    surface = surface_for_job(job, wp)
    path = path_for_job(job, surface)
    return robot, settings, surface, path, plan_for_job(settings, path, robot, wp), wp


def _depth_below_patch_mm(robot, surface, q):
    """Depth of the TCP below the sphere patch (0 outside its footprint or above it)."""
    x = (robot.base_T_mm @ robot.fk_tcp(q))[:3, 3]
    d = np.linalg.norm(x - surface.center_mm) - surface.radius_mm
    if d >= 0 or not surface.boundary.contains(surface.uv_from_points(x[None]))[0]:
        return 0.0
    return -d


def test_reconfigurations_happen_off_the_part(forced):
    robot, settings, surface, path, jp, _wp = forced
    lifted = jp.events["lifted_connectors"]
    assert len(lifted) >= 3 and max(c["joint_change_deg"] for c in lifted) > 100
    inserted = (jp.path_index < 0) & np.isin(jp.zone, [ZONE_CODE["self_motion"], ZONE_CODE["retract"]])
    heights = np.array([np.linalg.norm((robot.base_T_mm @ robot.fk_tcp(q))[:3, 3] - surface.center_mm)
                        - surface.radius_mm for q in jp.q[inserted]])
    assert heights.max() >= 0.5 * settings.planner.lift_mm - 1.0


def test_no_non_work_motion_enters_the_part(forced):
    """Joint-linear interpolation between every pair of rows, the way a controller runs joint moves."""
    robot, settings, surface, path, jp, _wp = forced
    work = jp.zone == ZONE_CODE["work"]
    worst = 0.0
    for i in range(len(jp.q) - 1):
        if work[i] and work[i + 1]:
            continue
        qa, qb = jp.q[i], jp.q[i + 1]
        n = max(2, int(np.ceil(np.max(np.abs(qb - qa)[~robot.prismatic]) / 0.01)))
        for f in np.linspace(0.0, 1.0, n):
            worst = max(worst, _depth_below_patch_mm(robot, surface, qa + (qb - qa) * f))
    assert worst <= 0.1


def test_a_forced_reconfiguration_job_passes_the_independent_motion_check(forced):
    """The job the forcing settings make, timed and checked as `camtool run` does: the independent
    4 ms motion check passes (no penetration, on the surface, 5 mm clear off work) with the lifts."""
    from camtool.run.stages import motion_check, time_for_job

    robot, settings, surface, path, jp, wp = forced
    m = motion_check(settings, time_for_job(settings, jp, path, robot), robot, wp, path, surface)
    assert m["ok"] and m["max_penetration_mm"] <= 0.1 and m["work_deviation_mm"] <= 0.1, m
    assert m["min_clearance_mm"] >= 5.0
    assert len(jp.events["lifted_connectors"]) >= 3


def test_cartesian_lift_along_a_given_direction_keeps_the_orientation():
    robot = get_robot("sia20")
    solver = CwlnSolver(robot, IkSettings(max_iterations=300))
    q0 = np.radians([10, 40, 0, -60, 0, 50, 0])
    T0 = robot.fk_tcp(q0)
    away = np.array([-1.0, 0.0, 0.0])
    rows = cartesian_lift(solver, T0, q0, 60.0, 3, away)
    T = np.array([robot.fk_tcp(q) for q in rows])
    assert np.allclose(T[:, :3, 3], T0[:3, 3] + np.outer([20, 40, 60], away), atol=1e-3)
    assert np.allclose(T[:, :3, :3], T0[:3, :3], atol=1e-5)


def test_a_lift_the_tool_axis_blocks_leaves_along_the_mean_normal():
    """A steep tool in a pocket: a lift along its axis drives its back end into the rim (a half-space the flange
    may not enter), one along the part's mean normal (here: the direction straight out) leaves cleanly."""
    from camtool.errors import PlanInfeasible
    from camtool.plan.connectors import lift_and_reconfigure

    robot = get_robot("sia20")
    solver = CwlnSolver(robot, IkSettings(max_iterations=300))
    q0 = np.radians([10, 40, 0, -60, 0, 50, 0])
    T0 = robot.fk_tcp(q0)
    z = T0[:3, 2]
    away = -z + 1.5 * np.cross(z, [0.0, 0.0, 1.0])   # 56 deg off the tool axis
    away /= np.linalg.norm(away)
    u = -z - (-z @ away) * away                       # what a lift along -z adds beyond `away`
    u /= np.linalg.norm(u)
    rim = robot.fk(q0)[:3, 3] @ u + 5.0

    def valid(q):
        return robot.fk(q)[:3, 3] @ u < rim

    s = LiftSettings(100.0, 4, np.radians(10), 50.0, 500.0, 0)
    with pytest.raises(PlanInfeasible, match="the arm still touches the part"):
        lift_and_reconfigure(solver, robot, T0, q0, T0, q0, s, valid)
    rows, info = lift_and_reconfigure(solver, robot, T0, q0, T0, q0, s, valid, away)
    assert info["lift_along"] == "mean_normal" and info["lift_mm"] == 100.0
    tcp = np.array([robot.fk_tcp(q)[:3, 3] for q in rows]) - T0[:3, 3]
    assert np.allclose(np.cross(tcp, away), 0.0, atol=1e-3) and np.all(tcp @ away > 0)
    assert all(valid(q) for q in rows)
    plain = lift_and_reconfigure(solver, robot, T0, q0, T0, q0, s, None, away)[1]
    assert "lift_along" not in plain     # the tool axis first, as before, wherever it is free


def test_every_connector_that_cannot_be_lifted_is_named_with_its_poses(forced):
    """A lift refused everywhere (a stretch end at the edge of reach): the first connector's message as before, and
    report.json's ``unliftable_path_indices`` the two poses it joins; with ``every_failure`` (a partial plan, which
    then leaves those poses out) every reconfiguring connector's, each one the end of a run and the next one's start."""
    from camtool.collision.stage import collision_world
    from camtool.errors import PlanInfeasible
    from camtool.plan.connectors import lift_reconfigurations
    from camtool.plan.strategy import plan_path

    robot, settings, _surface, path, jp, _wp = forced
    raw = plan_path(path, robot, settings.planner, collision_world(settings, robot))
    solver = CwlnSolver(robot, IkSettings(max_iterations=300), free_spin=path.free_spin)
    s = LiftSettings(settings.planner.lift_mm, 1, settings.planner.reconfigure_threshold_rad,   # one step: quick
                     settings.planner.reconfigure_threshold_mm, settings.planner.track_scale_mm, 0)
    with pytest.raises(PlanInfeasible, match="the arm still touches the part") as first:
        lift_reconfigurations(raw, path, robot, s, solver, lambda q: False)
    assert "more connector" not in str(first.value)
    a, b = first.value.report["unliftable_path_indices"]
    assert path.segment[b] == path.segment[a] + 1 and a + 1 <= b
    with pytest.raises(PlanInfeasible) as every:
        lift_reconfigurations(raw, path, robot, s, solver, lambda q: False, every_failure=True)
    ends = every.value.report["unliftable_path_indices"]
    more = re.search(r"\(and (\d+) more connector\(s\)\)$", str(every.value))
    assert more and len(ends) == 2 * (int(more.group(1)) + 1) >= 2 * len(jp.events["lifted_connectors"]) - 4
    assert str(every.value).startswith(str(first.value)) and ends[:2] == [a, b]
    assert np.all(np.diff(ends) > 0)   # pairs, in path order: a run's last pose, the next one's first (a retract's
    assert np.all(path.segment[ends[1::2]] - path.segment[ends[::2]] <= 1)   # two runs are in one segment)


def test_a_lift_refused_only_by_a_joint_limit_says_the_part_is_at_the_edge_of_reach():
    """The IRB2400 at axis 3 (j2 + j3) 64.9 deg of its 65: every lift along the tool axis goes further past the
    limit, the higher the further (issue #46's shell, --allow-partial). The advice was 'raise planner.lift_mm',
    which only makes it worse; a lift that meets the part still gets it."""
    from camtool.errors import PlanInfeasible
    from camtool.plan.connectors import _beyond_limits, lift_and_reconfigure

    robot = get_robot("irb2400")
    solver = CwlnSolver(robot, IkSettings(max_iterations=300))
    s = LiftSettings(100.0, 4, np.radians(10), 50.0, 500.0, 0)
    q0 = np.radians([0.0, 40.0, 24.9, 0.0, -60.0, 0.0])
    T0 = robot.fk_tcp(q0)
    with pytest.raises(PlanInfeasible) as limit:
        lift_and_reconfigure(solver, robot, T0, q0, T0, q0, s, lambda q: _beyond_limits(robot, [q]) is None)
    text = str(limit.value)
    heights = [float(h) for h in re.findall(r"at (\d+) mm above the surface", text)]
    values = [float(v) for v in re.findall(r"rax_3 = ([\d.]+) deg", text)]
    assert heights == [100, 75, 50, 25, 15, 10] and values == sorted(values, reverse=True) and values[-1] > 65.0
    assert "raise planner.lift_mm" not in text and "edge of the robot's reach" in text
    q1 = np.radians([0.0, 20.0, 10.0, 0.0, -60.0, 0.0])    # far from the limits, the part in the way: higher may clear it
    T1 = robot.fk_tcp(q1)
    with pytest.raises(PlanInfeasible, match="the arm still touches the part; raise planner.lift_mm"):
        lift_and_reconfigure(solver, robot, T1, q1, T1, q1, s, lambda q: False)
