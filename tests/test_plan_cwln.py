"""CWLN IK and gradient projection: the Pinocchio reference and the compiled kernel."""
import numpy as np
import pytest

from camtool.plan.cwln import CwlnSolver, IkSettings
from camtool.plan.kernel import DhKernel
from camtool.robots import BUILTIN_ROBOTS, get_robot
from camtool.transforms import matrix_from_xyz_rpy, rotation_angle_rad


def random_pose(robot, rng):
    q = robot.limits.lower + (robot.limits.upper - robot.limits.lower) * (0.2 + 0.6 * rng.random(robot.dof))
    return q, robot.fk_tcp(q)


def controller_pose(robot, rng):
    """random_pose, drawn again until the controller takes it too (the IRB2400's coupled axis 3 = j2 + j3)."""
    while True:
        q, T = random_pose(robot, rng)
        if robot.within_limits(q):
            return q, T


@pytest.mark.parametrize("name", BUILTIN_ROBOTS)
def test_cwln_converges_from_a_nearby_start(name):
    robot = get_robot(name).with_placement(tool_T_mm=matrix_from_xyz_rpy([0, 0, 120], [0, 0, 0]))
    solver = CwlnSolver(robot, IkSettings())
    rng = np.random.default_rng(0)
    for _ in range(20):
        q, T = controller_pose(robot, rng)
        res = solver.solve(T, q + rng.normal(0, 0.05, robot.dof) * np.where(robot.prismatic, 100, 1))
        assert res.converged
        Tq = robot.fk_tcp(res.q)
        assert np.linalg.norm(Tq[:3, 3] - T[:3, 3]) <= 1e-4
        assert rotation_angle_rad(Tq, T) <= np.radians(1e-4)
        assert robot.within_limits(res.q)


def test_kernel_matches_reference_solver():
    robot = get_robot("seed8").with_placement(tool_T_mm=matrix_from_xyz_rpy([10, 0, 150], [0, 10, 0]))
    s = IkSettings()
    solver = CwlnSolver(robot, s)
    kernel = DhKernel(robot, s, False, np.full(8, 1.0))
    rng = np.random.default_rng(1)
    for _ in range(20):
        q, T = random_pose(robot, rng)
        q0 = q + rng.normal(0, 0.1, 8) * np.where(robot.prismatic, 100, 1)
        ref = solver.solve(T, q0)
        qk, pe, oe, conv, it = kernel.solve(T, q0)
        assert conv == ref.converged
        assert np.allclose(qk, ref.q, atol=1e-8)


def test_clamp_weight_and_task_form():
    robot = get_robot("sia20")
    s = IkSettings(clamp_buffer_rad=np.radians(10))
    solver = CwlnSolver(robot, s)
    q = np.zeros(7)
    w, phi = solver.clamp(q)
    assert np.all(w == 1) and np.all(phi == 0)  # interior: full weight, no clamp task
    q[1] = robot.limits.upper[1] - np.radians(5)  # half-way into the buffer near the upper limit
    w, phi = solver.clamp(q)
    assert w[1] == pytest.approx(0.5) and phi[1] == pytest.approx(-np.radians(5))
    q[1] = robot.limits.upper[1]
    w, phi = solver.clamp(q)
    assert w[1] == 0 and phi[1] < 0  # at the limit: frozen, pushed back inside


def test_solution_respects_limits_near_a_limit():
    robot = get_robot("sia20")
    solver = CwlnSolver(robot, IkSettings())
    q = np.zeros(7)
    q[3] = robot.limits.upper[3] - np.radians(3)
    q[1] = 0.4
    T = robot.fk_tcp(q)
    res = solver.solve(T, np.zeros(7) + 0.1)
    assert res.converged and robot.within_limits(res.q)


def self_motion_neighbour(robot, q, steps=25, h=0.02):
    """A configuration on q's self-motion manifold, made by walking along the Jacobian's
    null space (numpy SVD) with a Newton correction: independent of the code under test."""
    q = q.copy()
    T = robot.fk_tcp(q)
    scale = np.where(robot.prismatic, 500.0, 1.0)
    direction = None
    for _ in range(steps):
        J = robot.jacobian(q, tcp=True) * scale
        n = np.linalg.svd(J)[2][-1]
        if direction is not None and n @ direction < 0:
            n = -n
        direction = n
        q = q + h * n * scale
        for _ in range(5):  # back onto the pose
            Tq = robot.fk_tcp(q)
            rot_err = 0.5 * sum(np.cross(Tq[:3, i], T[:3, i]) for i in range(3))
            e = np.concatenate([T[:3, 3] - Tq[:3, 3], rot_err])
            q = q + np.linalg.pinv(robot.jacobian(q, tcp=True)) @ e
    return q


@pytest.mark.parametrize("use_kernel", [False, True])
def test_gradient_projection_keeps_tool_and_moves_towards_reference(use_kernel):
    robot = get_robot("seed8")
    s = IkSettings()
    q = np.array([100.0, 0.3, 0.8, -0.4, 1.2, 0.3, 0.9, -0.2])
    T = robot.fk_tcp(q)
    q_ref = self_motion_neighbour(robot, q)
    assert np.allclose(robot.fk_tcp(q_ref)[:3, 3], T[:3, 3], atol=1e-6)
    if use_kernel:
        k = DhKernel(robot, s, False, np.full(8, 1.0))
        q2, pe, oe, conv, _ = k.self_motion(T, q, q_ref)
    else:
        r = CwlnSolver(robot, s).self_motion(T, q, q_ref)
        q2, pe, conv = r.q, r.position_error_mm, r.converged
    assert conv and pe <= 1e-4
    scale = np.where(robot.prismatic, 500.0, 1.0)
    start = np.linalg.norm((q - q_ref) / scale)
    assert start > 0.3
    assert np.linalg.norm((q2 - q_ref) / scale) < 0.05 * start  # reaches the reference along the manifold


def test_free_spin_ignores_rotation_about_tool_z():
    robot = get_robot("sia20")
    solver = CwlnSolver(robot, IkSettings(), free_spin=True)
    q = np.array([0.2, 0.5, 0.1, -1.0, 0.3, 0.6, 0.0])
    T = robot.fk_tcp(q)
    spun = T.copy()
    spun[:3, :3] = T[:3, :3] @ matrix_from_xyz_rpy([0, 0, 0], [0, 0, 120])[:3, :3]
    res = solver.solve(spun, q)
    assert res.converged and res.iterations == 0  # already on the task: z axes agree
    kernel = DhKernel(robot, IkSettings(), True, np.full(7, 1.0))
    assert kernel.solve(spun, q)[3]


def test_solve_without_clamp_puts_the_tool_on_the_target_with_the_least_change():
    """``solve(clamp=False)`` (used between and next to solved poses) is a least-norm correction: from a start inside
    the track's clamping buffer it stays inside it, where ``solve``'s clamp task pulls the track out."""
    robot = get_robot("seed8")
    solver = CwlnSolver(robot, IkSettings())
    rng = np.random.default_rng(3)
    q = robot.limits.lower + (robot.limits.upper - robot.limits.lower) * (0.2 + 0.6 * rng.random(8))
    q[0] = robot.limits.lower[0] + 20.0  # 20 mm from the track's limit: inside the 50 mm buffer
    T = robot.fk_tcp(q)
    start = q + np.r_[0.5, 0.002 * rng.normal(size=7)]
    projected = solver.solve(T, start, clamp=False)
    solved = solver.solve(T, start)
    assert projected.converged and solved.converged
    Tq = robot.fk_tcp(projected.q)
    assert np.linalg.norm(Tq[:3, 3] - T[:3, 3]) <= 1e-4
    assert rotation_angle_rad(Tq, T) <= np.radians(1e-4)
    assert abs(projected.q[0] - start[0]) < 5.0            # the track barely moves ...
    assert solved.q[0] - start[0] > 15.0                    # ... where the clamp task pushes it towards the buffer's edge
