"""Building blocks of the closed-form IK solvers (``ik_spherical_wrist``, ``ik_srs``).

``Chain`` reads a Robot's joint placements from its Pinocchio model (every
joint a pure RZ or PZ about its local z axis, as ``robots/dh.py`` builds them),
so the solvers work from the robot's own DH table for either convention.
Lengths are mm, angles rad.
"""
from __future__ import annotations

import numpy as np

from ..errors import BadInput
from .dh import MM_TO_M
from .model import Robot

TWO_PI = 2.0 * np.pi


def rz(q: float) -> np.ndarray:
    """3x3 rotation about z."""
    c, s = np.cos(q), np.sin(q)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_axis(u: np.ndarray, angle: float) -> np.ndarray:
    """3x3 rotation by ``angle`` about the unit vector ``u`` (Rodrigues)."""
    K = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)


def wrap_pi(q):
    """Angles wrapped into (-pi, pi]."""
    return np.pi - np.mod(np.pi - np.asarray(q, float), TWO_PI)


def sinusoid_roots(kc: float, ks: float, k0: float, value: float, tol: float = 1e-9):
    """Roots x of ``kc cos x + ks sin x + k0 = value``: (x_plus, x_minus, margin).

    ``x_plus = phi + acos(c)``, ``x_minus = phi - acos(c)`` with
    ``phi = atan2(ks, kc)``; ``margin = 1 - |c|`` (negative: no real root).
    Returns None if the sinusoid is constant.
    """
    r = np.hypot(kc, ks)
    if r < 1e-12:
        return None
    c = (value - k0) / r
    margin = 1.0 - abs(c)
    if margin < -tol:
        return None, None, margin
    a = np.arccos(np.clip(c, -1.0, 1.0))
    phi = np.arctan2(ks, kc)
    return phi + a, phi - a, margin


def axis_intersection(points: list[np.ndarray], dirs: list[np.ndarray]) -> tuple[np.ndarray, float]:
    """Least-squares common point of lines (point, unit direction); returns (point, worst distance mm)."""
    A = np.zeros((3, 3))
    b = np.zeros(3)
    for p, d in zip(points, dirs):
        P = np.eye(3) - np.outer(d, d)
        A += P
        b += P @ p
    if np.linalg.cond(A) > 1e12:
        return np.full(3, np.nan), np.inf
    x = np.linalg.solve(A, b)
    worst = max(np.linalg.norm((np.eye(3) - np.outer(d, d)) @ (x - p)) for p, d in zip(points, dirs))
    return x, float(worst)


class Chain:
    """A Robot's kinematic chain as plain 4x4 matrices (mm), for closed-form IK.

    ``P[i]`` places joint i in the frame of joint i-1 (after its motion);
    ``flange`` places the flange in the last joint's frame.
    """

    def __init__(self, robot: Robot):
        m = robot.model
        self.robot = robot
        self.n = robot.dof
        self.P = []
        for i in range(1, m.njoints):
            kind = m.joints[i].shortname()
            if kind not in ("JointModelRZ", "JointModelPZ"):
                raise BadInput(f"robot {robot.name}: joint {robot.joint_names[i - 1]} is a {kind}; "
                               "closed-form IK needs a DH chain (revolute/prismatic about local z)")
            self.P.append(self._mat(m.jointPlacements[i]))
        frame = m.frames[robot.flange_frame_id]
        if frame.parentJoint != m.njoints - 1:
            raise BadInput(f"robot {robot.name}: the flange is not on the last joint")
        self.flange = self._mat(frame.placement)

    @staticmethod
    def _mat(se3) -> np.ndarray:
        T = np.eye(4)
        T[:3, :3] = se3.rotation
        T[:3, 3] = se3.translation / MM_TO_M
        return T

    def motion(self, i: int, q: float) -> np.ndarray:
        """4x4 motion of joint i at value q (rad or mm)."""
        T = np.eye(4)
        if self.robot.prismatic[i]:
            T[2, 3] = q
        else:
            T[:3, :3] = rz(q)
        return T

    def frames(self, q) -> list[np.ndarray]:
        """Base-frame pose of every joint frame after its motion, then the flange."""
        out, T = [], np.eye(4)
        for i in range(self.n):
            T = T @ self.P[i] @ self.motion(i, q[i])
            out.append(T)
        out.append(T @ self.flange)
        return out

    def frames_many(self, Q) -> np.ndarray:
        """``frames`` of every row of Q (K, dof): (K, dof + 1, 4, 4), the same products in the same order."""
        Q = np.asarray(Q, float).reshape(-1, self.n)
        K = len(Q)
        out = np.empty((K, self.n + 1, 4, 4))
        T = np.broadcast_to(np.eye(4), (K, 4, 4))
        M = np.zeros((K, 4, 4))
        M[:, 3, 3] = 1.0
        for i in range(self.n):
            M[:, :3, :3] = 0.0
            M[:, :3, 3] = 0.0
            if self.robot.prismatic[i]:
                M[:, 0, 0] = M[:, 1, 1] = M[:, 2, 2] = 1.0
                M[:, 2, 3] = Q[:, i]
            else:
                c, s = np.cos(Q[:, i]), np.sin(Q[:, i])
                M[:, 0, 0], M[:, 0, 1], M[:, 1, 0], M[:, 1, 1], M[:, 2, 2] = c, -s, s, c, 1.0
            T = T @ self.P[i] @ M
            out[:, i] = T
        out[:, self.n] = T @ self.flange
        return out

    def fk(self, q) -> np.ndarray:
        return self.frames(q)[-1]

    def axes(self, q) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Base-frame origin and unit direction of every joint axis at q."""
        pts, dirs, T = [], [], np.eye(4)
        for i in range(self.n):
            B = T @ self.P[i]
            pts.append(B[:3, 3].copy())
            dirs.append(B[:3, 2].copy())
            T = B @ self.motion(i, q[i])
        return pts, dirs


def spherical_group(M: np.ndarray, A: np.ndarray, B: np.ndarray, singular_tol: float = 1e-9):
    """Solve ``M = Rz(x1) A Rz(x2) B Rz(x3)`` (3x3 rotations): two branches.

    Returns [(x1, x2, x3, gamma), ...] with gamma = +1 for the branch
    ``x2 = phi + acos(.)`` and -1 for ``phi - acos(.)``. At a singular middle
    joint (first and last axes aligned) x1 is set to 0 and x3 takes the sum.
    """
    u = M[:, 2]
    b = B[:, 2]
    a = A[2, :]  # z row of A: (A Rz(x2) b)_z = a . Rz(x2) b
    roots = sinusoid_roots(a[0] * b[0] + a[1] * b[1], a[1] * b[0] - a[0] * b[1], a[2] * b[2], u[2], tol=1e-7)
    if roots is None or roots[0] is None:
        return []
    out = []
    for x2, gamma in ((roots[0], 1), (roots[1], -1)):
        v = A @ rz(x2) @ b
        if np.hypot(v[0], v[1]) < singular_tol or np.hypot(u[0], u[1]) < singular_tol:
            x1 = 0.0
        else:
            x1 = np.arctan2(u[1], u[0]) - np.arctan2(v[1], v[0])
        R3 = (rz(x1) @ A @ rz(x2) @ B).T @ M
        x3 = np.arctan2(R3[1, 0], R3[0, 0])
        out.append((float(wrap_pi(x1)), float(wrap_pi(x2)), float(wrap_pi(x3)), gamma))
    return out


def limit_equivalents(q: np.ndarray, lower: np.ndarray, upper: np.ndarray, revolute: np.ndarray,
                      tol: float = 1e-9) -> list[list[float]] | None:
    """Per joint, every 2*pi-equivalent of q inside the limits; None if a joint has none."""
    out = []
    for x, lo, hi, rev in zip(q, lower, upper, revolute):
        if not rev:
            if lo - tol <= x <= hi + tol:
                out.append([float(x)])
                continue
            return None
        k0 = int(np.ceil((lo - tol - x) / TWO_PI))
        k1 = int(np.floor((hi + tol - x) / TWO_PI))
        vals = [float(x + k * TWO_PI) for k in range(k0, k1 + 1)]
        if not vals:
            return None
        out.append(vals)
    return out


def nearest_equivalent(q: np.ndarray, q_ref: np.ndarray, lower, upper, revolute) -> np.ndarray | None:
    """The 2*pi-equivalent of q inside the limits nearest to q_ref, or None if there is none."""
    eq = limit_equivalents(q, lower, upper, revolute)
    if eq is None:
        return None
    return np.array([min(vals, key=lambda v: abs(v - r)) for vals, r in zip(eq, q_ref)])


def rz_batch(q: np.ndarray) -> np.ndarray:
    """(K, 3, 3) rotations about z."""
    c, s = np.cos(q), np.sin(q)
    R = np.zeros((len(q), 3, 3))
    R[:, 0, 0] = c
    R[:, 0, 1] = -s
    R[:, 1, 0] = s
    R[:, 1, 1] = c
    R[:, 2, 2] = 1.0
    return R


def rot_axis_batch(u: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(K, 3, 3) Rodrigues rotations by ``angle[k]`` about unit ``u[k]``."""
    K = np.zeros((len(u), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -u[:, 2], u[:, 1], -u[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = u[:, 2], -u[:, 1], u[:, 0]
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * K + (1.0 - c) * (K @ K)


def spherical_group_batch(M: np.ndarray, A: np.ndarray, B: np.ndarray, gamma: int,
                          singular_tol: float = 1e-9) -> np.ndarray:
    """``spherical_group`` for a stack of rotations M (K, 3, 3), one branch: (K, 3) angles.

    Rows with no real root are NaN.
    """
    u = M[:, :, 2]
    b = B[:, 2]
    a = A[2, :]
    kc, ks, k0 = a[0] * b[0] + a[1] * b[1], a[1] * b[0] - a[0] * b[1], a[2] * b[2]
    r = np.hypot(kc, ks)
    c = (u[:, 2] - k0) / r
    bad = np.abs(c) > 1.0 + 1e-7
    x2 = np.arctan2(ks, kc) + gamma * np.arccos(np.clip(c, -1.0, 1.0))
    v = np.einsum("ij,kjl,l->ki", A, rz_batch(x2), b)
    sing = (np.hypot(v[:, 0], v[:, 1]) < singular_tol) | (np.hypot(u[:, 0], u[:, 1]) < singular_tol)
    x1 = np.where(sing, 0.0, np.arctan2(u[:, 1], u[:, 0]) - np.arctan2(v[:, 1], v[:, 0]))
    R = rz_batch(x1) @ A @ rz_batch(x2) @ B
    R3 = np.transpose(R, (0, 2, 1)) @ M
    x3 = np.arctan2(R3[:, 1, 0], R3[:, 0, 0])
    out = wrap_pi(np.column_stack([x1, x2, x3]))
    out[bad] = np.nan
    return out
