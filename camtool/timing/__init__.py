"""Time a JointPath into a Trajectory within every joint limit; report and check it.

Entry points:

- ``time_trajectory(joint_path, path, robot, method, tcp_speed_mm_s, check_dt_ms)``
- ``timing_report(trajectory, robot)``
- ``check_trajectory(trajectory, robot, dt_s)`` (independent checker, ``check.py``)

Surface zones (work, lead_in, lead_out) are split into *runs*: consecutive
surface poses of one path segment. Each run starts and ends at rest; inside,
the TCP moves at ``tcp_speed_mm_s`` (smooth ramps at both ends) and the joint
path is interpolated by quintic Hermite pieces with finite-difference
through-velocities and -accelerations, stretched locally where a limit would
be broken (``quintic.py``). With ``method="ruckig"`` every such piece is then
replaced by a jerk-limited ruckig state-to-state move between the same states,
written out exactly (``ruckig_through.py``); a piece ruckig cannot give keeps
its quintic and is listed as a fallback. Everything
between runs (self-motion, approach, depart, retract) is timed by rest-to-rest
ruckig moves (``ruckig_moves.py``) with ``zones="stop"``; with ``zones="flow"``
a free chain passes its intermediate poses without stopping (``flow.py``).
See docs/timing.md.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import BadInput, CamtoolError, PlanInfeasible
from ..toolpath import ZONE_CODE, ZONES
from ..trajectory import Trajectory
from .check import check_trajectory
from .flow import flow_chain, hard_steps
from .quintic import MARGIN, time_runs
from .ruckig_moves import RuckigMover, rest_to_rest_chain
from .ruckig_through import on_grid, through_pieces

__all__ = ["TimedTrajectory", "check_trajectory", "time_trajectory", "timing_report", "SURFACE_ZONES"]

SURFACE_ZONES = ("work", "lead_in", "lead_out")
METHODS = ("quintic", "ruckig")
ZONE_MODES = ("stop", "flow")
SLOWDOWN_REPORT_RATIO = 0.995  # pieces slower than this share of the planned TCP speed are reported
MAX_LISTED_FALLBACKS = 20      # ruckig fallback pieces listed one by one in the report


@dataclass(frozen=True)
class TimedTrajectory(Trajectory):
    """A Trajectory plus how it was timed: method, TCP speed and the slow-downs applied.

    ``slowdowns``: one dict per stretch of surface pieces slowed below the set
    TCP speed to respect a limit: JointPath rows, Path indices, time span and
    the lowest speed ratio (actual / planned). Per surface piece (waypoint to
    next waypoint of a run): ``piece_row`` (JointPath row it starts at),
    ``piece_zone``, ``piece_ruckig`` (True if it is a ruckig move) and
    ``piece_reason`` ("" or why a ruckig piece kept its quintic).
    """

    method: str = ""
    tcp_speed_mm_s: float = 0.0
    slowdowns: tuple = ()
    piece_row: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    piece_zone: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    piece_ruckig: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    piece_reason: np.ndarray = field(default_factory=lambda: np.zeros(0, str))


def _tcp_positions_mm(joint_path, path, robot) -> np.ndarray:
    """World-frame TCP position per JointPath row: from the Path, or by FK for inserted poses."""
    pidx = np.asarray(joint_path.path_index)
    pos = np.empty((len(pidx), 3))
    on = pidx >= 0
    pos[on] = np.asarray(path.poses_mm)[pidx[on], :3, 3]
    for i in np.nonzero(~on)[0]:
        pos[i] = (robot.base_T_mm @ robot.fk_tcp(joint_path.q[i]))[:3, 3]
    return pos


def _validate(joint_path, path, robot, method, tcp_speed_mm_s, check_dt_ms, zones="stop"):
    if method not in METHODS:
        raise BadInput(f"timing.method: expected one of {', '.join(METHODS)}, found {method!r}")
    if zones not in ZONE_MODES:
        raise BadInput(f"timing.zones: expected one of {', '.join(ZONE_MODES)}, found {zones!r}")
    if not tcp_speed_mm_s > 0:
        raise BadInput(f"timing.tcp_speed_mm_s: expected a number > 0, found {tcp_speed_mm_s}")
    if not check_dt_ms > 0:
        raise BadInput(f"timing.check_dt_ms: expected a number > 0, found {check_dt_ms}")
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


def _runs(joint_path, path):
    """Run-start and run-end flags per JointPath row (surface poses of one segment)."""
    zone = np.asarray(joint_path.zone)
    pidx = np.asarray(joint_path.path_index)
    surface = np.isin(zone, [ZONE_CODE[z] for z in SURFACE_ZONES])
    seg = np.where(pidx >= 0, np.asarray(path.segment)[np.maximum(pidx, 0)], -1)
    n = len(zone)
    same_prev = np.zeros(n, bool)
    same_prev[1:] = surface[:-1] & surface[1:] & (seg[1:] == seg[:-1])
    start = surface & ~same_prev
    end = np.zeros(n, bool)
    end[:-1] = surface[:-1] & ~same_prev[1:]
    end[-1] = surface[-1]
    return surface, start, end


def _inner_zone(z0: np.ndarray, z1: np.ndarray) -> np.ndarray:
    """Zone of samples inside a piece: its ends' zone, or the non-work one where they differ.

    So a piece counts as work time (both ends work) exactly as it does without samples.
    """
    return np.where((z0 == z1) | (z1 == ZONE_CODE["work"]), z0, z1)


def _slowdowns(h_plan, h_final, piece_rows, run_of_piece, t_piece_start, joint_path, zone):
    """Group consecutive surface pieces that run below the planned TCP speed."""
    ratio = h_plan / h_final
    slow = ratio < SLOWDOWN_REPORT_RATIO
    out = []
    k = 0
    n = len(slow)
    pidx = np.asarray(joint_path.path_index)
    while k < n:
        if not slow[k]:
            k += 1
            continue
        e = k
        while e + 1 < n and slow[e + 1] and run_of_piece[e + 1] == run_of_piece[k]:
            e += 1
        a, b = int(piece_rows[k]), int(piece_rows[e]) + 1
        out.append({
            "first_row": a, "last_row": b,
            "first_path_index": int(pidx[a]), "last_path_index": int(pidx[b]),
            "t_start_s": float(t_piece_start[k]), "t_end_s": float(t_piece_start[e] + h_final[e]),
            "speed_ratio": float(ratio[k:e + 1].min()),
            "zone": ZONES[int(zone[a])],
            "at_run_end": bool(k == 0 or run_of_piece[k - 1] != run_of_piece[k]
                               or e == n - 1 or run_of_piece[e + 1] != run_of_piece[e]),
        })
        k = e + 1
    return tuple(out)


def time_trajectory(joint_path, path, robot, method: str = "quintic", tcp_speed_mm_s: float = 100.0,
                    check_dt_ms: float = 4.0, zones: str = "stop") -> TimedTrajectory:
    """Time ``joint_path`` (rad / mm per row) into a TimedTrajectory within every joint limit.

    ``path`` gives the TCP positions (mm, world frame) used for the TCP speed on
    surface zones; ``method`` is "quintic" or "ruckig" (work-zone
    interpolation); the result is verified by ``check_trajectory`` at
    ``check_dt_ms`` and a CamtoolError is raised if it breaks a limit. ``zones``:
    "stop" (rest at every free pose) or "flow" (free chains pass their poses
    without stopping, ``flow.py``).
    """
    _validate(joint_path, path, robot, method, tcp_speed_mm_s, check_dt_ms, zones)
    L = robot.limits
    q = np.asarray(joint_path.q, float)
    zone = np.asarray(joint_path.zone)
    pidx = np.asarray(joint_path.path_index)
    n, dof = q.shape
    surface, start, end = _runs(joint_path, path)

    # --- surface runs: TCP time law, through-derivatives, local slow-down
    sidx = np.nonzero(surface)[0]
    pos = _tcp_positions_mm(joint_path, path, robot)
    first, last = start[sidx], end[sidx]
    run_id = np.cumsum(first) - 1
    step_mm = np.linalg.norm(np.diff(pos[sidx], axis=0), axis=1)
    runs = time_runs(q[sidx], step_mm, first, last, run_id, L, tcp_speed_mm_s)
    s_qd, s_qdd = runs.qd, runs.qdd
    pieces = np.nonzero(~last[:-1])[0] if len(sidx) > 1 else np.zeros(0, int)
    h_final = runs.h_s.copy()
    inner = None
    piece_ruckig = np.zeros(len(pieces), bool)
    piece_reason = np.full(len(pieces), "", dtype=object)
    if method == "ruckig" and len(pieces):
        through = through_pieces(L, q[sidx], s_qd, s_qdd, runs.h_s, pieces, share=MARGIN)
        h_final[pieces] = through.duration_s
        inner = (pieces[through.piece], through.t_s, through.q, through.qd, through.qdd)
        piece_ruckig, piece_reason = through.used, through.reason
    row_of = {int(r): k for k, r in enumerate(sidx)}  # JointPath row -> surface waypoint

    # --- assemble items in JointPath order: runs and the free chains between them
    mover = RuckigMover(L)
    parts_t, parts_q, parts_qd, parts_qdd, parts_zone, parts_pidx = [], [], [], [], [], []
    t_offset = 0.0
    piece_t0 = np.zeros(max(len(sidx) - 1, 0))

    def emit(t_rel, qq_, vv_, aa_, zz, pp, skip_first):
        nonlocal t_offset
        s = 1 if skip_first else 0
        parts_t.append(t_offset + t_rel[s:])
        parts_q.append(qq_[s:])
        parts_qd.append(vv_[s:])
        parts_qdd.append(aa_[s:])
        parts_zone.append(np.asarray(zz)[s:])
        parts_pidx.append(np.asarray(pp)[s:])
        t_offset += float(t_rel[-1])

    def emit_free(chain):
        if zones == "flow":
            rows_ = np.asarray(chain)
            hard = hard_steps(q[rows_], robot.prismatic, np.asarray(joint_path.jump)[rows_],
                              (zone[rows_] == ZONE_CODE["retract"]) | np.asarray(joint_path.retract)[rows_])
            t_rel, cq, cv, ca, pose = flow_chain(mover, q[rows_], hard)
        else:
            t_rel, cq, cv, ca, pose = rest_to_rest_chain(mover, q[chain])
        rows = np.asarray(chain)
        step_zone = np.empty(len(chain), int)
        for k in range(len(chain)):
            nxt = rows[min(k + 1, len(rows) - 1)]
            if not surface[nxt]:
                step_zone[k] = zone[nxt]
            elif not surface[rows[k]]:
                step_zone[k] = zone[rows[k]]
            else:
                step_zone[k] = ZONE_CODE["self_motion"]
        prev_pose = np.maximum.accumulate(np.where(pose >= 0, pose, 0))
        zz = np.where(pose >= 0, zone[rows[np.maximum(pose, 0)]], step_zone[prev_pose])
        pp = np.where(pose >= 0, pidx[rows[np.maximum(pose, 0)]], -1)
        emit(t_rel, cq, cv, ca, zz, pp, skip_first=bool(parts_t))

    def snap_to_grid():
        """Start a ruckig run on the exact time grid: stretch the last free interval by < 1 ns."""
        nonlocal t_offset
        g = float(on_grid(t_offset, up=True))
        if g != t_offset:
            last = next(p for p in reversed(parts_t) if len(p))
            last[-1] = g
            t_offset = g

    def emit_run(a, b):
        ka, kb = row_of[a], row_of[b]
        if inner is not None and parts_t:
            snap_to_grid()
        h = h_final[ka:kb]
        t_way = np.concatenate([[0.0], np.cumsum(h)])
        piece_t0[ka:kb] = t_offset + t_way[:-1]
        t_rel, rq, rv, ra = t_way, q[sidx[ka:kb + 1]], s_qd[ka:kb + 1], s_qdd[ka:kb + 1]
        zz, pp = zone[sidx[ka:kb + 1]], pidx[sidx[ka:kb + 1]]
        if inner is not None and kb > ka:
            sel = (inner[0] >= ka) & (inner[0] < kb)
            if sel.any():
                ti = t_way[inner[0][sel] - ka] + inner[1][sel]
                t_rel = np.concatenate([t_rel, ti])
                rq = np.concatenate([rq, inner[2][sel]])
                rv = np.concatenate([rv, inner[3][sel]])
                ra = np.concatenate([ra, inner[4][sel]])
                zz = np.concatenate([zz, _inner_zone(zone[sidx[inner[0][sel]]], zone[sidx[inner[0][sel] + 1]])])
                pp = np.concatenate([pp, np.full(int(sel.sum()), -1)])
                o = np.argsort(t_rel, kind="stable")
                t_rel, rq, rv, ra, zz, pp = t_rel[o], rq[o], rv[o], ra[o], zz[o], pp[o]
        emit(t_rel, rq, rv, ra, zz, pp, skip_first=bool(parts_t))

    run_starts = np.nonzero(start)[0]
    run_ends = np.nonzero(end)[0]
    prev_end = None
    for a, b in zip(run_starts, run_ends):
        lo = 0 if prev_end is None else prev_end
        chain = list(range(lo, a + 1))
        if len(chain) >= 2:
            emit_free(chain)
        emit_run(int(a), int(b))
        prev_end = int(b)
    tail = list(range(0 if prev_end is None else prev_end, n))
    if len(tail) >= 2 or not parts_t:
        emit_free(tail)

    t_s = np.concatenate(parts_t)
    traj = TimedTrajectory(
        robot_name=robot.name, joint_names=tuple(robot.joint_names), prismatic=np.asarray(robot.prismatic, bool),
        t_s=t_s, q=np.concatenate(parts_q), qd=np.concatenate(parts_qd), qdd=np.concatenate(parts_qdd),
        zone=np.concatenate(parts_zone).astype(zone.dtype if zone.dtype.kind in "iu" else int),
        path_index=np.concatenate(parts_pidx).astype(int),
        limits={"lower": L.lower.copy(), "upper": L.upper.copy(), "velocity": L.velocity.copy(),
                "acceleration": L.acceleration.copy(), "jerk": L.jerk.copy()},
        method=method, tcp_speed_mm_s=float(tcp_speed_mm_s),
        slowdowns=_slowdowns(runs.h_plan_s[pieces], h_final[pieces], sidx[pieces], run_id[pieces],
                             piece_t0[pieces], joint_path, zone) if len(pieces) else (),
        piece_row=sidx[pieces].astype(int), piece_zone=zone[sidx[pieces]].astype(int),
        piece_ruckig=np.asarray(piece_ruckig, bool), piece_reason=np.asarray(piece_reason, str),
    )
    findings = check_trajectory(traj, robot, dt_s=check_dt_ms / 1000.0)
    if findings:
        raise CamtoolError(f"timing produced a trajectory that breaks a limit ({len(findings)} findings): "
                           f"{findings[0]}")
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


def timing_report(trajectory: Trajectory, robot, dt_s: float = 0.004) -> dict:
    """Cycle time, peak joint use (|value| / limit, from a ``dt_s`` resampling), work time, slow-downs,
    share of ruckig pieces and ruckig fallbacks."""
    tr = trajectory
    L = robot.limits
    peaks = {"speed": 0.0, "acc": 0.0, "jerk": 0.0}
    per_joint = np.zeros((3, robot.dof))
    m = len(tr.t_s)
    step = 20000
    for a in range(0, max(m - 1, 1), step):
        b = min(a + step, m - 1)
        part = Trajectory(tr.robot_name, tr.joint_names, tr.prismatic, tr.t_s[a:b + 1], tr.q[a:b + 1],
                          tr.qd[a:b + 1], tr.qdd[a:b + 1], tr.zone[a:b + 1], tr.path_index[a:b + 1])
        _t, _q, v, acc, j = part.sample(dt_s)
        for r, (x, lim) in enumerate(((v, L.velocity), (acc, L.acceleration), (j, L.jerk))):
            np.maximum(per_joint[r], (np.abs(x) / lim).max(axis=0), out=per_joint[r])
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
        "slowdowns": [dict(s) for s in getattr(tr, "slowdowns", ())],
        **_piece_figures(tr),
        "waypoints": int(m),
    }
