"""`camtool place` on 13 placements of sphere patches and plates around seed8, irb2400 and sia20.

Eight of the user placements are out of reach (some poses beyond the arm),
five are reachable. For each, ``place`` searches x, y, z in -300..300 mm (and
yaw in -30..30 deg where the part was turned) and the table shows whether it
found a placement that plans with every pose reachable, how long it took, and
the cost of the chosen placement beside the user's (docs/placement.md:
cycle time x (1 + margin penalty) x (1 + move term), from the full plan; the
user's cost is '-' when their placement does not plan). The user's cost and
the chosen one are both from the real pipeline (fit, raster, plan, time).

The rasters are coarsened (step-over 20 mm, pitch 10 mm) to keep the run to a
few minutes; ``--full`` uses each job's own raster. Prints figures only;
never asserts.

    .venv/bin/python benchmarks/placement.py [-j 2] [--full] [--only 2 5]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from camtool.job import load_job
from camtool.placement.search import PlacementProblem, parse_vary

ROOT = Path(__file__).resolve().parents[1]
XYZ = ("x=-300:300", "y=-300:300", "z=-300:300")
CASES = [  # (label, job file, --set overrides, --vary)
    ("seed8 sphere, as shipped", "sphere.toml", [], XYZ),
    ("seed8 sphere, 150 mm higher", "sphere.toml", ["cell.workpiece_xyz_mm=[1000,0,250]"], XYZ),
    ("seed8 sphere, 300 mm to the side", "sphere.toml", ["cell.workpiece_xyz_mm=[1000,300,100]"], XYZ),
    ("seed8 sphere, 100 mm farther", "sphere.toml", ["cell.workpiece_xyz_mm=[1100,0,100]"], XYZ),
    ("seed8 sphere, 250 mm lower", "sphere.toml", ["cell.workpiece_xyz_mm=[1000,0,-150]"], XYZ),
    ("seed8 sphere, turned 20 deg", "sphere.toml", ["cell.workpiece_rpy_deg=[0,0,20]"], XYZ + ("yaw=-30:30",)),
    ("seed8 plate, as shipped", "plate_hole.toml", [], XYZ),
    ("seed8 plate, 550 mm higher", "plate_hole.toml", ["cell.workpiece_xyz_mm=[700,0,900]"], XYZ),
    ("irb2400 plate, as shipped", "irb2400_plate.toml", [], XYZ),
    ("irb2400 plate, 700 mm farther", "irb2400_plate.toml", ["cell.workpiece_xyz_mm=[1700,0,900]"], XYZ),
    ("irb2400 plate, 800 mm higher", "irb2400_plate.toml", ["cell.workpiece_xyz_mm=[1000,0,1700]"], XYZ),
    ("sia20 plate, at 600 mm", "plate_hole.toml", ["robot.name=sia20", "cell.workpiece_xyz_mm=[600,0,400]"], XYZ),
    ("sia20 plate, at 900 mm", "plate_hole.toml", ["robot.name=sia20", "cell.workpiece_xyz_mm=[900,0,400]"], XYZ),
]
QUICK = ["raster.step_over_mm=20", "raster.pitch_mm=10"]


def _cost(v) -> str:
    if v is None:
        return "-"
    return f"{v['cost']:.1f}" if v["ok"] else f"- ({v['unreachable']} unr.)"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-j", "--jobs", type=int, default=1)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--full", action="store_true", help="each job's own raster (slower)")
    ap.add_argument("--only", type=int, nargs="+", help="case numbers (1-based) to run")
    args = ap.parse_args()
    print(f"{len(CASES)} placements; raster {'as in each job' if args.full else 'step-over 20 mm, pitch 10 mm'}; "
          f"{args.jobs} process(es); seed {args.seed}")
    head = (f"{'#':>2}  {'case':<34} {'poses':>6}  {'user screen':<16} {'found':<5} {'wall s':>6}  "
            f"{'move (dx, dy, dz mm, yaw)':<28} {'cost user':>14} {'cost chosen':>11} {'cycle user':>10} "
            f"{'cycle chosen':>12}")
    print(head)
    found, total_s, rows = 0, 0.0, 0
    for n, (label, file, sets, vary) in enumerate(CASES, 1):
        if args.only and n not in args.only:
            continue
        rows += 1
        job = load_job(ROOT / "samples" / file, sets + ([] if args.full else QUICK))
        t0 = time.perf_counter()
        with PlacementProblem(job, [parse_vary(v) for v in vary], args.jobs) as problem:
            study = problem.run(seed=args.seed)
        wall = time.perf_counter() - t0
        total_s += wall
        user = study.verified.get(study.zero)
        u = study.user
        screen = "reachable" if u.feasible else f"{u.unreachable} out of reach"
        chosen = study.verified.get(study.chosen) if study.chosen else None
        found += chosen is not None
        move = "-"
        if study.chosen is not None:
            dx, dy, dz, yaw = study.chosen[:4]
            move = f"({dx:+.0f}, {dy:+.0f}, {dz:+.0f}" + (f", {yaw:+.1f} deg" if yaw else "")
            move += (f", tilt {study.chosen[4]:+.1f}/{study.chosen[5]:+.1f} deg)" if len(study.chosen) > 4 else ")")
        cyc_u = f"{user['cycle_s']:.1f}" if user and user["ok"] else "-"
        cyc_c = f"{chosen['cycle_s']:.1f}" if chosen else "-"
        print(f"{n:>2}  {label:<34} {study.n_poses:>6}  {screen:<16} {'yes' if chosen else 'NO':<5} {wall:>6.1f}  "
              f"{move:<28} {_cost(user):>14} {_cost(chosen):>11} {cyc_u:>10} {cyc_c:>12}", flush=True)
    print(f"place found a placement that plans with every pose reachable for {found} of {rows}; "
          f"{total_s:.1f} s in all, {total_s / max(rows, 1):.1f} s per placement")


if __name__ == "__main__":
    main()
