"""The KUKA KR 16-2 and the FANUC M-20iA against their ROS-Industrial descriptions (issue #47):
the vendored URDFs loaded with Pinocchio and driven through the drivers' conventions, written
here from the driver sources (kuka_rsi_hw_interface: degrees to radians only; fanuc_driver
fanuc_utils.cpp with J23_factor = 1: ROS joint_3 = J3 + J2), not from camtool's data."""
import math
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from camtool.errors import BadInput
from camtool.robots import BUILTIN_ROBOTS, get_robot
from camtool.robots.ik_spherical_wrist import SphericalWristIK
from camtool.robots.library import robot_from_toml
from camtool.transforms import rotation_angle_rad

ROOT = Path(__file__).resolve().parents[1]
ROSI = ROOT / "camtool" / "robots" / "data" / "ros-industrial"
URDF = {"kr16": ROSI / "kuka_kr16_support" / "urdf" / "kr16_2.urdf",
        "m20ia": ROSI / "fanuc_m20ia_support" / "urdf" / "m20ia.urdf"}
# the controllers' axis limits (deg) as the packages cite the manufacturers' data (KUKA A1..A6;
# FANUC J1..J6, J3 the pendant's)
LIMITS = {"kr16": [(-185, 185), (-155, 35), (-130, 154), (-350, 350), (-130, 130), (-350, 350)],
          "m20ia": [(-170, 170), (-100, 160), (-185, 273.12), (-200, 200), (-140, 140), (-270, 270)]}


def urdf_from_controller(name, ctrl_deg):
    """The drivers: KUKA joint_aN = AN (rad); FANUC joint_n = Jn (rad) and joint_3 = J3 + J2."""
    q = np.radians(np.asarray(ctrl_deg, float)).copy()
    if name == "m20ia":
        q[..., 2] += q[..., 1]
    return q


def tool0(name, q_urdf) -> np.ndarray:
    m = pin.buildModelFromUrdf(str(URDF[name]))
    d = m.createData()
    pin.framesForwardKinematics(m, d, np.asarray(q_urdf, float))
    M = d.oMf[m.getFrameId("tool0")]
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = M.rotation, M.translation * 1000.0
    return T


def test_both_robots_are_built_in_manufacturer_robots():
    assert {"kr16", "m20ia"} <= set(BUILTIN_ROBOTS)
    for name in ("kr16", "m20ia"):
        c = get_robot(name).conventions
        assert c.source == "manufacturer" and c.urdf_path == URDF[name]


@pytest.mark.parametrize("name", ["kr16", "m20ia"])
def test_tool0_is_the_urdf_s_through_the_driver_conventions(name):
    """For random controller values within the limits, camtool's flange (its conventions) and the
    URDF's tool0 (the driver's conventions) are one pose: 1e-6 mm, 1e-6 deg."""
    robot = get_robot(name)
    conv = robot.conventions
    lo, hi = np.array(LIMITS[name], float).T
    rng = np.random.default_rng(47)
    m = pin.buildModelFromUrdf(str(URDF[name]))
    d = m.createData()
    fid = m.getFrameId("tool0")
    worst_mm = worst_deg = 0.0
    for ctrl in lo + (hi - lo) * rng.random((300, 6)):
        q = conv.model_from_controller(np.radians(ctrl))
        A = robot.fk(q) @ conv.tool0_in_flange
        pin.framesForwardKinematics(m, d, urdf_from_controller(name, ctrl))
        B = d.oMf[fid]
        worst_mm = max(worst_mm, float(np.abs(A[:3, 3] - B.translation * 1000.0).max()))
        worst_deg = max(worst_deg, math.degrees(rotation_angle_rad(A[:3, :3], B.rotation)))
    assert worst_mm < 1e-6 and worst_deg < 1e-6


def test_fanuc_j3_is_the_pendant_s_from_the_horizontal():
    """fanuc_driver: ROS joint_3 = J3 + J2 (J23_factor 1): the controller's J3 is j3 - j2. With J3 = 0
    the forearm stays horizontal whatever J2 does (the pendant's J3 is measured from the horizontal)."""
    r = get_robot("m20ia")
    conv = r.conventions
    assert conv.axis_formulas()[2] == "J3 = j3 - j2" and conv.coupled
    q = np.radians([10.0, 25.0, 40.0, 0.0, -30.0, 5.0])
    assert np.degrees(conv.controller_from_model(q))[2] == pytest.approx(15.0)
    for j2 in (-40.0, 0.0, 60.0):
        qm = conv.model_from_controller(np.radians([0.0, j2, 0.0, 0.0, 0.0, 0.0]))
        T3, T5 = _joint_origins(qm)   # J3's axis to J5's: (835, 0, 250) mm in the forearm, unturned
        assert np.allclose(T5 - T3, [835.0, 0.0, 250.0], atol=1e-6), j2


def _joint_origins(q_model):
    m = pin.buildModelFromUrdf(str(URDF["m20ia"]))
    d = m.createData()
    pin.forwardKinematics(m, d, urdf_from_controller("m20ia", np.degrees(get_robot("m20ia").conventions
                                                                       .controller_from_model(q_model))))
    return d.oMi[m.getJointId("joint_3")].translation * 1000, d.oMi[m.getJointId("joint_5")].translation * 1000


def test_the_controller_frames_are_the_urdf_s():
    """KUKA: base = base_link ($ROBROOT, identity); FANUC: World is the URDF's `base`, 525 mm up on J1."""
    for name, up in (("kr16", 0.0), ("m20ia", 525.0)):
        m = pin.buildModelFromUrdf(str(URDF[name]))
        d = m.createData()
        pin.framesForwardKinematics(m, d, np.zeros(6))
        base = d.oMf[m.getFrameId("base")]
        F = get_robot(name).conventions.robot_frame_in_base
        assert np.allclose(base.translation * 1000.0, [0, 0, up]) and np.allclose(F[:3, 3], [0, 0, up])
        assert np.allclose(base.rotation, np.eye(3)) and np.allclose(F[:3, :3], np.eye(3))


@pytest.mark.parametrize("name", ["kr16", "m20ia"])
def test_limits_and_speeds_are_the_packages(name):
    """Position and speed limits as the URDF gives them (KUKA: radians of whole degrees; FANUC: six
    decimals of radians, so 1e-5 rad)."""
    r = get_robot(name)
    m = pin.buildModelFromUrdf(str(URDF[name]))
    assert np.allclose(r.limits.lower, m.lowerPositionLimit, atol=1e-5)
    assert np.allclose(r.limits.upper, m.upperPositionLimit, atol=1e-5)
    assert np.allclose(r.limits.velocity, m.velocityLimit, atol=1e-5)
    lo, hi = np.array(LIMITS[name], float).T
    assert np.allclose(np.degrees(r.conventions.lower), lo) and np.allclose(np.degrees(r.conventions.upper), hi)


def test_m20ia_urdf_is_the_vendored_macro_expanded():
    """The M-20iA package ships only the xacro macro; the URDF is its expansion with prefix "", by
    scripts/rosi_macro_to_urdf.py, byte for byte."""
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        from rosi_macro_to_urdf import expand
    finally:
        sys.path.pop(0)
    macro = (ROSI / "fanuc_m20ia_support" / "urdf" / "m20ia_macro.xacro").read_text()
    assert expand(macro, "fanuc_m20ia") == URDF["m20ia"].read_text()


def test_licences_are_vendored_with_the_packages():
    readme = (ROSI / "README.md").read_text()
    for pkg in ("kuka_kr16_support", "fanuc_m20ia_support"):
        assert pkg in readme
        assert "<license>BSD</license>" in (ROSI / pkg / "package.xml").read_text()
    assert (ROSI / "kuka_kr16_support" / "LICENSE-Apache-2.0.txt").read_text().startswith("Apache License")
    assert "BSD" in (ROSI / "fanuc_m20ia_support" / "LICENSE.txt").read_text()
    assert 'name="J23_factor" default="1"' in (ROSI / "fanuc_m20ia_support" / "launch" /
                                               "robot_interface_streaming_m20ia.launch").read_text()


@pytest.mark.parametrize("name", ["kr16", "m20ia"])
def test_closed_form_ik_solves_both(name):
    """Both are of the IRB2400 family (offset shoulder, parallel axes 2 and 3, spherical wrist): the
    planner's closed-form seeds reach every random pose exactly."""
    r = get_robot(name)
    ik = SphericalWristIK(r)
    rng = np.random.default_rng(3)
    lo, hi = r.limits.lower * 0.8, r.limits.upper * 0.8
    for q in lo + (hi - lo) * rng.random((20, 6)):
        T = r.fk(q)
        sols = ik.solve(T)
        assert sols and min(np.abs(r.fk(s.q)[:3, 3] - T[:3, 3]).max() for s in sols) < 1e-6


def test_a_minus_coupling_names_its_joint(tmp_path):
    data = {"name": "arm", "joint": [{"name": n, "alpha_deg": a, "a_mm": 100, "lower": -90, "upper": 90,
                                      "velocity": 90, "acceleration": 360, "jerk": 1800}
                                     for n, a in (("j1", 0), ("j2", -90), ("j3", 0))],
            "controller": {"axis": [{"name": "J1", "joint": "j1", "lower": -90, "upper": 90},
                                    {"name": "J2", "joint": "j2", "lower": -90, "upper": 90},
                                    {"name": "J3", "joint": "j3", "minus": ["j9"], "lower": -90, "upper": 90}]}}
    with pytest.raises(BadInput, match=r"axis\[2\]\.minus: the robot has no joint 'j9'"):
        robot_from_toml(data, "arm.toml")
    data["controller"]["axis"][2]["minus"] = ["j2"]
    conv = robot_from_toml(data, "arm.toml").conventions
    assert conv.axis_formulas()[2] == "J3 = j3 - j2"


def test_kr16_urdf_s_tool0_is_the_macro_s(tmp_path):
    """Upstream's generated kr16_2.urdf predates the macro's `flange` link; its tool0 is the
    macro's (flange 158 mm out on link_6, tool0 the flange turned 90 deg about y) at every
    configuration."""
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        from rosi_macro_to_urdf import expand
    finally:
        sys.path.pop(0)
    text = (ROSI / "kuka_kr16_support" / "urdf" / "kr16_2_macro.xacro").read_text()
    f = tmp_path / "kr16_macro.urdf"
    f.write_text(expand(text, "kr16"))
    a, b = pin.buildModelFromUrdf(str(f)), pin.buildModelFromUrdf(str(URDF["kr16"]))
    da, db = a.createData(), b.createData()
    for q in np.random.default_rng(5).uniform(b.lowerPositionLimit, b.upperPositionLimit, (50, 6)):
        pin.framesForwardKinematics(a, da, q)
        pin.framesForwardKinematics(b, db, q)
        A, B = da.oMf[a.getFrameId("tool0")], db.oMf[b.getFrameId("tool0")]
        assert np.abs(A.translation - B.translation).max() < 1e-9
        assert math.degrees(rotation_angle_rad(A.rotation, B.rotation)) < 1e-8
