"""The tool's free wrist bend (camtool.collision.wrist_bend) against the ROS-Industrial description itself:
the IRB2400's link_4 collision mesh placed by Pinocchio on the vendored URDF and a 25 mm x 150 mm
cylinder on its tool0, their distance by coal on the raw mesh (not camtool's hull, frames or bodies)."""
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest
import trimesh

from camtool.collision import CollisionWorld
from camtool.collision.world import CellSettings
from camtool.collision.wrist_bend import WristBend
from camtool.placement.kinematics import ClosedForm
from camtool.robots import get_robot

ROSI = Path(__file__).resolve().parents[1] / "camtool" / "robots" / "data" / "ros-industrial"
TCP_MM, RADIUS_MM, CLEAR_MM = 150.0, 25.0, 5.0


def _robot(tcp_mm=TCP_MM):
    tool = np.eye(4)
    tool[2, 3] = tcp_mm
    return get_robot("irb2400").with_placement(tool_T_mm=tool)


def _bvh(mesh):
    b = coal.BVHModelOBBRSS()
    b.beginModel(len(mesh.faces), len(mesh.vertices))
    b.addVertices(np.asarray(mesh.vertices, float))
    b.addTriangles(np.asarray(mesh.faces, np.int32))
    b.endModel()
    return b


class _UrdfForearm:
    """Distance (mm) of the tool cylinder on the URDF's tool0 to the URDF's link_4 mesh, at a model q."""

    def __init__(self, robot):
        self.conv = robot.conventions
        self.model = pin.buildModelFromUrdf(str(self.conv.urdf_path))
        self.data = self.model.createData()
        m = trimesh.load(ROSI / "abb_irb2400_support" / "meshes" / "irb2400" / "collision" / "link_4.stl")
        m.apply_scale(1000.0)   # the STL is in metres
        self.link4 = _bvh(m)
        cyl = trimesh.creation.cylinder(radius=RADIUS_MM, height=TCP_MM, sections=256)
        cyl.apply_translation([0.0, 0.0, TCP_MM / 2])
        self.tool = _bvh(cyl)

    def _frame(self, name):
        M = self.data.oMf[self.model.getFrameId(name)]
        return coal.Transform3s(M.rotation.copy(), M.translation * 1000.0)

    def distance_mm(self, q_model) -> float:
        q = np.zeros(self.model.nq)
        for k, name in enumerate(self.conv.urdf_joint_names):
            q[self.model.joints[self.model.getJointId(name)].idx_q] = self.conv.urdf_from_model(q_model)[k]
        pin.framesForwardKinematics(self.model, self.data, q)
        res = coal.DistanceResult()
        return coal.distance(self.tool, self._frame("tool0"), self.link4, self._frame("link_4"),
                             coal.DistanceRequest(), res)


@pytest.fixture(scope="module")
def bend():
    return WristBend(CollisionWorld(_robot(), CellSettings(clearance_mm=CLEAR_MM), RADIUS_MM))


def test_free_range_is_where_the_urdf_tool_meets_link_4(bend):
    ref = _UrdfForearm(_robot())
    # the bend where the URDF's tool comes within the clearance, by bisection on the reference's distance
    q = np.zeros(6)

    def gap(j5_deg):
        q[4] = np.radians(j5_deg)
        return ref.distance_mm(q) - CLEAR_MM

    lo, hi = 90.0, 120.0
    assert gap(lo) > 0 > gap(hi)
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if gap(mid) > 0 else (lo, mid)
    a, b = bend.free_range_deg()
    assert bend.matters and bend.names == (("link_4", "tool"),)
    assert b == pytest.approx(lo, abs=0.6) and a == pytest.approx(-lo, abs=0.6)
    assert lo < 120.0 - 10.0   # well inside j5's own limit: the joint limits alone do not say it


def test_ok_follows_the_reference_at_any_arm_pose(bend):
    ref = _UrdfForearm(_robot())
    rng = np.random.default_rng(3)
    lower, upper = bend.grid_rad[0], bend.grid_rad[-1]
    Q = rng.uniform(-1.0, 1.0, (60, 6)) * np.radians([170, 90, 90, 190, 0, 350])
    Q[:, 4] = rng.uniform(lower, upper, len(Q))
    ok = bend.ok(Q)
    d = np.array([ref.distance_mm(q) for q in Q])
    clear = d >= CLEAR_MM + 1.0      # a degree of bend moves the tool's edge by about 4 mm: a band either side
    close = d < CLEAR_MM - 1.0
    assert ok[clear].all() and not ok[close].any()
    assert clear.sum() > 10 and close.sum() > 3
    assert bend.ok(Q[:4]).shape == (4,) and bend.ok(Q[:4].reshape(2, 2, 6)).shape == (2, 2)


def test_beyond_the_limits_is_refused(bend):
    q = np.zeros((2, 6))
    q[:, 4] = np.radians([0.0, 125.0])
    assert bend.ok(q).tolist() == [True, False]


def test_a_tool_without_a_body_leaves_the_bend_free():
    b = WristBend(CollisionWorld(_robot(0.0), CellSettings(clearance_mm=CLEAR_MM), RADIUS_MM))
    assert not b.matters and b.ok(np.zeros((3, 6))).all()


def test_the_screen_refuses_a_pose_only_a_far_bend_reaches(bend):
    robot = _robot()
    q = np.radians([-36.0, 37.0, 16.0, -31.0, -107.0, 28.0])   # the noether panel's lower corner (issue #46)
    T = robot.fk_tcp(q)[None]
    plain = ClosedForm.for_robot(robot)
    wrist = ClosedForm.for_robot(robot, joint_ok=bend.ok)
    assert np.isfinite(plain.best(T)[1]).all()
    assert not np.isfinite(wrist.best(T)[1]).any()
    q = np.radians([-36.0, 37.0, 16.0, -31.0, -95.0, 28.0])
    assert np.isfinite(wrist.best(robot.fk_tcp(q)[None])[1]).all()


def test_why_names_the_bend_the_link_and_the_free_range(bend):
    robot = _robot()
    text = bend.why(np.radians([-36.0, 37.0, 16.0, -31.0, -107.0, 28.0]), robot.joint_names)
    a, b = bend.free_range_deg()
    assert text == (f"j5 = -107.0 deg there; with this tool and cell.clearance_mm 5 mm it clears link_4 only "
                    f"within [{a:.1f}, {b:.1f}] deg (its limits: [-120, 120] deg)")
    assert bend.why(np.radians([-36.0, 37.0, 16.0, -31.0, -95.0, 28.0]), robot.joint_names) == ""


def test_screen_model_counts_the_bend_margin_from_the_free_range():
    from camtool.job import load_job
    from camtool.placement.kinematics import screen_model
    from camtool.run.job_settings import JobSettings
    from camtool.run.stages import robot_for_job

    from conftest import SAMPLES

    job = load_job(SAMPLES / "irb2400_plate.toml", ["tool.tcp_xyz_mm=[0.0, 0.0, 150.0]"])
    robot = robot_for_job(job)
    settings = JobSettings.from_job(job, robot)
    model = screen_model(robot, settings)
    a, b = WristBend(CollisionWorld(robot, settings.cell, settings.check.tool_radius_mm)).free_range_deg()
    assert np.degrees([model.lower[4], model.upper[4]]) == pytest.approx([a, b])
    assert np.allclose(np.delete(model.lower, 4), np.delete(robot.limits.lower, 4))
    assert np.allclose(robot.limits.upper[4], np.radians(120.0))   # the robot's own limits untouched
    assert screen_model(robot).upper[4] == pytest.approx(np.radians(120.0))   # no settings: the limits alone
