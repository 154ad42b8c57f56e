"""Where camtool's model meets the controller's conventions: the two conversion points.

- ``controller_axes`` / ``model_joints``: model joint values (rad / mm, in the robot
  model's order) <-> controller axis values (deg / mm per axis name, as the profile maps
  them). Every writer and reader converts joint values here and nowhere else.
- ``controller_pose`` / ``base_pose``: a TCP pose in the robot base frame (mm) <-> the
  pose a Cartesian target states (in the program's work object). Every writer and reader
  converts Cartesian targets here and nowhere else.

Controller-specific conventions (joint couplings, flange frames, axis orders) belong in
these functions, so that writers, readers and the simulator cannot disagree.
"""
from __future__ import annotations

import numpy as np

from camtool.transforms import invert, matrix_from_xyz_rpy


def controller_axes(profile, robot, q: np.ndarray) -> dict[str, np.ndarray]:
    """Controller axis values (deg / mm) per axis name for M x dof model joint values."""
    return profile.to_axes(np.asarray(q, float), robot)


def model_joints(profile, robot, values: dict[str, np.ndarray]) -> np.ndarray:
    """M x dof model joint values (rad / mm) from controller axis values per axis name; NaN
    for the joints whose axis is missing or NaN (e.g. left to the controller's IK)."""
    n = len(next(iter(values.values()))) if values else 0
    q = np.full((n, robot.dof), np.nan)
    for a in profile.axes:
        if a.axis not in values:
            continue
        i = robot.joint_names.index(a.joint)
        x = (np.asarray(values[a.axis], float) - a.offset) / a.sign
        q[:, i] = x if robot.prismatic[i] else np.radians(x)
    return q


def wobj_frame(profile) -> np.ndarray:
    """The profile's work object (4 x 4, mm) in the robot base frame."""
    return matrix_from_xyz_rpy(profile.wobj["xyz_mm"], profile.wobj["rpy_deg"])


def controller_pose(profile, P: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """TCP positions (S, 3) and rotations (S, 3, 3) in the robot base frame -> the target
    poses a program states, in the profile's work object."""
    W = invert(wobj_frame(profile))
    return np.asarray(P, float) @ W[:3, :3].T + W[:3, 3], W[:3, :3][None] @ np.asarray(R, float)


def controller_pose_base(profile, P: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """As ``controller_pose``, for formats whose Cartesian targets are stated in the robot
    base frame (Yaskawa ``///RECTAN`` / ``///BASE`` positions): the TCP pose itself."""
    return np.asarray(P, float), np.asarray(R, float)


def base_pose(frame: np.ndarray, T: np.ndarray) -> np.ndarray:
    """A target pose a program states (4 x 4, mm, in a work object whose frame in the base
    is ``frame``) -> the TCP pose in the robot base frame."""
    return np.asarray(frame, float) @ np.asarray(T, float)
