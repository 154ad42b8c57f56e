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
    return Trajectory(robot.name, robot.joint_names, robot.prismatic, t, q, qd, qdd,
                      np.zeros(n, int), np.arange(n))


def with_q(traj: Trajectory, q, t_s=None) -> Trajectory:
    """A copy of ``traj`` with other joint values (and times)."""
    from dataclasses import replace
    return replace(traj, q=np.asarray(q, float), t_s=traj.t_s if t_s is None else np.asarray(t_s, float))
