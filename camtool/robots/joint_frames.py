"""The joint frames of a robot (Pinocchio's ``oMi``, mm, in its base frame) for many configurations at once.

Every collision query places the robot's bodies on these frames. Asked of Pinocchio
one configuration at a time they cost about 17 us each in Python, and a plan of the
sample's 11k poses asks 22k times (0.4 s). Pinocchio's Python API has no batched
forward kinematics; a chain of revolute and prismatic joints is a few matrix
products per joint for all configurations at once in numpy. Models with other
joints (spherical, planar, free-flyer, a continuous joint's cos/sin pair) are
asked of Pinocchio one configuration at a time, as before.
"""
from __future__ import annotations

import numpy as np

MM_PER_M = 1000.0
_AXIS = {"X": 0, "Y": 1, "Z": 2}


def joint_frames_mm(robot, q, data=None) -> np.ndarray:
    """(dof, 4, 4) the robot's joint frames after their motion (Pinocchio's oMi), mm, in its base
    frame, at q (rad / mm); ``data`` a Pinocchio data to reuse."""
    import pinocchio as pin

    data = robot.model.createData() if data is None else data
    scale = np.where(np.asarray(robot.prismatic, bool), 1.0 / MM_PER_M, 1.0)
    pin.forwardKinematics(robot.model, data, np.asarray(q, float) * scale)
    F = np.array([data.oMi[j].homogeneous for j in range(1, robot.model.njoints)])
    F[:, :3, 3] *= MM_PER_M
    return F


def _joint(model, j):
    """("R" or "P", unit axis (3,)) of joint j, or None for a kind this module does not compose."""
    name = model.joints[j].shortname()
    for kind, prefix in (("R", "JointModelR"), ("P", "JointModelP")):
        if name in (prefix + "X", prefix + "Y", prefix + "Z"):
            axis = np.zeros(3)
            axis[_AXIS[name[-1]]] = 1.0
            return kind, axis
    if name in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
        axis = np.asarray(model.joints[j].extract().axis, float)
        return ("R" if "Revolute" in name else "P"), axis / np.linalg.norm(axis)
    return None


class JointFrames:
    """``frames(Q)``: (K, dof, 4, 4) joint frames (mm, base frame) of the K configurations Q (rad / mm)."""

    def __init__(self, robot):
        model = robot.model
        self.robot = robot
        joints = [_joint(model, j) for j in range(1, model.njoints)]
        self.batched = model.nq == robot.dof and all(joints) and \
            all(model.joints[j].idx_q == j - 1 for j in range(1, model.njoints))
        self._data = None if self.batched else model.createData()
        self._parent = [int(model.parents[j]) - 1 for j in range(1, model.njoints)]   # -1: the base
        placements = np.array([model.jointPlacements[j].homogeneous for j in range(1, model.njoints)])
        placements[:, :3, 3] *= MM_PER_M
        self._placement = placements
        self._joints = joints

    def __call__(self, Q) -> np.ndarray:
        Q = np.asarray(Q, float).reshape(-1, self.robot.dof)
        if not self.batched:
            return np.array([joint_frames_mm(self.robot, q, self._data) for q in Q]).reshape(
                len(Q), self.robot.dof, 4, 4)
        K, n = len(Q), len(self._joints)
        out = np.empty((K, n, 4, 4))
        for j, ((kind, axis), parent) in enumerate(zip(self._joints, self._parent)):
            local = np.broadcast_to(self._placement[j], (K, 4, 4)) @ _motion(kind, axis, Q[:, j])
            out[:, j] = local if parent < 0 else out[:, parent] @ local
        return out


def _motion(kind: str, axis: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(K, 4, 4) a joint's motion: rotation by q (rad) about ``axis``, or translation by q (mm) along it."""
    M = np.zeros((len(q), 4, 4))
    M[:, 3, 3] = 1.0
    if kind == "P":
        M[:, 0, 0] = M[:, 1, 1] = M[:, 2, 2] = 1.0
        M[:, :3, 3] = q[:, None] * axis
        return M
    c, s = np.cos(q), np.sin(q)
    x, y, z = axis
    C = 1.0 - c   # Rodrigues: R = c I + s [axis]x + (1 - c) axis axis^T
    M[:, 0, 0], M[:, 0, 1], M[:, 0, 2] = c + x * x * C, x * y * C - z * s, x * z * C + y * s
    M[:, 1, 0], M[:, 1, 1], M[:, 1, 2] = y * x * C + z * s, c + y * y * C, y * z * C - x * s
    M[:, 2, 0], M[:, 2, 1], M[:, 2, 2] = z * x * C - y * s, z * y * C + x * s, c + z * z * C
    return M
