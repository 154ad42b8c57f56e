"""camtool.transforms against scipy's Rotation and hand-built rotation matrices."""
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from camtool.transforms import (invert, matrix_from_xyz_rpy, quaternion_wxyz_from_matrix, rotation_angle_rad,
                                rotation_from_rpy, rpy_deg_from_matrix)


def rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def random_pose(rng):
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-2000, 2000, 3)
    return T


@pytest.mark.parametrize("rpy", [(0, 0, 0), (30, 0, 0), (0, -45, 0), (0, 0, 90), (10, 20, 30), (-170, 80, 135)])
def test_matrix_from_xyz_rpy_is_fixed_axis_roll_pitch_yaw(rpy):
    T = matrix_from_xyz_rpy([12.5, -300.0, 4.0], rpy)
    r, p, y = np.radians(rpy)
    # fixed axes x, then y, then z: R = Rz(yaw) Ry(pitch) Rx(roll)
    assert np.allclose(T[:3, :3], rz(y) @ ry(p) @ rx(r), atol=1e-12)
    assert np.allclose(T[:3, :3], Rotation.from_euler("xyz", rpy, degrees=True).as_matrix(), atol=1e-12)
    assert np.array_equal(T[:3, 3], [12.5, -300.0, 4.0])
    assert np.array_equal(T[3], [0, 0, 0, 1])


def _same_bits(a, b):
    return np.array_equal(a, b) and np.array_equal(np.signbit(a), np.signbit(b))


def test_rpy_in_numpy_is_scipy_bit_for_bit():
    # programs stay byte-identical to the scipy version: no last-bit difference, no -0.0 for 0.0
    rng = np.random.default_rng(25)
    angles_deg = np.concatenate([rng.uniform(-180, 180, (2000, 3)), rng.uniform(-1e-6, 1e-6, (200, 3)),
                                 rng.choice([-180.0, -90.0, -45.0, -0.0, 0.0, 30.0, 90.0, 180.0, 270.0], (500, 3))])
    for rpy in angles_deg:
        ref = Rotation.from_euler("xyz", rpy, degrees=True).as_matrix()
        assert _same_bits(matrix_from_xyz_rpy([0, 0, 0], rpy)[:3, :3], ref), rpy
        assert _same_bits(rotation_from_rpy(np.deg2rad(rpy)), ref), rpy
        r, p, y = np.deg2rad(rpy)
        assert np.allclose(rotation_from_rpy([r, p, y]), rz(y) @ ry(p) @ rx(r), rtol=0, atol=1e-15)


def test_rpy_from_a_matrix_is_scipys():
    rng = np.random.default_rng(26)
    frames = [Rotation.random(random_state=rng).as_matrix() for _ in range(200)]
    frames += [matrix_from_xyz_rpy([1, 2, 3], rpy) for rpy in ([0, 0, 0], [0, 90, 0], [0, -90, 30], [180, 0, 180])]
    signed_zeros = np.eye(3)
    signed_zeros[[1, 2], [0, 1]] = -0.0  # scipy's roll is -0.0 here
    frames += [np.eye(3), np.eye(4), signed_zeros]
    for R in frames:
        with warnings.catch_warnings():  # gimbal lock
            warnings.simplefilter("ignore")
            assert _same_bits(rpy_deg_from_matrix(R), Rotation.from_matrix(R[:3, :3]).as_euler("xyz", degrees=True))


def test_matrix_from_xyz_rpy_rotates_a_vector_as_expected():
    # a yaw of 90 deg takes x to y; a pitch of 90 deg takes z to x
    assert np.allclose(matrix_from_xyz_rpy([0, 0, 0], [0, 0, 90])[:3, :3] @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    assert np.allclose(matrix_from_xyz_rpy([0, 0, 0], [0, 90, 0])[:3, :3] @ [0, 0, 1], [1, 0, 0], atol=1e-12)
    # translation applies after rotation (child -> parent)
    T = matrix_from_xyz_rpy([100, 0, 0], [0, 0, 90])
    assert np.allclose(T @ [10, 0, 0, 1], [100, 10, 0, 1], atol=1e-12)


def quat_to_matrix(w, x, y, z):
    """Rotation matrix of a unit quaternion, written out by hand."""
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def test_quaternion_is_scalar_first_unit_with_nonnegative_w():
    rng = np.random.default_rng(3)
    for _ in range(50):
        R = Rotation.random(random_state=rng).as_matrix()
        q = quaternion_wxyz_from_matrix(R)
        assert q.shape == (4,)
        assert q[0] >= 0
        assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-12)
        assert np.allclose(quat_to_matrix(*q), R, atol=1e-10)
        x, y, z, w = Rotation.from_matrix(R).as_quat()
        ref = np.array([w, x, y, z])
        assert np.allclose(q, ref, atol=1e-12) or np.allclose(q, -ref, atol=1e-12)


def test_quaternion_of_known_rotations():
    assert np.allclose(quaternion_wxyz_from_matrix(np.eye(3)), [1, 0, 0, 0])
    h = np.sqrt(0.5)
    assert np.allclose(quaternion_wxyz_from_matrix(rz(np.pi / 2)), [h, 0, 0, h], atol=1e-12)
    # 270 deg about +x is -90 deg: w >= 0 flips the sign of the whole quaternion
    assert np.allclose(quaternion_wxyz_from_matrix(rx(1.5 * np.pi)), [h, -h, 0, 0], atol=1e-12)
    q = quaternion_wxyz_from_matrix(ry(np.pi))  # half turn: w = 0
    assert abs(q[0]) < 1e-12 and abs(abs(q[2]) - 1) < 1e-12


def test_quaternion_accepts_a_4x4_pose():
    T = matrix_from_xyz_rpy([500, 20, -7], [10, 20, 30])
    assert np.allclose(quaternion_wxyz_from_matrix(T), quaternion_wxyz_from_matrix(T[:3, :3]))


def test_invert_is_the_matrix_inverse():
    rng = np.random.default_rng(7)
    for _ in range(20):
        T = random_pose(rng)
        Ti = invert(T)
        assert np.allclose(Ti, np.linalg.inv(T), atol=1e-9)
        assert np.allclose(Ti @ T, np.eye(4), atol=1e-9)
        assert np.allclose(T @ Ti, np.eye(4), atol=1e-9)
        assert np.array_equal(Ti[3], [0, 0, 0, 1])
    T = random_pose(rng)
    before = T.copy()
    invert(T)
    assert np.array_equal(T, before)  # the argument is not changed


def test_invert_maps_a_point_back():
    T = matrix_from_xyz_rpy([100, 200, 300], [0, 0, 90])
    p_child = np.array([10.0, 0, 0, 1])
    p_parent = T @ p_child
    assert np.allclose(p_parent, [100, 210, 300, 1])
    assert np.allclose(invert(T) @ p_parent, p_child, atol=1e-12)


def test_rotation_angle_matches_scipy():
    rng = np.random.default_rng(11)
    for _ in range(50):
        Ra, Rb = Rotation.random(2, random_state=rng)
        ref = (Ra.inv() * Rb).magnitude()
        assert rotation_angle_rad(Ra.as_matrix(), Rb.as_matrix()) == pytest.approx(ref, abs=1e-10)


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-6, 0.3, np.pi / 2, 3.0, np.pi - 1e-6, np.pi])
def test_rotation_angle_over_the_whole_range(angle):
    axis = np.array([1.0, -2.0, 0.5])
    axis /= np.linalg.norm(axis)
    Ra = Rotation.from_euler("xyz", [20, -40, 60], degrees=True).as_matrix()
    Rb = Ra @ Rotation.from_rotvec(angle * axis).as_matrix()
    got = rotation_angle_rad(Ra, Rb)
    assert 0.0 <= got <= np.pi
    assert got == pytest.approx(angle, abs=1e-12 if angle < 1e-3 else 1e-9)
    assert rotation_angle_rad(Rb, Ra) == pytest.approx(got, abs=1e-12)  # symmetric


def test_rotation_angle_small_angles_beat_arccos():
    # arccos((tr - 1) / 2) returns 0 for 1e-9 rad; the atan2 form must resolve it
    Rb = rx(1e-9)
    assert rotation_angle_rad(np.eye(3), Rb) == pytest.approx(1e-9, rel=1e-6)


def test_rotation_angle_accepts_4x4_poses_and_ignores_translation():
    Ta = matrix_from_xyz_rpy([0, 0, 0], [0, 0, 0])
    Tb = matrix_from_xyz_rpy([1000, -500, 3], [0, 0, 25])
    assert rotation_angle_rad(Ta, Tb) == pytest.approx(np.radians(25), abs=1e-12)
    assert isinstance(rotation_angle_rad(Ta, Tb), float)
