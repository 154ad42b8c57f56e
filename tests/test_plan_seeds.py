"""Analytic IK seeds for the seed strategy (planner.ik_seeds): exact family solutions
as reverse-planning, start and restart candidates, polished by CWLN."""
import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.plan import plan_path
from camtool.plan.strategy import AnalyticSeeds
from camtool.report.run_report import plan_metrics
from camtool.robots import get_robot
from camtool.robots.ik_srs import SrsIK

from plan_fixtures import sphere_rows
from camtool.settings import PlannerSettings

REVERSE_KW = dict(track_scale_mm=1.0, posture_gain=0.0)  # the jump-provoking set-up of test_plan_strategy


def _inner(robot, buf=0.1):
    return robot.limits.lower + buf * (robot.limits.upper - robot.limits.lower), \
        robot.limits.upper - buf * (robot.limits.upper - robot.limits.lower)


@pytest.mark.parametrize("name, kind", [("seed8", "srs"), ("sia20", "srs"), ("irb2400", "spherical_wrist")])
def test_draws_are_exact_solutions_inside_the_limits(name, kind):
    robot = get_robot(name)
    lo, hi = _inner(robot)
    seeds = AnalyticSeeds.for_robot(robot, lo, hi)
    assert seeds is not None and seeds.kind == kind
    rng = np.random.default_rng(4)
    found = 0
    for _ in range(10):
        q_true = lo + (hi - lo) * rng.random(robot.dof)
        T = robot.fk_tcp(q_true)
        qs = seeds.draw(T, rng)
        for q in qs:
            assert robot.within_limits(q)
            assert np.abs(robot.fk_tcp(q)[:3, 3] - T[:3, 3]).max() < 1e-6
            assert np.abs(robot.fk_tcp(q)[:3, :3] - T[:3, :3]).max() < 1e-9
            if robot.prismatic.any():
                assert lo[0] <= q[0] <= hi[0]  # the drawn track value stays inside the given range
        found += len(qs)
        assert len({tuple(np.round(q, 6)) for q in qs}) == len(qs)  # distinct families
    assert found >= 20


def test_track_shift_matches_a_solver_built_at_that_track():
    robot = get_robot("seed8")
    seeds = AnalyticSeeds.for_robot(robot, *_inner(robot))
    assert seeds.shift is not None and np.allclose(np.linalg.norm(seeds.shift), 1.0)
    q = np.r_[400.0, np.radians([20, -30, 40, 60, -20, 30, 10])]
    T = robot.fk(q)
    direct = SrsIK(robot, [400.0]).solve(T, 0.7)
    moved = T.copy()
    moved[:3, 3] -= (400.0 - seeds.ik.fixed[0]) * seeds.shift
    via_shift = seeds.ik.solve(moved, 0.7)
    assert [s.family for s in direct] == [s.family for s in via_shift]
    assert max(np.abs(a.q - b.q).max() for a, b in zip(direct, via_shift)) < 1e-9


def test_robots_without_families_fall_back_or_refuse():
    robot = get_robot("irb2400_paper")  # no spherical wrist (d5 between axes 4/5 and 6)
    assert AnalyticSeeds.for_robot(robot, *_inner(robot)) is None
    path = sphere_rows(center=(900.0, 0.0, 600.0), radius=300.0, el_deg=(10, 20), az_deg=(-5, 5), rows=1,
                       pitch_mm=20.0)
    with pytest.raises(BadInput, match="no closed-form IK families"):
        plan_path(path, robot, PlannerSettings.make(ik_seeds="analytic"))
    with pytest.raises(BadInput, match="planner.ik_seeds"):
        plan_path(path, get_robot("seed8"), PlannerSettings.make(ik_seeds="magic"))


@pytest.fixture(scope="module")
def reverse_plans():
    path = sphere_rows(rows=4)
    robot = get_robot("seed8")
    return path, robot, {mode: plan_path(path, robot, PlannerSettings.make(ik_seeds=mode, **REVERSE_KW)) for mode in ("random", "analytic")}


def test_analytic_reverse_planning_moves_the_jumps_off_the_surface(reverse_plans):
    path, robot, plans = reverse_plans
    jp = plans["analytic"]
    m = plan_metrics(path, jp, robot, "seed", 50, 100)
    assert jp.events["ik_seeds"] == "analytic" and plans["random"].events["ik_seeds"] == "random"
    assert m["on_surface_jumps"] == 0 and m["reverse_plans"] >= 1
    assert jp.position_error_mm[jp.path_index >= 0].max() <= 1e-4
    assert all(robot.within_limits(q) for q in jp.q)
    assert jp.events["reverse_plan_seconds"] > 0
    # the two candidate sources really differ
    assert not np.array_equal(jp.q, plans["random"].q)


def test_analytic_seeds_are_deterministic(reverse_plans):
    path, robot, plans = reverse_plans
    again = plan_path(path, robot, PlannerSettings.make(ik_seeds="analytic", **REVERSE_KW))
    assert np.array_equal(again.q, plans["analytic"].q)
    assert again.events["reverse_plans"] == plans["analytic"].events["reverse_plans"]


def test_auto_is_analytic_for_srs_and_random_is_the_default(reverse_plans):
    path, robot, plans = reverse_plans
    auto = plan_path(path, robot, PlannerSettings.make(ik_seeds="auto", **REVERSE_KW))
    assert np.array_equal(auto.q, plans["analytic"].q)
    default = plan_path(path, robot, PlannerSettings.make(**REVERSE_KW))
    assert np.array_equal(default.q, plans["random"].q)


def test_analytic_start_configuration_has_margin():
    path = sphere_rows(rows=1, pitch_mm=20.0)
    robot = get_robot("seed8")
    jp = plan_path(path, robot, PlannerSettings.make(ik_seeds="analytic"))
    ev = jp.events
    assert ev["start_configuration"] == "searched" and ev["ik_seeds"] == "analytic"
    span = robot.limits.upper - robot.limits.lower
    q0 = jp.q[0]
    margin = np.min(np.minimum(q0 - robot.limits.lower, robot.limits.upper - q0) / span)
    assert ev["start_margin"] == pytest.approx(margin, abs=1e-9) and margin > 0.1
    assert jp.reached.all()
