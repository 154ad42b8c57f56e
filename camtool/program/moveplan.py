"""The move list of a program (``MovePlan``): one entry per motion instruction, in order.

The data every program stage passes on (``camtool.program.candidates`` picks the targets,
``camtool.program.blend`` blends their corners, ``camtool.program.steps`` refines the list,
the writers write it); it imports none of them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

KIND_JOINT, KIND_LINEAR, KIND_CIRCULAR = "J", "L", "C"


@dataclass
class MovePlan:
    """The moves of a program, one entry per motion instruction, in order.

    ``wp`` waypoint index of each move's target (``wp[0] == 0``: the first move comes
    from wherever the robot is); ``kind`` J (joint) or L (linear); ``t`` planned time at
    the target (s); ``level`` blend level index (-1 = exact stop); ``row`` 0-based work
    row of the move's target when the target lies on the surface (from the row's first
    to its last work point), else -1; ``row_start`` / ``row_end`` the move that reaches
    a row's first / last work point; ``free`` the target lies off the surface (outside
    every row: free motion, leads, retracts; a part may end there); ``deviation_mm`` the
    largest deviation of the skipped waypoints; kind C (``camtool.program.steps.FitArcs``)
    a circular move through ``via_P`` (with ``via_R``, ``via_q``).
    """

    wp: np.ndarray
    kind: np.ndarray
    t: np.ndarray
    level: np.ndarray
    row: np.ndarray
    row_start: np.ndarray
    row_end: np.ndarray
    free: np.ndarray
    deviation_mm: np.ndarray
    P: np.ndarray          # (n, 3) TCP position of each target, base frame
    R: np.ndarray          # (n, 3, 3) TCP rotation of each target, base frame
    q: np.ndarray          # (n, dof) joint values of each target
    rows: int = 0
    zone: np.ndarray | None = None   # (n,) zone code of each target (``camtool.path.toolpath.ZONES``)
    via_P: np.ndarray | None = None  # (n, 3) circle point of each circular move (kind C), NaN elsewhere
    via_R: np.ndarray | None = None  # (n, 3, 3) its TCP rotation
    via_q: np.ndarray | None = None  # (n, dof) its joint values

    def __len__(self) -> int:
        return len(self.wp)
