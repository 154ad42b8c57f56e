"""Robot library: FK against an independent DH product, Jacobian against finite
differences, URDF round trip, user TOML robots."""
import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.robots import BUILTIN_ROBOTS, get_robot
from camtool.robots.urdf import robot_from_urdf, urdf_from_robot
from camtool.transforms import rotation_angle_rad


def dh_product(robot, q):
    """Independent FK: the textbook product of DH matrices, written here from the tables."""
    T = np.eye(4)
    for row, qi, is_p in zip(robot.dh, q, robot.prismatic):
        th = row.theta_rad + (0 if is_p else qi)
        d = row.d_mm + (qi if is_p else 0)
        a, al = row.a_mm, row.alpha_rad
        ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(al), np.sin(al)
        if robot.convention == "modified":
            A = np.array([[ct, -st, 0, a], [st * ca, ct * ca, -sa, -sa * d], [st * sa, ct * sa, ca, ca * d], [0, 0, 0, 1]])
        else:
            A = np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d], [0, 0, 0, 1]])
        T = T @ A
    return T


def random_q(robot, rng, n):
    lo, hi = robot.limits.lower, robot.limits.upper
    return lo + (hi - lo) * rng.random((n, robot.dof))


def rot_err(Ra, Rb):
    return rotation_angle_rad(Ra, Rb)


@pytest.mark.parametrize("name", BUILTIN_ROBOTS)
def test_fk_matches_dh_product(name):
    robot = get_robot(name)
    rng = np.random.default_rng(1)
    pos_err = rot = 0.0
    for q in random_q(robot, rng, 200):
        A, B = robot.fk(q), dh_product(robot, q)
        pos_err = max(pos_err, np.abs(A[:3, 3] - B[:3, 3]).max())
        rot = max(rot, rot_err(A[:3, :3], B[:3, :3]))
    assert pos_err <= 1e-6
    assert rot <= 1e-9


@pytest.mark.parametrize("name", BUILTIN_ROBOTS)
def test_jacobian_matches_finite_differences(name):
    robot = get_robot(name)
    rng = np.random.default_rng(2)
    h = 1e-6
    worst_lin = worst_ang = 0.0
    for q in random_q(robot, rng, 200):
        J = robot.jacobian(q)
        T0 = robot.fk(q)
        for k in range(robot.dof):
            dq = np.zeros(robot.dof)
            dq[k] = h
            Tp, Tm = robot.fk(q + dq), robot.fk(q - dq)
            lin = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
            W = (Tp[:3, :3] - Tm[:3, :3]) / (2 * h) @ T0[:3, :3].T
            ang = np.array([W[2, 1], W[0, 2], W[1, 0]])
            # central differences carry O(h^2) truncation and O(eps/h) rounding:
            # scale-free comparison per column
            worst_lin = max(worst_lin, np.abs(lin - J[:3, k]).max())
            worst_ang = max(worst_ang, np.abs(ang - J[3:, k]).max())
    assert worst_lin <= 1e-6 * 1000  # mm per rad: arm reach ~1e3 mm, FD noise ~1e-7 mm/1e-6
    assert worst_ang <= 1e-8


def test_jacobian_tcp_matches_finite_differences():
    robot = get_robot("seed8").with_placement(tool_T_mm=np.array(
        [[1, 0, 0, 10.0], [0, 1, 0, -20.0], [0, 0, 1, 150.0], [0, 0, 0, 1]]))
    q = np.array([100, 0.3, -0.5, 0.7, 1.1, -0.4, 0.6, 0.2])
    J = robot.jacobian(q, tcp=True)
    h = 1e-6
    for k in range(robot.dof):
        dq = np.zeros(8)
        dq[k] = h
        lin = (robot.fk_tcp(q + dq)[:3, 3] - robot.fk_tcp(q - dq)[:3, 3]) / (2 * h)
        assert np.allclose(lin, J[:3, k], atol=1e-4)


def test_seed8_home_and_track_axis():
    robot = get_robot("seed8")
    assert np.allclose(robot.fk(np.zeros(8))[:3, 3], [0, 0, 1448], atol=1e-9)
    q = np.zeros(8)
    q[0] = 250.0
    assert np.allclose(robot.fk(q)[:3, 3], [0, 250, 1448], atol=1e-9)  # track moves along base y


def test_seed8_params_override():
    robot = get_robot("seed8", {"L2": 500.0, "L4": 100.0})
    assert np.allclose(robot.fk(np.zeros(8))[:3, 3], [0, 0, 480 + 500 + 418 + 100])
    with pytest.raises(BadInput, match="L9"):
        get_robot("seed8", {"L9": 1.0})


def test_irb2400_datasheet_home():
    assert np.allclose(get_robot("irb2400").fk(np.zeros(6))[:3, 3], [940, 0, 1455], atol=1e-9)


@pytest.mark.parametrize("name", BUILTIN_ROBOTS)
def test_urdf_round_trip(tmp_path, name):
    robot = get_robot(name)
    f = tmp_path / f"{name}.urdf"
    f.write_text(urdf_from_robot(robot))
    loaded = robot_from_urdf(f)
    assert loaded.dof == robot.dof
    assert list(loaded.prismatic) == list(robot.prismatic)
    assert np.allclose(loaded.limits.lower, robot.limits.lower)
    rng = np.random.default_rng(3)
    for q in random_q(robot, rng, 50):
        A, B = robot.fk(q), loaded.fk(q)
        assert np.abs(A[:3, 3] - B[:3, 3]).max() <= 1e-6
        assert rot_err(A[:3, :3], B[:3, :3]) <= 1e-9


def test_user_toml_robot(tmp_path):
    f = tmp_path / "arm.toml"
    f.write_text("""
name = "two_link"
convention = "standard"
[[joint]]
name = "a"
a_mm = 300
lower = -90
upper = 90
velocity = 100
acceleration = 200
jerk = 1000
[[joint]]
name = "b"
a_mm = 200
lower = -90
upper = 90
velocity = 100
acceleration = 200
jerk = 1000
""")
    robot = get_robot(str(f))
    assert np.allclose(robot.fk([0, np.pi / 2])[:3, 3], [300, 200, 0])


def test_user_toml_robot_errors_name_the_key(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text('name = "x"\n[[joint]]\na_mm = "oops"\nlower=-1\nupper=1\nvelocity=1\nacceleration=1\njerk=1\n')
    with pytest.raises(BadInput, match=r"joint\[0\]\.a_mm"):
        get_robot(str(f))
    f.write_text('name = "x"\n[[joint]]\nlower=-1\nupper=1\nvelocity=1\nacceleration=1\n')
    with pytest.raises(BadInput, match=r"joint\[0\]\.jerk: missing"):
        get_robot(str(f))


def test_unknown_robot():
    with pytest.raises(BadInput, match="unknown robot 'foo'"):
        get_robot("foo")
