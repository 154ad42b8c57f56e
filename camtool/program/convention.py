"""Where camtool's model meets the controller's conventions: the two conversion points.

- ``controller_axes`` / ``model_joints``: model joint values (rad / mm, in the robot
  model's order) <-> controller axis values (deg / mm per axis name, as the profile maps
  them). Every writer and reader converts joint values here and nowhere else.
- ``controller_pose`` / ``base_pose``: a TCP pose in the robot base frame (mm) <-> the
  pose a Cartesian target states (in the program's work object). Every writer and reader
  converts Cartesian targets here and nowhere else.

Controller-specific conventions (joint couplings, flange frames, axis orders) belong in
these functions, so that writers, readers and the simulator cannot disagree. They come
from the robot (``robot.conventions``, camtool/robots/conventions.py): the controller's
axis values are ``robot.conventions.controller_from_model(q)`` (the IRB2400's axis 3 =
j2 + j3), each written on the profile axis of the joint that drives it, with the
profile's sign, offset and unit; Cartesian targets are stated for the controller's tool0
and in its robot frame (``robot_frame_in_base``: the SIA20D's 410 mm above the foot).
"""
from __future__ import annotations

import numpy as np

from camtool.transforms import invert, matrix_from_xyz_rpy


def _by_driving_joint(conv, q_ctrl: np.ndarray) -> np.ndarray:
    """Controller axis values (M x n, rad / mm) placed in the column of the joint that drives each axis."""
    out = np.empty_like(q_ctrl)
    out[:, list(conv.axis_joints)] = q_ctrl
    return out


def controller_axes(profile, robot, q: np.ndarray) -> dict[str, np.ndarray]:
    """Controller axis values (deg / mm) per axis name for M x dof model joint values."""
    conv = robot.conventions
    q_ctrl = conv.controller_from_model(np.atleast_2d(np.asarray(q, float)))
    return profile.to_axes(_by_driving_joint(conv, q_ctrl), robot)


def model_joints(profile, robot, values: dict[str, np.ndarray]) -> np.ndarray:
    """M x dof model joint values (rad / mm) from controller axis values per axis name; NaN
    for the joints whose axis is missing or NaN (e.g. left to the controller's IK), and for
    the joints a missing axis is coupled to."""
    n = len(next(iter(values.values()))) if values else 0
    by_joint = np.full((n, robot.dof), np.nan)
    for a in profile.axes:
        if a.axis not in values:
            continue
        i = robot.joint_names.index(a.joint)
        x = (np.asarray(values[a.axis], float) - a.offset) / a.sign
        by_joint[:, i] = x if robot.prismatic[i] else np.radians(x)
    conv = robot.conventions
    q_ctrl = by_joint[:, list(conv.axis_joints)]
    inv = np.linalg.inv(conv.matrix)
    q = np.nan_to_num(q_ctrl - conv.offset) @ inv.T
    missing = np.isnan(q_ctrl).astype(float) @ (np.abs(inv.T) > 1e-12)   # joints that depend on a missing axis
    q[missing > 0] = np.nan
    return q


def stated_joints(profile, robot, arm_axes) -> tuple[int, ...]:
    """Indices of the model joints a Cartesian target states beside its pose: those the profile puts
    on an axis outside ``arm_axes`` (the six the controller solves for the pose; a 7th axis such as
    the SIA20D's E on INFORM's ``Re``, a track on ``eax_a`` or ``BS1``). The controller moves them
    linearly in a straight move (``camtool.program.candidates.HeldJointChords``)."""
    arm = set(arm_axes)
    return tuple(sorted(robot.joint_names.index(a.joint) for a in profile.axes
                        if a.axis not in arm and a.joint in robot.joint_names))


def tool_in_tool0(robot, tool_in_flange_mm: np.ndarray) -> np.ndarray:
    """The TCP in the controller's tool0 (what tooldata / the tool file state) from the TCP in the flange."""
    return robot.conventions.tool_in_tool0(tool_in_flange_mm)


def wobj_frame(profile) -> np.ndarray:
    """The profile's work object (4 x 4, mm) in the robot base frame."""
    return matrix_from_xyz_rpy(profile.wobj["xyz_mm"], profile.wobj["rpy_deg"])


def controller_pose(profile, P: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """TCP positions (S, 3) and rotations (S, 3, 3) in the robot base frame -> the target
    poses a program states, in the profile's work object."""
    W = invert(wobj_frame(profile))
    return np.asarray(P, float) @ W[:3, :3].T + W[:3, 3], W[:3, :3][None] @ np.asarray(R, float)


def controller_pose_base(profile, P: np.ndarray, R: np.ndarray, robot=None) -> tuple[np.ndarray, np.ndarray]:
    """As ``controller_pose``, for formats whose Cartesian targets are stated in the
    controller's robot frame (Yaskawa ``///RECTAN`` positions): the TCP pose in
    ``robot.conventions.robot_frame_in_base`` (the SIA20D's is 410 mm above camtool's base)."""
    F = invert(robot_frame(robot))
    return np.asarray(P, float) @ F[:3, :3].T + F[:3, 3], F[:3, :3][None] @ np.asarray(R, float)


def robot_frame(robot) -> np.ndarray:
    """The controller's robot frame (4 x 4, mm) in camtool's base frame (identity without a robot)."""
    return np.eye(4) if robot is None else np.asarray(robot.conventions.robot_frame_in_base, float)


def base_pose(frame: np.ndarray, T: np.ndarray) -> np.ndarray:
    """A target pose a program states (4 x 4, mm, in a work object whose frame in the base
    is ``frame``) -> the TCP pose in the robot base frame."""
    return np.asarray(frame, float) @ np.asarray(T, float)
