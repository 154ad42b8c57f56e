"""Bounds a real robot meets, checked once when a robot is loaded (issue #49).

A robot description may hold numbers that are finite but absurd: a joint that turns at 1e-9 deg/s, an
acceleration of 1e30, limits of a million turns. They pass the parsers and then reach the planner or
the timer, which fail deep inside (``ValueError``) or run for hours. ``validate_robot`` refuses them at
load with one line naming the joint, the value and the bound. Every industrial arm and track meets
these bounds by orders of magnitude; the bounds are wide on purpose.

``[controller.urdf]`` is checked here too: the file must be a regular file under the robot cap
(opened once with O_NONBLOCK through ``safe_io``), so a FIFO there is one line at load, never a hang.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import BadInput

DEG = math.pi / 180.0
# (lowest, highest) per limit and joint kind, in native units (rad or mm, per s, s^2, s^3)
REVOLUTE = {"position": 3600 * DEG, "velocity": (0.1 * DEG, 10_000 * DEG),
            "acceleration": (0.1 * DEG, 1e6 * DEG), "jerk": (0.1 * DEG, 1e9 * DEG)}
PRISMATIC = {"position": 1e5, "velocity": (0.1, 1e5), "acceleration": (0.1, 1e7), "jerk": (0.1, 1e10)}


def _shown(value: float, prismatic: bool) -> str:
    return f"{value:.6g} mm" if prismatic else f"{value / DEG:.6g} deg"


def validate_robot(robot, source: str = "") -> None:
    """BadInput (one line) when a joint limit of ``robot`` is outside what a real robot has (module doc)."""
    where = source or robot.source
    lim = robot.limits
    for j, name in enumerate(robot.joint_names):
        pri = bool(robot.prismatic[j])
        b = PRISMATIC if pri else REVOLUTE
        unit = "mm" if pri else "deg"
        for side, v in (("lower", lim.lower[j]), ("upper", lim.upper[j])):
            if not math.isfinite(v) or abs(v) > b["position"]:
                raise BadInput(f"{where}: joint {j + 1} ({name}) {side} limit {_shown(v, pri)} is beyond "
                               f"{_shown(b['position'], pri)}; no real robot's joint reaches that")
        for key in ("velocity", "acceleration", "jerk"):
            v = float(np.asarray(getattr(lim, key))[j])
            lo, hi = b[key]
            if not (lo <= v <= hi):
                scale = 1.0 if pri else DEG
                raise BadInput(f"{where}: joint {j + 1} ({name}) {key} {v / scale:.6g} {unit}/s"
                               f"{'' if key == 'velocity' else '^2' if key == 'acceleration' else '^3'} is outside "
                               f"{lo / scale:g}..{hi / scale:g}; give the robot's real {key}")
    conv = robot.conventions
    if conv is not None and getattr(conv, "urdf_path", None) is not None:
        from ..safe_io import check_input

        check_input(conv.urdf_path, "robot")  # a regular file under the cap, opened without blocking
