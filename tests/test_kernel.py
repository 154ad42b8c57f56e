"""The compiled CWLN kernel (camtool.plan.kernel) against Pinocchio, finite differences,
scipy and the Pinocchio-based reference solver CwlnSolver."""
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from camtool.plan.cwln import CwlnSolver, IkSettings
from camtool.plan.kernel import DhKernel, _log3, fk_jacobian
from camtool.robots import BUILTIN_ROBOTS, get_robot
from camtool.transforms import matrix_from_xyz_rpy, rotation_angle_rad

TOOL = matrix_from_xyz_rpy([15.0, -5.0, 140.0], [0.0, 12.0, 30.0])


def robot_with_tool(name):
    return get_robot(name).with_placement(tool_T_mm=TOOL)


def kernel_for(robot, settings=IkSettings(), free_spin=False, thr=1.0):
    return DhKernel(robot, settings, free_spin, np.full(robot.dof, thr))


def interior_q(robot, rng, lo=0.2, hi=0.8):
    L = robot.limits
    return L.lower + (L.upper - L.lower) * (lo + (hi - lo) * rng.random(robot.dof))


def controller_interior_q(robot, rng, lo=0.2, hi=0.8):
    """interior_q, drawn again until the controller takes it too (the IRB2400's coupled axis 3 = j2 + j3)."""
    while True:
        q = interior_q(robot, rng, lo, hi)
        if robot.within_limits(q):
            return q


def perturbation(robot, rng, rad):
    return rng.normal(0, rad, robot.dof) * np.where(robot.prismatic, 100.0, 1.0)


# -- kinematics -------------------------------------------------------------------
@pytest.mark.parametrize("name", BUILTIN_ROBOTS)
def test_fk_and_jacobian_match_pinocchio(name):
    robot = robot_with_tool(name)
    k = kernel_for(robot)
    rng = np.random.default_rng(5)
    T, J = np.empty((4, 4)), np.empty((6, robot.dof))
    for _ in range(25):
        q = interior_q(robot, rng, 0.0, 1.0)
        fk_jacobian(q, k.dh, k.modified, k.tail, T, J)
        assert np.allclose(T, robot.fk_tcp(q), atol=1e-8)
        assert np.allclose(J, robot.jacobian(q, tcp=True), atol=1e-8)


@pytest.mark.parametrize("name", ["seed8", "sia20"])  # modified DH with a track; standard DH
def test_jacobian_matches_finite_differences(name):
    robot = robot_with_tool(name)
    k = kernel_for(robot)
    rng = np.random.default_rng(6)
    q = interior_q(robot, rng)
    T, J = np.empty((4, 4)), np.empty((6, robot.dof))
    fk_jacobian(q, k.dh, k.modified, k.tail, T, J)
    h = 1e-6
    for i in range(robot.dof):
        step = np.zeros(robot.dof)
        step[i] = h
        Tp, Tm = robot.fk_tcp(q + step), robot.fk_tcp(q - step)
        dp = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
        w = Rotation.from_matrix(Tp[:3, :3] @ Tm[:3, :3].T).as_rotvec() / (2 * h)
        assert np.allclose(J[:3, i], dp, atol=1e-4 * max(1.0, np.abs(dp).max())), i
        assert np.allclose(J[3:, i], w, atol=1e-7), i
    if robot.prismatic.any():  # a track moves the tool along its axis, without rotating it
        i = int(np.flatnonzero(robot.prismatic)[0])
        assert np.linalg.norm(J[:3, i]) == pytest.approx(1.0) and np.allclose(J[3:, i], 0)


def test_log3_matches_scipy_rotation_vectors():
    rng = np.random.default_rng(7)
    w = np.empty(3)
    for R in Rotation.random(40, random_state=rng):
        ref = R.as_rotvec()
        ang = _log3(np.ascontiguousarray(R.as_matrix()), w)
        assert ang == pytest.approx(np.linalg.norm(ref), abs=1e-10)
        assert np.allclose(w, ref, atol=1e-9)


@pytest.mark.parametrize("angle", [0.0, 1e-10, 1e-8, 1e-3, np.pi - 1e-4, np.pi - 1e-9, np.pi])
@pytest.mark.parametrize("axis", [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, -2, 3)])
def test_log3_near_zero_and_near_pi(angle, axis):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    R = Rotation.from_rotvec(angle * axis).as_matrix()
    w = np.empty(3)
    ang = _log3(np.ascontiguousarray(R), w)
    assert ang == pytest.approx(angle, abs=1e-9)
    # near pi the sign of the axis is free: both vectors give the same rotation
    assert np.allclose(Rotation.from_rotvec(w).as_matrix(), R, atol=1e-8)
    if angle < 3.0:
        assert np.allclose(w, angle * axis, atol=1e-9)


def test_log3_half_turn_about_a_general_axis():
    axis = np.array([1.0, -2.0, 3.0]) / np.sqrt(14.0)
    R = Rotation.from_rotvec(np.pi * axis).as_matrix()
    w = np.empty(3)
    _log3(np.ascontiguousarray(R), w)
    assert np.allclose(np.abs(w), np.pi * np.abs(axis), atol=1e-8)


# -- construction -------------------------------------------------------------------
def test_build_returns_none_without_a_dh_table():
    robot = get_robot("sia20")
    assert isinstance(DhKernel.build(robot, IkSettings(), False, np.ones(7)), DhKernel)
    assert DhKernel.build(replace(robot, dh=()), IkSettings(), False, np.ones(7)) is None


def test_refuses_a_dh_table_that_disagrees_with_the_model():
    robot = get_robot("sia20")
    rows = list(robot.dh)
    rows[3] = replace(rows[3], d_mm=rows[3].d_mm + 5.0)
    with pytest.raises(RuntimeError, match="disagree"):
        DhKernel(replace(robot, dh=tuple(rows)), IkSettings(), False, np.ones(7))


def test_settings_become_per_joint_arrays():
    robot = get_robot("seed8")
    s = IkSettings(clamp_buffer_rad=0.1, clamp_buffer_mm=40.0, track_scale_mm=300.0, max_step_rad=0.4,
                   max_step_mm=150.0)
    k = kernel_for(robot, s)
    track = robot.prismatic
    assert np.allclose(k.jscale[track], 300.0) and np.allclose(k.jscale[~track], 1.0)
    assert np.allclose(k.max_step[track], 150.0) and np.allclose(k.max_step[~track], 0.4)
    rng_ = robot.limits.upper - robot.limits.lower
    assert np.allclose(k.buf, np.minimum(np.where(track, 40.0, 0.1), 0.25 * rng_))
    assert np.allclose(k.q_ref, 0.5 * (robot.limits.lower + robot.limits.upper))


# -- solve ---------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["seed8", "sia20", "irb2400"])
def test_solve_reaches_the_target_like_the_reference_solver(name):
    robot = robot_with_tool(name)
    s = IkSettings()
    kernel, ref = kernel_for(robot, s), CwlnSolver(robot, s)
    rng = np.random.default_rng(8)
    for _ in range(12):
        q_true = controller_interior_q(robot, rng)
        target = robot.fk_tcp(q_true)
        q0 = np.clip(q_true + perturbation(robot, rng, 0.1), robot.limits.lower, robot.limits.upper)
        q, pe, oe, conv, it = kernel.solve(target, q0)
        assert conv
        Tq = robot.fk_tcp(q)  # independent FK, not the kernel's own error
        assert np.linalg.norm(Tq[:3, 3] - target[:3, 3]) <= s.position_tol_mm * 1.01
        assert rotation_angle_rad(Tq, target) <= s.orientation_tol_rad * 1.01
        assert pe == pytest.approx(np.linalg.norm(Tq[:3, 3] - target[:3, 3]), abs=1e-9)
        assert robot.within_limits(q)
        r = ref.solve(target, q0)
        assert r.converged and r.iterations == it
        assert np.allclose(q, r.q, atol=1e-8)


def test_solve_does_not_change_the_start_and_reports_no_iterations_on_target():
    robot = robot_with_tool("sia20")
    kernel = kernel_for(robot)
    q0 = np.array([0.2, 0.5, 0.1, -1.0, 0.3, 0.6, 0.0])
    before = q0.copy()
    q, pe, oe, conv, it = kernel.solve(robot.fk_tcp(q0), q0)
    assert conv and it == 0 and np.array_equal(q, q0) and np.array_equal(q0, before)


def test_solve_clamps_the_start_and_stays_within_limits():
    robot = get_robot("sia20")
    kernel = kernel_for(robot)
    q_true = np.zeros(7)
    q_true[1] = 0.4
    q_true[3] = robot.limits.upper[3] - np.radians(3)  # inside the clamp buffer
    target = robot.fk_tcp(q_true)
    q0 = np.full(7, 0.1)
    q0[5] = robot.limits.upper[5] + 1.0  # outside the limits: clamped before the first step
    q, pe, oe, conv, it = kernel.solve(target, q0)
    assert conv and robot.within_limits(q)
    ref = CwlnSolver(robot, IkSettings()).solve(target, q0)
    assert np.allclose(q, ref.q, atol=1e-8)


def test_first_step_on_a_half_turn_error_matches_the_reference():
    robot = get_robot("sia20")
    q0 = np.array([0.2, 0.5, 0.1, -1.0, 0.3, 0.6, 0.0])
    target = robot.fk_tcp(q0)
    axis = np.array([1.0, -2.0, 3.0]) / np.sqrt(14.0)
    target[:3, :3] = Rotation.from_rotvec(np.pi * axis).as_matrix() @ target[:3, :3]
    q, *_ = kernel_for(robot).solve(target, q0, max_iterations=1)
    ref = CwlnSolver(robot, IkSettings()).solve(target, q0, max_iterations=1)
    assert np.allclose(q, ref.q, atol=1e-6)


def test_unreachable_target_does_not_converge():
    robot = get_robot("irb2400")
    kernel = kernel_for(robot)
    q0 = np.array([0.1, 0.2, 0.1, 0.3, 0.4, 0.5])
    target = robot.fk_tcp(q0)
    target[:3, 3] += [5000.0, 0, 0]  # far beyond the arm's reach
    q, pe, oe, conv, it = kernel.solve(target, q0, max_iterations=30)
    assert not conv and it == 30 and pe > 1000.0
    assert robot.within_limits(q)
    assert pe == pytest.approx(np.linalg.norm(robot.fk_tcp(q)[:3, 3] - target[:3, 3]), rel=1e-9)


def test_free_spin_matches_reference_and_leaves_spin_free():
    robot = robot_with_tool("sia20")
    s = IkSettings()
    kernel = kernel_for(robot, s, free_spin=True)
    ref = CwlnSolver(robot, s, free_spin=True)
    rng = np.random.default_rng(9)
    for _ in range(6):
        q_true = interior_q(robot, rng, 0.3, 0.7)
        target = robot.fk_tcp(q_true)
        target[:3, :3] = target[:3, :3] @ Rotation.from_euler("z", rng.uniform(-3, 3)).as_matrix()
        q0 = q_true + perturbation(robot, rng, 0.08)
        q, pe, oe, conv, it = kernel.solve(target, q0)
        assert conv
        Tq = robot.fk_tcp(q)
        assert np.linalg.norm(Tq[:3, 3] - target[:3, 3]) <= 1.01e-4
        tilt = np.arctan2(np.linalg.norm(np.cross(Tq[:3, 2], target[:3, 2])), Tq[:3, 2] @ target[:3, 2])
        assert tilt <= 1.01 * s.orientation_tol_rad and oe == pytest.approx(tilt, abs=1e-9)
        r = ref.solve(target, q0)
        assert r.converged and np.allclose(q, r.q, atol=1e-8)


# -- run: a warm-started sequence -------------------------------------------------------
def line_of_targets(robot, q_a, q_b, n):
    qs = q_a + np.linspace(0, 1, n)[:, None] * (q_b - q_a)
    return qs, np.array([robot.fk_tcp(q) for q in qs])


def test_run_follows_a_smooth_sequence():
    robot = robot_with_tool("seed8")
    kernel = DhKernel(robot, IkSettings(), False, np.where(robot.prismatic, 50.0, 0.3))  # mm for the track
    q_a = np.array([200.0, 0.3, 0.8, -0.4, 1.2, 0.3, 0.9, -0.2])
    q_b = q_a + np.array([150.0, 0.2, -0.1, 0.15, -0.2, 0.1, 0.2, 0.3])
    _, targets = line_of_targets(robot, q_a, q_b, 30)
    stop, out_q, out_pe, out_oe = kernel.run(targets, q_a)
    assert stop == len(targets)
    assert out_q.shape == (30, 8)
    for k in range(30):
        Tq = robot.fk_tcp(out_q[k])
        assert np.linalg.norm(Tq[:3, 3] - targets[k][:3, 3]) <= 1.01e-4
        assert rotation_angle_rad(Tq, targets[k]) <= 1.01 * IkSettings().orientation_tol_rad
        assert out_pe[k] <= 1e-4 and robot.within_limits(out_q[k])
    steps = np.abs(np.diff(np.vstack([q_a, out_q]), axis=0))
    assert np.all(steps <= kernel.thr)  # no jumps between warm-started neighbours
    # warm start: each solve starts from the previous answer, as a hand loop over solve() does
    q = q_a.copy()
    for k in range(30):
        q, *_ = kernel.solve(targets[k], q)
        assert np.allclose(q, out_q[k], atol=1e-9)


def test_run_stops_at_the_first_pose_out_of_reach():
    robot = robot_with_tool("sia20")
    kernel = kernel_for(robot, IkSettings(max_iterations=40))
    q_a = np.array([0.2, 0.5, 0.1, -1.0, 0.3, 0.6, 0.0])
    _, targets = line_of_targets(robot, q_a, q_a + 0.1, 10)
    targets[6, :3, 3] += [0.0, 0.0, 4000.0]
    stop, out_q, out_pe, out_oe = kernel.run(targets, q_a)
    assert stop == 6
    assert np.all(out_pe[:6] <= 1e-4) and out_pe[6] > 1000.0
    assert out_pe[6] == pytest.approx(np.linalg.norm(robot.fk_tcp(out_q[6])[:3, 3] - targets[6, :3, 3]), rel=1e-9)


def test_run_stops_at_the_first_jump():
    robot = robot_with_tool("sia20")
    thr = np.full(7, 0.05)
    kernel = DhKernel(robot, IkSettings(), False, thr)
    q_a = np.array([0.2, 0.5, 0.1, -1.0, 0.3, 0.6, 0.0])
    q_b = q_a.copy()
    q_b[6] += 0.4  # a 0.4 rad wrist turn: the tool only spins, joint 7 must move past the threshold
    targets = np.array([robot.fk_tcp(q_a), robot.fk_tcp(q_a), robot.fk_tcp(q_b), robot.fk_tcp(q_b)])
    stop, out_q, out_pe, _ = kernel.run(targets, q_a)
    assert stop == 2
    assert np.allclose(out_q[:2], q_a)  # on target from the start: no motion
    assert out_pe[2] <= 1e-4  # converged, but the step into it is a jump
    assert np.abs(out_q[2] - out_q[1]).max() > 0.05


def test_posture_gain_keeps_the_sequence_on_target_and_pulls_to_mid_range():
    robot = robot_with_tool("sia20")
    q_a = np.array([0.2, 0.9, 0.1, -1.3, 0.3, 0.9, 0.4])
    _, targets = line_of_targets(robot, q_a, q_a, 40)  # the same pose 40 times: only posture changes
    plain = kernel_for(robot, thr=0.5)
    pulled = kernel_for(robot, IkSettings(posture_gain=0.2), thr=0.5)
    stop0, q0, pe0, _ = plain.run(targets, q_a)
    stop1, q1, pe1, _ = pulled.run(targets, q_a)
    assert stop0 == stop1 == 40
    assert np.all(pe1 <= 1e-4)
    assert np.allclose(q0, q_a, atol=1e-12)  # without the pull nothing moves
    assert np.abs(q1[-1] - q_a).max() > 0.05  # the arm moved in its null space ...
    for k in range(40):  # ... with the tool on the pose (independent FK)
        assert np.linalg.norm(robot.fk_tcp(q1[k])[:3, 3] - targets[k][:3, 3]) <= 1.01e-4
    dist = np.linalg.norm(np.vstack([q_a, q1]) - pulled.q_ref, axis=1)
    assert np.all(np.diff(dist) <= 1e-6) and dist[-1] < dist[0] - 1e-3  # ... towards mid-range (polish: 1e-6)


# -- self-motion -------------------------------------------------------------------------
def test_self_motion_matches_the_reference_solver():
    robot = robot_with_tool("seed8")
    s = IkSettings()
    q = np.array([100.0, 0.3, 0.8, -0.4, 1.2, 0.3, 0.9, -0.2])
    T = robot.fk_tcp(q)
    q_ref = q + np.array([80.0, 0.3, -0.2, 0.2, 0.1, -0.3, 0.2, 0.1])
    qk, pe, oe, conv, _ = kernel_for(robot, s).self_motion(T, q, q_ref, iterations=60)
    r = CwlnSolver(robot, s).self_motion(T, q, q_ref, iterations=60)
    assert conv and r.converged
    assert np.linalg.norm(robot.fk_tcp(qk)[:3, 3] - T[:3, 3]) <= 1.01e-4
    assert np.allclose(qk, r.q, atol=1e-6 * np.where(robot.prismatic, 100, 1).max())
    scale = np.where(robot.prismatic, 500.0, 1.0)
    assert np.linalg.norm((qk - q_ref) / scale) < np.linalg.norm((q - q_ref) / scale)


def test_batched_tcp_jacobians_are_pinocchios():
    robot = get_robot("seed8")
    kernel = DhKernel(robot, IkSettings(), False, np.full(robot.dof, np.inf))
    rng = np.random.default_rng(3)
    qs = robot.limits.lower + (robot.limits.upper - robot.limits.lower) * rng.random((20, robot.dof))
    J = kernel.jacobians(qs)
    assert J.shape == (20, 6, robot.dof)
    for q, Jk in zip(qs, J):
        assert np.allclose(Jk, robot.jacobian(q, tcp=True), atol=1e-8)
