"""The planned path the simulator measures a program against (``Reference``)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from camtool.program.targets import _Chain

# --- the planned path ------------------------------------------------------------------------------

@dataclass(frozen=True)
class Reference:
    """The planned path: TCP points (mm, robot base frame) in order, ``breaks`` where the
    polyline does not continue (between rows), the plan's duration (s, or None), its number
    of work rows and feed; ``motion`` (optional) the timed motion's own TCP curve: a point
    is on the planned path when it is near either (the poses' polyline, or the curve the
    plan itself moves along between them)."""

    points: np.ndarray
    breaks: np.ndarray
    duration_s: float | None = None
    rows: int | None = None
    feed_mm_s: float | None = None
    motion: "Reference | None" = None  # the planned motion's own TCP curve, when it bows off the poses
    times: np.ndarray | None = None    # the plan's time at each point (s from its start), when known
    window: int = 1                    # segments either side of the plan's one searched first (with times)
    _tree: object = field(default=None, compare=False, repr=False)

    def tree(self):
        """A KD-tree of the points, built once."""
        if self._tree is None:
            from scipy.spatial import cKDTree
            object.__setattr__(self, "_tree", cKDTree(self.points))
        return self._tree


REF_SAG_MM = 0.005  # the planned motion's curve is kept where it bows more than this off the poses' chords


def _hermite(t_s, q, qd, qdd, k, tt):
    """Joint values at times ``tt`` inside steps ``k`` (waypoint k to k+1) of the timed motion
    (``trajectory.quintic_at``: the plan's own definition of its motion, not a writer's)."""
    from camtool.trajectory import quintic_at

    return quintic_at(t_s, q, qd, qdd, k, tt)


def reference_from_trajectory(trajectory, robot, feed_mm_s: float | None = None) -> Reference:
    """The planned path of a timed trajectory: the polyline through the TCP of its waypoints on its
    process zones (lead-in, work, lead-out): the path's poses and the planner's own there (a chord
    sag's midposes on the surface, a bowed chord's on the line: ``plan.sag``, ``plan.densify``),
    broken between stretches; and, where the timed motion itself bows off that polyline by more than
    ``REF_SAG_MM`` (its quintic pieces between waypoints), that motion's TCP curve as
    ``Reference.motion``."""
    from camtool.path.toolpath import ZONE_CODE

    zone = np.asarray(trajectory.zone)
    t = np.asarray(trajectory.t_s, float)
    qa = np.asarray(trajectory.q, float)
    proc = np.isin(zone, [ZONE_CODE["work"], ZONE_CODE["lead_in"], ZONE_CODE["lead_out"]])
    stretch = np.cumsum(np.r_[1, np.diff(proc.astype(int)) != 0])  # stretch number of every waypoint
    idx = np.flatnonzero(proc)
    chain = _Chain(robot)
    P = chain.fk(qa[idx])[0]
    breaks = np.r_[stretch[idx[1:]] != stretch[idx[:-1]], True]  # the polyline ends after point i
    work = zone == ZONE_CODE["work"]
    rows = int(np.sum(np.diff(np.r_[0, work.astype(int)]) == 1))
    motion = None
    steps = np.flatnonzero(proc[:-1] & proc[1:] & (t[1:] > t[:-1]))  # steps of the timed motion on the zones
    if len(steps) and getattr(trajectory, "qd", None) is not None:
        qd, qdd = np.asarray(trajectory.qd, float), np.asarray(trajectory.qdd, float)
        Pw = chain.fk(qa)[0]
        mid = chain.fk(_hermite(t, qa, qd, qdd, steps, (t[steps] + t[steps + 1]) / 2))[0]
        sag = np.linalg.norm(mid - (Pw[steps] + Pw[steps + 1]) / 2, axis=1)
        bow = steps[sag > REF_SAG_MM]
        if len(bow):
            n = 8  # points per bowed step
            kk = np.repeat(bow, n + 1)
            frac = np.tile(np.arange(n + 1) / n, len(bow))
            Pm = chain.fk(_hermite(t, qa, qd, qdd, kk, t[kk] + frac * (t[kk + 1] - t[kk])))[0]
            mb = np.zeros(len(Pm), bool)
            mb[n::n + 1] = True  # each bowed step is its own polyline
            tm = t[kk] + frac * (t[kk + 1] - t[kk]) - t[0]
            motion = Reference(Pm, mb, times=tm, window=2)
    return Reference(P, breaks, float(t[-1] - t[0]), rows, feed_mm_s, motion, t[idx] - t[0])


def reference_from_path(path, robot, duration_s: float | None = None, feed_mm_s: float | None = None) -> Reference:
    """The planned path from the raster ``Path`` itself: its poses of the process zones (world
    frame) in the robot base frame, broken between stretches."""
    from camtool.path.toolpath import ZONE_CODE

    zone = np.asarray(path.zone)
    proc = np.isin(zone, [ZONE_CODE["work"], ZONE_CODE["lead_in"], ZONE_CODE["lead_out"]])
    idx = np.flatnonzero(proc)
    Tb = np.linalg.inv(np.asarray(robot.base_T_mm, float))
    P = np.asarray(path.poses_mm, float)[idx, :3, 3] @ Tb[:3, :3].T + Tb[:3, 3]
    breaks = np.r_[np.diff(idx) != 1, True]
    work = zone == ZONE_CODE["work"]
    rows = int(np.sum(np.diff(np.r_[0, work.astype(int)]) == 1))
    return Reference(P, breaks, duration_s, rows, feed_mm_s)


def reference_from_samples(t_s, q, robot, feed_mm_s: float | None = None) -> Reference:
    """A planned path from timed joint samples without zones (a CSV program): one polyline."""
    P, _R = _Chain(robot).fk(np.asarray(q, float))
    breaks = np.zeros(len(P), bool)
    breaks[-1] = True
    return Reference(P, breaks, float(t_s[-1] - t_s[0]) if len(t_s) else None, None, feed_mm_s)
