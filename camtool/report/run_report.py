"""Run report: planner metrics, timing figures, per-point diagnostics and plots.

``OUTDIR/report.json`` (keys documented in docs/report.md), ``OUTDIR/points.csv``
and ``OUTDIR/plots/*.png``. Angles in degrees, lengths in mm, times in s.
"""
from __future__ import annotations

import json
import math
from pathlib import Path as FsPath

import numpy as np

from ..timing.feed import display_envelope
from ..path.toolpath import ZONE_CODE, ZONES, Path
from ..trajectory import JointPath, Trajectory
from .. import safe_io
from ..program.text import column_names

WORK = ZONE_CODE["work"]


def _edge(q: np.ndarray, prismatic: np.ndarray) -> np.ndarray:
    """Native joint values (rad / mm) to user units (deg / mm)."""
    return np.where(prismatic, q, np.degrees(q))


def adjacent_work_steps(jp: JointPath) -> np.ndarray:
    """Boolean mask over JointPath steps k -> k+1 that join two adjacent work poses."""
    idx = jp.path_index
    return (jp.zone[:-1] == WORK) & (jp.zone[1:] == WORK) & (idx[:-1] >= 0) & (idx[1:] == idx[:-1] + 1)


def plan_metrics(path: Path, jp: JointPath, robot, method: str, jump_threshold_deg: float,
                 jump_threshold_mm: float) -> dict:
    """The planner's figures: accuracy on work poses, jumps, reverse plans, retracts, speed."""
    work_rows = (jp.zone == WORK) & (jp.path_index >= 0)
    steps = np.abs(np.diff(jp.q, axis=0))
    adj = adjacent_work_steps(jp)
    rev = ~robot.prismatic
    thr = np.where(robot.prismatic, jump_threshold_mm, np.radians(jump_threshold_deg))
    on_surface = int(np.any(steps[adj] > thr, axis=1).sum()) if adj.any() else 0
    max_step_deg = float(np.degrees(steps[adj][:, rev].max())) if adj.any() else 0.0
    max_step_mm = float(steps[adj][:, ~rev].max()) if adj.any() and (~rev).any() else 0.0
    ev = jp.events
    seconds = float(ev.get("plan_seconds", 0.0))
    return {
        "robot": robot.name,
        "robot_conventions": {"source": robot.conventions.source, "summary": robot.conventions.summary(),
                              "reference": robot.conventions.reference},
        "method": method,
        "points_total": int(len(path)),
        "points_work": int(np.count_nonzero(path.zone == WORK)),
        "on_surface_jumps": on_surface,
        "max_joint_step_work_deg": round(max_step_deg, 6),
        "max_track_step_work_mm": round(max_step_mm, 6),
        "max_position_error_mm": float(jp.position_error_mm[work_rows].max()),
        "max_orientation_error_deg": float(np.degrees(jp.orientation_error_rad[work_rows].max())),
        "reverse_plans": len(ev.get("reverse_plans", [])),
        "reverse_plan_events": ev.get("reverse_plans", []),
        "retracts": len(ev.get("retracts", [])),
        "singular_points": ev.get("retracts", []),
        "gradient_projections": int(ev.get("gradient_projections", 0)),
        "start_configuration": ev.get("start_configuration"),
        "start_margin": None if ev.get("start_margin") is None else round(float(ev["start_margin"]), 4),
        "ik_seeds": ev.get("ik_seeds"),
        "reverse_plan_seconds": round(float(ev.get("reverse_plan_seconds", 0.0)), 4),
        "plan_seconds": round(seconds, 4),
        "plan_cpu_seconds": round(float(ev.get("plan_cpu_seconds", seconds)), 4),
        "points_per_second": round(len(path) / seconds, 1) if seconds > 0 else None,
    }


def stage_seconds(seconds: dict) -> dict:
    """report.json's ``stage_seconds``: wall seconds per stage of the run in the order they ran (ms), and
    their ``total``."""
    out = {str(k): round(float(v), 3) for k, v in seconds.items()}
    out["total"] = round(float(sum(seconds.values())), 3)
    return out


def write_json_atomic(obj: dict, file: FsPath) -> None:
    """Write JSON through a temporary file and a rename: never half-written, no temporary file left.

    NaN and infinite numbers become ``null`` (strict JSON); the file is 0644 like every other output.
    """
    file = FsPath(file)
    file.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(_strict(obj), indent=2, allow_nan=False) + "\n"
    safe_io.write_file(file.parent, file.name, text)  # O_EXCL|O_NOFOLLOW in a private folder, then renamed


def _strict(x):
    """JSON-ready copy: numpy values as Python ones, dict keys as strings, non-finite floats as None."""
    if isinstance(x, dict):
        return {str(_strict(k)) if not isinstance(k, str) else k: _strict(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_strict(v) for v in x]
    if isinstance(x, np.ndarray):
        return _strict(x.tolist())
    if isinstance(x, np.generic):
        return _strict(x.item())
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, FsPath):
        return str(x)
    return x


def write_points_csv(path: Path, jp: JointPath, robot, file: FsPath) -> None:
    """Per-point diagnostics: indices, zone, TCP position, joint values, IK errors, flags.

    CSV as the csv module writes it (comma-separated, CRLF), one format string a row:
    no field holds a comma, a quote or a line break."""
    file = FsPath(file)
    names = [f"{n}_{'mm' if p else 'deg'}" for n, p in zip(column_names(robot.joint_names), robot.prismatic)]
    step = np.zeros(len(jp.q))
    step[1:] = np.degrees(np.abs(np.diff(jp.q, axis=0))[:, ~robot.prismatic].max(axis=1))
    idx = np.asarray(jp.path_index, int)
    src = np.maximum(idx, 0)
    xyz = path.poses_mm[src, :3, 3].copy()
    for k in np.flatnonzero(idx < 0):   # inserted rows: the TCP of their own joint values
        xyz[k] = (robot.base_T_mm @ robot.fk_tcp(jp.q[k]))[:3, 3]
    seg = np.where(idx >= 0, path.segment[src], -1)
    pt = np.where(idx >= 0, path.point[src], 0)
    joints = _edge(np.asarray(jp.q, float), robot.prismatic)
    header = ["row", "path_index", "segment", "point", "zone", "x_mm", "y_mm", "z_mm", *names,
              "position_error_mm", "orientation_error_deg", "max_joint_step_deg", "jump",
              "reverse_planned", "retract", "singular", "reached"]
    row = ",".join(["%d", "%d", "%d", "%d", "%s", "%.4f", "%.4f", "%.4f", *(["%.5f"] * robot.dof),
                    "%.3e", "%.3e", "%.4f", "%d", "%d", "%d", "%d", "%d"]) + "\r\n"
    flags = np.stack([jp.jump, jp.reverse_planned, jp.retract, jp.singular, jp.reached], axis=1).astype(int)
    ori_deg = np.degrees(jp.orientation_error_rad)
    # Python numbers, not numpy scalars: the same text, formatted several times faster
    zones = [ZONES[z] for z in np.asarray(jp.zone).tolist()]
    lines = [row % (k, i, sg, p, z, *x, *q, e, o, st, *fl) for k, (i, sg, p, z, x, q, e, o, st, fl) in enumerate(zip(
        idx.tolist(), seg.tolist(), pt.tolist(), zones, xyz.tolist(), joints.tolist(),
        np.asarray(jp.position_error_mm, float).tolist(), ori_deg.tolist(), step.tolist(), flags.tolist()))]
    with open(file, "w", newline="") as f:
        f.write(",".join(header) + "\r\n")
        f.write("".join(lines))


def import_plotting():
    """matplotlib's pyplot on the Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_joints(trajectories: dict[str, Trajectory], robot, outdir: FsPath, dt_s: float = 0.02) -> list[FsPath]:
    """Joint angle, speed and acceleration against time (the paper's Figures 10-15).

    One PNG per quantity; with several trajectories (``--compare``), one column each. A long run
    is drawn as each time bin's lowest and highest value (``timing.feed.display_envelope``): the
    peaks a limit is judged by stay, and a 600 s cycle draws 6000 points a line instead of 30,000.
    """
    plt = import_plotting()
    outdir = FsPath(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    sampled = {name: tr.sample(dt_s) for name, tr in trajectories.items()}
    files = []
    for qi, (key, label, unit_r, unit_p) in enumerate((("angle", "joint value", "deg", "mm"),
                                                       ("speed", "joint speed", "deg/s", "mm/s"),
                                                       ("acceleration", "joint acceleration", "deg/s²", "mm/s²"))):
        cols = len(sampled)
        fig, axes = plt.subplots(2, cols, figsize=(7 * cols, 6), sharex="col", squeeze=False,
                                 gridspec_kw={"height_ratios": [1, 2]})
        for c, (name, (t, q, v, a, _j)) in enumerate(sampled.items()):
            x = (q, v, a)[qi]
            lim = (None, robot.limits.velocity, robot.limits.acceleration)[qi]
            top, bottom = axes[0, c], axes[1, c]
            for i, jn in enumerate(robot.joint_names):
                ax = top if robot.prismatic[i] else bottom
                y = x[:, i] if robot.prismatic[i] else np.degrees(x[:, i])
                ax.plot(*display_envelope(t, y), lw=0.7, label=jn)   # long runs: each bin's low and high
            if lim is not None and robot.prismatic.any():
                top.axhline(lim[robot.prismatic][0], color="r", ls=":", lw=0.8)
                top.axhline(-lim[robot.prismatic][0], color="r", ls=":", lw=0.8)
            if lim is not None:
                r = np.degrees(lim[~robot.prismatic].min())
                bottom.axhline(r, color="r", ls=":", lw=0.8)
                bottom.axhline(-r, color="r", ls=":", lw=0.8)
            top.set_title(f"{name}: {label}")
            top.set_ylabel(f"track [{unit_p}]" if robot.prismatic.any() else "")
            bottom.set_ylabel(f"revolute [{unit_r}]")
            bottom.set_xlabel("time [s]")
            bottom.legend(fontsize=7, ncol=4, loc="upper right")
            if not robot.prismatic.any():
                top.set_visible(False)
        fig.tight_layout()
        f = outdir / f"joint_{key}.png"
        safe_io.save_figure(fig, f, dpi=90)
        plt.close(fig)
        files.append(f)
    return files


def plot_unreachable(path: Path, unreachable: list[dict], file: FsPath) -> FsPath:
    """A map of the path with the unreachable poses marked (3-D view and x-z view)."""
    plt = import_plotting()
    file = FsPath(file)
    file.parent.mkdir(parents=True, exist_ok=True)
    p = path.poses_mm[:, :3, 3]
    bad = np.array([u["index"] for u in unreachable], dtype=int)
    fig = plt.figure(figsize=(12, 5))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    ax.plot(p[:, 0], p[:, 1], p[:, 2], lw=0.3, color="0.6")
    ax.scatter(p[bad, 0], p[bad, 1], p[bad, 2], s=4, color="r", label=f"unreachable ({len(bad)})")
    ax.set_xlabel("x [mm]"); ax.set_ylabel("y [mm]"); ax.set_zlabel("z [mm]")
    ax.legend()
    ax2 = fig.add_subplot(1, 2, 2)
    ax2.plot(p[:, 1], p[:, 2], lw=0.3, color="0.6")
    ax2.scatter(p[bad, 1], p[bad, 2], s=4, color="r")
    ax2.set_xlabel("y [mm]"); ax2.set_ylabel("z [mm]"); ax2.set_aspect("equal")
    ax2.set_title("unreachable poses (red), seen along x")
    fig.tight_layout()
    safe_io.save_figure(fig, file, dpi=90)
    plt.close(fig)
    return file
