"""Planner speed on the seed sphere job, one core, beside two anchors in the same run.

Prints points per second for:
- camtool's full seed strategy (plan_path: start search, CWLN, jump checks, GP,
  connectors) on the seed job's path;
- camtool's compiled CWLN hot loop alone (warm-started along the same poses, up to
  the first pose it cannot take without a jump);
- anchor 1: a plain damped-least-squares loop on Pinocchio, warm-started;
- anchor 2: roboticstoolbox-python's C++ ``ik_LM``, warm-started (benchmark-only
  extra; skipped with a note when not installed).
Every timed call is warmed up first, outside the timed region (numba compiles or
loads a kernel on its first call with given argument types; the anchors build
their models). All solve the same poses to about the same tolerance; the accuracy each reached
is measured by one FK (Pinocchio) and printed too. With ``--dense`` it also
plans the dense variant (2 mm x 2 mm) in a child process and prints its peak RSS.

    .venv/bin/python benchmarks/plan_speed.py [--dense]
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[var] = "1"

import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

from camtool.job import load_job  # noqa: E402
from camtool.run.pipeline import path_for_job, robot_for_job, surface_for_job, workpiece_for_job  # noqa: E402
from camtool.plan import plan_path  # noqa: E402
from camtool.plan.cwln import IkSettings  # noqa: E402
from camtool.plan.kernel import DhKernel, warm_up  # noqa: E402
from camtool.transforms import rotation_angle_rad  # noqa: E402
from camtool.settings import PlannerSettings

ROOT = Path(__file__).resolve().parents[1]


def accuracy(robot, qs, targets):
    pe = max(np.linalg.norm(robot.fk_tcp(q)[:3, 3] - T[:3, 3]) for q, T in zip(qs, targets))
    oe = max(np.degrees(rotation_angle_rad(robot.fk_tcp(q), T)) for q, T in zip(qs, targets))
    return pe, oe


def plain_dls(robot, targets, q0, lam=1e-3, tol_m=1e-7, tol_rad=np.radians(1e-4), max_it=100):
    """Anchor 1: the loop a user writes first: Pinocchio FK + Jacobian, damped least squares."""
    model, data, fid = robot.model, robot.model.createData(), robot.flange_frame_id
    scale = np.where(robot.prismatic, 1e-3, 1.0)
    q = q0 * scale
    out = []
    for T in targets:
        target = pin.SE3(T[:3, :3], T[:3, 3] * 1e-3)
        for _ in range(max_it):
            pin.framesForwardKinematics(model, data, q)
            M = data.oMf[fid]
            err = pin.log6(M.actInv(target)).vector  # in the local frame
            if np.linalg.norm(err[:3]) < tol_m and np.linalg.norm(err[3:]) < tol_rad:
                break
            J = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)
            q = q + J.T @ np.linalg.solve(J @ J.T + lam**2 * np.eye(6), err)
        out.append(q / scale)
    return np.array(out)


def rtb_robot(robot):
    import roboticstoolbox as rtb

    links = []
    for row in robot.dh:
        cls = rtb.PrismaticMDH if row.prismatic else rtb.RevoluteMDH
        if row.prismatic:
            links.append(cls(a=row.a_mm / 1e3, alpha=row.alpha_rad, theta=row.theta_rad, offset=row.d_mm / 1e3,
                             qlim=[-1.0, 1.0]))
        else:
            links.append(cls(a=row.a_mm / 1e3, alpha=row.alpha_rad, d=row.d_mm / 1e3, offset=row.theta_rad))
    return rtb.DHRobot(links)


def rtb_ik_lm(robot, targets, q0, tol):
    """Anchor 2: roboticstoolbox's C++ Levenberg-Marquardt IK (ETS.ik_LM), warm-started.

    Its ``tol`` bounds 0.5 e^T e (m, rad): 1e-6 leaves ~0.1 mm of error, 1e-10
    reaches ~1e-5 mm, comparable with camtool's 1e-4 mm tolerance."""
    bot = rtb_robot(robot).ets()
    scale = np.where(robot.prismatic, 1e-3, 1.0)
    q = q0 * scale
    Ts = [np.vstack([np.hstack([T[:3, :3], T[:3, 3:4] * 1e-3]), [0, 0, 0, 1]]) for T in targets]
    out = []
    for T in Ts:
        sol = bot.ik_LM(T, q0=q, tol=tol)
        q = sol[0]
        out.append(q / scale)
    return np.array(out)


def timed(fn, *args):
    t = time.perf_counter()
    r = fn(*args)
    return r, time.perf_counter() - t


def dense_child():
    job = load_job(ROOT / "samples" / "sphere.toml", ["raster.step_over_mm=2", "raster.pitch_mm=2"])
    path = path_for_job(job, surface_for_job(job, workpiece_for_job(job)))
    t = time.perf_counter()
    jp = plan_path(path, robot_for_job(job), PlannerSettings.make(**job.planner))
    dt = time.perf_counter() - t
    rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"dense variant: {len(path)} poses planned in {dt:.2f} s ({len(path) / dt:,.0f} points/s), "
          f"peak RSS {rss_mb:,.0f} MB (goal <= 2048 MB); reverse plans {len(jp.events['reverse_plans'])}")


def main():
    if "--dense-child" in sys.argv:
        return dense_child()
    warm_up()
    job = load_job(ROOT / "samples" / "sphere.toml")
    path = path_for_job(job, surface_for_job(job, workpiece_for_job(job)))
    robot = robot_for_job(job)
    targets = np.einsum("ij,njk->nik", np.linalg.inv(robot.base_T_mm), path.poses_mm)
    n = len(path)
    print(f"seed sphere job: {n} poses ({int(path.is_work.sum())} work), robot {robot.name}, one core\n")

    # warm-up outside every timed region: numba compiles (or loads from its cache) each kernel for the
    # argument types it is first called with, so each is called once on these very arrays first
    plan_path(path, robot, PlannerSettings.make(**job.planner))
    jp, t_seed = timed(lambda: plan_path(path, robot, PlannerSettings.make(**job.planner)))
    q0 = jp.q[0]
    kernel = DhKernel(robot, IkSettings(), False, np.full(robot.dof, np.inf))
    kernel.run(targets[:2].copy(), q0)
    (stop, q_k, _pe, _oe), t_kernel = timed(kernel.run, targets, q0)
    rows = [("camtool seed strategy (plan_path)", n, t_seed, accuracy(robot, jp.q[jp.path_index >= 0][::50], targets[::50])),
            ("camtool CWLN kernel (hot loop only)", stop, t_kernel, accuracy(robot, q_k[:stop:50], targets[:stop:50]))]
    m = 2000  # the Python anchors are slow: time them on the first poses
    plain_dls(robot, targets[:5], q0)  # warm-up
    q_p, t_plain = timed(plain_dls, robot, targets[:m], q0)
    rows.append(("anchor: plain DLS loop on Pinocchio", m, t_plain, accuracy(robot, q_p[::20], targets[:m:20])))
    try:
        for tol in (1e-6, 1e-10):
            rtb_ik_lm(robot, targets[:5], q0, tol)  # warm-up (the robot model, the C++ extension)
            q_r, t_rtb = timed(rtb_ik_lm, robot, targets[:m], q0, tol)
            rows.append((f"anchor: roboticstoolbox ik_LM tol {tol:g}", m, t_rtb,
                         accuracy(robot, q_r[::20], targets[:m:20])))
    except ImportError:
        print("(roboticstoolbox-python not installed: pip install roboticstoolbox-python for anchor 2)")
    print(f"{'method':<42}{'poses':>8}{'seconds':>10}{'points/s':>12}{'max err mm':>12}{'max err deg':>13}")
    for name, count, t, (pe, oe) in rows:
        print(f"{name:<42}{count:>8}{t:>10.3f}{count / t:>12,.0f}{pe:>12.2e}{oe:>13.2e}")
    base = {name: count / t for name, count, t, _ in rows}
    seed_rate = base["camtool seed strategy (plan_path)"]
    kernel_rate = base["camtool CWLN kernel (hot loop only)"]
    for name in list(base)[2:]:
        print(f"seed strategy / {name.split(': ')[1]}: {seed_rate / base[name]:.1f}x; "
              f"CWLN kernel / {name.split(': ')[1]}: {kernel_rate / base[name]:.1f}x")
    if "--dense" in sys.argv:
        subprocess.run([sys.executable, __file__, "--dense-child"], check=True)


if __name__ == "__main__":
    main()
