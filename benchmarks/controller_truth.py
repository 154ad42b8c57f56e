"""Controller truth: camtool's robots and programs against the ROS-Industrial descriptions.

Prints, for the manufacturer robots:
1. flange agreement: for N random controller joint values, camtool's tool0 (through its
   conventions) against the vendored URDF's (through the ROS-I drivers' conventions);
2. per-target figures of written programs read as the controller would
   (tests/controller_reader.py, independent of camtool's readers): the samples
   irb2400_plate (RAPID; coarse with --quick) and sia20_wall (INFORM, small grid), and two harder jobs:
   irb2400_line_arc (seed 001's line and arc: MoveL / MoveC, tool down) and the full
   8 x 8 sia20_wall grid;
3. the same for KUKA KRL and FANUC LS (tests/controller_reader_kf.py, issue #47): the samples
   kr16_sphere (KRL: PTP / LIN / CIRC) and fanuc_plate (LS, a fixture in the cell), and three
   harder jobs: kr16_sphere with twice the rows, the M-20iA on the sphere patch (LS with C moves)
   and the KR 16 on the plate with its fixture (KRL).

The anchor: the same figures for the paper model (sia20_paper) the SIA20D replaced:
the flange difference with the same joint values.

    python benchmarks/controller_truth.py [--quick]
"""
from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from camtool.robots import get_robot  # noqa: E402
from controller_reader import (URDFS, LIMITS_DEG, Urdf, check_program, motoman_from_urdf, plan_from_csv,  # noqa: E402
                               rapid_tool, read_jbi, read_rapid, tool0, urdf_from_rax)
from camtool.transforms import rotation_angle_rad  # noqa: E402
import controller_reader_kf as kf  # noqa: E402


def flange_agreement(name: str, n: int, seed: int = 23):
    robot, urdf = get_robot(name), Urdf(URDFS[name])
    conv = robot.conventions
    lo, hi = np.array(LIMITS_DEG[name], float).T
    rng = np.random.default_rng(seed)
    mm, deg = [], []
    for ctrl in lo + (hi - lo) * rng.random((n, len(lo))):
        q = conv.model_from_controller(np.radians(ctrl))
        if name == "irb2400":
            qu = urdf_from_rax(ctrl)
        else:   # controller S,L,U,R,B,T,E -> ROS S,L,E,U,R,B,T
            c = np.radians(ctrl)
            qu = np.r_[c[:2], c[6], c[2:6]]
        A = robot.fk(q) @ conv.tool0_in_flange
        B = tool0(urdf, name, qu)
        mm.append(np.abs(A[:3, 3] - B[:3, 3]).max())
        deg.append(math.degrees(rotation_angle_rad(A[:3, :3], B[:3, :3])))
    return max(mm), max(deg)


def flange_agreement_kf(name: str, n: int, seed: int = 47):
    """KUKA / FANUC: camtool's tool0 (conventions) against the URDF's tool0 driven as the ROS-I
    drivers drive it (kuka_rsi_hw_interface: degrees to radians; fanuc_driver: joint_3 = J3 + J2)."""
    robot, urdf = get_robot(name), Urdf(kf.URDFS[name])
    conv = robot.conventions
    lo, hi = np.array(kf.LIMITS_DEG[name], float).T
    to_urdf = kf.urdf_from_kuka if name == "kr16" else kf.urdf_from_fanuc
    mm, deg = [], []
    for ctrl in lo + (hi - lo) * np.random.default_rng(seed).random((n, len(lo))):
        A = robot.fk(conv.model_from_controller(np.radians(ctrl))) @ conv.tool0_in_flange
        B = urdf.frame(to_urdf(ctrl), "tool0")
        mm.append(np.abs(A[:3, 3] - B[:3, 3]).max())
        deg.append(math.degrees(rotation_angle_rad(A[:3, :3], B[:3, :3])))
    return max(mm), max(deg)


def program_truth_kf(label, robot_name, job, prog_file, csv_file, *sets):
    """Section 3: one KRL or LS program read as its controller would, every target against the plan."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "o"
        try:
            secs = run(ROOT / "samples" / job, out, *sets)
        except SystemExit as exc:
            print(f"{label:<40} no program: {exc}")
            return None
        prog = out / prog_file
        targets, tool = kf.read_krl(prog) if prog.suffix == ".src" else kf.read_ls(prog)
        q, T = plan_from_csv(out / csv_file, get_robot(robot_name).with_placement(tool_T_mm=tool))
        t = kf.check_program(robot_name, targets, q, T, tool)
    print(f"{label:<40} {t.targets:>6} {t.max_pos_mm:>10.4f} {t.max_ori_deg:>9.4f} "
          f"{t.switches - t.switch_mismatch:>4}/{t.switches:<4} {t.beyond_limits:>6} {t.beyond_serial:>6} {secs:>6.1f}")
    return t


def paper_vs_sia20d(n: int = 200):
    paper, real = get_robot("sia20_paper"), get_robot("sia20")
    rng = np.random.default_rng(1)
    d = [np.linalg.norm(paper.fk(q)[:3, 3] - real.fk(q)[:3, 3])
         for q in rng.uniform(real.limits.lower, real.limits.upper, (n, 7))]
    return float(np.mean(d)), float(np.max(d))


def run(job: Path, out: Path, *sets: str) -> float:
    t0 = time.perf_counter()
    cmd = [sys.executable, "-m", "camtool.cli", "run", str(job), "-o", str(out)]
    for s in sets:
        cmd += ["--set", s]
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    if r.returncode != 0:
        raise SystemExit(f"{job.name}: {r.stderr.strip()}")
    return time.perf_counter() - t0


def program_truth(label, robot_name, job, fmt_file, csv_file, *sets):
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "o"
        try:
            secs = run(ROOT / "samples" / job, out, *sets)
        except SystemExit as exc:   # a job that writes no program: said, and the other jobs still run
            print(f"{label:<34} no program: {exc}")
            return None
        prog = out / fmt_file
        if prog.suffix == ".mod":
            tool = rapid_tool(prog)
            targets = read_rapid(prog)
        else:
            tool = np.eye(4)
            targets = read_jbi(prog)
        robot = get_robot(robot_name).with_placement(tool_T_mm=tool)
        q, T = plan_from_csv(out / csv_file, robot)
        t = check_program(robot_name, targets, q, T, tool)
    print(f"{label:<34} {t.targets:>6} {t.max_pos_mm:>10.4f} {t.max_ori_deg:>9.4f} "
          f"{t.conf_checked - t.conf_mismatch:>5}/{t.conf_checked:<5} {t.switches - t.switch_conf_mismatch:>4}/"
          f"{t.switches:<4} {t.beyond_limits:>6} {secs:>6.1f}")
    return t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the samples only, the plate coarse (no harder jobs)")
    ap.add_argument("-n", type=int, default=1000, help="random configurations per robot")
    args = ap.parse_args()
    print(f"1. tool0 pose, camtool (conventions) vs ROS-I URDF (driver conventions), {args.n} random controller values")
    for name in ("irb2400", "sia20"):
        mm, deg = flange_agreement(name, args.n)
        print(f"   {name:<8} worst {mm:.2e} mm, {deg:.2e} deg")
    mean, worst = paper_vs_sia20d()
    print(f"   anchor: sia20_paper vs SIA20D, same joint values: flange {mean:.0f} mm on average, {worst:.0f} mm worst")
    print("2. programs read as the controller would (ROS-I URDF + driver conventions), every target vs the plan")
    print(f"{'job':<34} {'targets':>6} {'pos mm':>10} {'ori deg':>9} {'conf ok':>11} {'J/L ok':>9} {'beyond':>6} {'run s':>6}")
    if args.quick:
        program_truth("irb2400_plate (coarse), RAPID", "irb2400", "irb2400_plate.toml", "PLATE2400.mod",
                      "PLATE2400.csv", "raster.step_over_mm=40")
    else:
        program_truth("irb2400_plate (the sample), RAPID", "irb2400", "irb2400_plate.toml", "PLATE2400.mod",
                      "PLATE2400.csv")
    program_truth("sia20_wall 3x2, INFORM", "sia20", "sia20_wall.toml", "SIAWALL.JBI", "SIAWALL.csv",
                  "task.grid_columns=3", "task.grid_rows=2", "task.start_mm=[0, 600, 800]",
                  'post.formats=["inform", "csv"]')
    if not args.quick:
        program_truth("irb2400_line_arc (seed 001), RAPID", "irb2400", "irb2400_line_arc.toml", "LINEARC.mod",
                      "LINEARC.csv", 'post.formats=["rapid", "csv"]')
        program_truth("sia20_wall 8x8 (full), INFORM", "sia20", "sia20_wall.toml", "SIAWALL.JBI", "SIAWALL.csv",
                      'post.formats=["inform", "csv"]')
    print(f"3. KUKA KRL and FANUC LS: tool0 pose, camtool vs ROS-I URDF (driver conventions), {args.n} random "
          "controller values")
    for name in ("kr16", "m20ia"):
        mm, deg = flange_agreement_kf(name, args.n)
        print(f"   {name:<8} worst {mm:.2e} mm, {deg:.2e} deg")
    print("   programs read as the controller would (ROS-I URDF + driver conventions), every target vs the plan")
    print(f"{'job':<40} {'targets':>6} {'pos mm':>10} {'ori deg':>9} {'J/L ok':>9} {'beyond':>6} {'serial':>6} "
          f"{'run s':>6}")
    program_truth_kf("kr16_sphere (the sample), KRL", "kr16", "kr16_sphere.toml", "KR16SPH.src", "KR16SPH.csv",
                     *(("raster.step_over_mm=120",) if args.quick else ()))
    program_truth_kf("fanuc_plate (the sample), LS", "m20ia", "fanuc_plate.toml", "M20PLATE.LS", "M20PLATE.csv",
                     *(("raster.step_over_mm=60",) if args.quick else ()))
    if not args.quick:
        program_truth_kf("kr16_sphere, twice the rows, KRL", "kr16", "kr16_sphere.toml", "KR16SPH.src",
                         "KR16SPH.csv", "raster.step_over_mm=20")
        program_truth_kf("m20ia on the sphere patch, LS", "m20ia", "kr16_sphere.toml", "M20SPH.LS", "M20SPH.csv",
                         "robot.name=m20ia", 'post.formats=["fanuc", "csv"]', "post.program_name=M20SPH")
        program_truth_kf("kr16 on the plate and fixture, KRL", "kr16", "fanuc_plate.toml", "KR16PLT.src",
                         "KR16PLT.csv", "robot.name=kr16", 'post.formats=["krl", "csv"]', "post.program_name=KR16PLT")


if __name__ == "__main__":
    main()
