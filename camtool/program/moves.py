"""A controller program read back, in a form every format shares: what the simulator runs.

A plugin that can say more than ``read`` (durations and joint targets) provides
``read_program(path, robot, profile) -> ProgramMoves``: every motion
instruction in run order, with its interpolation (joint, linear, circular), its
target (joint values, or a TCP pose in the robot base frame with whatever joint
values the target fixes, such as external axes), its timing (a duration or a TCP
speed), its blend radius (0 = exact stop), the program part (module, job) it
lives in, and where the process (the tool on the surface) starts and stops.
``camtool.simulate`` re-executes it the way the controller interpolates it.

This module holds data and the controller's zone convention for joint moves
(``joint_travel``), which the writers' blend model and the simulator both use;
it imports no writer.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

JOINT, LINEAR, CIRCULAR = "J", "L", "C"
CONF_UNKNOWN = -99  # conf value of a target that asks for no configuration
ZONE_DEG_PER_MM = 0.15  # a joint move's blend starts r mm of TCP travel or 0.15 r deg of joint travel early


def joint_travel(dq: np.ndarray, prismatic: np.ndarray) -> np.ndarray:
    """A joint move's length for blending, in TCP-equivalent mm: its largest joint travel
    (deg / ``ZONE_DEG_PER_MM``, or mm for prismatic joints); rows of dq are moves."""
    dq = np.abs(np.atleast_2d(dq))
    return np.where(prismatic[None, :], dq, np.degrees(dq) / ZONE_DEG_PER_MM).max(axis=1)


@dataclass
class ProgramMoves:
    """Motion instructions of a program in run order (M moves, robot with ``dof`` joints).

    - ``kind`` (M,): ``J`` joint-linear, ``L`` linear TCP, ``C`` circular TCP;
    - ``q`` (M, dof): the target's joint values (rad / mm); NaN for the joints a
      Cartesian target leaves to the controller's inverse kinematics;
    - ``pose`` (M, 4, 4): a Cartesian target's TCP pose in the robot base frame, mm
      (NaN for joint targets); ``via`` (M, 4, 4) the circle point of a circular move;
    - ``conf`` (M, 4): the configuration the program asks for (``CONF_UNKNOWN``: none);
    - ``duration_s`` (M,): the move's duration when the program gives one (``\\T``, or
      implied by VJ), NaN otherwise (a speed instead, or the first move);
    - ``speed_mm_s`` (M,): the TCP speed of a Cartesian move, NaN otherwise;
      ``ori_speed_deg_s`` (M,): its reorientation speed limit, NaN when none;
    - ``blend_mm`` (M,): the corner radius at the target (0: an exact stop);
    - ``part`` (M,): index of the module / job the move is in (a change is a switch);
    - ``row_start`` (M,): the process starts (tool on, or a row-start marker) before this
      move; ``row_end`` (M,): it stops after this move;
    - ``where``: ``file:line`` of every move; ``row_names``: the marker text per row;
    - ``tool_T_mm``: the TCP in the flange frame when the program declares it, else None;
    - ``conf_convention``: how ``conf`` is meant (``abb``: cf1, cf4, cf6, cfx;
      ``yaskawa``: flip, lower arm, rear, R>=180, T>=180, S>=180 packed as bits), or "".
    """

    kind: np.ndarray
    q: np.ndarray
    pose: np.ndarray
    via: np.ndarray
    conf: np.ndarray
    duration_s: np.ndarray
    speed_mm_s: np.ndarray
    ori_speed_deg_s: np.ndarray
    blend_mm: np.ndarray
    part: np.ndarray
    row_start: np.ndarray
    row_end: np.ndarray
    where: list = field(default_factory=list)
    row_names: list = field(default_factory=list)
    tool_T_mm: np.ndarray | None = None
    conf_convention: str = ""

    def __len__(self) -> int:
        return len(self.kind)

    @property
    def cartesian(self) -> np.ndarray:
        """(M,) True for Cartesian (linear / circular) moves."""
        return self.kind != JOINT


def empty_moves(M: int, dof: int) -> dict:
    """Keyword arguments of a ProgramMoves with M moves, every value unknown."""
    nan = np.full(M, np.nan)
    return dict(kind=np.full(M, JOINT), q=np.full((M, dof), np.nan), pose=np.full((M, 4, 4), np.nan),
                via=np.full((M, 4, 4), np.nan), conf=np.full((M, 4), CONF_UNKNOWN, int), duration_s=nan.copy(),
                speed_mm_s=nan.copy(), ori_speed_deg_s=nan.copy(), blend_mm=np.zeros(M),
                part=np.zeros(M, int), row_start=np.zeros(M, bool), row_end=np.zeros(M, bool))
