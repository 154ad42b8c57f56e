"""The part tilted on its fixture: roll and pitch of the workpiece for ``camtool place``.

A process engineer tilts a part whose normals turn further than the robot's wrist allows at any position and
yaw (a folded sheet: j5 past the bend where the tool meets link_4). The tilt is two placement variables beside
x, y, z and yaw, ``roll`` about world x and ``pitch`` about world y (deg), turning the part about the centre of
its work poses (``work_centre``; a workpiece frame's origin may lie far from the part, and a turn about it would
move the part out of the --vary bounds):

    D = shift(d) . Rz(yaw) about cell.workpiece_xyz_mm . Ry(pitch) Rx(roll) about the work centre

``placed_pose`` turns that into the placed job's ``cell.workpiece_xyz_mm`` / ``workpiece_rpy_deg``; an offset
without a tilt keeps the arithmetic ``camtool place`` always had (the placements that need no tilt come out
byte for byte as before).

``TiltSettings``: how far and how coarse. The search tilts only when no untilted placement within the bounds
plans (``search.PlacementProblem.run``): a tilted fixture costs a fixture, so a part that fits upright stays
upright. The tilt stage screens the untilted stage's grid at every tilt of a coarse grid (``step_deg``, like the
yaw's), then refines round the best with the steps halving, so its work is counted (placements screened),
never timed.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import BadInput
from ..transforms import matrix_from_xyz_rpy, rpy_deg_from_matrix

TILT_AXES = ("roll", "pitch")
DEFAULT_MAX_DEG = 30.0     # the tilt's bound (deg): a fixture's usual tilt table range; --tilt-max-deg
DEFAULT_STEP_DEG = 15.0    # the coarse tilt grid's step (deg); the refinement halves it
HALF_VALUES = 3            # at most this many coarse values each side of 0 (a wider bound, a coarser step)
MAX_TILT_DEG = 90.0        # beyond, the part would face away from the robot


@dataclass(frozen=True)
class TiltSettings:
    """The tilt stage: bound (deg, 0 = never tilted) and coarse grid step (deg)."""

    max_deg: float = DEFAULT_MAX_DEG
    step_deg: float = DEFAULT_STEP_DEG

    def __post_init__(self):
        if not (math.isfinite(self.max_deg) and 0.0 <= self.max_deg <= MAX_TILT_DEG):
            raise BadInput(f"--tilt-max-deg: expected an angle in [0, {MAX_TILT_DEG:g}] deg, found {self.max_deg:g}")
        if not (math.isfinite(self.step_deg) and self.step_deg > 0.0):
            raise BadInput(f"tilt step: expected a positive angle, found {self.step_deg:g}")

    @property
    def enabled(self) -> bool:
        return self.max_deg > 0.0

    def values_deg(self) -> np.ndarray:
        """The coarse grid of one tilt axis: 0 and evenly spaced values out to +-``max_deg``, at most ``step_deg``
        apart, or as many as HALF_VALUES each side (7 in all: the stage screens the upright grid at every pair)."""
        n = min(HALF_VALUES, max(1, int(math.ceil(self.max_deg / self.step_deg - 1e-9))))
        return np.linspace(-self.max_deg, self.max_deg, 2 * n + 1)


def tilt_matrix(roll_deg: float, pitch_deg: float, centre_mm) -> np.ndarray:
    """4x4 world transform: Ry(pitch) Rx(roll) (world axes, deg) about the point ``centre_mm``."""
    T = matrix_from_xyz_rpy([0.0, 0.0, 0.0], [float(roll_deg), float(pitch_deg), 0.0])
    c = np.asarray(centre_mm, float)
    T[:3, 3] = c - T[:3, :3] @ c
    return T


def work_centre(path) -> np.ndarray:
    """The middle (mm, world) of the bounding box of a path's work TCPs (of every pose without work): the tilt's pivot."""
    from ..path.toolpath import WORK

    P = np.asarray(path.poses_mm, float)[:, :3, 3]
    work = np.asarray(path.zone) == WORK
    P = P[work] if work.any() else P
    return 0.5 * (P.min(axis=0) + P.max(axis=0)) if len(P) else np.zeros(3)


def is_tilted(offset) -> bool:
    """Whether an offset (dx, dy, dz, dyaw[, droll, dpitch]) tilts the part."""
    return any(float(a) for a in offset[4:6])


def placed_pose(xyz_mm, rpy_deg, D: np.ndarray) -> tuple[list[float], list[float]]:
    """(workpiece_xyz_mm, workpiece_rpy_deg) of the workpiece frame (xyz, rpy) moved by the world transform D,
    rounded to 1e-6 as ``camtool place`` writes them."""
    W = D @ matrix_from_xyz_rpy(xyz_mm, rpy_deg)
    rpy = rpy_deg_from_matrix(W[:3, :3])
    return [round(float(v), 6) for v in W[:3, 3]], [round(float(v), 6) + 0.0 for v in rpy]
