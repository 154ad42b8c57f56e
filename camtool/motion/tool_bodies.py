"""The motion check's capsules that are rigid with the TCP, in the TCP's frame: what a path modifier may measure
against the part from the poses alone, before any plan (``camtool.path.axis_tilt``).

The check's bodies (``check.chain_bodies``) run between the robot's joint origins, the flange and the TCP; on a
spherical wrist the tool (flange to TCP) and the wrist (the last joint origin to the flange) lie on the last
joint's axis, so their place in the TCP frame does not depend on the configuration. Which do is measured, not
assumed: a body is kept when its ends in the TCP frame agree at two configurations within ``RIGID_MM``. The
part of the tool the check leaves out next to the TCP (``tool_contact_exempt_mm``) is left out here too.
"""
from __future__ import annotations

import numpy as np

from ..path.axis_tilt import AxisBody
from .check import MotionCheckSettings, chain_bodies
from .fk_batch import BatchFK

RIGID_MM = 1e-6
_TURN_RAD = 0.35    # the second configuration: each revolute joint this far from the first, inside its limits


def _configurations(robot) -> np.ndarray:
    """Two configurations inside the limits (2, dof): the middle of every joint's range, and every joint moved."""
    lo, hi = np.asarray(robot.limits.lower, float), np.asarray(robot.limits.upper, float)
    mid = np.where(np.asarray(robot.prismatic, bool), 0.5 * (lo + hi), np.clip(0.0, lo, hi))
    moved = np.clip(mid + np.where(np.asarray(robot.prismatic, bool), 0.1 * (hi - lo), _TURN_RAD), lo, hi)
    return np.stack([mid, moved])


def tool_axis_bodies(robot, settings: MotionCheckSettings = MotionCheckSettings()) -> tuple[AxisBody, ...]:
    """The check's capsules rigid with the TCP (module docstring), their axes in the TCP frame (mm)."""
    fk = BatchFK(robot)
    fkb = fk(_configurations(robot))
    dof = robot.dof
    out = []
    for body in chain_bodies(robot, fk, settings):
        ends = []
        for i in (body.start, body.end):
            p = fkb.joint_origins[:, i] if i < dof else (fkb.flange if i == dof else fkb.tcp)
            ends.append(np.einsum("sji,sj->si", fkb.tcp_R, p - fkb.tcp))   # into each TCP frame
        a, b = ends
        if np.abs(a[0] - a[1]).max() > RIGID_MM or np.abs(b[0] - b[1]).max() > RIGID_MM:
            continue
        a, b = a[0], b[0]
        length = float(np.linalg.norm(b - a))
        exempt = settings.tool_contact_exempt_mm - (0.0 if body.kind == "tool" else body.exempt_before)
        keep = length - min(max(exempt, 0.0), length)   # the check leaves out the stretch next to the TCP
        if keep <= 1e-9:
            continue
        b = a + (b - a) * (keep / length)
        out.append(AxisBody(body.name, tuple(round(float(v), 9) for v in a), tuple(round(float(v), 9) for v in b), float(body.radius)))
    return tuple(out)
