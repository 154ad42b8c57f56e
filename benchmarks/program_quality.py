"""Program quality: what the written controller programs make the robot do (prints figures,
never asserts).

For each job (the sample sphere job and the irb2400 plate) the trajectory is planned and
timed with camtool.run.stages, then ``camtool.program.post.write_programs`` writes, checks and
simulates every RAPID / INFORM program (``camtool.simulate``: the program re-executed as
the controller interpolates it, at 4 ms, against the planned path). Per program:

- motion instructions per metre of work (all moves / simulated TCP path length on work);
- exact stops and module / job switches on the surface (inside work rows);
- the simulated TCP's largest distance from the planned path on work (mm), and the
  tolerance ``post.path_tol_mm``;
- the share of work time within 1 % of the commanded feed;
- file sizes, and the time spent writing, checking and simulating (wall s per format;
  and the CPU seconds of the whole ``write_programs``, best of 3, one BLAS thread).

    .venv/bin/python benchmarks/program_quality.py [--job samples/sphere.toml ...] [--set KEY=VALUE ...]

The baseline column is today's writer before this change (commit 623b006, one MoveAbsJ /
MOVJ PL=0 per trajectory waypoint, modules split every 5000 moves / jobs every 2000
positions), measured on the same machine on the trajectories of that commit: its programs
simulated with the row boundaries taken from the trajectory (they had no row markers), and
``write_programs`` (write + check, best of 3) timed on the same trajectory.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # CPU seconds of one thread, comparable with the baseline

ROOT = Path(__file__).resolve().parents[1]
JOBS = [ROOT / "samples" / "sphere.toml", ROOT / "samples" / "irb2400_plate.toml"]

# commit 623b006, measured at the start of this change (see the module doc)
BASELINE = {
    ("sphere", "rapid"): dict(moves=14154, per_m=274.8, stops_on_work=0, switches_on_work=1, max_dev_mm=0.0181,
                              within_1pct=0.672, bytes=2260636),
    ("sphere", "inform"): dict(moves=14154, per_m=274.8, stops_on_work=10375, switches_on_work=5, max_dev_mm=0.0197,
                               within_1pct=0.672, bytes=1486560),
    ("irb2400_plate", "rapid"): dict(moves=3820, per_m=343.6, stops_on_work=0, switches_on_work=0, max_dev_mm=0.0772,
                                     within_1pct=0.522, bytes=551067),
}
# CPU seconds (one BLAS thread) of write_programs, write + check of every format, CSV included, best of 3,
# of commit 623b006 on the trajectories of this tree (camtool time ... -o DIR; same machine)
BASELINE_POST_S = {"sphere": 1.12, "irb2400_plate": 0.094}


def trajectory_for(job):
    """(robot, raster path, timed trajectory) of a job, as `camtool run` plans them."""
    from camtool.run.job_settings import JobSettings
    from camtool.run.stages import (
        part_for_checks,
        path_for_job,
        plan_and_time,
        robot_for_job,
        surface_for_job,
        workpiece_for_job,
    )

    robot = robot_for_job(job)
    settings = JobSettings.from_job(job, robot)
    wp = workpiece_for_job(job)
    surface = surface_for_job(job, wp)
    path = path_for_job(job, surface)
    _joint_path, trajectory = plan_and_time(settings, path, robot, workpiece=part_for_checks(settings, wp, surface))
    return robot, path, trajectory


def measure(job_file: Path, overrides: list[str]) -> list[dict]:
    from camtool.job import load_job
    from camtool.run.post_inputs import write_job_programs

    job = load_job(job_file, overrides)
    t0 = time.perf_counter()
    robot, path, trajectory = trajectory_for(job)
    t_plan = time.perf_counter() - t0
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        t_post = float("inf")
        for _ in range(3):  # best of 3, CPU time
            report: dict = {}
            t0 = time.process_time()
            files = write_job_programs(trajectory, robot, job, Path(tmp), path=path, report=report)
            t_post = min(t_post, time.process_time() - t0)
        sizes = {f.name: f.stat().st_size for f in files}
    for fmt, fig in report.items():
        wl = fig["work_length_mm"] / 1000.0
        rows.append(dict(job=job_file.stem, format=fmt, moves=fig["moves"], per_m=fig["moves"] / max(wl, 1e-9),
                         work_m=wl, stops_on_work=fig["exact_stops_on_surface"],
                         switches_on_work=fig["part_switches_on_surface"], max_dev_mm=fig["max_deviation_mm"],
                         tol_mm=fig["path_tol_mm"], within_1pct=fig["feed"].get("within_1pct", float("nan")),
                         bytes=fig["bytes"], write_s=fig["write_s"], check_s=fig["check_s"],
                         simulate_s=fig["simulate_s"], time_err=(fig["duration_s"] / fig["planned_duration_s"] - 1)))
    for r in rows:
        r.update(post_s=t_post, plan_s=t_plan, files=len(sizes))
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--job", action="append", type=Path, help="job file(s) (default: sphere and irb2400 plate)")
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    args = ap.parse_args(argv)
    jobs = args.job or JOBS
    print("program quality: written programs re-executed by camtool.simulate (4 ms) against the planned path")
    head = (f"{'job / format':<22} {'moves':>7} {'per m':>7} {'stops':>6} {'switch':>6} {'dev mm':>8} {'tol':>5} "
            f"{'feed1%':>7} {'bytes':>9} {'write':>6} {'check':>6} {'sim':>6} {'time':>7}")
    print(head)
    print("-" * len(head))
    for jf in jobs:
        for r in measure(jf, args.overrides):
            print(f"{r['job'] + ' / ' + r['format']:<22} {r['moves']:>7d} {r['per_m']:>7.1f} {r['stops_on_work']:>6d} "
                  f"{r['switches_on_work']:>6d} {r['max_dev_mm']:>8.4f} {r['tol_mm']:>5.2f} {100 * r['within_1pct']:>6.1f}% "
                  f"{r['bytes']:>9d} {r['write_s']:>6.3f} {r['check_s']:>6.3f} {r['simulate_s']:>6.3f} "
                  f"{100 * r['time_err']:>+6.2f}%")
            b = BASELINE.get((r["job"], r["format"]))
            if b:
                print(f"{'  baseline (623b006)':<22} {b['moves']:>7d} {b['per_m']:>7.1f} {b['stops_on_work']:>6d} "
                      f"{b['switches_on_work']:>6d} {b['max_dev_mm']:>8.4f} {'':>5} {100 * b['within_1pct']:>6.1f}% "
                      f"{b['bytes']:>9d}")
                print(f"{'  ratio':<22} {'':>7} {r['per_m'] / b['per_m']:>7.3f}")
        print(f"{jf.stem}: write_programs (every format, CSV included; write + check + simulate) {r['post_s']:.3f} "
              f"CPU s; baseline (write + check) {BASELINE_POST_S.get(jf.stem, float('nan')):.3f} CPU s; "
              f"planning {r['plan_s']:.1f} s")
    print("stops / switch: exact stops and module/job switches on the surface; dev: largest simulated distance from "
          "the planned path on work; feed1%: share of work time within 1 % of the commanded feed; time: program "
          "time against the plan")
    return 0


if __name__ == "__main__":
    sys.exit(main())
