"""Rigid transforms: 4x4 homogeneous matrices in mm, quaternions as (w, x, y, z).

Conventions, written down once:
- A pose ``T`` is a 4x4 matrix mapping child-frame coordinates to the parent
  frame; translations are in mm.
- Quaternions are scalar-first (w, x, y, z) everywhere camtool shows them.
- ``rpy_deg`` is roll, pitch, yaw about fixed x, y, z axes (extrinsic XYZ), in
  degrees, as in URDF.
"""
import numpy as np


def matrix_from_xyz_rpy(xyz_mm, rpy_deg) -> np.ndarray:
    """4x4 pose from a translation in mm and fixed-axis roll/pitch/yaw in degrees."""
    T = np.eye(4)
    from scipy.spatial.transform import Rotation  # here: scipy.spatial costs ~0.3 s of start-up

    T[:3, :3] = Rotation.from_euler("xyz", rpy_deg, degrees=True).as_matrix()
    T[:3, 3] = xyz_mm
    return T


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
