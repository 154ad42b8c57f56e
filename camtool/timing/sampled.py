"""What the figures need of a trajectory's samples, gathered as the limit check samples it.

The limit check (``check.check_trajectory``) resamples a timed trajectory every
``check_dt_s`` a block of waypoints at a time; ``SampledMotion`` keeps of each
block only what the report, the feed plot and the faces' feed need: the sample
times, the TCP positions (forward kinematics) and each joint's peak speed,
acceleration and jerk as a share of its limit. The dense job's samples
(776k x 8 joints x 4 quantities, about 200 MB) are so never held at once; what
is kept is about 25 MB, and the trajectory is sampled once for the check and
every figure (issue #25).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..path.toolpath import freeze_arrays
from ..trajectory import Trajectory, TrajectorySamples, sample_blocks
from .feed import tcp_positions_world


@dataclass(frozen=True)
class SampledMotion:
    """A trajectory as sampled every ``dt_s``: ``t_s`` (K,), ``tcp_mm`` (K, 3) world TCP positions and
    ``peak_ratio`` (3, dof): max |qd| / velocity, |qdd| / acceleration, |qddd| / jerk limit per joint.
    ``waypoints``, ``t_first_s`` and ``t_last_s`` identify the trajectory sampled (``matches``)."""

    dt_s: float
    waypoints: int
    t_first_s: float
    t_last_s: float
    t_s: np.ndarray
    tcp_mm: np.ndarray
    peak_ratio: np.ndarray

    def __post_init__(self):
        freeze_arrays(self)

    def matches(self, trajectory: Trajectory, dt_s: float | None = None) -> bool:
        """True if this is ``trajectory`` (same waypoint count and end times) sampled at ``dt_s``."""
        t = trajectory.t_s
        return (self.waypoints == len(t) and len(t) > 0 and self.t_first_s == float(t[0])
                and self.t_last_s == float(t[-1]) and (dt_s is None or self.dt_s == dt_s))


class MotionGatherer:
    """Called with each block of samples (``check_trajectory``'s ``each_block``); ``result()`` is their
    ``SampledMotion``."""

    def __init__(self, trajectory: Trajectory, robot, dt_s: float):
        self._trajectory, self._robot, self._dt_s = trajectory, robot, float(dt_s)
        self._t, self._tcp = [], []
        self._peak = np.zeros((3, robot.dof))

    def __call__(self, block: TrajectorySamples) -> None:
        L = self._robot.limits
        self._t.append(block.t_s)
        self._tcp.append(tcp_positions_world(self._robot, block.q))
        for r, (x, limit) in enumerate(((block.qd, L.velocity), (block.qdd, L.acceleration),
                                        (block.qddd, L.jerk))):
            if len(x):
                np.maximum(self._peak[r], (np.abs(x) / limit).max(axis=0), out=self._peak[r])

    def result(self) -> SampledMotion:
        t = self._trajectory.t_s
        return SampledMotion(self._dt_s, int(len(t)), float(t[0]), float(t[-1]),
                             np.concatenate(self._t) if self._t else np.zeros(0),
                             np.concatenate(self._tcp) if self._tcp else np.zeros((0, 3)), self._peak)


def sample_motion(trajectory: Trajectory, robot, dt_s: float) -> SampledMotion:
    """``trajectory`` sampled every ``dt_s`` into a ``SampledMotion`` (no check), a block at a time."""
    gather = MotionGatherer(trajectory, robot, dt_s)
    for block in sample_blocks(trajectory, dt_s):
        gather(block)
    return gather.result()
