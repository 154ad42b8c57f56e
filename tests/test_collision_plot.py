"""Obstacles drawn in report.html (camtool.collision.plot) from report.json's collision world."""
import numpy as np
import plotly.graph_objects as go

from camtool.collision import CellSettings, CollisionWorld
from camtool.collision.plot import obstacle_traces
from camtool.collision.shapes import WORLD, Body
from camtool.robots import get_robot
from camtool.transforms import matrix_from_xyz_rpy


def test_every_obstacle_is_drawn_where_it_is():
    T = matrix_from_xyz_rpy([1000.0, 0.0, -50.0], [0.0, 0.0, 30.0])
    box = Body("table", "obstacle", WORLD, "box", (600.0, 1200.0, 40.0), T)
    post = Body("post", "obstacle", WORLD, "cylinder", (30.0, 700.0), matrix_from_xyz_rpy([600, 560, 300], [0, 0, 0]))
    floor = Body("floor", "obstacle", WORLD, "halfspace", (-400.0,), np.eye(4))
    world = CollisionWorld(get_robot("seed8"), CellSettings(obstacles=(box, post, floor)))
    traces = obstacle_traces(go, {"motion_check": {"cell": world.describe()}})
    assert [t.name for t in traces] == ["obstacle table", "obstacle post", "obstacle floor"]
    V = np.c_[traces[0].x, traces[0].y, traces[0].z]
    assert np.allclose(V.mean(axis=0), [1000.0, 0.0, -50.0], atol=0.1)
    assert np.allclose(sorted({round(z, 1) for z in traces[0].z}), [-70.0, -30.0])
    assert set(traces[2].z) == {-400.0}
    assert obstacle_traces(go, {"motion_check": {}}) == [] and obstacle_traces(go, {}) == []


def test_robot_shapes_are_drawn_where_the_check_measures_them():
    """Every drawn vertex lies on the body the world measures: a hull vertex of the irb2400's ROS-I mesh,
    the surface of a seed8 capsule; the carriage and the tool as their boxes and cylinders."""
    from scipy.spatial import cKDTree

    from camtool.collision.plot import RobotShapes

    for name in ("irb2400", "seed8"):
        robot = get_robot(name)
        world = CollisionWorld(robot)
        shapes = RobotShapes(world)
        rng = np.random.default_rng(5)
        q = robot.limits.lower + rng.random(robot.dof) * (robot.limits.upper - robot.limits.lower)
        V = shapes.vertices_mm(q)
        poses = world.body_poses_mm(world.joint_frames_mm(q))
        assert set(shapes.body) == set(range(len(world.robot_bodies)))
        for b, body in enumerate(world.robot_bodies):
            T = poses[b]
            local = (V[shapes.body == b] - T[:3, 3]) @ T[:3, :3]
            if body.shape == "convex":
                assert cKDTree(body.points_mm).query(local)[0].max() < 1e-6, (name, body.name)
            elif body.shape == "capsule":
                r, L = body.size_mm
                z = np.clip(local[:, 2], -L / 2, L / 2)
                assert np.allclose(np.linalg.norm(local - np.c_[0 * z, 0 * z, z], axis=1), r, atol=1e-6)
            elif body.shape == "box":
                assert np.allclose(np.abs(local), np.asarray(body.size_mm) / 2, atol=1e-6)
            elif body.shape == "cylinder":
                r, L = body.size_mm
                assert np.allclose(np.abs(local[:, 2]), L / 2, atol=1e-6)
                assert np.all(np.linalg.norm(local[:, :2], axis=1) <= r + 1e-6)
    trace = shapes.trace(go, np.zeros(robot.dof), "robot")
    assert len(trace.i) == len(shapes.faces) and trace.name == "robot"
