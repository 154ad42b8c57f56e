"""Arm-angle IK of SRS arms (seed 002): SIA-20 and seed8's 7R arm, against Pinocchio FK."""
import numpy as np
import pytest

from camtool.errors import BadInput, PlanInfeasible
from camtool.robots import get_robot
from camtool.robots.ik_srs import FAMILIES, SrsIK, srs_seed_solutions, srs_solutions
from camtool.transforms import rotation_angle_rad

ARM_ANGLES = np.linspace(-np.pi, np.pi, 8, endpoint=False)


def test_eight_families_exist():
    assert len(FAMILIES) == 8 and len(set(FAMILIES)) == 8


def _check(robot, ik, n_poses, seed, fixed=()):
    rng = np.random.default_rng(seed)
    worst_mm = worst_rad = 0.0
    straight = 0
    for k in range(n_poses):
        qa = rng.uniform(robot.limits.lower[-7:], robot.limits.upper[-7:])
        T = robot.fk(np.concatenate([fixed, qa]))
        try:
            psi_own = ik.arm_angle(qa)
            own = ik.solve(T, psi_own)
        except PlanInfeasible as exc:
            assert "elbow straight" in str(exc)
            straight += 1
            continue
        # the generating configuration is one of the 8 at its own arm angle
        assert any(np.allclose(s.q, qa, atol=1e-7) for s in own)
        for psi in ARM_ANGLES:
            sols = ik.solve(T, psi)
            assert [s.family for s in sols] == list(FAMILIES)
            for s in sols:
                Ts = robot.fk(ik.full_q(s.q))
                worst_mm = max(worst_mm, float(np.linalg.norm(Ts[:3, 3] - T[:3, 3])))
                worst_rad = max(worst_rad, rotation_angle_rad(Ts, T))
                if k % 10 == 0:  # arm_angle inverts solve (sampled, to keep the test fast)
                    assert abs(np.angle(np.exp(1j * (ik.arm_angle(s.q) - psi)))) < 1e-8
    assert straight <= n_poses // 100
    return worst_mm, worst_rad


def test_sia20_fk_matches_1000_poses_times_8_arm_angles():
    robot = get_robot("sia20")
    worst_mm, worst_rad = _check(robot, SrsIK(robot), 1000, seed=11)
    assert worst_mm < 1e-6 and worst_rad < 1e-9, (worst_mm, worst_rad)


def test_seed8_arm_at_a_fixed_track_position():
    robot = get_robot("seed8")
    worst_mm, worst_rad = _check(robot, SrsIK(robot, [250.0]), 150, seed=5, fixed=[250.0])
    assert worst_mm < 1e-6 and worst_rad < 1e-9, (worst_mm, worst_rad)


def test_sia20_gammas_are_the_signs_of_joints_4_2_6():
    robot = get_robot("sia20")
    T = robot.fk(np.radians([20, 40, -30, 70, 10, -50, 15]))
    for s in srs_solutions(robot, T, 0.4):
        assert tuple(int(np.sign(v)) for v in s.q[[3, 1, 5]]) == s.family


def test_limit_flags():
    robot = get_robot("sia20")
    q = np.radians([20, 40, 5, 70, 10, -50, 15])  # the shoulder flip puts joint 3 at -175 deg
    ik = SrsIK(robot)
    sols = ik.solve(robot.fk(q), ik.arm_angle(q))
    for s in sols:
        inside = bool(np.all(s.q >= robot.limits.lower) and np.all(s.q <= robot.limits.upper))
        assert s.within_limits == inside
    assert any(s.within_limits for s in sols) and not all(s.within_limits for s in sols)


def test_straight_elbow_is_a_clear_error():
    robot = get_robot("sia20")
    T = robot.fk(np.radians([30, 20, 10, 0.0, 10, 20, 0]))
    with pytest.raises(PlanInfeasible, match="elbow straight"):
        SrsIK(robot).solve(T, 0.0)
    T[:3, 3] *= 3.0
    with pytest.raises(PlanInfeasible, match="out of reach"):
        SrsIK(robot).solve(T, 0.0)


@pytest.mark.parametrize("name", ["irb2400", "irb2400_paper"])
def test_non_srs_robots_are_bad_input(name):
    with pytest.raises(BadInput, match=name):
        SrsIK(get_robot(name))


def test_seed8_needs_its_track_value():
    with pytest.raises(BadInput, match="fixed value"):
        SrsIK(get_robot("seed8"))


def test_seed_solutions_for_the_planner_are_exact_and_inside_limits():
    robot = get_robot("seed8")
    q = np.array([120.0, *np.radians([10, 40, -20, 60, 15, -30, 25])])
    T = robot.fk_tcp(q)
    seeds = srs_seed_solutions(robot, T, q_ref=q)
    assert seeds and np.allclose(seeds[0], q, atol=1e-7)
    near = srs_seed_solutions(robot, T, q_ref=q + np.r_[0.0, np.full(7, 0.05)])
    assert np.max(np.abs(near[0] - q)) < 0.3
    for s in seeds:
        assert robot.within_limits(s) and s[0] == 120.0
        assert np.linalg.norm(robot.fk_tcp(s)[:3, 3] - T[:3, 3]) < 1e-6


@pytest.mark.parametrize("name", ["sia20", "sia20_paper", "seed8"])
def test_prepare_batch_is_prepare_for_many_poses(name):
    """The batched preparation gives what ``prepare`` gives pose by pose, and leaves out the same poses."""
    r = get_robot(name)
    ik = SrsIK(r) if r.dof == 7 else SrsIK(r, [0.0])
    rng = np.random.default_rng(0)
    qs = r.limits.lower + rng.random((120, r.dof)) * (r.limits.upper - r.limits.lower)
    if r.dof == 8:
        qs[:, 0] = 0.0
    Ts = np.array([r.fk(q) for q in qs])
    Ts[::7, :3, 3] *= 3.0                                   # some out of reach
    st, ok = ik.prepare_batch(Ts)
    one = []
    for T in Ts:
        try:
            one.append(ik.prepare(T))
        except PlanInfeasible:
            one.append(None)
    assert np.array_equal(ok, [p is not None for p in one]) and 0 < ok.sum() < len(Ts)
    ref = ik.stack([p for p in one if p is not None])
    for key in ("u", "R7"):
        assert np.allclose(st[key], ref[key], atol=1e-12)
    for g in (1, -1):
        assert np.allclose(st["q4"][g], ref["q4"][g], atol=1e-12)
        assert np.allclose(st["R3ref"][g], ref["R3ref"][g], atol=1e-12)
