"""Timing quality on real jobs beside TOPP-RA: cycle time, work time, feed on work.

For each job variant (the seed sphere sample, its 2.5 mm pitch variant and a harder
placement) the joint path is planned once with camtool.run.stages, timed by
``camtool.timing.time_trajectory`` with the job's timing settings, and measured on
the trajectory resampled at ``timing.check_dt_ms`` (TCP by FK, feed = TCP distance /
time; shares are shares of work length). The anchor is TOPP-RA (``toppra``, the
``bench`` extra) on the same joint path: the same sections (runs rest at their ends,
free chains rest at their ends and at hard steps), each a cubic spline through the
same poses (runs in TCP chord length, free chains in joint-space cruise time), the
same joint speed and acceleration limits (100 %, camtool uses 98 %), no jerk limit,
and the TCP capped at the commanded feed on work.

    .venv/bin/python benchmarks/timing_quality.py [--case sample|pitch25|hard] [--set KEY=VALUE ...]
        [--png DIR]

``--set`` overrides apply to every case (e.g. ``--set timing.zones=stop``). With the default
``timing.slow_scope = "row"`` each case is also timed with ``"stretch"`` (a second camtool column).
``--png DIR`` writes the feed plot of every camtool timing. Needs ``toppra`` (``pip install toppra``).
"""
from __future__ import annotations

import argparse
import logging
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from camtool.job import load_job
from camtool.run.job_settings import JobSettings
from camtool.run.stages import (
    part_for_checks,
    path_for_job,
    plan_with_sized_leads,
    robot_for_job,
    surface_for_job,
    workpiece_for_job,
)
from camtool.timing import time_trajectory
from camtool.timing.assemble import run_layout, tcp_positions_mm
from camtool.timing.feed import feed_profile, feed_statistics, plot_feed
from camtool.timing.flow import hard_steps
from camtool.path.toolpath import ZONE_CODE

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "samples" / "sphere.toml"
CASES = {
    "sample": [],
    "pitch25": ["raster.pitch_mm=2.5"],
    "hard": ["cell.workpiece_xyz_mm=[1000.0, -250.0, 100.0]"],  # 250 mm aside: more joint motion per row
}
WORK = ZONE_CODE["work"]


# ----------------------------------------------------------------------------- TOPP-RA anchor


def _toppra_section(qs: np.ndarray, u: np.ndarray, limits, work_range=None, feed=None, sub: int = 3):
    """(duration, work time) of one rest-to-rest section by TOPP-RA on a cubic spline q(u)."""
    import toppra as ta
    import toppra.algorithm as algo
    import toppra.constraint as constraint

    spline = ta.SplineInterpolator(u, qs)
    grid = np.unique(np.concatenate([u] + [u[:-1] + (k / sub) * np.diff(u) for k in range(1, sub)]))
    vel, acc = limits.velocity, limits.acceleration

    def vlim(s):  # on work, every joint's speed is capped at feed * |dq/ds|: that caps ds/dt (TCP) at the feed
        v = vel
        if work_range is not None and work_range[0] - 1e-9 <= s <= work_range[1] + 1e-9:
            v = np.minimum(vel, np.maximum(feed * np.abs(spline(s, 1)), 1e-9))
        return np.column_stack([-v, v])

    pc_v = constraint.JointVelocityConstraintVarying(vlim)
    pc_a = constraint.JointAccelerationConstraint(np.column_stack([-acc, acc]))
    inst = algo.TOPPRA([pc_v, pc_a], spline, gridpoints=grid, parametrizer="ParametrizeConstAccel")
    inst.compute_parameterization(0.0, 0.0)
    sd = inst.problem_data.sd_vec
    if sd is None:
        raise RuntimeError("TOPP-RA failed on a section")
    ds = np.diff(grid)
    dt = 2 * ds / np.maximum(sd[:-1] + sd[1:], 1e-12)
    work = 0.0
    if work_range is not None:
        mid = 0.5 * (grid[:-1] + grid[1:])
        work = float(dt[(mid > work_range[0]) & (mid < work_range[1])].sum())
    return float(dt.sum()), work


def toppra_anchor(joint_path, path, robot, feed: float) -> dict:
    """Cycle, work, lead and free time of the TOPP-RA anchor on ``joint_path`` (see the module doc)."""
    L = robot.limits
    q = np.asarray(joint_path.q, float)
    zone = np.asarray(joint_path.zone)
    layout = run_layout(joint_path, path)
    pos = tcp_positions_mm(joint_path, path, robot)
    total = work = free = 0.0
    prev_end = 0
    runs = layout.runs()

    def chain(rows):
        nonlocal total, free
        qs = q[rows]
        keep = np.r_[True, np.abs(np.diff(qs, axis=0)).max(axis=1) > 1e-12]
        rows = rows[keep]
        qs = q[rows]
        if len(qs) < 2:
            return
        hard = hard_steps(qs, robot.prismatic, np.asarray(joint_path.jump)[rows],
                          (zone[rows] == ZONE_CODE["retract"]) | np.asarray(joint_path.retract)[rows])
        cuts = np.r_[0, np.flatnonzero(hard), np.flatnonzero(hard) + 1, len(qs) - 1]
        cuts = np.unique(cuts)
        for a, b in zip(cuts[:-1], cuts[1:]):
            sq = qs[a:b + 1]
            h = (np.abs(np.diff(sq, axis=0)) / L.velocity).max(axis=1)
            u = np.r_[0.0, np.cumsum(h)]
            d, _ = _toppra_section(sq, u, L, sub=20)
            total += d
            free += d

    for a, b in runs:
        if a > prev_end:
            chain(np.arange(prev_end, a + 1))
        rows = np.arange(a, b + 1)
        s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(pos[rows], axis=0), axis=1))]
        keep = np.r_[True, np.diff(s) > 1e-9]
        rows, s = rows[keep], s[keep]
        if len(rows) < 2:
            prev_end = b
            continue
        w = np.flatnonzero(zone[rows] == WORK)
        wr = (s[w[0]], s[w[-1]]) if len(w) else None
        # parameter u = TCP length / feed (s): TOPP-RA's solver is badly conditioned with u in mm
        d, wt = _toppra_section(q[rows], s / feed, L, None if wr is None else (wr[0] / feed, wr[1] / feed), 1.0)
        total += d
        work += wt
        prev_end = b
    if len(q) - 1 > prev_end:
        chain(np.arange(prev_end, len(q)))
    return {"cycle_time_s": total, "work_time_s": work, "free_time_s": free, "lead_time_s": total - work - free}


# ----------------------------------------------------------------------------- camtool


def zone_times(tr) -> dict:
    """Work, lead and free time of a camtool trajectory (waypoint intervals by their zones)."""
    z = np.asarray(tr.zone)
    dt = np.diff(tr.t_s)
    lead = np.isin(z, [ZONE_CODE["lead_in"], ZONE_CODE["lead_out"]])
    surf = lead | (z == WORK)
    work = (z[:-1] == WORK) & (z[1:] == WORK)
    on_surface = surf[:-1] & surf[1:]
    return {"work_time_s": float(dt[work].sum()), "lead_time_s": float(dt[on_surface & ~work].sum()),
            "free_time_s": float(dt[~on_surface].sum())}


def time_and_measure(jp, path, robot, timing, png: Path | None, title: str) -> dict:
    """camtool's timing of the joint path, measured on its check samples."""
    t0 = time.perf_counter()
    tr = time_trajectory(jp, path, robot, timing)
    wall = time.perf_counter() - t0
    prof = feed_profile(tr, tr.sampled)
    if png is not None:
        plot_feed(prof, timing.tcp_speed_mm_s, png, title=title)
    return {"cycle_time_s": tr.duration_s, **zone_times(tr), **feed_statistics(prof, timing.tcp_speed_mm_s),
            "timing_s": wall, "slowed_rows": len({s.get("run", s["first_row"]) for s in tr.slowdowns}),
            "short_leads": len(getattr(tr, "short_leads", ())),
            "label": f"{getattr(timing, 'feed', '-')}/{getattr(timing, 'slow_scope', '-')}/{timing.zones}"}


def run_case(name: str, overrides: list[str], png_dir: Path | None) -> dict:
    """Plan the case once; time it with the job's settings (and with slow_scope = "stretch" when the job's
    is "row"), and by TOPP-RA."""
    job = load_job(SAMPLE, overrides)
    robot = robot_for_job(job)
    settings = JobSettings.from_job(job, robot)
    wp = workpiece_for_job(job)
    surface = surface_for_job(job, wp)
    # planned as `camtool run` plans it: smoothed runs, leads sized for the ramps
    path, jp = plan_with_sized_leads(settings, surface, path_for_job(job, surface), robot,
                                     part_for_checks(settings, wp, surface))
    feed = settings.timing.tcp_speed_mm_s
    png = (lambda tag: None if png_dir is None else Path(png_dir) / f"feed_{name}{tag}.png")
    runs = [time_and_measure(jp, path, robot, settings.timing, png(""), f"{name}: {' '.join(overrides)}")]
    if getattr(settings.timing, "feed", "") == "constant" and settings.timing.slow_scope == "row":
        stretch = replace(settings.timing, slow_scope="stretch")
        runs.append(time_and_measure(jp, path, robot, stretch, png("_stretch"),
                                     f"{name}: {' '.join(overrides)} timing.slow_scope=stretch"))
    t1 = time.perf_counter()
    anchor = toppra_anchor(jp, path, robot, feed)
    wall_anchor = time.perf_counter() - t1
    return {"name": name, "overrides": overrides, "poses": len(jp.q), "feed": feed, "camtool": runs,
            "lead_mm": jp.events.get("leads", {}).get("lead_mm_used", settings.raster.lead_mm),
            "smoothed_runs": len(jp.events.get("smoothed_runs", [])),
            "toppra": {**anchor, "timing_s": wall_anchor}}


def print_case(r: dict) -> None:
    runs, a = r["camtool"], r["toppra"]
    c0 = runs[0]
    print(f"\n{r['name']} ({' '.join(r['overrides']) or 'as is'}; {r['poses']} poses, "
          f"work {c0['work_length_mm'] / 1000:.1f} m at {r['feed']:g} mm/s; leads {r['lead_mm']:g} mm, "
          f"{r['smoothed_runs']} runs smoothed)")
    head = "".join(f"{'camtool ' + c['label']:>30s}{'ratio':>7s}" for c in runs)
    print(f"  {'':26s}{head}{'TOPP-RA':>10s}")
    for key, label in (("cycle_time_s", "cycle time [s]"), ("work_time_s", "work time [s]"),
                       ("lead_time_s", "lead time [s]"), ("free_time_s", "free chains [s]")):
        cells = "".join(f"{c[key]:28.1f}{c[key] / max(a[key], 1e-9):7.3f}" for c in runs)
        print(f"  {label:26s}{cells}{a[key]:10.1f}")
    for key, label in (("work_share_within_1pct", "work within +-1 % of feed"),
                       ("work_share_within_2pct", "work within +-2 % of feed")):
        cells = "".join(f"{100 * c[key]:27.1f}%{'':7s}" for c in runs)
        print(f"  {label:26s}{cells}{'-':>10s}")
    cells = "".join(f"{c['min_work_feed_mm_s']:20.1f} / {c['median_work_feed_mm_s']:5.1f}{'':7s}" for c in runs)
    print(f"  {'min / median work feed':26s}{cells}{'<= feed':>10s}")
    cells = "".join(f"{c['slowed_rows']:20d} / {c['short_leads']:5d}{'':7s}" for c in runs)
    print(f"  {'slowed rows / short leads':26s}{cells}{'-':>10s}")
    cells = "".join(f"{c['timing_s']:28.1f}{'':7s}" for c in runs)
    print(f"  {'time to compute [s]':26s}{cells}{a['timing_s']:10.1f}")


def main(argv=None):
    logging.getLogger("toppra").setLevel(logging.ERROR)
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--case", action="append", choices=list(CASES))
    ap.add_argument("--set", action="append", default=[], dest="overrides")
    ap.add_argument("--png", type=Path, default=None)
    args = ap.parse_args(argv)
    for name in args.case or list(CASES):
        print_case(run_case(name, CASES[name] + args.overrides, args.png))
        sys.stdout.flush()


if __name__ == "__main__":
    main()
