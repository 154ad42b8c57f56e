"""Where a run's work feed goes (issue #46): the time law's own speed bound on every piece of every surface run.

    PYTHONPATH=. python benchmarks/feed_budget.py JOB.toml RUN_DIR [--feed 100]

Reads RUN_DIR/points.csv (the planned joint path, every row) and re-builds each surface run's spline as the time
stage does (``timing.runs.path_parameter`` knots, ``timing.pathlaw.PathSpline``), then bounds the constant feed
on each piece exactly (``pathlaw.speed_bounds``: q' v, q'' v^2, q''' v^3 against 98 % of the limits). It prints,
for all rows and for the Path's own poses only (rows the planner inserted -- sag, densify, spline_bow -- left out):

- the length-weighted median over rows of each row's lowest work bound (``slow_scope = "row"`` runs every row at
  it, so this is close to report.json's median work feed) and the least;
- the share of the work length whose own piece bound is below 20 / 50 / 80 / 98 % of the feed;
- which piece length class and joint set each row's lowest bound (the binding piece).

No time law is planned (the S-curves' ramps only lower the feed further), so it runs in seconds on a finished run.
"""
from __future__ import annotations

import argparse
import csv
from collections import Counter

import numpy as np

from camtool.job import load_job
from camtool.run.stages import robot_for_job
from camtool.timing.pathlaw import PathSpline, speed_bounds
from camtool.timing.runs import path_parameter

SURFACE = ("lead_in", "work", "lead_out")
CLASSES_MM = (0.2, 0.7, 2.0)     # piece length classes: < 0.2, 0.2-0.7, 0.7-2, >= 2 mm


def read_rows(points_csv: str) -> dict:
    with open(points_csv, newline="") as f:
        rows = list(csv.DictReader(f))
    seg = np.array([int(r["segment"]) for r in rows])
    last = np.maximum.accumulate(np.where(seg >= 0, np.arange(len(seg)), 0))
    return {"zone": np.array([r["zone"] for r in rows]), "segment": seg[last],
            "path_index": np.array([int(r["path_index"]) for r in rows]),
            "xyz": np.array([[float(r[k]) for k in ("x_mm", "y_mm", "z_mm")] for r in rows]),
            "q": np.radians(np.array([[float(r[f"j{i}_deg"]) for i in range(1, 7)] for r in rows]))}


def surface_runs(d: dict) -> list[np.ndarray]:
    """Row indices of each surface run: consecutive lead / work rows of one segment."""
    surf = np.isin(d["zone"], SURFACE)
    brk = np.r_[True, (np.diff(d["segment"]) != 0) | ~surf[1:] | ~surf[:-1]]
    starts = np.flatnonzero(surf & brk)
    ends = np.r_[starts[1:], len(surf)]
    return [np.arange(a, b)[surf[a:b]] for a, b in zip(starts, ends)]


def piece_class(h: float) -> str:
    names = ("< 0.2", "0.2-0.7", "0.7-2", ">= 2")
    return names[int(np.searchsorted(CLASSES_MM, h, side="right"))]


def budget(d: dict, runs: list, limits, feed: float, path_poses_only: bool) -> dict:
    row_min, row_len, pieces, lens, binding = [], [], [], [], Counter()
    for k in runs:
        if path_poses_only:
            k = k[d["path_index"][k] >= 0]
        z = d["zone"][k]
        work = (z[:-1] == "work") & (z[1:] == "work")
        if len(k) < 3 or not work.any():
            continue
        step = np.linalg.norm(np.diff(d["xyz"][k], axis=0), axis=1)
        s = path_parameter(d["q"][k], step, limits, feed)
        bound, joint, kind = speed_bounds(*PathSpline(s, d["q"][k]).piece_bounds(), limits)
        w = np.flatnonzero(work)
        i = w[np.argmin(bound[w])]
        binding[(piece_class(step[i]), f"j{joint[i] + 1}", ("speed", "acceleration", "jerk")[kind[i]])] += 1
        row_min.append(min(bound[i], feed))
        row_len.append(step[w].sum())
        pieces.append(np.minimum(bound[w], feed))
        lens.append(step[w])
    row_min, row_len = np.array(row_min), np.array(row_len)
    o = np.argsort(row_min)
    c = np.cumsum(row_len[o]) / row_len.sum()
    b, L = np.concatenate(pieces), np.concatenate(lens)
    below = {p: float(L[b < p / 100 * feed].sum() / L.sum()) for p in (20, 50, 80, 98)}
    return {"rows": len(row_min), "median": float(row_min[o][np.searchsorted(c, 0.5)]), "least": float(row_min.min()),
            "below": below, "binding": binding}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("job")
    ap.add_argument("run_dir")
    ap.add_argument("--feed", type=float, default=100.0)
    a = ap.parse_args()
    limits = robot_for_job(load_job(a.job, [])).limits
    d = read_rows(f"{a.run_dir}/points.csv")
    runs = surface_runs(d)
    for label, only in (("every row", False), ("the Path's poses only", True)):
        r = budget(d, runs, limits, a.feed, only)
        below = "  ".join(f"<{p}%: {v:.3f}" for p, v in r["below"].items())
        print(f"{label:22s} {r['rows']} rows: row feed bound median {r['median']:.1f} least {r['least']:.1f} mm/s; "
              f"work length below the feed share: {below}")
        print(" " * 23 + "binding pieces (length mm, joint, limit): "
              + ", ".join(f"{k[0]} {k[1]} {k[2]}: {n}" for k, n in r["binding"].most_common(5)))


if __name__ == "__main__":
    main()
