"""Closed-form IK of the IRB2400 (seed 001), checked against Pinocchio FK and numerical IK."""
import numpy as np
import pytest
from scipy.optimize import least_squares

from camtool.errors import BadInput, PlanInfeasible
from camtool.plan.cwln import CwlnSolver, IkSettings
from camtool.robots import get_robot
from camtool.robots.ik_spherical_wrist import SphericalWristIK, closed_form_ik
from camtool.transforms import rotation_angle_rad


@pytest.fixture(scope="module")
def irb():
    robot = get_robot("irb2400")
    return robot, SphericalWristIK(robot)


def _same_mod_2pi(qa, qb, tol=1e-5):
    return bool(np.all(np.abs(np.angle(np.exp(1j * (np.asarray(qa) - np.asarray(qb))))) < tol))


def test_fk_of_every_solution_matches_1000_random_poses(irb):
    robot, ik = irb
    rng = np.random.default_rng(7)
    worst_mm = worst_rad = 0.0
    counts = []
    for _ in range(1000):
        q = rng.uniform(robot.limits.lower, robot.limits.upper)
        T = robot.fk(q)
        sols = ik.solve(T)
        counts.append(len(sols))
        assert any(_same_mod_2pi(s.q, q, 1e-7) for s in sols), "the generating q is not among the solutions"
        for s in sols:
            Ts = robot.fk(s.q)
            worst_mm = max(worst_mm, float(np.linalg.norm(Ts[:3, 3] - T[:3, 3])))
            worst_rad = max(worst_rad, rotation_angle_rad(Ts, T))
        families = {s.branch for s in sols}
        assert len(families) == len(sols)
    assert worst_mm < 1e-6 and worst_rad < 1e-9, (worst_mm, worst_rad)
    assert max(counts) == 8 and min(counts) >= 4


def test_numerical_ik_finds_nothing_the_closed_form_misses(irb):
    robot, ik = irb
    rng = np.random.default_rng(3)
    cwln = CwlnSolver(robot, IkSettings(max_iterations=300))
    matched = 0
    for _ in range(3):  # 3 poses: with the serial j3 box (coupled limits) fewer random starts converge
        q = rng.uniform(0.8 * robot.limits.lower, 0.8 * robot.limits.upper)
        while not robot.within_limits(q):  # a configuration the controller takes (coupled axis 3 = j2 + j3)
            q = rng.uniform(0.8 * robot.limits.lower, 0.8 * robot.limits.upper)
        T = robot.fk(q)
        sols = ik.solve(T)
        for _start in range(50):
            q0 = rng.uniform(robot.limits.lower, robot.limits.upper)
            while not robot.within_limits(q0):
                q0 = rng.uniform(robot.limits.lower, robot.limits.upper)
            res = cwln.solve(T, q0)
            if res.converged:
                assert any(_same_mod_2pi(s.q, res.q) for s in sols), res.q
                matched += 1

            def resid(x):
                Tx = robot.fk(x)
                R = Tx[:3, :3].T @ T[:3, :3]
                return np.concatenate([(Tx[:3, 3] - T[:3, 3]) / 1000.0,
                                       0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])])
            ls = least_squares(resid, q0, xtol=1e-15, ftol=1e-15, gtol=1e-15)
            Tl = robot.fk(ls.x)
            if np.linalg.norm(Tl[:3, 3] - T[:3, 3]) < 1e-6 and rotation_angle_rad(Tl, T) < 1e-9:
                assert any(_same_mod_2pi(s.q, ls.x) for s in sols), ls.x
                matched += 1
    assert matched >= 50  # the numerical solvers did converge, so the check above ran


def test_best_picks_least_change_inside_limits_using_2pi_equivalents(irb):
    robot, ik = irb
    q_true = np.radians([10.0, 20.0, -10.0, 190.0, 30.0, 350.0])  # j4, j6 beyond 180 deg
    assert robot.within_limits(q_true)
    T = robot.fk(q_true)
    q = ik.best(T, q_true + 0.01)
    assert np.allclose(q, q_true, atol=1e-9)
    assert robot.within_limits(q)
    # every returned candidate is flagged, and at least one is out of limits for this pose
    flags = [s.within_limits for s in ik.solve(T)]
    assert any(flags)
    # near the 2pi-equivalent: -170 deg on j4 is also inside +-200, and is picked when the reference is there
    q2 = ik.best(T, np.radians([10.0, 20.0, -10.0, -170.0, 30.0, -10.0]))
    assert np.isclose(q2[3], q_true[3] - 2 * np.pi) and np.isclose(q2[5], q_true[5] - 2 * np.pi)


def test_out_of_limits_only_pose_raises():
    robot = get_robot("irb2400")
    ik = SphericalWristIK(robot)
    q = np.radians([0.0, 0.0, 85.0, 0.0, 30.0, 0.0])  # joint 3 beyond +65
    sols = ik.solve(robot.fk(q))
    assert sols and not any(s.within_limits for s in sols if _same_mod_2pi(s.q, q))
    T = np.eye(4)
    T[:3, 3] = (5000.0, 0.0, 600.0)
    assert ik.solve(T) == []
    with pytest.raises(PlanInfeasible):
        ik.best(T, np.zeros(6))


@pytest.mark.parametrize("name", ["irb2400_paper", "sia20", "seed8"])
def test_other_geometries_are_bad_input(name):
    with pytest.raises(BadInput, match=name):
        closed_form_ik(get_robot(name), np.eye(4))
