"""Rigid transforms: 4x4 homogeneous matrices in mm, quaternions as (w, x, y, z).

Conventions, written down once:
- A pose ``T`` is a 4x4 matrix mapping child-frame coordinates to the parent
  frame; translations are in mm.
- Quaternions are scalar-first (w, x, y, z) everywhere camtool shows them.
- ``rpy_deg`` is roll, pitch, yaw about fixed x, y, z axes (extrinsic XYZ), in
  degrees, as in URDF.

Roll-pitch-yaw to a matrix is numpy here (bit for bit scipy's Rotation), and the
unrotated frame back to roll-pitch-yaw too: importing scipy.spatial costs ~0.2 s of
start-up, and ``camtool robots`` needs no more than these.
"""
import numpy as np


def _quaternion_product(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product p q of quaternions stored (x, y, z, w), in scipy's order of operations."""
    cross = np.cross(p[:3], q[:3])
    return np.array([p[3] * q[0] + q[3] * p[0] + cross[0],
                     p[3] * q[1] + q[3] * p[1] + cross[1],
                     p[3] * q[2] + q[3] * p[2] + cross[2],
                     p[3] * q[3] - p[0] * q[0] - p[1] * q[1] - p[2] * q[2]])


def rotation_from_rpy(rpy_rad) -> np.ndarray:
    """3x3 rotation of fixed-axis roll, pitch, yaw in rad: R = Rz(yaw) Ry(pitch) Rx(roll), as URDF defines it.

    Evaluated as scipy does, through the quaternion qz qy qx, so it is bit for bit
    ``Rotation.from_euler("xyz", rpy_rad).as_matrix()``.
    """
    qx, qy, qz = np.zeros((3, 4))  # the rotations about x, y and z
    for axis, (q, angle) in enumerate(zip((qx, qy, qz), np.asarray(rpy_rad, float), strict=True)):
        q[axis], q[3] = np.sin(angle / 2.0), np.cos(angle / 2.0)
    x, y, z, w = _quaternion_product(qz, _quaternion_product(qy, qx))
    x2, y2, z2, w2 = x * x, y * y, z * z, w * w
    xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
    return np.array([[x2 - y2 - z2 + w2, 2 * (xy - zw), 2 * (xz + yw)],
                     [2 * (xy + zw), -x2 + y2 - z2 + w2, 2 * (yz - xw)],
                     [2 * (xz - yw), 2 * (yz + xw), -x2 - y2 + z2 + w2]])


def matrix_from_xyz_rpy(xyz_mm, rpy_deg) -> np.ndarray:
    """4x4 pose from a translation in mm and fixed-axis roll/pitch/yaw in degrees."""
    T = np.eye(4)
    T[:3, :3] = rotation_from_rpy(np.deg2rad(np.asarray(rpy_deg, float)))
    T[:3, 3] = xyz_mm
    return T


def rpy_deg_from_matrix(R: np.ndarray) -> np.ndarray:
    """Fixed-axis roll, pitch, yaw in degrees of a rotation (3x3, or a 4x4 pose), as scipy's
    ``Rotation.from_matrix(R).as_euler("xyz", degrees=True)``, its choice at gimbal lock included."""
    R = np.asarray(R, float)[:3, :3]
    if np.array_equal(R, np.eye(3)) and not np.signbit(R).any():  # (scipy's angle for a -0.0 entry can be -0.0)
        return np.zeros(3)  # the unrotated frame, the usual one: no scipy import (start-up time)
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(R).as_euler("xyz", degrees=True)


def quaternion_wxyz_from_matrix(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a 3x3 rotation, with w >= 0."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(R[:3, :3]).as_quat()
    q = np.array([w, x, y, z])
    return -q if q[0] < 0 else q


def invert(T: np.ndarray) -> np.ndarray:
    """Inverse of a rigid 4x4 transform."""
    Ti = np.eye(4)
    Ti[:3, :3] = T[:3, :3].T
    Ti[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return Ti


def rotation_angle_rad(Ra: np.ndarray, Rb: np.ndarray) -> float:
    """Angle in rad of the rotation taking Ra to Rb (0..pi)."""
    R = Ra[:3, :3].T @ Rb[:3, :3]
    s = 0.5 * np.linalg.norm([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    c = (np.trace(R) - 1.0) / 2.0
    return float(np.arctan2(s, c))  # accurate near 0, unlike arccos
