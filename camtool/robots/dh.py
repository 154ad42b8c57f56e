"""Denavit-Hartenberg tables and their conversion to Pinocchio models.

Both conventions are supported; each row gives a, alpha, d, theta for one joint
(lengths in mm, angles in rad; ``theta`` or ``d`` is the constant offset added
to the joint variable).

- modified (Craig): ``T_i = RotX(alpha_{i-1}) TransX(a_{i-1}) RotZ(theta_i) TransZ(d_i)``
  where the row i holds alpha_{i-1} and a_{i-1}.
- standard: ``T_i = RotZ(theta_i) TransZ(d_i) TransX(a_i) RotX(alpha_i)``.

The joint moves about (revolute) or along (prismatic) the local z axis.
Pinocchio works in metres: **this module is the one place where mm become m**
(``MM_TO_M``); everything camtool shows stays in mm.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

MM_TO_M = 1e-3
# Longer than this (mm, 1 km) is not a robot's length but a typo or a unit slip; the
# loaders (library.py, urdf.py) reject such lengths with BadInput before a model is built.
MAX_LENGTH_MM = 1e6


@dataclass(frozen=True)
class DHRow:
    """One joint's DH parameters: a_mm, alpha_rad, d_mm, theta_rad (offsets)."""

    a_mm: float
    alpha_rad: float
    d_mm: float
    theta_rad: float
    prismatic: bool = False


def rot_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    T = np.eye(4)
    T[1:3, 1:3] = [[c, -s], [s, c]]
    return T


def rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    T = np.eye(4)
    T[0:2, 0:2] = [[c, -s], [s, c]]
    return T


def trans(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def _se3_m(T_mm: np.ndarray) -> pin.SE3:
    return pin.SE3(T_mm[:3, :3].copy(), T_mm[:3, 3] * MM_TO_M)


def build_pinocchio_model(rows: list[DHRow], convention: str, flange_T_mm: np.ndarray,
                          joint_names: list[str], name: str) -> tuple[pin.Model, int]:
    """Build a Pinocchio model from DH rows; returns (model, flange frame id).

    The constant part of each row is split around the joint so that the joint
    itself is a pure RZ or PZ: modified rows put RotX TransX RotZ(theta0) before
    the joint and TransZ(d0) after it; standard rows put RotZ(theta0) TransZ(d0)
    TransX(a) RotX(alpha) after it. Prismatic rows carry theta as the constant
    rotation and d as the offset of the joint variable.
    """
    values = np.array([[r.a_mm, r.alpha_rad, r.d_mm, r.theta_rad] for r in rows], dtype=float).reshape(-1, 4)
    if not (np.isfinite(values).all() and np.isfinite(flange_T_mm).all()):
        raise ValueError(f"{name}: DH table or flange with NaN or infinite values")  # the loaders check first
    model = pin.Model()
    model.name = name
    parent = 0
    pending = np.eye(4)  # constant transform carried into the next joint placement
    for row, jname in zip(rows, joint_names):
        if convention == "modified":
            before = pending @ rot_x(row.alpha_rad) @ trans(x=row.a_mm) @ rot_z(row.theta_rad)
            after = trans(z=row.d_mm)
        else:
            before = pending
            after = rot_z(row.theta_rad) @ trans(z=row.d_mm) @ trans(x=row.a_mm) @ rot_x(row.alpha_rad)
        joint = pin.JointModelPZ() if row.prismatic else pin.JointModelRZ()
        parent = model.addJoint(parent, joint, _se3_m(before), jname)
        model.appendBodyToJoint(parent, pin.Inertia(1.0, np.zeros(3), np.eye(3) * 1e-3), pin.SE3.Identity())
        pending = after
    flange = pending @ flange_T_mm
    fid = model.addFrame(pin.Frame("flange", parent, 0, _se3_m(flange), pin.FrameType.OP_FRAME))
    return model, fid


