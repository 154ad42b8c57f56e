"""Controller conventions against the independent references: the vendored ROS-Industrial URDFs
(loaded with Pinocchio) driven through the ROS-I drivers' conventions, written here from the driver
sources (abb_driver src/abb_utils.cpp, motoman_driver MotoPlus/CtrlGroup.c), not from camtool's data."""
import math
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from camtool.errors import BadInput
from camtool.robots import BUILTIN_ROBOTS, get_robot
from camtool.robots.confdata import abb_confdata, yaskawa_rconf
from camtool.robots.library import robot_from_toml
from camtool.transforms import rotation_angle_rad

ROSI = Path(__file__).resolve().parents[1] / "camtool" / "robots" / "data" / "ros-industrial"
IRB_URDF = ROSI / "abb_irb2400_support" / "urdf" / "irb2400.urdf"
SIA_URDF = ROSI / "motoman_sia20d_support" / "urdf" / "sia20d.urdf"
SIA_XACRO = ROSI / "motoman_sia20d_support" / "urdf" / "sia20d_macro.xacro"
TOL_MM, TOL_DEG = 1e-6, 1e-6

# controller axis limits (deg) as the manufacturers publish them (ABB IRB 2400 and Yaskawa SIA20D
# specifications; the URDFs give the same in rounded radians), in the controller's axis order
IRB_LIMITS = [(-180, 180), (-100, 110), (-60, 65), (-200, 200), (-120, 120), (-400, 400)]
SIA_LIMITS = [(-180, 180), (-110, 110), (-130, 130), (-180, 180), (-110, 110), (-180, 180), (-170, 170)]  # S L U R B T E


def abb_driver_urdf_from_controller(rax_deg):
    """abb_driver: joint_n = rax_n in rad; with J23_coupled (irb2400 launch default) joint_3 = rax_3 - rax_2."""
    j = np.radians(np.asarray(rax_deg, float))
    j[..., 2] -= j[..., 1]
    return j


def motoman_driver_urdf_from_controller(ctrl_deg):
    """motoman_driver Ros_CtrlGroup_ConvertToRosPos, 7-axis robot: controller S,L,U,R,B,T,E -> ROS S,L,E,U,R,B,T."""
    c = np.radians(np.asarray(ctrl_deg, float))
    return np.concatenate([c[..., :2], c[..., 6:7], c[..., 2:6]], axis=-1)


class Urdf:
    """Pinocchio FK of a vendored URDF (kinematics only; the package:// meshes are not needed)."""

    def __init__(self, path):
        self.model = pin.buildModelFromUrdf(str(path))
        self.data = self.model.createData()

    def frame(self, q_rad, name) -> np.ndarray:
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q_rad, float))
        M = self.data.oMf[self.model.getFrameId(name)]
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = M.rotation, M.translation * 1000.0
        return T

    def joint_origin(self, q_rad, name) -> np.ndarray:
        pin.forwardKinematics(self.model, self.data, np.asarray(q_rad, float))
        return self.data.oMi[self.model.getJointId(name)].translation * 1000.0


def sia_tool0_in_link_t() -> np.ndarray:
    """The xacro's link_t -> tool0 joint (rpy 0 0 -3.1415926535); the generated URDF rounds it to -3.1416."""
    text = SIA_XACRO.read_text()
    m = re.search(r'link_t-tool0".*?rpy="([^"]+)"', text, re.S)
    yaw = float(m.group(1).split()[2])
    T = np.eye(4)
    T[:2, :2] = [[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]]
    return T


def random_controller_deg(limits, rng, n):
    lo, hi = np.array(limits, float).T
    return lo + (hi - lo) * rng.random((n, len(limits)))


def pose_error(A, B):
    return float(np.abs(A[:3, 3] - B[:3, 3]).max()), math.degrees(rotation_angle_rad(A[:3, :3], B[:3, :3]))


def test_irb2400_flange_equals_the_urdf_tool0_through_the_linkage():
    robot, urdf = get_robot("irb2400"), Urdf(IRB_URDF)
    conv = robot.conventions
    rng = np.random.default_rng(23)
    worst_mm = worst_deg = 0.0
    for rax in random_controller_deg(IRB_LIMITS, rng, 300):
        q = conv.model_from_controller(np.radians(rax))               # camtool, through its conventions
        A = conv.pose_in_robot_frame(robot.fk(q) @ conv.tool0_in_flange)
        qu = abb_driver_urdf_from_controller(rax)                     # ROS-I, through the driver's
        B = np.linalg.inv(urdf.frame(qu, "base")) @ urdf.frame(qu, "tool0")
        mm, deg = pose_error(A, B)
        worst_mm, worst_deg = max(worst_mm, mm), max(worst_deg, deg)
        assert np.allclose(conv.urdf_from_model(q), qu, atol=1e-12)   # the API the collision world uses
    assert worst_mm <= TOL_MM and worst_deg <= TOL_DEG, (worst_mm, worst_deg)


def test_sia20_flange_equals_the_urdf_tool0_in_the_robot_frame():
    robot, urdf = get_robot("sia20"), Urdf(SIA_URDF)
    conv = robot.conventions
    assert conv.controller_axis_names == ("S", "L", "U", "R", "B", "T", "E")
    tool0 = sia_tool0_in_link_t()
    rng = np.random.default_rng(20)
    worst_mm = worst_deg = 0.0
    for ctrl in random_controller_deg(SIA_LIMITS, rng, 300):
        q = conv.model_from_controller(np.radians(ctrl))
        A = conv.pose_in_robot_frame(robot.fk(q) @ conv.tool0_in_flange)  # JBI positions are in the robot frame
        qu = motoman_driver_urdf_from_controller(ctrl)
        base = urdf.frame(qu, "base")                                # "Motoman Robot (not Base) Frame"
        B = np.linalg.inv(base) @ urdf.frame(qu, "link_t") @ tool0
        mm, deg = pose_error(A, B)
        worst_mm, worst_deg = max(worst_mm, mm), max(worst_deg, deg)
        # the generated URDF's tool0 is the xacro's to its rounding of pi (4.2e-4 deg)
        assert pose_error(urdf.frame(qu, "tool0"), urdf.frame(qu, "link_t") @ tool0)[1] < 5e-4
        assert np.allclose(conv.urdf_from_model(q), qu, atol=1e-12)
        assert np.allclose(urdf.frame(qu, "base_link"), np.eye(4))  # camtool's base frame is the URDF's base_link
        assert pose_error(robot.fk(q), urdf.frame(qu, "link_t") @ tool0)[0] <= TOL_MM
    assert worst_mm <= TOL_MM and worst_deg <= TOL_DEG, (worst_mm, worst_deg)


@pytest.mark.parametrize("name,limits", [("irb2400", IRB_LIMITS), ("sia20", SIA_LIMITS)])
def test_controller_limits_are_the_manufacturers(name, limits):
    conv = get_robot(name).conventions
    assert np.allclose(np.degrees(conv.lower), [lo for lo, _ in limits])
    assert np.allclose(np.degrees(conv.upper), [hi for _, hi in limits])


def test_irb2400_axis_3_is_limited_on_the_coupled_angle():
    robot = get_robot("irb2400")
    conv = robot.conventions
    q = np.radians([0.0, 50.0, 30.0, 0.0, 30.0, 0.0])      # serial j3 = 30 inside -60..65, but j2 + j3 = 80
    assert np.all(q >= robot.limits.lower) and np.all(q <= robot.limits.upper)
    assert not robot.within_limits(q)
    (line,) = conv.check_controller_limits(conv.controller_from_model(q))
    assert "rax_3 = 80.0000 deg" in line and "[-60.0000, 65.0000]" in line
    ok = np.radians([0.0, 50.0, -100.0, 0.0, 30.0, 0.0])   # serial j3 = -100, coupled -50: the controller takes it
    assert robot.within_limits(ok)
    # the serial box is exactly what the coupled range and axis 2's allow
    assert np.allclose(np.degrees([robot.limits.lower[2], robot.limits.upper[2]]), [-60 - 110, 65 + 100])


def test_closed_form_ik_keeps_only_configurations_the_controller_takes():
    from camtool.robots.ik_spherical_wrist import SphericalWristIK
    robot = get_robot("irb2400")
    ik = SphericalWristIK(robot)
    rng = np.random.default_rng(5)
    seen_refused = 0
    for _ in range(200):
        q = rng.uniform(robot.limits.lower, robot.limits.upper)
        sols = ik.solve(robot.fk(q))
        for s in sols:
            coupled = math.degrees(s.q[1] + s.q[2])
            if s.within_limits:
                assert -60 - 1e-6 <= coupled <= 65 + 1e-6 or any(
                    robot.within_limits(s.q + k * 2 * np.pi * np.eye(6)[i]) for i in (3, 5) for k in (-1, 1))
            elif -60 < coupled < 65 and robot.within_limits(s.q):
                pytest.fail(f"refused a solution the controller takes: {np.degrees(s.q)}")
            seen_refused += not s.within_limits
        try:
            qb = ik.best(robot.fk(q), np.zeros(6))
        except Exception:
            continue
        assert robot.within_limits(qb)
    assert seen_refused > 0


def test_paper_and_seed_robots_have_identity_conventions_declared_as_paper():
    for name in ("seed8", "irb2400_paper", "sia20_paper"):
        conv = get_robot(name).conventions
        assert conv.source == "paper" and conv.identity and conv.urdf_path is None
        q = np.linspace(-0.5, 0.5, get_robot(name).dof)
        assert np.array_equal(conv.controller_from_model(q), q)
    for name in ("irb2400", "sia20"):
        conv = get_robot(name).conventions
        assert conv.source == "manufacturer" and conv.urdf_path.is_file() and "ROS-Industrial" in conv.reference
    assert {get_robot(n).conventions.source for n in BUILTIN_ROBOTS} == {"paper", "manufacturer"}


def test_sia20d_is_not_the_papers_table():
    """Seed 002's far corner: 842 mm from the shoulder; beyond the paper's 820, within the SIA20D's 910."""
    paper, real = get_robot("sia20_paper"), get_robot("sia20")
    up = np.zeros(7)
    assert np.allclose(paper.fk(up)[:3, 3], [0, 0, 360 + 420 + 400 + 111])
    assert np.allclose(real.fk(up)[:3, 3], [0, 0, 410 + 490 + 420 + 180])
    assert np.isclose(np.degrees(real.limits.velocity[3]), 170)   # U = 2.967 rad/s (URDF)


def test_conventions_round_trip_vectorised():
    for name in BUILTIN_ROBOTS:
        robot = get_robot(name)
        conv = robot.conventions
        q = np.random.default_rng(1).uniform(robot.limits.lower, robot.limits.upper, (4, 3, robot.dof))
        qc = conv.controller_from_model(q)
        assert qc.shape == q.shape
        assert np.allclose(conv.model_from_controller(qc), q, atol=1e-12)
        assert conv.within_limits(q).shape == (4, 3)


def test_user_robot_without_controller_table_is_identity_user(tmp_path):
    robot = get_robot("irb2400_paper")
    assert robot.conventions.source == "paper"
    data = {"name": "arm", "joint": [{"name": "a", "lower": -90, "upper": 90, "velocity": 10, "acceleration": 10,
                                      "jerk": 10}]}
    r = robot_from_toml(data, "arm.toml")
    assert r.conventions.source == "user" and r.conventions.identity


@pytest.mark.parametrize("controller,message", [
    ({"sorce": "user"}, "arm.toml: [controller] sorce: unknown key; did you mean source?"),
    ({"source": "vendor"}, "source: expected one of paper, manufacturer, user"),
    ({"axis": [{"name": "A1", "joint": "x", "lower": -1, "upper": 1}]}, "axis[0].joint: the robot has no joint 'x'"),
    ({"axis": [{"name": "A1", "joint": "a", "lower": -1}]}, "axis[0].upper: missing"),
    ({"axis": [{"name": "A1", "joint": "a", "lower": -1, "upper": 1, "direction": 2}]}, "direction: expected 1 or -1"),
    ({"robot_frame_in_base": {"xyz": [0, 0, 1]}}, "robot_frame_in_base xyz: unknown key; did you mean xyz_mm?"),
])
def test_controller_table_errors_name_the_key(controller, message):
    data = {"name": "arm", "joint": [{"name": "a", "lower": -90, "upper": 90, "velocity": 10, "acceleration": 10,
                                      "jerk": 10}], "controller": controller}
    with pytest.raises(BadInput, match=re.escape(message)):
        robot_from_toml(data, "arm.toml")


def test_user_direction_offset_and_tool0():
    data = {"name": "arm", "joint": [{"name": "a", "lower": -90, "upper": 90, "velocity": 10, "acceleration": 10,
                                      "jerk": 10}, {"name": "b", "lower": -90, "upper": 90, "velocity": 10,
                                                    "acceleration": 10, "jerk": 10, "a_mm": 100}],
            "controller": {"axis": [{"name": "B", "joint": "b", "direction": -1, "zero_offset": 10, "lower": -80,
                                     "upper": 100},
                                    {"name": "A", "joint": "a", "plus": ["b"], "lower": -90, "upper": 90}],
                           "tool0_in_flange": {"rpy_deg": [0, 0, 90]}}}
    conv = robot_from_toml(data, "arm.toml").conventions
    q = np.radians([20.0, 30.0])
    assert np.allclose(np.degrees(conv.controller_from_model(q)), [-30 + 10, 50])
    assert np.allclose(conv.model_from_controller(conv.controller_from_model(q)), q)
    assert conv.axis_formulas() == ["B = -b + 10 deg", "A = a + b"]
    tcp = np.eye(4)
    tcp[:3, 3] = [10, 0, 0]
    assert np.allclose(conv.tool_in_tool0(tcp)[:3, 3], [0, -10, 0])


def test_abb_confdata_agrees_with_the_axis_quadrants_and_the_urdf_geometry():
    """cf1/cf4/cf6 = floor(rax / 90 deg) of the controller values; cfx's bits from the URDF's geometry."""
    robot, urdf = get_robot("irb2400"), Urdf(IRB_URDF)
    conv = robot.conventions
    rng = np.random.default_rng(7)
    rax = random_controller_deg(IRB_LIMITS, rng, 300)
    q = conv.model_from_controller(np.radians(rax))
    cf = abb_confdata(robot, q)
    assert np.array_equal(cf[:, :3], np.floor(rax[:, [0, 3, 5]] / 90.0).astype(int))
    zero = urdf.joint_origin(np.zeros(6), "joint_5"), urdf.joint_origin(np.zeros(6), "joint_2"), \
        urdf.joint_origin(np.zeros(6), "joint_3")
    for k in range(len(rax)):
        qu = abb_driver_urdf_from_controller(rax[k])
        wc = urdf.joint_origin(qu, "joint_5")                 # the IRB2400's wrist centre: axes 4, 5, 6 meet there
        link1 = urdf.frame(qu, "link_1")
        behind1 = (np.linalg.inv(link1) @ np.append(wc, 1))[0] < 0
        o2, o3 = urdf.joint_origin(qu, "joint_2"), urdf.joint_origin(qu, "joint_3")
        y2 = urdf.frame(qu, "link_2")[:3, 1]                  # axis 2 (URDF joint_2 turns about y)
        side = np.cross(o3 - o2, wc - o2) @ y2
        side0 = np.cross(zero[2] - zero[1], zero[0] - zero[1])[1]
        expect = 4 * behind1 + 2 * (np.sign(side) != np.sign(side0)) + (rax[k, 4] < 0)
        assert cf[k, 3] == expect, (rax[k], cf[k])


def test_yaskawa_rconf_uses_the_controller_axes():
    robot = get_robot("sia20")
    conv = robot.conventions
    ctrl = np.array([[180, 30, 60, -175, -20, 179, 5], [-175, -30, -60, 10, 20, -180, 0]], float)  # S L U R B T E
    rc = yaskawa_rconf(robot, conv.model_from_controller(np.radians(ctrl)))
    assert rc.shape == (2, 8)
    assert list(rc[:, 0]) == [1, 0]                            # flip: B < 0
    assert list(rc[:, 3]) == [0, 0] and list(rc[:, 4]) == [0, 1] and list(rc[:, 5]) == [1, 0]  # R, T, S >= 180
    assert list(rc[:, 2]) == [0, 1]                            # rear: L = -30 leans the arm back at U = -60
