"""The work feed a placement lets the timing hold: closed-form IK on short stencils along the rows.

The timing (``camtool.timing.runs``) runs each row's work at one feed (``slow_scope = "row"``): the
commanded one, or the highest that keeps every joint within ``MARGIN`` of its speed, acceleration and
jerk limits along the whole row, from the joint path's derivatives along the TCP path length s:

    feed <= min over joints of (v_max / |q'|, sqrt(a_max / |q''|), cbrt(j_max / |q'''|))   (x MARGIN)

Near a wrist singularity (6R: q5 = 0) q4 and q6 turn fast for a small TCP move: q' grows as 1/|sin q5|
and q''' as 1/|sin q5|^3, so the jerk bound binds first and the feed falls as |sin q5| (the IRB2400 on
the free-form sheets: j4's jerk on nearly every row). The screen's least-norm joint speeds on 96 poses
see neither the jerk nor the rows between its poses, so this module estimates the feed itself:

- ``FeedStencils.build``: up to ``count`` stencils of 4 consecutive work poses of one row (path
  indices i-1 .. i+2): half the budget at each row's sharpest bends of the TCP pose (the third
  derivative of its position and rotation along the row, which the placement does not change: the
  joints' jerk peaks there), the rest spread evenly over the work; and each row's work length;
- ``expected_feed``: at one placement, closed-form IK of the stencils (the centre pose's solution with
  the most joint-limit margin, its neighbours the candidates nearest it: one continuous motion), a
  cubic in s through each stencil's joints (q', q'', q''' at its centre), the bound above per stencil,
  each row at the lowest bound of its stencils (capped at the commanded feed) and the median of the
  rows weighted by their work length: the work feed a user would read in report.json's
  ``work_feed.median_work_feed_mm_s``. A stencil pose without a solution inside the limits holds no feed.
  On a plate whose rows miss the IRB2400's wrist singularity by 7.5 mm it reads 48 mm/s where the timing
  holds 44 (tests/test_placement_feed.py); a row's slowest spot between its stencils is not seen.

- ``timed_feed``: for the search's few finalists (every pose solved anyway), the timing's own time law
  (``timing.runs.time_runs``) on every run through every pose, one continuous IK branch per run. On
  ``bezier_ocean_cad`` it orders placements as their planned runs do (57-72 mm/s where those hold
  22.7-33.6: the planner's sag midposes slow every row alike, docs/placement.md).

Hand-written because no library times a path from closed-form IK branches; the bound is the timing's
own (``pathlaw.speed_bounds``) on a cubic fitted to 4 poses instead of the spline through all of them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import CamtoolError
from ..path.toolpath import SURFACE_CODES, WORK, Path
from ..timing.pathlaw import speed_bounds
from ..timing.runs import time_runs
from ..timing.quintic import MARGIN
from .kinematics import best_of

STENCIL = 4          # poses per stencil: i-1, i, i+1, i+2 (a cubic's 4 coefficients)
ORIENTATION_MM = 200.0   # 1 rad of tool turn weighs as this many mm of travel in picking stencils (the planner's)


@dataclass(frozen=True)
class FeedStencils:
    """Stencils along the rows (picklable): path indices (K, 4), arc length from the centre pose (K, 4) mm,
    the row (index into ``row_length_mm``) of each, and each row's work length (mm)."""

    index: np.ndarray
    s_mm: np.ndarray
    row: np.ndarray
    row_length_mm: np.ndarray

    @classmethod
    def build(cls, path: Path, count: int) -> "FeedStencils":
        """Up to ``count`` stencils of 4 consecutive work poses of one segment, evenly spread over the work."""
        n = len(path)
        seg, work = np.asarray(path.segment), np.asarray(path.zone) == WORK
        p = np.asarray(path.poses_mm, float)[:, :3, 3]
        step = np.linalg.norm(np.diff(p, axis=0), axis=1)
        same = (seg[1:] == seg[:-1]) & work[1:] & work[:-1]          # piece k -> k+1 is work of one row
        rows, inverse = np.unique(seg, return_inverse=True)
        length = np.bincount(inverse[:-1], weights=np.where(same, step, 0.0), minlength=len(rows))
        centre = np.arange(1, n - 2) if n >= STENCIL else np.zeros(0, int)
        centre = centre[same[centre - 1] & same[centre] & same[centre + 1]]   # pieces i-1 .. i+2 on one row
        cum = np.concatenate([[0.0], np.cumsum(step)])
        if count < len(centre):
            centre = _pick(centre, inverse[centre], _turning(path.poses_mm, centre, cum), count)
        index = centre[:, None] + np.arange(-1, STENCIL - 1)[None, :]
        s = cum[index] - cum[centre][:, None]
        return cls(index.astype(int), s, inverse[centre].astype(int), length)

    def __len__(self) -> int:
        return len(self.index)


def _turning(poses_mm: np.ndarray, centre: np.ndarray, cum: np.ndarray) -> np.ndarray:
    """Per stencil centre, how sharply the TCP pose bends there: the third derivative of the cubic through the 4 poses' positions
    and rotation vectors (from the centre's orientation, x ORIENTATION_MM), a placement-independent proxy of the
    joints' jerk."""
    index = centre[:, None] + np.arange(-1, STENCIL - 1)[None, :]
    P = np.asarray(poses_mm, float)[index]                               # (K, 4, 4, 4)
    rel = np.einsum("kji,kmjl->kmil", P[:, 1, :3, :3], P[:, :, :3, :3])
    rv = Rotation.from_matrix(rel.reshape(-1, 3, 3)).as_rotvec().reshape(len(centre), STENCIL, 3)
    x = np.concatenate([P[:, :, :3, 3], ORIENTATION_MM * rv], axis=-1)    # (K, 4, 6)
    s = cum[index] - cum[centre][:, None]
    V = s[:, :, None] ** np.arange(STENCIL)[None, None, :]
    good = np.abs(np.linalg.det(V)) > 0.0                                  # not where poses repeat
    out = np.zeros(len(centre))
    out[good] = np.linalg.norm(np.linalg.solve(V[good], x[good])[:, 3], axis=-1)
    return out


def _pick(centre: np.ndarray, row: np.ndarray, score: np.ndarray, count: int) -> np.ndarray:
    """``count`` stencil centres: in each row its sharpest bends (half the budget, shared evenly by the rows: a
    row slows at its slowest spot) and the rest spread evenly over the work."""
    rows = np.unique(row)
    per_row = max(1, (count // 2) // max(len(rows), 1))
    order = np.lexsort((-score, row))                                    # by row, sharpest first, stable
    rank = np.arange(len(order)) - np.searchsorted(row[order], row[order])
    sharp = order[rank < per_row]
    rest = max(count - len(sharp), 1)
    even = np.unique(np.round(np.linspace(0, len(centre) - 1, rest)).astype(int))
    return centre[np.union1d(sharp, even)]


@dataclass(frozen=True)
class FeedEstimate:
    """The expected work feed of a placement: length-weighted median over the rows and the slowest row
    (mm/s), and the share of the commanded feed of the median."""

    median_mm_s: float
    min_mm_s: float
    share: float


def _nearest(cands: np.ndarray, q_ref: np.ndarray, revolute: np.ndarray) -> np.ndarray:
    """Per pose the candidate (C, K, n) nearest ``q_ref`` (K, n), taken to the 2*pi-equivalent next to it."""
    dev = cands - q_ref[None]
    dev = np.where(revolute, (dev + np.pi) % (2.0 * np.pi) - np.pi, dev)
    with np.errstate(invalid="ignore"):
        far = np.where(np.isnan(dev).any(axis=-1), np.inf, np.abs(dev).max(axis=-1))
    c = np.argmin(far, axis=0)
    K = cands.shape[1]
    return q_ref + dev[c, np.arange(K)]


def stencil_bounds(limits, q: np.ndarray, s_mm: np.ndarray) -> np.ndarray:
    """Highest feed (mm/s) per stencil from joints ``q`` (K, 4, n) at arc lengths ``s_mm`` (K, 4): the
    timing's bound (``speed_bounds``) on the centre piece of the cubic through the 4 poses (the exact maxima
    of |q'|, |q''|, |q'''| there, as ``PathSpline.piece_bounds``); 0 where a pose has no solution."""
    K = len(q)
    if K == 0:
        return np.zeros(0)
    V = s_mm[:, :, None] ** np.arange(STENCIL)[None, None, :]          # (K, 4, 4) Vandermonde
    good = np.isfinite(q).all(axis=(1, 2)) & (np.abs(np.linalg.det(V)) > 0.0)
    c = np.zeros((K, STENCIL, q.shape[2]))
    c[good] = np.linalg.solve(V[good], q[good])                          # q(s) = c0 + c1 s + c2 s^2 + c3 s^3
    s_end = s_mm[:, 2:3]                                                 # the centre piece: s in [0, s_end]
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.where(c[:, 3] != 0, -c[:, 2] / (3 * c[:, 3]), -1.0)      # where |q'| peaks inside the piece
    x = np.where((x > 0) & (x < s_end), x, 0.0)
    p1 = np.maximum.reduce([np.abs(c[:, 1]), np.abs(c[:, 1] + 2 * c[:, 2] * s_end + 3 * c[:, 3] * s_end ** 2),
                            np.abs(c[:, 1] + 2 * c[:, 2] * x + 3 * c[:, 3] * x ** 2)])
    p2 = np.maximum(np.abs(2 * c[:, 2]), np.abs(2 * c[:, 2] + 6 * c[:, 3] * s_end))
    p3 = np.abs(6 * c[:, 3])
    bound, _, _ = speed_bounds(p1, p2, p3, limits, MARGIN)
    return np.where(good, bound, 0.0)


def expected_feed(model, stencils: FeedStencils, poses_mm: np.ndarray, B: np.ndarray,
                  feed_mm_s: float) -> FeedEstimate:
    """The expected work feed at the placement whose base <- world transform is ``B`` (module doc);
    ``poses_mm``: the path's world poses at the job's placement, ``feed_mm_s`` the commanded feed."""
    K = len(stencils)
    if K == 0 or feed_mm_s <= 0:
        return FeedEstimate(float(feed_mm_s), float(feed_mm_s), 1.0)
    T = np.einsum("ij,njk->nik", B, poses_mm[stencils.index.ravel()])
    cands = model.candidates(T).reshape(-1, K, STENCIL, model.robot.dof)
    q_c, m_c, _ = best_of(cands[:, :, 1], model.lower, model.upper, model.revolute, model.controller_ok)
    q = np.stack([q_c if j == 1 else _nearest(cands[:, :, j], q_c, model.revolute) for j in range(STENCIL)], 1)
    q[~np.isfinite(m_c)] = np.nan
    bound = np.minimum(stencil_bounds(model.robot.limits, q, stencils.s_mm), feed_mm_s)
    return row_feed(bound, stencils.row, stencils.row_length_mm, feed_mm_s)


def row_feed(bound: np.ndarray, row: np.ndarray, row_length_mm: np.ndarray, feed_mm_s: float) -> FeedEstimate:
    """Each row at the lowest bound of its stencils (``bound`` mm/s, ``row`` their rows); the median over the rows
    that have stencils, weighted by their work length, and the slowest row."""
    feeds = np.full(len(row_length_mm), float(feed_mm_s))
    np.minimum.at(feeds, row, np.minimum(bound, feed_mm_s))
    seen = np.zeros(len(row_length_mm), bool)
    seen[row] = True
    w = np.where(seen, row_length_mm, 0.0)
    if w.sum() <= 0:
        return FeedEstimate(float(feed_mm_s), float(feed_mm_s), 1.0)
    median = weighted_median(feeds[seen], w[seen])
    return FeedEstimate(median, float(feeds[seen].min()), median / float(feed_mm_s))


def weighted_median(values: np.ndarray, weights: np.ndarray) -> float:
    """The lower weighted median: the smallest value with at least half the total weight at or below it."""
    order = np.argsort(values, kind="stable")
    cum = np.cumsum(np.asarray(weights, float)[order])
    return float(np.asarray(values, float)[order][np.searchsorted(cum, 0.5 * cum[-1])])


def timed_feed(model, path_zone: np.ndarray, path_segment: np.ndarray, T_base: np.ndarray,
               feed_mm_s: float) -> FeedEstimate | None:
    """The work feed of every pose of the path (``T_base`` (N, 4, 4), base frame), timed by the timing's own
    time law (``timing.runs.time_runs``: each run, its leads and work, a spline through every pose): the finer
    figure the search takes for its few finalists. One continuous IK branch per run: the first pose's
    solution with the most margin, each next the candidate nearest the one before; a run that branch takes
    past a joint limit (the planner turns it round with a reverse plan or a retract) is left out. None where a
    pose has no solution inside the limits or no run is timed."""
    surface = np.isin(path_zone, SURFACE_CODES)
    seg = np.asarray(path_segment)
    start = surface & np.r_[True, (seg[1:] != seg[:-1]) | ~surface[:-1]]
    run = np.cumsum(start) - 1
    keep = np.flatnonzero(surface)
    if not len(keep) or feed_mm_s <= 0:
        return None
    T = np.asarray(T_base, float)[keep]
    cands = model.candidates(T)
    q, m, _ = best_of(cands, model.lower, model.upper, model.revolute, model.controller_ok)
    if not np.isfinite(m).all():
        return None
    r = run[keep]
    first = np.r_[True, r[1:] != r[:-1]]
    for i in np.flatnonzero(~first):          # sequential by nature: each pose follows the one before
        q[i] = _nearest(cands[:, i:i + 1], q[i - 1:i], model.revolute)[0]
    step = np.linalg.norm(np.diff(T[:, :3, 3], axis=0), axis=1)
    zone = np.asarray(path_zone)[keep]
    starts = np.flatnonzero(first)
    feeds, length = [], []
    for a, b in zip(starts, np.r_[starts[1:], len(keep)]):
        work = (zone[a:b - 1] == WORK) & (zone[a + 1:b] == WORK)
        if b - a < 2 or not work.any():
            continue
        one = np.zeros(b - a, bool)
        try:   # one run at a time: a run the planner takes with a reverse plan or a retract is left out
            law = time_runs(q[a:b], step[a:b - 1], np.r_[True, one[1:]], np.r_[one[1:], True], np.zeros(b - a, int),
                            zone[a:b], model.robot.limits, feed_mm_s)
        except CamtoolError:
            continue
        feeds.append(min(float(law.run_feed_mm_s[0]), feed_mm_s))
        length.append(float(step[a:b - 1][work].sum()))
    if not feeds:
        return None
    median = weighted_median(np.array(feeds), np.array(length))
    return FeedEstimate(median, min(feeds), median / float(feed_mm_s))
