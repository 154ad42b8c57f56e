"""Hypervolume of the two-step MOPSO front and of NSGA-II's at the same evaluation budget.

Both optimisers work on the same arm-design problem of the seed sphere job
(seed8, L1 in 300..600 mm, L3 in 300..500 mm; F1 arm length in mm, F2
singularities on the coarse raster; unreachable points = invalid), with the
same evaluation function and cache. The budget is MOPSO's:
particles x (1 + explore + optimise iterations). The hypervolume (pymoo) uses
a FIXED reference point: (the longest arm in the box + 10 mm, 10
singularities). Prints figures only; never asserts. Needs pymoo
(pip install 'camtool[design]').

    .venv/bin/python benchmarks/design_hypervolume.py [--seeds 0 1 2] [-j 2]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from camtool.design import DesignProblem, MopsoSettings, Variable, run_mopso
from camtool.design.nsga2 import hypervolume, run_nsga2
from camtool.design.objectives import robot_params
from camtool.job import load_job

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--job", default=str(ROOT / "samples" / "sphere.toml"))
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--particles", type=int, default=12)
    ap.add_argument("--explore-iters", type=int, default=3)
    ap.add_argument("--iters", type=int, default=5)
    ap.add_argument("--coarse", type=float, default=4.0)
    ap.add_argument("-j", "--jobs", type=int, default=1)
    args = ap.parse_args()

    job = load_job(args.job)
    variables = [Variable("L1", 300.0, 600.0), Variable("L3", 300.0, 500.0)]
    settings = MopsoSettings(particles=args.particles, explore_iters=args.explore_iters,
                             optimise_iters=args.iters)
    params = robot_params(job)
    longest_mm = sum(params.values()) - sum(params[v.name] for v in variables) + sum(v.upper_mm for v in variables)
    ref = np.array([longest_mm + 10.0, 10.0])
    print(f"job {args.job}; budget {settings.budget} evaluations per run "
          f"({args.particles} particles x (1 + {args.explore_iters} + {args.iters})); coarse x{args.coarse:g}")
    print(f"hypervolume reference point: length {ref[0]:g} mm, {ref[1]:g} singularities")
    rows = []
    with DesignProblem(job, variables, coarse=args.coarse, jobs=args.jobs) as problem:
        for seed in args.seeds:
            out = {}
            for method in ("mopso", "nsga2"):
                runs0, t0 = problem.planner_runs, time.perf_counter()
                if method == "mopso":
                    r = run_mopso(problem.evaluate, problem.lower, problem.upper, settings,
                                  np.random.default_rng(seed), resolution=problem.resolution_mm)
                    n_invalid = int(np.sum(r.violation > 0))
                else:
                    r = run_nsga2(problem.evaluate, problem.lower, problem.upper, settings.budget,
                                  settings.particles, seed, resolution=problem.resolution_mm)
                    n_invalid = int(np.sum(r.violation > 0))
                hv = hypervolume(r.front_F, ref)
                out[method] = hv
                front = "; ".join(f"L1 {x[0]:g} L3 {x[1]:g} -> {f[0]:g} mm/{int(f[1])}"
                                  for x, f in zip(r.front_X, r.front_F))
                print(f"seed {seed} {method:5s}: {r.evaluations:3d} evaluations ({n_invalid} invalid), "
                      f"hypervolume {hv:10.1f}, {problem.planner_runs - runs0:3d} new planner runs, "
                      f"{time.perf_counter() - t0:5.1f} s; front: {front}")
            rows.append(out)
        print(f"planner runs in all: {problem.planner_runs}, designs planned {problem.planned}, "
              f"requested {problem.requested}")
    for method in ("mopso", "nsga2"):
        v = np.array([r[method] for r in rows])
        print(f"{method:5s} hypervolume over {len(v)} seeds: mean {v.mean():.1f}, min {v.min():.1f}, max {v.max():.1f}")


if __name__ == "__main__":
    main()
