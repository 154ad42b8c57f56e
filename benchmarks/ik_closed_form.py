"""Closed-form IK against numerical CWLN on the same poses (prints figures, never asserts).

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/ik_closed_form.py

IRB2400 (datasheet geometry): 500 poses = FK of random q inside the limits.
Closed form: all solutions (``solve``) and the least-change pick (``best``).
CWLN: from a start 0.3 rad (every joint) away from the generating q, and
from a random start. SIA-20: arm-angle IK, 8 families per call.
"""
import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one core, before numpy loads

import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from camtool.plan.cwln import CwlnSolver, IkSettings  # noqa: E402
from camtool.robots import get_robot  # noqa: E402
from camtool.robots.ik_spherical_wrist import SphericalWristIK  # noqa: E402
from camtool.robots.ik_srs import SrsIK  # noqa: E402
from camtool.transforms import rotation_angle_rad  # noqa: E402

N = 500


def per_call_us(fn, items):
    t = time.perf_counter()
    out = [fn(x) for x in items]
    return (time.perf_counter() - t) / len(items) * 1e6, out


def main():
    robot = get_robot("irb2400")
    rng = np.random.default_rng(0)
    # configurations the controller takes: inside the joint box and the coupled axis 3 (j2 + j3)
    draw = rng.uniform(robot.limits.lower, robot.limits.upper, (4 * N, 6))
    qs = draw[robot.conventions.within_limits(draw)][:N]
    poses = [robot.fk(q) for q in qs]
    ik = SphericalWristIK(robot)
    us, sols = per_call_us(ik.solve, poses)
    err = max(max(np.linalg.norm(robot.fk(s.q)[:3, 3] - T[:3, 3]) for s in S) for S, T in zip(sols, poses))
    print(f"irb2400 closed form, all solutions: {us:8.1f} us/pose, mean {np.mean([len(s) for s in sols]):.2f} "
          f"solutions, worst FK error {err:.1e} mm")
    us, _ = per_call_us(lambda k: ik.best(poses[k], qs[k] + 0.3), range(N))
    print(f"irb2400 closed form, best near q_ref: {us:8.1f} us/pose")
    cw = CwlnSolver(robot, IkSettings(max_iterations=300))
    for label, starts in (("start 0.3 rad off", qs + 0.3), ("random start", rng.uniform(robot.limits.lower,
                                                                                          robot.limits.upper, (N, 6)))):
        us, res = per_call_us(lambda k: cw.solve(poses[k], np.clip(starts[k], robot.limits.lower,
                                                                  robot.limits.upper)), range(N))
        ok = np.mean([r.converged for r in res])
        print(f"irb2400 CWLN, {label:>17}: {us:8.1f} us/pose, converged {100 * ok:5.1f} %")
    sia = get_robot("sia20_paper")   # seed 002's table
    srs = SrsIK(sia)
    qa = rng.uniform(sia.limits.lower, sia.limits.upper, (N, 7))
    sp = [sia.fk(q) for q in qa]
    us, out = per_call_us(lambda T: srs.solve(T, 0.7), sp)
    err = max(max(rotation_angle_rad(sia.fk(s.q), T) for s in S) for S, T in zip(out, sp))
    print(f"sia20_paper arm-angle IK, 8 families:{us:8.1f} us/pose, worst orientation error {err:.1e} rad")


if __name__ == "__main__":
    main()
