"""The reachability screen of one workpiece placement, and its cost.

A *placement* is an offset of the job's workpiece placement: a translation
(dx, dy, dz) in mm in the world frame and a yaw (deg) about the world z axis
through the job's workpiece origin (``cell.workpiece_xyz_mm``), added to
``cell.workpiece_rpy_deg``'s yaw. Its world transform is

    D = [Rz(yaw) | xyz + d - Rz(yaw) xyz],   new workpiece pose = D @ old pose,

and the already-rastered path is moved with it, ``poses' = D @ poses``, instead
of being fitted and rastered again (docs/placement.md says when that is exact).

Screening a placement (``screen_batch``), cheapest test first:

1. **Wrist-centre bound** on every pose of the path (``ClosedForm.bound``):
   a pose whose wrist centre no shoulder position can reach with the elbow
   inside its limits is out of reach. No IK is solved.
2. **Closed-form IK** on a subsample of the path (``screen_indices``: the
   poses extreme along 26 directions, the ends of every run, and an even
   spread): per pose the sampled solution with the most joint-limit margin
   (``ClosedForm.best``). A pose with none inside the limits is out of reach.
3. With ``full=True`` (the few finalists), closed-form IK on every pose.

A placement that passes gets its figures and cost:

- ``joint_margin``: the smallest joint-limit margin over the subsample, as a
  share of the joint's range (the best sampled solution per pose);
- ``reach_used``: the largest shoulder-wrist distance over every pose, as a
  share of the straight-elbow distance (with a track, at the track value that
  brings the shoulder nearest);
- ``dexterity``: the smallest inverse condition number of the TCP Jacobian
  (scaled as the planner weighs errors and joints) over the subsample;
- ``speed_ratio``: the largest joint speed over its limit that the least-norm
  joint motion needs for the nominal TCP speed along the path;
- ``est_work_s``: the work-zone time at the nominal TCP speed, each pose's
  share stretched by ``max(1, speed ratio)`` (where limits slow the TCP);
- ``feed_mm_s``: the work feed the timing is expected to hold (``feed.py``: the
  speed, acceleration and jerk limits on stencils of 4 poses along the rows, each
  row at its slowest; the median over the work length; with ``full=True`` the
  timing's own time law on every run through every pose), ``feed_share`` its share
  of the nominal TCP speed.

    cost = est_work_s * (1 + penalty) * (1 + move_per_m * move) * (1 + feed_weight * (1 - feed_share))
    penalty = sum over (joint margin, reach margin, dexterity) of max(0, 1 - value / goal)^2
    move = |d| / 1 m + |yaw| / 90 deg

so a margin at zero doubles the cost per margin, margins above their goals
cost nothing, and of two equally good placements the one nearer the user's
wins; a placement whose rows hold two thirds of the feed costs twice one that
holds it (``feed_weight`` 3, as a joint margin at zero does): grinding and painting need the constant
feed (removal and film depend on it), and the cycle time alone does not see it
before the plan. Infeasible placements cost ``inf``.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from ..path.toolpath import WORK, Path
from .feed import FeedStencils, expected_feed, timed_feed
from .kinematics import ClosedForm, dexterity
from .tilt import tilt_matrix, work_centre

AXES = ("x", "y", "z", "yaw", "roll", "pitch")
UNITS = {"x": "mm", "y": "mm", "z": "mm", "yaw": "deg", "roll": "deg", "pitch": "deg"}


@dataclass(frozen=True)
class ScreenSettings:
    """Sizes of the screen and the goals and weights of the cost (module doc)."""

    screen_poses: int = 96            # IK subsample of the path
    joint_margin_goal: float = 0.10   # share of the joint range
    reach_margin_goal: float = 0.10   # share of the straight-elbow reach
    dexterity_goal: float = 0.02      # inverse condition number
    move_per_m: float = 0.02          # cost share per metre (and per 90 deg) of move
    orientation_mm: float = 200.0     # planner.orientation_weight_mm
    track_scale_mm: float = 500.0     # planner.track_scale_mm
    tcp_speed_mm_s: float = 100.0     # timing.tcp_speed_mm_s
    feed_weight: float = 3.0          # cost share per share of the feed the work is expected to lose
    feed_stencils: int = 256          # stencils of 4 work poses the feed is estimated on (feed.py)

    def penalty(self, joint_margin, reach_used, dex) -> float:
        """The margin penalty (module doc); a missing figure counts as meeting its goal."""
        terms = []
        if joint_margin is not None:
            terms.append(max(0.0, 1.0 - joint_margin / self.joint_margin_goal) ** 2)
        if reach_used is not None:
            terms.append(max(0.0, 1.0 - (1.0 - reach_used) / self.reach_margin_goal) ** 2)
        if dex is not None:
            terms.append(max(0.0, 1.0 - dex / self.dexterity_goal) ** 2)
        return float(sum(terms))

    def move(self, offset) -> float:
        """The move measure of an offset (dx, dy, dz mm, dyaw deg[, droll, dpitch deg]): |d| / 1 m + |yaw| / 90 deg
        (+ (|roll| + |pitch|) / 90 deg: a tilt turns the part as far as a yaw)."""
        turn = abs(offset[3]) + sum(abs(float(a)) for a in offset[4:])
        return float(np.linalg.norm(offset[:3]) / 1000.0 + turn / 90.0)

    def feed_factor(self, feed_share) -> float:
        """The feed term: 1 + feed_weight * (1 - feed_share); 1 without a figure."""
        if feed_share is None:
            return 1.0
        return 1.0 + self.feed_weight * max(0.0, 1.0 - float(feed_share))

    def cost(self, time_s: float, penalty: float, offset, feed_share=None) -> float:
        return float(time_s * (1.0 + penalty) * (1.0 + self.move_per_m * self.move(offset))
                     * self.feed_factor(feed_share))


def placement_matrix(offset, pivot_mm, tilt_centre_mm=None) -> np.ndarray:
    """World transform D of an offset (dx, dy, dz mm, dyaw deg[, droll, dpitch deg]): the tilt about
    ``tilt_centre_mm`` (``placement.tilt``), then yaw about world z through ``pivot_mm``, then d."""
    dx, dy, dz, yaw = (float(v) for v in offset[:4])
    c, s = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
    D = np.eye(4)
    D[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    p = np.asarray(pivot_mm, float)
    D[:3, 3] = p + np.array([dx, dy, dz]) - D[:3, :3] @ p
    if any(float(a) for a in offset[4:]):
        D = D @ tilt_matrix(*offset[4:6], tilt_centre_mm if tilt_centre_mm is not None else pivot_mm)
    return D


def move_path(path: Path, D: np.ndarray) -> Path:
    """The path moved rigidly by the world transform D (``poses' = D @ poses``)."""
    from dataclasses import replace

    return replace(path, poses_mm=np.einsum("ij,njk->nik", np.asarray(D, float), path.poses_mm))


def screen_indices(path: Path, W: np.ndarray, count: int) -> np.ndarray:
    """About ``count`` path indices for the IK screen: the poses whose wrist centres W are extreme along 26
    directions, up to a third of the budget from the first and last poses of the runs, the rest an even
    spread over the work poses."""
    n = len(path)
    if n <= count:
        return np.arange(n)
    dirs = np.array([(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1) if (i, j, k) != (0, 0, 0)],
                    float)
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    pick = set(np.argmax((W - W.mean(axis=0)) @ dirs.T, axis=0).tolist())
    starts = np.flatnonzero(np.diff(np.concatenate([[-1], path.segment])) != 0)
    ends = np.unique(np.concatenate([starts, starts - 1, [n - 1]]))
    ends = ends[(ends >= 0) & (ends < n)]
    pick |= set(ends[_spread(len(ends), max(count // 3, 2))].tolist())
    work = np.flatnonzero(path.zone == WORK)
    work = work if len(work) else np.arange(n)
    rest = count - len(pick)
    if rest > 0:
        pick |= set(work[_spread(len(work), rest)].tolist())
    return np.array(sorted(pick), int)


def _spread(n: int, m: int) -> np.ndarray:
    """At most m evenly spread indices of n items (first and last kept)."""
    if n <= m:
        return np.arange(n)
    return np.unique(np.round(np.linspace(0, n - 1, max(m, 1))).astype(int))


def _twists_per_mm(path: Path, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(K, 6) world twist of the TCP per mm of travel at path indices ``idx`` (central differences), and
    (K,) the work length (mm) each index stands for."""
    n = len(path)
    a, b = np.clip(idx - 1, 0, n - 1), np.clip(idx + 1, 0, n - 1)
    P = path.poses_mm
    dp = P[b, :3, 3] - P[a, :3, 3]
    ds = np.linalg.norm(dp, axis=1)
    rel = np.einsum("kji,kjl->kil", P[a, :3, :3], P[b, :3, :3])
    w = np.einsum("kij,kj->ki", P[a, :3, :3], Rotation.from_matrix(rel).as_rotvec())
    ok = ds > 1e-9
    tw = np.zeros((len(idx), 6))
    tw[ok] = np.column_stack([dp[ok], w[ok]]) / ds[ok, None]
    return tw, ok


@dataclass
class PathGeometry:
    """What the screen needs of one path (moved rigidly per placement): picklable."""

    poses_mm: np.ndarray           # (N, 4, 4) world TCP poses at the job's placement
    wrist_world: np.ndarray        # (S, N, 3) wrist centres per sampled tool spin
    sub: np.ndarray                # IK subsample (path indices)
    work_sub: np.ndarray           # the work poses among them
    twists: np.ndarray             # (len(work_sub), 6) world twist per mm
    work_length_mm: float
    base_inv: np.ndarray
    pivot_mm: np.ndarray
    stencils: FeedStencils | None = None   # the feed's stencils along the rows (feed.py)
    zone: np.ndarray | None = None         # the path's zones and segments (the finalists' timed feed)
    segment: np.ndarray | None = None
    tilt_centre_mm: np.ndarray | None = None   # the tilt's pivot: the work poses' centre (``tilt.work_centre``)
    n_poses: int = field(init=False)

    def __post_init__(self):
        self.n_poses = len(self.poses_mm)

    @classmethod
    def build(cls, path: Path, model: ClosedForm, robot, pivot_mm, settings: ScreenSettings) -> "PathGeometry":
        P = np.asarray(path.poses_mm, float)
        w_tcp = model.wrist_offset()
        W = np.stack([np.einsum("nij,j->ni", P[:, :3, :3], S[:3, :3] @ w_tcp) + P[:, :3, 3] for S in model.spins])
        sub = screen_indices(path, W[0], settings.screen_poses)
        work = np.flatnonzero(path.zone == WORK)
        work_sub = sub[path.zone[sub] == WORK]
        if len(work_sub) == 0:
            work_sub = sub
        tw, ok = _twists_per_mm(path, work_sub)
        work_sub, tw = work_sub[ok], tw[ok]
        p = P[:, :3, 3]
        steps = np.linalg.norm(np.diff(p, axis=0), axis=1)
        on_work = (path.zone[1:] == WORK) & (path.zone[:-1] == WORK) & (path.segment[1:] == path.segment[:-1])
        length = float(steps[on_work].sum()) if len(work) > 1 else 0.0
        stencils = FeedStencils.build(path, settings.feed_stencils) if settings.feed_stencils > 0 else None
        return cls(P, W, sub, work_sub, tw, length, np.linalg.inv(robot.base_T_mm), np.asarray(pivot_mm, float),
                   stencils, np.asarray(path.zone), np.asarray(path.segment), work_centre(path))

    def base_transform(self, offset) -> np.ndarray:
        """World pose of the path at the job's placement -> robot base frame at ``offset``."""
        return self.base_inv @ placement_matrix(offset, self.pivot_mm, self.tilt_centre_mm)


@dataclass
class ScreenResult:
    """The screen's verdict and figures for one placement offset (dx, dy, dz mm, dyaw deg)."""

    offset: tuple
    feasible: bool
    stage: str                     # "bound" | "ik" | "full" (where it failed) or "ok"
    unreachable: int               # poses out of reach among those checked at that stage
    checked: int
    reach_used: float              # largest over every pose (bound), share of d_max
    joint_margin: float | None = None
    joint_margin_joint: str | None = None
    dexterity: float | None = None
    speed_ratio: float | None = None
    est_work_s: float | None = None
    penalty: float | None = None
    cost: float = math.inf
    full_checked: bool = False
    feed_mm_s: float | None = None         # expected work feed (median over the work length)
    feed_min_mm_s: float | None = None     # expected feed of the slowest row
    feed_share: float | None = None

    def as_dict(self) -> dict:
        d = asdict(self)
        d["offset"] = [round(float(v), 3) for v in self.offset]
        for k in ("reach_used", "joint_margin", "dexterity", "speed_ratio", "est_work_s", "penalty", "cost",
                  "feed_mm_s", "feed_min_mm_s", "feed_share"):
            if d[k] is not None:
                d[k] = None if not math.isfinite(d[k]) else round(float(d[k]), 5)
        return d


def screen_batch(model: ClosedForm, geom: PathGeometry, offsets, settings: ScreenSettings, full: bool = False,
                 chunk_poses: int = 4096) -> list[ScreenResult]:
    """Screen many placement offsets (module doc); the result order follows ``offsets``."""
    offsets = [tuple(float(v) for v in o) for o in offsets]
    results: list[ScreenResult | None] = [None] * len(offsets)
    passed = []
    for i, off in enumerate(offsets):                         # 1. the wrist-centre bound, every pose
        B = geom.base_transform(off)
        W = geom.wrist_world @ B[:3, :3].T + B[:3, 3]
        ok, used, _ = model.bound(W)
        ok_any = ok.any(axis=0)
        used_best = np.min(used, axis=0)
        used_max = float(np.max(used_best)) if len(used_best) else 0.0
        bad = int(np.count_nonzero(~ok_any))
        if bad:
            results[i] = ScreenResult(off, False, "bound", bad, geom.n_poses, used_max)
        else:
            passed.append((i, B, used_max))
    # 2. closed-form IK on the subsample, many placements per call
    idx = np.arange(geom.n_poses) if full else geom.sub
    per = max(1, chunk_poses // max(len(idx), 1))
    for a in range(0, len(passed), per):
        group = passed[a:a + per]
        T = np.concatenate([np.einsum("ij,njk->nik", B, geom.poses_mm[idx]) for _, B, _ in group])
        q, m, _ = model.best(T, recheck_below=settings.joint_margin_goal)
        q = q.reshape(len(group), len(idx), -1)
        m = m.reshape(len(group), len(idx))
        for (i, B, used_max), qg, mg in zip(group, q, m):
            off = offsets[i]
            bad = int(np.count_nonzero(~np.isfinite(mg)))
            if bad:
                results[i] = ScreenResult(off, False, "full" if full else "ik", bad, len(idx), used_max,
                                          full_checked=full)
                continue
            results[i] = _figures(model, geom, settings, off, B, used_max, idx, qg, mg, full)
    return results


def _figures(model, geom, settings, off, B, used_max, idx, q, m, full) -> ScreenResult:
    """Margins, dexterity, speed demand, time and cost of a placement that passed the screen."""
    robot = model.robot
    k = int(np.argmin(m))
    span = model.upper - model.lower
    mid = 0.5 * (model.upper + model.lower)
    per_joint = (0.5 * span - np.abs(q[k] - mid)) / span
    joint = robot.joint_names[int(np.argmin(per_joint))]
    pos = {int(p): j for j, p in enumerate(idx)}
    rows = np.array([pos[int(p)] for p in geom.sub if int(p) in pos])
    J = model.jacobian(q[rows])
    dex = float(dexterity(J, robot.prismatic, settings.orientation_mm, settings.track_scale_mm).min())
    work_rows = np.array([pos[int(p)] for p in geom.work_sub if int(p) in pos], int)
    speed, time_s = 0.0, 0.0
    if len(work_rows):
        Jw = model.jacobian(q[work_rows])
        C = np.where(robot.prismatic, settings.track_scale_mm, 1.0)
        R = B[:3, :3]
        tw = np.concatenate([geom.twists[:, :3] @ R.T, geom.twists[:, 3:] @ R.T], axis=1)
        y = np.einsum("kij,kj->ki", np.linalg.pinv(Jw * C[None, None, :]), tw)
        qd = y * C[None, :] * settings.tcp_speed_mm_s
        ratio = np.max(np.abs(qd) / robot.limits.velocity[None, :], axis=1)
        speed = float(ratio.max())
        time_s = geom.work_length_mm / settings.tcp_speed_mm_s * float(np.mean(np.maximum(ratio, 1.0)))
    jm = float(m.min())
    pen = settings.penalty(jm, used_max, dex)
    feed = None
    if geom.stencils is not None and full:   # every pose solved: the time law on every run, as the timing will
        T = np.einsum("ij,njk->nik", B, geom.poses_mm)
        feed = timed_feed(model, geom.zone, geom.segment, T, settings.tcp_speed_mm_s)
    if feed is None and geom.stencils is not None and len(geom.stencils):
        feed = expected_feed(model, geom.stencils, geom.poses_mm, B, settings.tcp_speed_mm_s)
    share = None if feed is None else feed.share
    return ScreenResult(off, True, "ok", 0, len(idx), used_max, jm, joint, dex, speed, time_s, pen,
                        settings.cost(time_s, pen, off, share), full_checked=full,
                        feed_mm_s=None if feed is None else feed.median_mm_s,
                        feed_min_mm_s=None if feed is None else feed.min_mm_s, feed_share=share)
