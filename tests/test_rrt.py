"""RRT-Connect free moves (seed 001): capsule clearance against a workpiece mesh, smoothing, timing."""
import numpy as np
import pytest
import trimesh

from camtool.errors import BadInput, PlanInfeasible
from camtool.plan.rrt import CapsuleChecker, edge_valid, plan_free_move, rrt_connect, shortcut
from camtool.robots import get_robot

Q_START = np.radians([-60, 20, 0, 0, 60, 0])
Q_GOAL = np.radians([60, 20, 0, 0, 60, 0])


@pytest.fixture(scope="module")
def cell():
    robot = get_robot("irb2400")
    box = trimesh.creation.box(extents=(400, 500, 1400))
    box.apply_translation((1000, 0, 700))  # a tall block in front of the robot, between start and goal
    return robot, box, CapsuleChecker(robot, box, radius_mm=60.0)


@pytest.fixture(scope="module")
def planned(cell):
    robot, box, chk = cell
    return plan_free_move(robot, Q_START, Q_GOAL, valid=chk, seed=3)


def test_straight_move_collides_but_the_rrt_path_does_not(cell, planned):
    robot, box, chk = cell
    assert chk(Q_START) and chk(Q_GOAL)
    assert not edge_valid(Q_START, Q_GOAL, chk, 0.03, np.ones(6))
    assert chk.clearance_mm(0.5 * (Q_START + Q_GOAL)) < 0
    tr, q, info = planned
    assert np.allclose(q[0], Q_START) and np.allclose(q[-1], Q_GOAL)
    for a, b in zip(q[:-1], q[1:]):
        assert edge_valid(a, b, chk, 0.01, np.ones(6))
    # the timed motion itself (ruckig between the waypoints), sampled every 4 ms
    _t, qs, *_ = tr.sample(0.004)
    clear = np.array([chk.clearance_mm(x) for x in qs])
    assert clear.min() >= 0.0 and all(robot.within_limits(x) for x in qs)
    assert info["smoothed_waypoints"] <= info["rrt_waypoints"]


def test_seeded_and_deterministic(cell, planned):
    robot, box, chk = cell
    _tr, q2, _ = plan_free_move(robot, Q_START, Q_GOAL, valid=chk, seed=3)
    assert np.array_equal(planned[1], q2)


def test_capsule_radius_matters(cell):
    robot, box, _ = cell
    q = np.radians([0, -30, 0, 0, 30, 0])
    d0 = CapsuleChecker(robot, box, radius_mm=10.0).clearance_mm(q)
    d1 = CapsuleChecker(robot, box, radius_mm=110.0).clearance_mm(q)
    assert d0 - d1 == pytest.approx(100.0)


def test_pluggable_validity_and_shortcut():
    lo, hi = np.full(2, -np.pi), np.full(2, np.pi)

    def valid(q):  # a wall in joint space: x in [-0.2, 0.2] blocked for y < 1.5
        return not (abs(q[0]) < 0.2 and q[1] < 1.5)

    path = rrt_connect([-1.0, 0.0], [1.0, 0.0], valid, lo, hi, step_rad=0.2, resolution_rad=0.01, seed=1)
    assert all(edge_valid(a, b, valid, 0.005, np.ones(2)) for a, b in zip(path[:-1], path[1:]))
    short = shortcut(path, valid, 0.01, 200, seed=1)
    length = lambda p: sum(np.linalg.norm(b - a) for a, b in zip(p[:-1], p[1:]))  # noqa: E731
    assert length(short) <= length(path) + 1e-12 and len(short) <= len(path)
    assert all(edge_valid(a, b, valid, 0.005, np.ones(2)) for a, b in zip(short[:-1], short[1:]))


def test_invalid_start_and_missing_mesh(cell):
    robot, box, chk = cell
    with pytest.raises(PlanInfeasible, match="start configuration"):
        rrt_connect(0.5 * (Q_START + Q_GOAL), Q_GOAL, chk, robot.limits.lower, robot.limits.upper)
    with pytest.raises(BadInput, match="mesh"):
        plan_free_move(robot, Q_START, Q_GOAL)


@pytest.mark.parametrize("watertight", [True, False])
def test_coal_and_trimesh_backends_agree(watertight):
    robot = get_robot("irb2400")
    if watertight:
        mesh = trimesh.creation.box(extents=(400, 500, 1400))
        mesh.apply_translation((1000, 0, 700))
    else:
        mesh = trimesh.load(str(__import__("conftest").SAMPLES / "sphere_patch.stl"))
        mesh.apply_translation((1000, 0, 100))
    fast = CapsuleChecker(robot, mesh, radius_mm=60.0)
    ref = CapsuleChecker(robot, mesh, radius_mm=60.0, backend="trimesh")
    rng = np.random.default_rng(0)
    P = rng.uniform(mesh.bounds[0] - 80, mesh.bounds[1] + 80, (400, 3))
    a, b = fast.distances(P), ref.distances(P)
    assert np.abs(a - b).max() < 1e-6  # both exact, in double precision
    assert (a < 0).any() == watertight  # inside points are negative only for a closed mesh
    with pytest.raises(BadInput, match="backend"):
        CapsuleChecker(robot, mesh, backend="fcl")


def test_tip_exemption_measures_the_tcp_as_a_point():
    """As the motion check: the chain's last tip_exempt_mm is no capsule, the TCP keeps the clearance itself
    (a lift 25 mm off the part with a 60 mm capsule at the TCP touched it; the check never measured that)."""
    robot = get_robot("irb2400")
    q = np.radians([0, 20, 0, 0, 60, 0])
    T = robot.fk_tcp(q)

    def plate_ahead(gap_mm):
        """A 200 x 200 mm plate square to the tool axis, its face ``gap_mm`` ahead of the TCP."""
        plate = trimesh.creation.box(extents=(200, 200, 10))
        M = np.eye(4)
        M[:3, :3] = T[:3, :3]
        M[:3, 3] = T[:3, 3] + T[:3, 2] * (gap_mm + 5.0)
        return plate.apply_transform(M)

    plate = plate_ahead(25.0)
    full = CapsuleChecker(robot, plate, radius_mm=60.0, clearance_mm=5.0)
    tip = CapsuleChecker(robot, plate, radius_mm=60.0, clearance_mm=5.0, tip_exempt_mm=100.0)
    assert full.clearance_mm(q) < 0 and not full(q)
    assert tip.clearance_mm(q) == pytest.approx(25.0, abs=0.5) and tip(q)
    lower = CapsuleChecker(robot, plate_ahead(3.0), radius_mm=60.0, clearance_mm=5.0, tip_exempt_mm=100.0)
    assert not lower(q)   # the TCP 3 mm above the plate: the point itself breaks the clearance


def test_a_timed_move_that_grazes_between_checked_points_is_rerouted():
    """A thin wall (0.02 rad) between the edge check's points (every 0.03 rad): the straight move
    passes the edge check, its 4 ms timed samples do not. Splitting a straight joint move keeps its
    path, so time_and_verify routes that move around the wall instead, and every timed sample of
    the result is valid."""
    from camtool.plan.rrt import edge_valid, time_and_verify

    robot = get_robot("irb2400")
    q0 = np.radians([0.0, 10.0, 20.0, 0.0, 45.0, 0.0])
    q1 = q0.copy()
    q1[0] = 0.6

    def valid(q):
        return not (abs(q[0] - 0.315) < 0.01 and abs(q[1] - q0[1]) < 0.2)

    assert edge_valid(q0, q1, valid, 0.03, np.ones(6))          # the coarse check passes the line
    tr, q = time_and_verify(robot, [q0, q1], valid)
    _t, qs, *_ = tr.sample(0.004)
    assert all(valid(x) for x in qs)
    assert len(q) > 2 and np.abs(q[:, 1] - q0[1]).max() >= 0.2   # it went round the wall


def test_an_open_patch_is_inside_only_behind_the_face_its_work_orients():
    """An open L of two square plates (a floor z = 0 and a wall x = 0, both 200 mm): work poses on the floor
    only (tool side +z). Below the floor is inside; beside the wall, which no work pose orients, is not."""
    robot = get_robot("irb2400")
    floor = trimesh.Trimesh([[0, -100, 0], [200, -100, 0], [200, 100, 0], [0, 100, 0]], [[0, 1, 2], [0, 2, 3]])
    wall = trimesh.Trimesh([[0, -100, 0], [0, 100, 0], [0, 100, 200], [0, -100, 200]], [[0, 1, 2], [0, 2, 3]])
    mesh = trimesh.util.concatenate([floor, wall])
    work = np.array([[x, y, 0.0] for x in (40.0, 100.0, 160.0) for y in (-60.0, 0.0, 60.0)])
    chk = CapsuleChecker(robot, mesh, radius_mm=10.0, outward=(work, np.tile([0.0, 0.0, 1.0], (len(work), 1))))
    d = chk.distances(np.array([[100.0, 0.0, -30.0], [-30.0, 0.0, 100.0], [30.0, 0.0, 100.0]]))
    assert d[0] == pytest.approx(-30.0, abs=1e-3)  # under the worked floor: inside the part
    assert d[1] == pytest.approx(30.0, abs=1e-3) and d[2] == pytest.approx(30.0, abs=1e-3)  # either side of the wall


def test_far_points_of_an_open_patch_are_screened_with_the_exact_answer():
    """A concave spherical cap (R 600 mm) worked on its inside, the robot near its centre, where every
    vertex is nearly equidistant: far link points are screened at a vertex, the near ones and those the
    screen keeps measured exactly. Behind or not agrees with the exact test at every point, near
    distances are exact and far ones a lower bound."""
    from camtool.plan.rrt import EXACT_BAND_MM

    robot = get_robot("irb2400")
    ball = trimesh.creation.icosphere(subdivisions=5, radius=600.0)
    cap = ball.submesh([np.flatnonzero(ball.triangles_center[:, 0] > 250.0)], append=True)
    cap.apply_translation((700.0, 0.0, 500.0))
    work = cap.triangles_center[::7]
    inward = (np.array([700.0, 0.0, 500.0]) - work) / 600.0
    chk = CapsuleChecker(robot, cap, radius_mm=60.0, outward=(work, inward))
    rng = np.random.default_rng(4)
    Q = rng.uniform(robot.limits.lower, robot.limits.upper, (400, robot.dof))
    P = np.concatenate([chk.link_points(q) for q in Q] + [rng.uniform((-500, -900, -400), (1800, 900, 1400), (20000, 3))])
    got, exact = chk.distances(P), chk._behind_exact(P)
    reach = chk.radius + EXACT_BAND_MM
    assert (exact < 0).sum() > 1000 and (exact >= 0).sum() > 1000   # both sides are tried
    assert np.array_equal(got < 0, exact < 0)
    near = np.abs(exact) < reach
    assert np.array_equal(got[near], exact[near])
    assert np.all(got[~near & (exact >= 0)] <= exact[~near & (exact >= 0)])
