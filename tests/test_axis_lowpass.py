"""path.axis_lowpass: a row's wobbling tool axes low-passed along it, against the surface's exact normals.

The part is a cylinder (R 100 mm) rastered across its axis at a 5 mm pitch; its tool axes are the exact normals
with a wobble of +-2 deg at every pose (what a faceted or scanned face's smoothed normals keep). Low-passed, they
must come back near the exact normals (the reference, in closed form), turn less between neighbours, and leave the
positions, the run's ends, the leads and the poses outside the mask as they were."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from camtool.path.axis_lowpass import MIN_POSES, AxisLowpassSettings, lowpassed_axes, work_runs
from camtool.path.toolpath import ZONE_CODE, Path

R_MM, PITCH_MM = 100.0, 5.0


def _cylinder_row(wobble_deg: float = 2.0, seed: int = 5) -> tuple[Path, np.ndarray]:
    """(a lead-in, a work row over -60..60 deg of the cylinder, a lead-out; the exact inward normals (n, 3))."""
    ang = np.arange(-60.0, 60.0 + 1e-9, np.degrees(PITCH_MM / R_MM))
    a = np.radians(ang)
    P = np.c_[R_MM * np.sin(a), np.zeros(len(a)), R_MM * np.cos(a)]
    z = -P / R_MM
    x = np.broadcast_to([0.0, 1.0, 0.0], z.shape)
    R = np.stack([x, np.cross(z, x), z], axis=2)
    rng = np.random.default_rng(seed)
    wob = Rotation.from_rotvec(np.c_[rng.uniform(-1, 1, len(a)), np.zeros(len(a)), np.zeros(len(a))]
                               * np.radians(wobble_deg))
    T = np.broadcast_to(np.eye(4), (len(a) + 2, 4, 4)).copy()
    T[1:-1, :3, :3] = (Rotation.from_matrix(R) * wob).as_matrix()
    T[1:-1, :3, 3] = P
    T[0], T[-1] = T[1], T[-2]
    T[0, :3, 3] -= 10.0 * z[0]
    T[-1, :3, 3] -= 10.0 * z[-1]
    zone = np.r_[ZONE_CODE["lead_in"], np.full(len(a), ZONE_CODE["work"]), ZONE_CODE["lead_out"]]
    return Path(T, np.zeros(len(T), int), np.r_[0, np.arange(1, len(a) + 1), 0], zone, pitch_mm=PITCH_MM), z


def _angles_deg(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", u, v), -1.0, 1.0)))


def test_wobbling_axes_come_back_to_the_normals():
    path, normal = _cylinder_row()
    out = lowpassed_axes(path, np.ones(len(path), bool), AxisLowpassSettings(sigma_mm=10.0))
    w = np.flatnonzero(path.zone == ZONE_CODE["work"])
    before = _angles_deg(path.poses_mm[w, :3, 2], normal)
    after = _angles_deg(out.poses_mm[w, :3, 2], normal)
    inner = slice(6, -6)    # 30 mm from the run's ends: the full window (nearer the ends it narrows)
    rms = [np.sqrt(np.mean(x[inner] ** 2)) for x in (before, after)]
    assert rms[1] < 0.45 * rms[0]     # a Gaussian of 2 poses' sigma averages ~7 independent wobbles: 1 / sqrt(7)
    even = np.degrees(PITCH_MM / R_MM)   # the exact normals turn this much a step
    turn = [np.abs(_angles_deg(P[w[:-1], :3, 2], P[w[1:], :3, 2]) - even)[inner].max()
            for P in (path.poses_mm, out.poses_mm)]
    assert turn[1] < 0.25 * turn[0]
    assert np.array_equal(out.poses_mm[:, :3, 3], path.poses_mm[:, :3, 3])
    for k in (0, 1, -2, -1):   # the leads and the run's ends keep their poses
        assert np.array_equal(out.poses_mm[k], path.poses_mm[k])
    for R in out.poses_mm[:, :3, :3]:
        assert np.allclose(R.T @ R, np.eye(3), atol=1e-12) and np.isclose(np.linalg.det(R), 1.0)


def test_a_smooth_row_keeps_its_axes():
    path, normal = _cylinder_row(wobble_deg=0.0)
    out = lowpassed_axes(path, np.ones(len(path), bool), AxisLowpassSettings(sigma_mm=10.0))
    w = path.zone == ZONE_CODE["work"]
    # a normal turning evenly along the row: every window is symmetric (narrowed at the ends), so each mean is the
    # middle one up to the turn's curvature; a one-sided window at the ends would pull them ~1 deg inwards
    assert _angles_deg(out.poses_mm[w, :3, 2], normal).max() < 0.05


def test_poses_outside_the_mask_and_short_runs_stay():
    path, _ = _cylinder_row()
    mask = np.zeros(len(path), bool)
    assert lowpassed_axes(path, mask, AxisLowpassSettings()) is path
    mask[1:MIN_POSES] = True     # a run of MIN_POSES - 1 poses
    assert lowpassed_axes(path, mask, AxisLowpassSettings()) is path


def test_work_runs_split_at_segments_faces_and_masks():
    path, _ = _cylinder_row()
    seg = path.segment.copy()
    seg[10:] = 1
    face = np.zeros(len(path), int)
    face[15:] = 2
    split = Path(path.poses_mm, seg, path.point, path.zone, pitch_mm=PITCH_MM, face=face)
    mask = np.ones(len(path), bool)
    mask[20] = False
    assert work_runs(split, mask) == [(1, 9), (10, 14), (15, 19), (21, len(path) - 2)]


def test_a_long_run_is_averaged_in_bounded_pieces_as_a_whole():
    """A run longer than ``CHUNK`` poses is averaged piece by piece over the poses within the weights' reach: the same
    orientations as one dense matrix of Gaussian weights over the whole run (its far weights are 0.0 in float64)."""
    from camtool.path import axis_lowpass

    rng = np.random.default_rng(3)
    n = 3 * axis_lowpass.CHUNK + 17
    s_mm = np.cumsum(rng.uniform(0.5, 5.0, n)) - 1.0
    q = Rotation.from_rotvec(rng.normal(0.0, 0.03, (n, 3))).as_quat()
    sigma = 10.0
    sig = np.minimum(sigma, np.minimum(s_mm - s_mm[0], s_mm[-1] - s_mm) / 3.0)
    dense = q.copy()
    on = sig > 0
    W = np.exp(-0.5 * ((s_mm[None, :] - s_mm[on, None]) / sig[on, None]) ** 2)
    dense[on] = W @ q / W.sum(axis=1)[:, None]
    np.testing.assert_allclose(axis_lowpass._smoothed(q, s_mm, sigma), dense, rtol=0, atol=1e-15)


def test_a_run_of_a_hundred_thousand_poses_fits_in_memory():
    """A 100 000-pose run (one dense matrix of its weights: 80 GB) is averaged within a few MB, and an axis that
    turns evenly along it keeps its poses (the symmetric window)."""
    n = 100_000
    s_mm = np.arange(n, dtype=float)
    q = Rotation.from_rotvec(np.outer(np.linspace(0.0, 0.5, n), [0.0, 1.0, 0.0])).as_quat()
    from camtool.path.axis_lowpass import _smoothed

    out = _smoothed(q, s_mm, 10.0)
    out /= np.linalg.norm(out, axis=1)[:, None]
    err_rad = (Rotation.from_quat(out) * Rotation.from_quat(q).inv()).magnitude()
    assert err_rad[100:-100].max() < 1e-9                   # 10 sigmas of poses on both sides: a symmetric window
    assert err_rad.max() < np.radians(0.05)                 # narrowed to the ends (test_a_smooth_row_keeps_its_axes)
