"""Configuration data from the controller's joint values: ABB confdata and Yaskawa ``///RCONF``.

Both are computed from the controller's axis values (``robot.conventions``), so
directions, zero offsets and the IRB2400's coupled axis 3 are those the controller uses.
Axes are named by their place in the controller's order: axis 1..6 are ABB's rax_1..rax_6
and Yaskawa's S, L, U, R, B, T.

- **ABB** (RAPID reference, "confdata"): cf1, cf4, cf6 are the quadrants of axes 1, 4
  and 6, ``floor(angle / 90 deg)`` (negative below 0); cfx = 4 * (wrist centre behind
  axis 1) + 2 * (wrist centre behind the lower arm) + (axis 5 < 0), ABB's table of the
  8 arm and wrist configurations.
- **Yaskawa** ``///RCONF`` (flip, lower arm, rear, R >= 180, T >= 180, S >= 180, then
  zeros): flip = B < 0 and the field order are *unverified* (no public Yaskawa manual
  found); the 180-degree fields use the controller's R, T and S.

The geometry: the wrist centre is the point of axis 6 nearest axis 4; "behind axis 1" is
the far side of axis 1 from where the wrist centre is at the zero configuration, in the
frame axis 1 turns; "behind the lower arm" the other side of the line from axis 2 to
axis 3 than at the zero configuration (where the arm is straight there, as on the SIA20D,
than with axis 3 at +90 deg).
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from .dh import MM_TO_M
from .model import Robot


def _axes(robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Origins (M, n, 3) mm, unit axes (M, n, 3) and joint rotations (M, n, 3, 3), model joint order."""
    model = robot.model
    data = model.createData()
    scale = np.where(robot.prismatic, MM_TO_M, 1.0)
    M, n = len(q), robot.dof
    o, z, R = np.empty((M, n, 3)), np.empty((M, n, 3)), np.empty((M, n, 3, 3))
    for k in range(M):
        pin.forwardKinematics(model, data, q[k] * scale)
        for j in range(n):
            T = data.oMi[j + 1]
            o[k, j], z[k, j], R[k, j] = T.translation / MM_TO_M, T.rotation[:, 2], T.rotation
    return o, z, R


def _wrist_centre(o4, z4, o6, z6) -> np.ndarray:
    """Points (M, 3) on axis 6 nearest axis 4."""
    w = o6 - o4
    b = np.einsum("si,si->s", z4, z6)
    d = np.einsum("si,si->s", z4, w)
    e = np.einsum("si,si->s", z6, w)
    den = 1.0 - b * b
    ok = np.abs(den) > 1e-9
    t6 = np.where(ok, (b * d - e) / np.where(ok, den, 1.0), 0.0)
    return o6 + t6[:, None] * z6


def arm_sides(robot: Robot, q_model: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(behind_axis1, behind_lower_arm) booleans (M,) of model configurations (see module doc)."""
    q = np.atleast_2d(np.asarray(q_model, float))
    aj = robot.conventions.axis_joints
    if len(aj) < 6:
        raise ValueError(f"{robot.name}: arm configuration needs 6 controller axes, it has {len(aj)}")
    j1, j2, j3, j4, j6 = aj[0], aj[1], aj[2], aj[3], aj[5]

    def sides(qq):
        o, z, R = _axes(robot, qq)
        wc = _wrist_centre(o[:, j4], z[:, j4], o[:, j6], z[:, j6])
        local = np.einsum("sji,sj->si", R[:, j1], wc - o[:, j1])       # wrist centre in axis 1's frame
        elbow = np.einsum("si,si->s", np.cross(o[:, j3] - o[:, j2], wc - o[:, j2]), z[:, j2])
        return local, elbow

    ref = np.zeros((1, robot.dof))
    local0, elbow0 = sides(ref)
    if abs(elbow0[0]) < 1e-6:                     # straight arm at zero: take axis 3 at +90 deg
        ref[0, j3] = np.pi / 2 * np.sign(robot.conventions.matrix[2, j3] or 1.0)
        _l, elbow0 = sides(ref)
    fwd = local0[0, :2]
    if np.linalg.norm(fwd) < 1e-6:                # wrist centre on axis 1 at zero: its frame's x axis
        fwd = np.array([1.0, 0.0])
    local, elbow = sides(q)
    behind1 = local[:, :2] @ fwd < 0
    behind_lower = np.sign(elbow) != np.sign(elbow0[0])
    return behind1, behind_lower


def quadrant(angle_rad: np.ndarray) -> np.ndarray:
    """ABB's quadrant number of an axis angle: floor(angle / 90 deg), as integers."""
    return np.floor(np.asarray(angle_rad, float) / (np.pi / 2) + 1e-12).astype(int)


def abb_confdata(robot: Robot, q_model: np.ndarray) -> np.ndarray:
    """(M, 4) integers [cf1, cf4, cf6, cfx] of model configurations, from the controller's axis values."""
    q = np.atleast_2d(np.asarray(q_model, float))
    qc = robot.conventions.controller_from_model(q)
    behind1, behind_lower = arm_sides(robot, q)
    cfx = 4 * behind1.astype(int) + 2 * behind_lower.astype(int) + (qc[:, 4] < 0).astype(int)
    return np.column_stack([quadrant(qc[:, 0]), quadrant(qc[:, 3]), quadrant(qc[:, 5]), cfx])


def yaskawa_rconf(robot: Robot, q_model: np.ndarray, n_fields: int = 8) -> np.ndarray:
    """(M, n_fields) integers of ``///RCONF`` (see module doc) from the controller's axis values."""
    q = np.atleast_2d(np.asarray(q_model, float))
    qc = robot.conventions.controller_from_model(q)
    behind1, behind_lower = arm_sides(robot, q)
    big = [(np.abs(qc[:, k]) >= np.pi - 1e-12).astype(int) for k in (3, 5, 0)]   # R, T, S >= 180 deg
    rows = np.column_stack([(qc[:, 4] < 0).astype(int), behind_lower.astype(int), behind1.astype(int), *big])
    return np.hstack([rows, np.zeros((len(q), max(0, n_fields - 6)), int)])
