"""Tool orientations low-passed along a free-form face's rows: a path modifier (issue #46).

A free-form face's tool axes are its smoothed normals sampled at each pose (``part.freeform_normals``), and the
spin about them follows ``raster.tool_x`` rules. Along a row they still wobble at the scale of the pitch (a CAD
mesh's facets, a scan's bumps), and the time law's joint spline turns that wobble into wrist jerk: j4's jerk set the
work feed of nearly every row of the free-form benchmark parts (``benchmarks/feed_levers.py``: noether's wavy sheet
held a median row bound of 20.7 of 100 mm/s, the bezier ocean 27.9, the dome scan 30.7). Low-passed along the row
over ``sigma_mm`` the same rows bound at 31.3, 35.7 and 46.1 mm/s; low-passing the positions instead (off the
facets) changed nothing. The sag's arc through the tool axes (a scan's, ``plan.sag``) then splits fewer steps too
(the dome: 411 rows -> 21).

Each work run of at least ``MIN_POSES`` consecutive poses on one free-form face gets its orientations (as unit
quaternions, signs aligned along the run) filtered by a Gaussian of ``sigma_mm`` along the row (in poses: the run's
median step) and normalised, its end poses too: the leads that hold an end pose's orientation take its new one
(they meet the run without a turn). Positions, connectors, analytic faces and other leads keep theirs. The Gaussian is scipy's (``gaussian_filter1d``; the run's ends extended by their point reflection);
the quaternion average is written here: for rotations a few degrees apart the normalised mean of aligned quaternions
is the chordal L2 mean (Hartley et al. 2013), which no library applies along a path.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial.transform import Rotation

from .toolpath import WORK, Path

MIN_POSES = 5   # a shorter run keeps its orientations (nothing to average over)


@dataclass(frozen=True)
class AxisLowpassSettings:
    """The Gaussian's sigma along the row (mm)."""

    sigma_mm: float = 10.0


def work_runs(path: Path, mask: np.ndarray) -> list[tuple[int, int]]:
    """[(a, b)] inclusive bounds of each run of at least two consecutive work poses of one segment and one face
    within ``mask``."""
    zone, seg = np.asarray(path.zone), np.asarray(path.segment)
    face = np.zeros(len(zone), int) if path.face is None else np.asarray(path.face)
    on = (zone == WORK) & np.asarray(mask, bool)
    link = np.r_[on[:-1] & on[1:] & (seg[:-1] == seg[1:]) & (face[:-1] == face[1:]), False]
    starts = np.flatnonzero(on & np.r_[True, ~link[:-1]])
    ends = np.flatnonzero(on & ~link)
    return [(int(a), int(b)) for a, b in zip(starts, ends) if b > a]


def lowpassed_axes(path: Path, mask: np.ndarray, settings: AxisLowpassSettings) -> Path:
    """``path`` with the orientations of its work runs within ``mask`` low-passed along them (module doc); the same
    object when no run is long enough."""
    P = np.asarray(path.poses_mm, float)
    out = None
    for a, b in work_runs(path, mask):
        if b + 1 - a < MIN_POSES:
            continue
        step = float(np.median(np.linalg.norm(np.diff(P[a:b + 1, :3, 3], axis=0), axis=1)))
        if step <= 0.0:
            continue
        q = Rotation.from_matrix(P[a:b + 1, :3, :3]).as_quat()
        q *= np.where(np.cumprod(np.sign(np.r_[1.0, np.einsum("ij,ij->i", q[1:], q[:-1])])) < 0, -1.0, 1.0)[:, None]
        q = _smoothed(q, settings.sigma_mm / step)
        out = P.copy() if out is None else out
        out[a:b + 1, :3, :3] = Rotation.from_quat(q / np.linalg.norm(q, axis=1)[:, None]).as_matrix()
        _turn_leads(path, P, out, a, b)
    return path if out is None else replace(path, poses_mm=out)


def _smoothed(q: np.ndarray, sigma: float) -> np.ndarray:
    """(n, 4) the rows of ``q`` Gaussian-filtered (``sigma`` in rows), each end extended by its point reflection
    (2 q_end - q_mirrored): a trend runs on through the ends, so an axis turning evenly along the row (a cylinder's)
    keeps its ends where they were (scipy's edge modes hold the ends' values or mirror them: a one-sided mean,
    2.3 deg off at the end of a 100 mm radius for a 10 mm sigma)."""
    pad = min(int(np.ceil(4.0 * sigma)), len(q) - 1)
    ext = np.concatenate([2.0 * q[0] - q[pad:0:-1], q, 2.0 * q[-1] - q[-2:-pad - 2:-1]])
    return gaussian_filter1d(ext, sigma, axis=0, mode="nearest")[pad:pad + len(q)]


def _turn_leads(path: Path, P: np.ndarray, out: np.ndarray, a: int, b: int) -> None:
    """Give the lead poses next to the run a..b (its segment's, holding its end pose's orientation, as
    ``path.raster`` makes them) the end pose's new orientation in ``out``, so the lead meets the run without a
    turn."""
    zone, seg = np.asarray(path.zone), np.asarray(path.segment)
    for end, step in ((a, -1), (b, 1)):
        k = end + step
        while 0 <= k < len(P) and zone[k] != WORK and seg[k] == seg[end] \
                and np.allclose(P[k, :3, :3], P[end, :3, :3], atol=1e-12):
            out[k, :3, :3] = out[end, :3, :3]
            k += step
