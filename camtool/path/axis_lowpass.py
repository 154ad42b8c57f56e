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
quaternions, signs aligned along the run) averaged with Gaussian weights of ``sigma_mm`` along the row, the window
narrowed near the run's ends so that it stays symmetric (``_smoothed``), and normalised; the end poses, where the
leads start, keep theirs, as do positions, leads, connectors and analytic faces. The weights are written here (a window that narrows to the ends); the quaternion average is written here: for rotations a few degrees apart the normalised mean of aligned quaternions
is the chordal L2 mean (Hartley et al. 2013), which no library applies along a path.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation

from .toolpath import WORK, Path

MIN_POSES = 5       # a shorter run keeps its orientations (nothing to average over)
CHUNK = 256         # poses averaged at a time (their weights' matrix stays small on a run of any length)
REACH_SIGMAS = 40.0  # past this many sigmas a Gaussian weight is 0.0 in float64 (exp(-800)): the poses summed


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
        s_mm = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(P[a:b + 1, :3, 3], axis=0), axis=1))]
        q = Rotation.from_matrix(P[a:b + 1, :3, :3]).as_quat()
        q *= np.where(np.cumprod(np.sign(np.r_[1.0, np.einsum("ij,ij->i", q[1:], q[:-1])])) < 0, -1.0, 1.0)[:, None]
        q = _smoothed(q, s_mm, settings.sigma_mm)
        out = P.copy() if out is None else out
        out[a + 1:b, :3, :3] = Rotation.from_quat(q[1:-1] / np.linalg.norm(q[1:-1], axis=1)[:, None]).as_matrix()
    return path if out is None else replace(path, poses_mm=out)


def _smoothed(q: np.ndarray, s_mm: np.ndarray, sigma_mm: float) -> np.ndarray:
    """(n, 4) the rows of ``q`` (at arc lengths ``s_mm`` along the run) averaged with Gaussian weights of
    ``sigma_mm``, narrowed near the run's ends to a third of the distance to the nearer end: every window is
    symmetric within the run (an axis that turns evenly keeps its poses; a one-sided window pulled the ends of the
    bezier dac's rows 0.37 deg inwards where they roll over the edge, and its row bound fell 89 -> 82 mm/s), and
    the end poses keep theirs. By hand: scipy's ``gaussian_filter1d`` has one sigma and even spacing."""
    sig = np.minimum(sigma_mm, np.minimum(s_mm - s_mm[0], s_mm[-1] - s_mm) / 3.0)
    out = q.copy()
    on = np.flatnonzero(sig > 0.0)
    for c in range(0, len(on), CHUNK):   # bounded memory: CHUNK centres by the poses within their weights' reach
        i = on[c:c + CHUNK]
        lo = np.searchsorted(s_mm, s_mm[i[0]] - REACH_SIGMAS * sigma_mm, "left")
        hi = np.searchsorted(s_mm, s_mm[i[-1]] + REACH_SIGMAS * sigma_mm, "right")
        W = np.exp(-0.5 * ((s_mm[None, lo:hi] - s_mm[i, None]) / sig[i, None]) ** 2)
        out[i] = W @ q[lo:hi] / W.sum(axis=1)[:, None]
    return out
