"""``JointPath`` (planned joint values per pose) and ``Trajectory`` (timed).

Joint vectors ``q`` are in native units: **rad for revolute joints, mm for
prismatic joints** (the track). Speeds are rad/s or mm/s, and so on.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class JointPath:
    """Joint values per path pose, with per-pose diagnostics.

    Arrays have one row per pose of the Path (plus any inserted retract poses,
    which have ``path_index == -1``).
    """

    q: np.ndarray                 # (N, dof) rad / mm
    path_index: np.ndarray        # (N,) index into Path poses, -1 if inserted
    zone: np.ndarray              # (N,) zone codes (camtool.toolpath.ZONES)
    position_error_mm: np.ndarray # (N,)
    orientation_error_rad: np.ndarray  # (N,)
    jump: np.ndarray              # (N,) bool: step into this pose exceeded the jump threshold
    reverse_planned: np.ndarray   # (N,) bool
    retract: np.ndarray           # (N,) bool: pose belongs to a retract-reorient-return move
    singular: np.ndarray          # (N,) bool: fallback singular point
    reached: np.ndarray           # (N,) bool: IK converged within tolerance
    events: dict = field(default_factory=dict)  # planner events: reverse plans, retracts, ...


@dataclass(frozen=True)
class Trajectory:
    """Timed joint trajectory: waypoints with time, q, q', q''.

    Between waypoints the motion is the quintic Hermite polynomial fixed by the
    positions, speeds and accelerations at both ends (``sample`` evaluates it).
    """

    robot_name: str
    joint_names: tuple[str, ...]
    prismatic: np.ndarray   # (dof,) bool
    t_s: np.ndarray         # (M,)
    q: np.ndarray           # (M, dof) rad / mm
    qd: np.ndarray          # (M, dof) rad/s / mm/s
    qdd: np.ndarray         # (M, dof) rad/s^2 / mm/s^2
    zone: np.ndarray        # (M,) zone codes
    path_index: np.ndarray  # (M,) index into the Path, -1 for inserted samples
    limits: dict = field(default_factory=dict)  # name -> (dof,) arrays used for timing

    @property
    def dof(self) -> int:
        return self.q.shape[1]

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0])

    def sample(self, dt_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Resample at a fixed step: (t, q, qd, qdd, qddd) from the quintic Hermite pieces."""
        t = np.arange(self.t_s[0], self.t_s[-1], dt_s)
        t = np.append(t, self.t_s[-1])
        k = np.clip(np.searchsorted(self.t_s, t, side="right") - 1, 0, len(self.t_s) - 2)
        h = (self.t_s[k + 1] - self.t_s[k])[:, None]
        s = ((t - self.t_s[k])[:, None]) / np.where(h > 0, h, 1.0)
        c = quintic_coefficients(self.q[k], self.qd[k] * h, self.qdd[k] * h**2,
                                 self.q[k + 1], self.qd[k + 1] * h, self.qdd[k + 1] * h**2)
        p = np.zeros_like(self.q[k]); v = np.zeros_like(p); a = np.zeros_like(p); j = np.zeros_like(p)
        for n in range(5, -1, -1):
            p = p * s + c[n]
        for n in range(5, 0, -1):
            v = v * s + n * c[n]
        for n in range(5, 1, -1):
            a = a * s + n * (n - 1) * c[n]
        for n in range(5, 2, -1):
            j = j * s + n * (n - 1) * (n - 2) * c[n]
        hs = np.where(h > 0, h, np.inf)
        return t, p, v / hs, a / hs**2, j / hs**3


def quintic_coefficients(p0, v0, a0, p1, v1, a1) -> list[np.ndarray]:
    """Coefficients c0..c5 of the quintic on s in [0, 1] matching p, p', p'' at both ends.

    Speeds and accelerations are per unit s (already scaled by the segment
    duration h and h^2).
    """
    c0, c1, c2 = p0, v0, a0 / 2.0
    c3 = 10 * (p1 - p0) - 6 * v0 - 4 * v1 - 1.5 * a0 + 0.5 * a1
    c4 = -15 * (p1 - p0) + 8 * v0 + 7 * v1 + 1.5 * a0 - a1
    c5 = 6 * (p1 - p0) - 3 * v0 - 3 * v1 - 0.5 * a0 + 0.5 * a1
    return [c0, c1, c2, c3, c4, c5]
