"""The independent checker flags each kind of limit break on hand-made trajectories."""
import numpy as np
import pytest

from camtool.timing import check_trajectory
from camtool.trajectory import Trajectory
from test_timing_fixtures import seed8

ROBOT = seed8()


def make(t, q_j, qd_j, qdd_j, joint=1, base=None):
    """A trajectory moving one joint (others held at ``base``)."""
    t = np.asarray(t, float)
    m = len(t)
    q = np.tile(np.zeros(8) if base is None else base, (m, 1))
    qd = np.zeros((m, 8))
    qdd = np.zeros((m, 8))
    q[:, joint] = q_j
    qd[:, joint] = qd_j
    qdd[:, joint] = qdd_j
    return Trajectory("seed8", ROBOT.joint_names, ROBOT.prismatic, t, q, qd, qdd,
                      np.zeros(m, int), np.full(m, -1))


def test_trajectory_within_limits_has_no_findings():
    t = np.linspace(0, 2.0, 11)
    d = 0.5  # smoothstep rest-to-rest: v 0.47 rad/s, a 0.72 rad/s^2, j 3.75 rad/s^3
    s = t / 2.0
    q = d * (10 * s**3 - 15 * s**4 + 6 * s**5)
    qd = d * (30 * s**2 - 60 * s**3 + 30 * s**4) / 2.0
    qdd = d * (60 * s - 180 * s**2 + 120 * s**3) / 4.0
    assert check_trajectory(make(t, q, qd, qdd), ROBOT, 0.004) == []


def test_position_break_is_flagged_in_degrees():
    t = [0.0, 1.0]
    out = check_trajectory(make(t, [3.1, 3.1], [0, 0], [0, 0], joint=2), ROBOT, 0.004)
    assert out and all("joint j3" in x and "position" in x and "deg" in x for x in out)
    assert "177.6" in out[0] and "170" in out[0]


def test_speed_break_is_flagged():
    t = np.linspace(0, 0.1, 6)
    out = check_trajectory(make(t, 2.5 * t, np.full(6, 2.5), np.zeros(6)), ROBOT, 0.004)
    assert any("joint j2" in x and "speed" in x and "deg/s " in x and "120" in x for x in out)
    assert not any("acceleration" in x or "jerk" in x for x in out)


def test_acceleration_break_is_flagged():
    t = np.linspace(0, 0.3, 7)
    a = 6.0  # rad/s^2 > 300 deg/s^2, constant: no jerk, speed stays below 2.09 rad/s
    out = check_trajectory(make(t, 0.5 * a * t**2, a * t, np.full(7, a)), ROBOT, 0.004)
    assert any("acceleration" in x and "deg/s^2" in x and "300" in x for x in out)
    assert not any("speed" in x or "jerk" in x for x in out)


def test_jerk_break_is_flagged():
    t = [0.0, 0.5]  # one smoothstep piece: jerk 60*0.1/0.125 = 48 rad/s^3 at the ends
    out = check_trajectory(make(t, [0.0, 0.1], [0, 0], [0, 0]), ROBOT, 0.004)
    assert any("jerk" in x and "deg/s^3" in x and "1500" in x for x in out)
    assert not any("speed" in x or "acceleration" in x for x in out)


def test_track_uses_mm():
    t = np.linspace(0, 0.1, 6)
    out = check_trajectory(make(t, 600 * t, np.full(6, 600.0), np.zeros(6), joint=0), ROBOT, 0.004)
    assert any("joint track" in x and "mm/s " in x and "500" in x for x in out)


@pytest.mark.parametrize("bad", ["time", "nan"])
def test_time_stamps_and_finite_values(bad):
    t = np.array([0.0, 1.0, 1.0 if bad == "time" else 2.0])
    q = np.array([0.0, 0.1, 0.2 if bad == "time" else np.nan])
    out = check_trajectory(make(t, q, np.zeros(3), np.zeros(3)), ROBOT, 0.004)
    assert len(out) == 1
    assert ("not strictly increasing" in out[0]) if bad == "time" else ("non-finite" in out[0])


def test_irb2400_axis_3_speed_is_the_coupled_speed():
    """j2 and j3 each at 140 deg/s (inside their 150) but the same way: the controller's axis 3
    (j2 + j3) turns at 280 deg/s, beyond its 150; the opposite way it stands still."""
    from camtool.robots import get_robot

    irb = get_robot("irb2400")
    t = np.linspace(0, 0.1, 6)
    w = np.radians(140.0)

    def traj(sign):
        q = np.tile(np.radians([0.0, 10.0, 20.0, 0.0, 45.0, 0.0]), (6, 1))
        qd = np.zeros((6, 6))
        q[:, 1] += w * t
        q[:, 2] += sign * w * t
        qd[:, 1], qd[:, 2] = w, sign * w
        return Trajectory("irb2400", irb.joint_names, irb.prismatic, t, q, qd, np.zeros((6, 6)),
                          np.zeros(6, int), np.full(6, -1))

    same = check_trajectory(traj(1.0), irb, 0.004)
    assert any("rax_3 (controller axis)" in x and "280" in x and "150" in x for x in same), same
    assert not any("joint j2:" in x or "joint j3:" in x for x in same)
    assert check_trajectory(traj(-1.0), irb, 0.004) == []
