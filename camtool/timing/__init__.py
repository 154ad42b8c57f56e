"""Time a JointPath into a Trajectory within every joint limit; report and check it.

Entry points:

- ``time_trajectory(joint_path, path, robot, settings)`` -> ``TimedTrajectory``
  (``settings``: ``camtool.settings.TimingSettings``)
- ``timing_report(trajectory, robot, sampled)`` (``sampled``: ``SampledMotion``, ``sampled.py``)
- ``check_trajectory(trajectory, robot, dt_s=None, samples=None)`` (independent checker, ``check.py``)
- ``sampled_for(trajectory, robot, dt_s)``: what a TimedTrajectory's check gathered of its samples, else
  a new sampling; ``limit_findings(trajectory, robot, dt_s)``: the check's findings, [] for a
  TimedTrajectory it passed

Surface zones (work, lead_in, lead_out) are split into *runs*: consecutive
surface poses of one path segment. Each run is a cubic spline through its poses
in TCP length, at rest at both ends; its time law holds the work at a constant
feed (``feed``, ``slow_scope``) and puts the jerk-limited ramps at the run ends,
in the leads (``runs.py``, ``pathlaw.py``). With ``method="ruckig"`` every piece
between two poses is then replaced by a jerk-limited ruckig state-to-state move
between the same states, written out exactly (``ruckig_through.py``); a piece
ruckig cannot give keeps the law's own samples and is listed as a fallback.
Everything between runs (self-motion, approach, depart, retract) is a free
chain: with ``zones="flow"`` (default) one jerk-limited motion along a spline
through its poses (``flow.py``), with ``zones="stop"`` rest-to-rest ruckig moves
(``ruckig_moves.py``). ``assemble.py`` puts the pieces together; ``feed.py``
measures the TCP feed. See docs/timing.md.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable

import numpy as np

from ..errors import BadInput, CamtoolError, PlanInfeasible
from ..path.toolpath import ZONE_CODE, ZONES
from ..trajectory import Trajectory, TrajectorySamples, sample_trajectory
from .assemble import (SURFACE_ZONES, lead_needed_mm, place, run_layout, short_leads, slowdowns, time_surface,
                       timeline_pieces)
from .check import check_trajectory
from .feed import feed_profile, feed_statistics, plot_feed, tcp_positions_world
from .runs import lead_bound_mm
from .sampled import MotionGatherer, SampledMotion, sample_motion

if TYPE_CHECKING:
    from ..settings import TimingSettings

__all__ = ["TimedTrajectory", "TrajectorySamples", "SampledMotion", "check_trajectory", "sample_trajectory",
           "sampled_for", "limit_findings",
           "time_trajectory", "timing_report", "plot_feed_png", "feed_profile", "feed_statistics",
           "lead_needed_mm", "lead_bound_mm", "tcp_positions_world", "SURFACE_ZONES"]

MAX_LISTED_FALLBACKS = 20      # ruckig fallback pieces listed one by one in the report


@dataclass(frozen=True)
class TimedTrajectory(Trajectory):
    """A Trajectory plus how it was timed: method, TCP feed and policy, the slowed rows, the short leads.

    ``slowdowns``: one dict per work stretch (the whole row with ``slow_scope="row"``)
    run below the commanded feed because a limit does not allow it: JointPath rows,
    Path indices, time span, ``feed_mm_s``, ``speed_ratio`` (feed / commanded), the
    binding ``joint`` and ``limit`` ("speed", "acceleration", "jerk", or "ramps" when
    lowered to fit its speed changes). ``short_leads``: one dict per ramp from / to
    rest that does not fit its lead (run, side, first / last work row, ``lead_mm``,
    ``needed_mm``). Per surface piece (waypoint to
    next waypoint of a run): ``piece_row`` (JointPath row it starts at),
    ``piece_zone``, ``piece_ruckig`` (True if it is a ruckig move) and
    ``piece_reason`` ("" or why a ruckig piece kept its quintic).

    ``sampled``: what ``time_trajectory``'s limit check gathered of the samples it
    checked (``SampledMotion`` at ``settings.check_dt_s``), for the figures
    (``sampled_for``); its presence says the check passed. Not an init argument,
    not compared, not shown, not saved, and not carried over by
    ``dataclasses.replace`` (None then).
    """

    method: str = ""
    tcp_speed_mm_s: float = 0.0
    slowdowns: tuple = ()
    feed: str = ""
    slow_scope: str = ""
    short_leads: tuple = ()
    piece_row: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    piece_zone: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    piece_ruckig: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    piece_reason: np.ndarray = field(default_factory=lambda: np.zeros(0, str))
    sampled: SampledMotion | None = field(default=None, init=False, repr=False, compare=False,
                                          metadata={"transient": True})


def _checked(trajectory: Trajectory, dt_s: float) -> SampledMotion | None:
    sampled = trajectory.sampled if isinstance(trajectory, TimedTrajectory) else None
    return sampled if sampled is not None and sampled.matches(trajectory, dt_s) else None


def sampled_for(trajectory: Trajectory, robot, dt_s: float) -> SampledMotion:
    """The trajectory sampled at ``dt_s`` for the figures: what ``time_trajectory``'s check gathered when
    it checked at ``dt_s``, else a new ``sample_motion`` (e.g. a trajectory loaded from a file)."""
    return _checked(trajectory, dt_s) or sample_motion(trajectory, robot, dt_s)


def limit_findings(trajectory: Trajectory, robot, dt_s: float) -> list[str]:
    """``check_trajectory`` at ``dt_s``: [] for a TimedTrajectory that ``time_trajectory`` checked at that
    step (it is raised there otherwise), else the check's findings (a trajectory from a file)."""
    return [] if _checked(trajectory, dt_s) is not None else check_trajectory(trajectory, robot, dt_s)


def _validate(joint_path, path, robot) -> None:
    """The joint path itself: shape, finite values, Path indices, joint limits (the settings are the job schema's)."""
    q = np.asarray(joint_path.q, float)
    if q.ndim != 2 or q.shape[1] != robot.dof or len(q) < 1:
        raise BadInput(f"joint path has shape {q.shape}, expected (N, {robot.dof}) for {robot.name}")
    if not np.all(np.isfinite(q)):
        raise PlanInfeasible(f"joint path row {int(np.nonzero(~np.isfinite(q).all(axis=1))[0][0])} "
                             "has non-finite joint values")
    pidx = np.asarray(joint_path.path_index)
    if np.any(pidx >= len(path)):
        raise BadInput(f"joint path refers to Path pose {int(pidx.max())}, but the Path has {len(path)} poses")
    L = robot.limits
    tol = 1e-9 * (1 + np.maximum(np.abs(L.lower), np.abs(L.upper)))
    out = (q < L.lower - tol) | (q > L.upper + tol)
    if out.any():
        i, j = (int(x[0]) for x in np.nonzero(out))
        val = q[i, j] if robot.prismatic[j] else np.degrees(q[i, j])
        unit = "mm" if robot.prismatic[j] else "deg"
        raise PlanInfeasible(f"joint path row {i}: joint {robot.joint_names[j]} = {val:.4g} {unit} is outside "
                             "its limits; it cannot be timed")


def time_trajectory(joint_path, path, robot, settings: TimingSettings,
                    before_check: Callable[[TimedTrajectory], None] | None = None) -> TimedTrajectory:
    """Time ``joint_path`` (rad / mm per row) into a TimedTrajectory within every joint limit.

    ``path`` gives the TCP positions (mm, world frame) used for the TCP speed on
    surface zones. ``settings`` (``TimingSettings``, validated by the job
    schema): ``method`` "quintic" or "ruckig" (surface-piece interpolation),
    ``tcp_speed_mm_s`` (the commanded feed), ``feed`` "constant" or "max" and
    ``slow_scope`` "row" or "stretch" (``runs.py``), ``zones`` "flow" (free chains
    pass their poses without stopping, ``flow.py``) or "stop" (rest at every free
    pose), and
    ``check_dt_s``: the result is verified by ``check_trajectory`` on a
    resampling at that step (what the figures need kept as ``sampled``), and a CamtoolError is
    raised if it breaks a limit. ``before_check(trajectory)`` is told the trajectory before that check
    (the raster task starts the independent motion check on it, alongside; a finding of the 4 ms
    check is raised all the same and ends the run).
    """
    _validate(joint_path, path, robot)
    L = robot.limits
    zone = np.asarray(joint_path.zone)
    layout = run_layout(joint_path, path)
    surface = time_surface(joint_path, path, robot, layout, settings.method, settings.tcp_speed_mm_s,
                           settings.feed, settings.slow_scope, settings.feed_factor)
    pieces = timeline_pieces(joint_path, robot, layout, surface, settings.zones)
    placed = place(pieces)
    s = placed.samples
    p = surface.pieces
    traj = TimedTrajectory(
        robot_name=robot.name, joint_names=tuple(robot.joint_names), prismatic=np.array(robot.prismatic, bool),
        t_s=s.t_s, q=s.q, qd=s.qd, qdd=s.qdd,
        zone=s.zone.astype(zone.dtype if zone.dtype.kind in "iu" else int),
        path_index=s.path_index.astype(int),
        limits={"lower": L.lower.copy(), "upper": L.upper.copy(), "velocity": L.velocity.copy(),
                "acceleration": L.acceleration.copy(), "jerk": L.jerk.copy()},
        method=settings.method, tcp_speed_mm_s=float(settings.tcp_speed_mm_s),
        slowdowns=slowdowns(surface, pieces, placed, joint_path, robot),
        feed=settings.feed, slow_scope=settings.slow_scope, short_leads=short_leads(surface, joint_path),
        piece_row=surface.rows[p].astype(int), piece_zone=zone[surface.rows[p]].astype(int),
        piece_ruckig=np.asarray(surface.interpolation.piece_ruckig, bool),
        piece_reason=np.asarray(surface.interpolation.piece_reason, str),
    )
    if before_check is not None:
        before_check(traj)
    gather = MotionGatherer(traj, robot, settings.check_dt_s)
    findings = check_trajectory(traj, robot, settings.check_dt_s, each_block=gather)
    if findings:
        raise CamtoolError(f"timing produced a trajectory that breaks a limit ({len(findings)} findings): "
                           f"{findings[0]}")
    object.__setattr__(traj, "sampled", gather.result())  # derived data, set once before anyone sees traj
    return traj


def _piece_figures(tr) -> dict:
    """Share of surface pieces that are ruckig moves (all, and work only) and the fallbacks."""
    rk = np.asarray(getattr(tr, "piece_ruckig", np.zeros(0, bool)), bool)
    zone = np.asarray(getattr(tr, "piece_zone", np.zeros(0, int)))
    reason = np.asarray(getattr(tr, "piece_reason", np.zeros(0, str)), str)
    rows = np.asarray(getattr(tr, "piece_row", np.zeros(0, int)))
    work = zone == ZONE_CODE["work"]
    is_ruckig = getattr(tr, "method", "") == "ruckig"
    fall = np.flatnonzero(~rk) if is_ruckig else np.zeros(0, int)
    by_reason = {str(r): int(c) for r, c in zip(*np.unique(reason[fall], return_counts=True))}
    return {
        "surface_pieces": int(len(rk)),
        "ruckig_piece_share": float(rk.mean()) if len(rk) else 0.0,
        "ruckig_work_piece_share": float(rk[work].mean()) if work.any() else 0.0,
        "ruckig_fallbacks": {
            "count": int(len(fall)), "by_reason": by_reason,
            "first": [{"row": int(rows[k]), "zone": ZONES[int(zone[k])], "reason": str(reason[k])}
                      for k in fall[:MAX_LISTED_FALLBACKS]]},
    }


def _feed_figures(tr, sampled: SampledMotion) -> dict:
    """TCP feed on work measured on the samples (``feed.py``); {} without a commanded feed."""
    feed = float(getattr(tr, "tcp_speed_mm_s", 0.0) or 0.0)
    if feed <= 0 or len(sampled.t_s) < 2:
        return {}
    return feed_statistics(feed_profile(tr, sampled), feed)


def plot_feed_png(trajectory: Trajectory, sampled: SampledMotion, png_path, title: str = ""):
    """Write a PNG of the TCP feed against TCP path length (work highlighted, the commanded feed and its
    +-1 % / +-2 % bands marked) measured on ``sampled``; returns the file's path (matplotlib, Agg)."""
    feed = float(getattr(trajectory, "tcp_speed_mm_s", 0.0) or 0.0)
    return plot_feed(feed_profile(trajectory, sampled), feed, png_path, title)


def timing_report(trajectory: Trajectory, robot, sampled: SampledMotion) -> dict:
    """Cycle time, peak joint use (|value| / limit over the samples: ``sampled``, from ``sampled_for``),
    work time, the TCP feed on work measured on the samples (``work_feed``: shares of work length within
    +-1 % / +-2 % of the commanded feed, min / median / max work feed), slowed rows with their binding
    joint, short leads, share of ruckig pieces and ruckig fallbacks."""
    tr = trajectory
    if not isinstance(sampled, SampledMotion):
        raise TypeError("timing_report: sampled must be the trajectory's SampledMotion "
                        "(sampled_for(trajectory, robot, dt_s))")
    if not sampled.matches(tr):
        raise ValueError(f"timing_report: the samples ({sampled.waypoints} waypoints) are not those of this "
                         f"trajectory ({len(tr.t_s)} waypoints)")
    per_joint = sampled.peak_ratio
    peaks = per_joint.max(axis=1)
    work = ZONE_CODE["work"]
    both_work = (tr.zone[:-1] == work) & (tr.zone[1:] == work)
    return {
        "cycle_time_s": float(tr.t_s[-1] - tr.t_s[0]),
        "work_time_s": float(np.diff(tr.t_s)[both_work].sum()),
        "peak_joint_speed_ratio": float(peaks[0]),
        "peak_joint_acc_ratio": float(peaks[1]),
        "peak_joint_jerk_ratio": float(peaks[2]),
        "peak_ratio_per_joint": {
            name: {"speed": float(per_joint[0, i]), "acc": float(per_joint[1, i]), "jerk": float(per_joint[2, i])}
            for i, name in enumerate(robot.joint_names)},
        "method": getattr(tr, "method", ""),
        "tcp_speed_mm_s": getattr(tr, "tcp_speed_mm_s", 0.0),
        "feed_policy": getattr(tr, "feed", ""),
        "slow_scope": getattr(tr, "slow_scope", ""),
        "work_feed": _feed_figures(tr, sampled),
        "slowdowns": [dict(s) for s in getattr(tr, "slowdowns", ())],
        "short_leads": [dict(s) for s in getattr(tr, "short_leads", ())],
        **_piece_figures(tr),
        "waypoints": int(len(tr.t_s)),
    }
