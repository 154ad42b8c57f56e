"""Robot library: FK against an independent DH product, Jacobian against finite
differences, URDF round trip, user TOML robots."""
import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.robots import BUILTIN_ROBOTS, get_robot
from camtool.robots.library import robot_toml_data
from camtool.robots.urdf import robot_from_urdf, urdf_from_robot
from camtool.transforms import matrix_from_xyz_rpy, rotation_angle_rad


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
    flange = robot_toml_data(robot.name).get("flange", {})  # the manufacturer robots' flange is the controller's tool0
    return T @ matrix_from_xyz_rpy(flange.get("xyz_mm", [0, 0, 0]), flange.get("rpy_deg", [0, 0, 0]))


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


# --------------------------------------------------------------------------- bad robot files: one line, BadInput

BAD = __import__("pathlib").Path(__file__).resolve().parent / "bad_input"
_LIMITS = "lower = -90\nupper = 90\nvelocity = 100\nacceleration = 200\njerk = 1000\n"
_ONE_JOINT = 'name = "x"\n[[joint]]\nname = "j1"\na_mm = 300\n' + _LIMITS


@pytest.mark.parametrize("text,message", [
    ('name = "x"\njoint = [1, 2]\n', r"joint\[0\]: expected a \[\[joint\]\] table .*found 1$"),
    (_ONE_JOINT + "[flange]\nxyz_mm = [0, 0]\n", r"\[flange\] xyz_mm: expected 3 numbers \[x, y, z\], found \[0, 0\]"),
    (_ONE_JOINT + "[flange]\nxyz = [0, 0, 100]\n", r"\[flange\] xyz: unknown key; did you mean xyz_mm\?$"),
    (_ONE_JOINT + "[flange]\nrpy_deg = [0, nan, 0]\n", r"\[flange\] rpy_deg: expected 3 finite numbers"),
    ('name = "x"\n[params]\nL1 = "long"\n[[joint]]\na_mm = "L1"\n' + _LIMITS,
     r"\[params\] L1: expected a length in mm, found 'long'"),
    ('name = "x"\n[[joint]]\nlower = nan\nupper = 90\nvelocity = 100\nacceleration = 200\njerk = 1000\n',
     r"joint\[0\]\.lower: expected a finite number, found nan"),
    ('name = "x"\n[[joint]]\nlower = -90\nupper = inf\nvelocity = 100\nacceleration = 200\njerk = 1000\n',
     r"joint\[0\]\.upper: expected a finite number, found inf"),
    ('name = "x"\n[[joint]]\nlower = -90\nupper = 90\nvelocity = -inf\nacceleration = 200\njerk = 1000\n',
     r"joint\[0\]\.velocity: expected a finite number, found -inf"),
    (_ONE_JOINT + '[[joint]]\nname = "j1"\n' + _LIMITS,
     r"joint\[1\]\.name: 'j1' is already the name of joint\[0\]; joint names must be unique"),
    ('name = "x"\n[[joint]]\na = 300\n' + _LIMITS, r"joint\[0\] a: unknown key; did you mean a_mm\?$"),
    ('name = "x"\n[[joint]]\nalpha_dge = 90\n' + _LIMITS, r"joint\[0\] alpha_dge: unknown key; did you mean alpha_deg\?$"),
    ('nmae = "x"\n[[joint]]\n' + _LIMITS, r": nmae: unknown key; did you mean name\?$"),
    ('name = "x"\n[[joint]]\na_mm = 1e12\n' + _LIMITS, r"joint\[0\]\.a_mm: 1e\+12 mm is not a plausible length"),
    (_ONE_JOINT + "[flange]\nxyz_mm = [0, 0, 1e12]\n", r"\[flange\] xyz_mm: 1e\+12 mm is not a plausible length"),
    ('name = "x"\n[params]\nL1 = 1e12\n[[joint]]\nd_mm = "L1"\n' + _LIMITS,
     r"\[params\] L1: 1e\+12 mm is not a plausible length"),
    ('name = "x"\n[[joint]]\ntype = "prismatic"\nlower = -1e9\nupper = 1000\nvelocity = 1\nacceleration = 1\njerk = 1\n',
     r"joint\[0\]\.lower: -1e\+09 mm is not a plausible length"),
    ('name = "x"\nparams = 5\n[[joint]]\n' + _LIMITS, r"params: expected a \[params\] table"),
])
def test_robot_toml_validation_one_line(tmp_path, text, message):
    f = tmp_path / "arm.toml"
    f.write_text(text)
    with pytest.raises(BadInput, match=message) as exc:
        get_robot(str(f))
    assert str(exc.value).startswith(str(f)) and "\n" not in str(exc.value)


def test_job_param_override_must_be_a_plausible_length():
    with pytest.raises(BadInput, match=r"robot\.params\.L2: 1e\+12 mm is not a plausible length"):
        get_robot("seed8", {"L2": 1e12})
    with pytest.raises(BadInput, match=r"robot\.params\.L2: expected a length > 0 mm, found nan"):
        get_robot("seed8", {"L2": float("nan")})
    with pytest.raises(BadInput, match=r"no parameter 'L22'.*did you mean L2\?"):
        get_robot("seed8", {"L22": 1.0})


def test_robot_toml_unreadable(tmp_path):
    (tmp_path / "dir.toml").mkdir()
    with pytest.raises(BadInput, match="is a folder"):
        get_robot(str(tmp_path / "dir.toml"))
    (tmp_path / "bin.toml").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(BadInput, match="cannot read the robot file"):
        get_robot(str(tmp_path / "bin.toml"))


def _urdf(joints: str, links=("a", "b")) -> str:
    return '<robot name="r">' + "".join(f'<link name="{n}"/>' for n in links) + joints + "</robot>"


def _joint(name="j", kind="revolute", parent="a", child="b", extra='<limit lower="-1" upper="1" velocity="1" effort="1"/>'):
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>{extra}</joint>')


@pytest.mark.parametrize("text,message", [
    (_urdf(""), "has no movable joint"),
    (_urdf(_joint(kind="fixed", extra="")), "has no movable joint"),
    ("hello", r"not a URDF: XML error"),
    ("<foo/>", r"root element is <foo>, expected <robot>"),
    (_urdf(_joint(child="c")), r"joint 'j': <child link='c'> is not a <link> of the robot"),
    (_urdf(_joint(kind="bogus")), r"joint 'j': type 'bogus' is not a URDF joint type"),
    (_urdf(_joint(kind="continuous", extra="")), r"continuous joints are not supported"),
    (_urdf(_joint(kind="floating", extra="")), r"floating joints are not supported"),
    (_urdf(_joint(extra="")), r"joint 'j': <limit lower=\.\.\.> missing"),
    (_urdf(_joint(extra='<limit lower="-1" upper="nan" velocity="1" effort="1"/>')),
     r"<limit upper='nan'> is not a finite number"),
    (_urdf(_joint(extra='<limit lower="-1" upper="1" velocity="inf" effort="1"/>')),
     r"<limit velocity='inf'> is not a finite number"),
    (_urdf(_joint(extra='<limit lower="1" upper="-1" velocity="1" effort="1"/>')), "lower must be below upper"),
    (_urdf(_joint() + _joint(parent="b", child="c"), ("a", "b", "c")), r"joint 'j' is defined twice"),
    (_urdf(_joint(), ("a", "a", "b")), r"link 'a' is defined twice"),
    (_urdf(_joint(extra='<origin xyz="1e9 0 0"/><limit lower="-1" upper="1" velocity="1" effort="1"/>')),
     r"<origin xyz> is 1e\+09 m from its parent"),
    (_urdf(_joint(extra='<origin xyz="nan 0 0"/><limit lower="-1" upper="1" velocity="1" effort="1"/>')),
     r"<origin xyz>: expected 3 finite numbers"),
    (_urdf(_joint(extra='<axis xyz="0 0 0"/><limit lower="-1" upper="1" velocity="1" effort="1"/>')),
     r"<axis xyz> is zero"),
    (_urdf(_joint(), ("a", "b", "c")), r"the links form 2 separate trees"),
])
def test_urdf_checked_before_pinocchio(tmp_path, text, message):
    f = tmp_path / "arm.urdf"
    f.write_text(text)
    with pytest.raises(BadInput, match=message) as exc:
        robot_from_urdf(f)
    assert str(exc.value).startswith(str(f)) and "\n" not in str(exc.value)


def test_cli_robot_without_movable_joint_is_exit_2_not_a_crash():
    from conftest import run_camtool

    r = run_camtool("fk", BAD / "no_joints.urdf", "0", "--json")
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.count("\n") == 1 and "no_joints.urdf: the URDF has no movable joint" in r.stderr


def test_cli_robot_toml_errors_exit_2(tmp_path):
    from conftest import run_camtool

    f = tmp_path / "arm.toml"
    f.write_text(_ONE_JOINT + "[flange]\nxyz = [0, 0, 100]\n")
    r = run_camtool("fk", f, "0", "--json")
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr == f"camtool: error: {f}: [flange] xyz: unknown key; did you mean xyz_mm?\n"


def test_dh_model_never_sees_nan():
    from camtool.robots.dh import DHRow, build_pinocchio_model

    with pytest.raises(ValueError, match="NaN or infinite"):
        build_pinocchio_model([DHRow(np.nan, 0.0, 0.0, 0.0)], "modified", np.eye(4), ["j1"], "x")
