"""Shared fixtures for the post-processor tests: smooth trajectories within limits."""
import numpy as np

from camtool.trajectory import Trajectory


def smooth_trajectory(robot, n: int = 80, duration_s: float = 8.0, fraction: float = 0.3) -> Trajectory:
    """A sinusoidal motion of every joint around mid-range, ``fraction`` of each range wide,
    with analytic speeds and accelerations (well within the speed limits)."""
    t = np.linspace(0.0, duration_s, n)
    lo, hi = robot.limits.lower, robot.limits.upper
    mid, amp = (lo + hi) / 2, (hi - lo) * fraction / 2
    w = 2 * np.pi / duration_s
    ph = np.linspace(0.0, np.pi, robot.dof)
    arg = w * t[:, None] + ph[None, :]
    q = mid + amp * np.sin(arg)
    qd = amp * w * np.cos(arg)
    qdd = -amp * w * w * np.sin(arg)
    conv = robot.conventions
    if not np.all(conv.within_limits(q)):
        # a coupled axis (the IRB2400's axis 3 = j2 + j3) leaves the controller's range: the same
        # sinusoids on the controller's axes, mapped back to the joints (a linear map)
        mid_c, amp_c = (conv.lower + conv.upper) / 2, (conv.upper - conv.lower) * fraction / 2
        lo_c = conv.model_from_controller
        q = lo_c(mid_c + amp_c * np.sin(arg))
        qd = (amp_c * w * np.cos(arg)) @ np.linalg.inv(conv.matrix).T
        qdd = (-amp_c * w * w * np.sin(arg)) @ np.linalg.inv(conv.matrix).T
    return Trajectory(robot.name, robot.joint_names, robot.prismatic, t, q, qd, qdd,
                      np.zeros(n, int), np.arange(n))


def with_q(traj: Trajectory, q, t_s=None) -> Trajectory:
    """A copy of ``traj`` with other joint values (and times)."""
    from dataclasses import replace
    return replace(traj, q=np.asarray(q, float), t_s=traj.t_s if t_s is None else np.asarray(t_s, float))


# The shipped sia20 INFORM profile has no pulse factors (the controller's own; no public source
# gives an SIA20D's), so it writes Cartesian positions only. Tests of pulse positions give the
# profile factors, as a user copies them from their controller: these are test values.
SIA20_TEST_PULSES = {"s": 1435.27, "l": 1435.27, "u": 1137.78, "r": 910.22, "b": 910.22, "t": 455.11, "e": 1137.78}


def profile_for_tests(robot_name: str, fmt: str, robot, tmp_path):
    """The shipped profile; for the sia20's INFORM one, with the test pulse factors above."""
    import re
    from camtool.program.profiles import default_profile_path, load_profile
    if (robot_name, fmt) != ("sia20", "inform"):
        return load_profile(None, robot_name, fmt, robot)
    text = default_profile_path("sia20", "inform").read_text()
    for j, v in SIA20_TEST_PULSES.items():
        text = re.sub(rf'^({j} = {{ axis = "RB1:\d", )', rf"\g<1>pulses = {v}, zero_pulses = 0, ", text, flags=re.M)
    f = tmp_path / "sia20_pulses_inform.toml"
    f.write_text(text)
    return load_profile(f, "sia20", "inform", robot)
