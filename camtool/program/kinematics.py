"""Batch TCP poses, Jacobians, dexterity and arm configuration of a robot (base frame, mm).

The program steps (merging, blending, arcs) and the writers' confdata use it. It runs on
the robot's own chain data (``Robot.chain``); robots whose model is no z-axis chain fall
back to ``camtool.motion.BatchFK`` / finite differences.
"""
from __future__ import annotations

import numpy as np


def weighted_sum(w, cols):
    """sum_j w[j] cols[j] for a constant vector w (mostly 0 and +-1 in a DH chain): zero terms skipped,
    unit ones taken as they are."""
    out = None
    for c, col in zip(w, cols):
        if abs(c) < 1e-15:
            continue
        term = col if c == 1.0 else (-col if c == -1.0 else col * c)
        out = term if out is None else out + term
    return np.zeros_like(cols[0]) if out is None else out


def walk_chain(chain, tool_T: np.ndarray, prismatic: np.ndarray, q: np.ndarray, axes=None, origins=None):
    """TCP positions (S, 3) and rotations (S, 3, 3) of a z-axis chain (``Robot.chain``: the placement
    before each joint and the flange) with ``tool_T``, in the frame the chain starts in (mm). The rotation
    is carried as its three columns, so each step is a few contiguous products. Given ``axes`` and
    ``origins`` (S, n, 3), each joint's axis and origin are stored there on the way."""
    before_list, flange = chain
    S = len(q)
    x, y, z = (np.zeros((S, 3)) for _ in range(3))
    x[:, 0] = y[:, 1] = z[:, 2] = 1.0
    p = np.zeros((S, 3))
    for i, before in enumerate(before_list):
        if np.any(before[:3, 3]):
            p = p + weighted_sum(before[:3, 3], (x, y, z))
        x, y, z = (weighted_sum(before[:3, j], (x, y, z)) for j in range(3))
        if axes is not None:
            axes[:, i] = z
        if prismatic[i]:
            p = p + z * q[:, i, None]
        else:
            c, s = np.cos(q[:, i])[:, None], np.sin(q[:, i])[:, None]
            x, y = c * x + s * y, c * y - s * x
        if origins is not None:
            origins[:, i] = p
    for v, C in ((flange[:3, 3], flange[:3, :3]), (tool_T[:3, 3], tool_T[:3, :3])):
        if np.any(v):
            p = p + weighted_sum(v, (x, y, z))
        x, y, z = (weighted_sum(C[:, j], (x, y, z)) for j in range(3))
    return p, np.stack([x, y, z], axis=2)

class Kinematics:
    """Batch TCP poses and translational Jacobians of a robot in its **base** frame (mm).

    DH robots use ``camtool.motion.BatchFK``'s chain with the joint axes collected on
    the way (one pass); other robots fall back to Pinocchio (slow, correct).
    """

    def __init__(self, robot):
        from camtool.motion.fk_batch import BatchFK

        self.robot = robot
        self.bfk = BatchFK(robot)  # for robots whose model is no z-axis chain
        self.dof = robot.dof
        self.prismatic = np.asarray(robot.prismatic, bool)
        base = np.asarray(robot.base_T_mm, float)
        self._inv_base_R = base[:3, :3].T
        self._base_p = base[:3, 3]
        chain = robot.chain
        self.uses_chain = chain is not None
        if chain is not None:
            self._chain = chain
            self._before, self._flange = chain
            tool = np.asarray(robot.tool_T_mm, float)
            self._tool_T = tool
            self._tool_R, self._tool_p = tool[:3, :3], tool[:3, 3]

    def _to_base(self, p, R):
        return (p - self._base_p) @ self._inv_base_R.T, self._inv_base_R @ R

    def pose(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """TCP positions (S, 3) and rotations (S, 3, 3) in the base frame."""
        q = np.asarray(q, float)
        if not self.uses_chain:
            fk = self.bfk(q)
            return self._to_base(fk.tcp, fk.tcp_R)
        return walk_chain(self._chain, self._tool_T, self.prismatic, q)  # the chain starts at the base frame

    def chain(self, q: np.ndarray):
        """(tcp (S, 3), tcp_R (S, 3, 3), origins (S, dof, 3), axes (S, dof, 3)) in the **world**
        frame for a z-axis chain: joint i turns about (slides along) ``axes[:, i]`` through
        ``origins[:, i]``."""
        q = np.asarray(q, float)
        b = self
        S = len(q)
        R = np.broadcast_to(self._inv_base_R.T, (S, 3, 3)).copy()
        p = np.broadcast_to(self._base_p, (S, 3)).copy()
        axes = np.empty((S, self.dof, 3))
        origins = np.empty((S, self.dof, 3))
        for i, before in enumerate(b._before):
            p += R @ before[:3, 3]
            R = R @ before[:3, :3]
            axes[:, i] = R[:, :, 2]
            if self.prismatic[i]:
                p += R[:, :, 2] * q[:, i, None]
            else:
                c, s = np.cos(q[:, i, None]), np.sin(q[:, i, None])
                x, y = R[:, :, 0].copy(), R[:, :, 1].copy()
                R[:, :, 0] = c * x + s * y
                R[:, :, 1] = c * y - s * x
            origins[:, i] = p
        flange_p = p + R @ b._flange[:3, 3]
        flange_R = R @ b._flange[:3, :3]
        return flange_p + flange_R @ b._tool_p, flange_R @ b._tool_R, origins, axes

    def pose_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(positions (S, 3), rotations (S, 3, 3), translational Jacobian (S, 3, dof)), base frame;
        Jacobian columns in mm per rad (revolute) or mm per mm (prismatic)."""
        q = np.asarray(q, float)
        if not self.uses_chain:
            p, R = self.pose(q)
            J = np.empty((len(q), 3, self.dof))
            for i in range(self.dof):
                h = 1e-6 if not self.prismatic[i] else 1e-3
                dq = q.copy()
                dq[:, i] += h
                J[:, :, i] = (self.pose(dq)[0] - p) / h
            return p, R, J
        tcp, tcp_R, origins, axes = self.chain(q)
        lever = tcp[:, None, :] - origins
        cols = np.where(self.prismatic[None, :, None], axes, np.cross(axes, lever))
        J = np.einsum("ij,sjk->sik", self._inv_base_R, np.transpose(cols, (0, 2, 1)))
        pb, Rb = self._to_base(tcp, tcp_R)
        return pb, Rb, J

    def jacobian6(self, q: np.ndarray) -> np.ndarray:
        """(S, 6, dof) TCP Jacobian in the base frame: rows 0-2 the TCP's velocity (mm per rad or
        mm per mm), rows 3-5 its angular velocity (rad per rad; 0 for prismatic joints)."""
        q = np.asarray(q, float)
        if not self.uses_chain:  # no z-axis chain: by finite differences of the pose
            from scipy.spatial.transform import Rotation

            p, R = self.pose(q)
            J = np.empty((len(q), 6, self.dof))
            for i in range(self.dof):
                h = 1e-3 if self.prismatic[i] else 1e-6
                dq = q.copy()
                dq[:, i] += h
                p2, R2 = self.pose(dq)
                J[:, :3, i] = (p2 - p) / h
                J[:, 3:, i] = Rotation.from_matrix(R2 @ np.transpose(R, (0, 2, 1))).as_rotvec() / h
            return J
        tcp, _tR, origins, axes = self.chain(q)
        lin = np.where(self.prismatic[None, :, None], axes, np.cross(axes, tcp[:, None, :] - origins))
        ang = np.where(self.prismatic[None, :, None], 0.0, axes)
        J = np.concatenate([np.transpose(lin, (0, 2, 1)), np.transpose(ang, (0, 2, 1))], axis=1)
        return np.concatenate([self._inv_base_R @ J[:, :3], self._inv_base_R @ J[:, 3:]], axis=1)

    def dexterity(self, q: np.ndarray, lever_mm: float = 500.0) -> np.ndarray:
        """(S,) smallest over largest singular value of the 6 x n TCP Jacobian (angular rows
        times ``lever_mm``): near 0 at a singularity, where a straight TCP line can need
        unbounded joint speeds."""
        q = np.asarray(q, float)
        if not self.uses_chain:
            return np.ones(len(q))
        tcp, _tR, origins, axes = self.chain(q)
        lin = np.where(self.prismatic[None, :, None], axes, np.cross(axes, tcp[:, None, :] - origins))
        ang = np.where(self.prismatic[None, :, None], 0.0, axes) * lever_mm
        J = np.concatenate([np.transpose(lin, (0, 2, 1)), np.transpose(ang, (0, 2, 1))], axis=1)
        sv = np.linalg.svd(J, compute_uv=False)
        k = min(6, J.shape[2])
        return sv[:, k - 1] / np.maximum(sv[:, 0], 1e-12)

    def arm_configuration(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(rear, lower_arm) per configuration of a 6R arm with a spherical wrist (bool arrays):

        - ``rear``: the wrist centre (on the last axis, nearest the 4th) lies behind
          axis 1, seen from axis 2 (the side the arm reaches to at its zero position);
        - ``lower_arm``: the wrist centre lies on the other side of the line from axis 2
          to axis 3 than at the zero position (elbow down / backward).
        """
        q = np.asarray(q, float)
        _t, _R, o, z = self.chain(q)
        _t0, _R0, o0, z0 = self.chain(np.zeros((1, self.dof)))

        def wrist(o, z):
            # point on axis 6 closest to axis 4
            p4, d4, p6, d6 = o[:, 3], z[:, 3], o[:, 5], z[:, 5]
            w = p6 - p4
            b_ = np.einsum("si,si->s", d4, d6)
            d = np.einsum("si,si->s", d4, w)
            e = np.einsum("si,si->s", d6, w)
            den = 1 - b_ * b_
            t6 = np.where(np.abs(den) > 1e-9, (b_ * d - e) / np.where(np.abs(den) > 1e-9, den, 1), 0.0)
            return p6 + t6[:, None] * d6

        def sides(o, z, wc):
            a1 = z[:, 0]
            reach = o[:, 1] - o[:, 0]
            reach = reach - np.einsum("si,si->s", reach, a1)[:, None] * a1
            n = np.linalg.norm(reach, axis=1, keepdims=True)
            reach = np.where(n > 1e-9, reach / np.maximum(n, 1e-12), 0.0)
            rel = wc - o[:, 0]
            front = np.einsum("si,si->s", rel, reach)
            elbow = np.einsum("si,si->s", np.cross(o[:, 2] - o[:, 1], wc - o[:, 1]), z[:, 1])
            return front, elbow

        wc = wrist(o, z)
        front, elbow = sides(o, z, wc)
        # "behind axis 1" in the frame the arm turns with: compare with the reach direction of
        # the zero configuration turned by joint 1, i.e. the configuration's own axis-2 offset
        _f0, elbow0 = sides(o0, z0, wrist(o0, z0))
        rear = front < 0
        lower = np.sign(elbow) != np.sign(elbow0[0] if elbow0[0] != 0 else 1.0)
        return rear, lower
