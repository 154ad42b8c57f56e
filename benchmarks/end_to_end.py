"""`camtool run` end to end, stage by stage, on the sample job and on the dense job (2 mm x 2 mm).

Each job runs as its own process (`python -m camtool.cli run ... --json`), exactly
as a user runs it, with every check on (the 4 ms limit check, the independent
motion check, every program simulated); the run must pass them all. Printed per
job: wall and CPU seconds of every stage (report.json's ``stage_seconds`` and
``stage_cpu_seconds``; the figures drawn alongside the post stage in a forked process,
``stage_seconds_alongside``, marked +), the start-up (imports, job loading) as what the whole
process took beyond its stages, the planning kernel's own time in the same run
(``plan_path``, the CWLN strategy: its CPU seconds ``plan_cpu_seconds``, beside its wall
seconds ``plan_seconds``), the ratio whole run / kernel and the process's peak RSS (its own
rusage). The kernel is one thread; its CPU time is the figure of its own work, which the
processes working alongside the run (on the other core, or on its own) cannot lengthen
as they lengthen its wall time: a ratio on the wall time would flatter the run.

Anchor, side by side: before each job the same fixed workload (numpy + Python,
about a second) runs in its own process; its CPU time says how fast the machine
was just then, and each job's CPU time is also printed in anchor units. The
machine is shared: CPU seconds and the anchor ratio are the steadier figures.

    .venv/bin/python benchmarks/end_to_end.py [--sample-only] [--runs N]

Bytecode: camtool's modules are compiled first (``compileall``), as an installed
package has them; an environment with PYTHONDONTWRITEBYTECODE set would otherwise
charge every run the compile of ~150 modules (about 0.5 s of its start-up).

Targets (issue #25): sample <= 8 s, dense <= 60 s and <= 1.0 GB, sample <= 25x its kernel.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "samples" / "sphere.toml"
DENSE = ["--set", "raster.step_over_mm=2", "--set", "raster.pitch_mm=2"]
ANCHOR = ("import numpy as np\n"
          "a = np.random.default_rng(0).random((300, 300))\n"
          "for _ in range(40): a = np.tanh(a @ a / 300.0)\n"
          "s = 0\n"
          "for i in range(3_000_000): s += i % 7\n")
TARGETS = {"sample": {"wall_s": 8.0, "ratio": 25.0}, "dense": {"wall_s": 60.0, "rss_gb": 1.0}}


def _spawn(cmd: list[str], env: dict):
    """(wall s, CPU s, peak RSS GB, exit code, stdout, stderr) of one child, measured by os.wait4."""
    t0 = time.perf_counter()
    with tempfile.TemporaryFile() as fo, tempfile.TemporaryFile() as fe:
        proc = subprocess.Popen(cmd, stdout=fo, stderr=fe, env=env, cwd=ROOT)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        fo.seek(0)
        fe.seek(0)
        return (wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1e6, proc.returncode,
                fo.read().decode(errors="replace"), fe.read().decode(errors="replace"))


def anchor(env: dict) -> float:
    """CPU seconds of the fixed anchor workload in its own process."""
    _, cpu, _, code, _, err = _spawn([sys.executable, "-c", ANCHOR], env)
    if code:
        raise SystemExit(f"anchor failed: {err}")
    return cpu


def run_job(name: str, extra: list[str], env: dict) -> dict:
    with tempfile.TemporaryDirectory(prefix=f"e2e-{name}-") as tmp:
        cmd = [sys.executable, "-m", "camtool.cli", "run", str(SAMPLE), "-o", str(Path(tmp) / "out"), "--json",
               *extra]
        wall, cpu, rss, code, out, err = _spawn(cmd, env)
        if code != 0:
            raise SystemExit(f"{name}: camtool run exited {code}: {err.strip().splitlines()[-1] if err else ''}")
        report = json.loads(out)
    checks = {"limits_ok": report.get("limits_ok") is True,
              "motion_check_ok": report.get("motion_check", {}).get("ok") is True,
              "programs_simulated": bool(report.get("programs_simulated"))}
    if not all(checks.values()):
        raise SystemExit(f"{name}: a check did not run or did not pass: {checks}")
    return {"name": name, "wall_s": wall, "cpu_s": cpu, "rss_gb": rss,
            "kernel_s": float(report.get("plan_cpu_seconds", report["plan_seconds"])),
            "kernel_wall_s": float(report["plan_seconds"]),
            "poses": int(report["points_total"]), "stages": report["stage_seconds"],
            "stages_cpu": report.get("stage_cpu_seconds", {}),
            "alongside": report.get("stage_seconds_alongside", {}),
            "alongside_cpu": report.get("stage_cpu_seconds_alongside", {})}


def print_job(r: dict, anchor_cpu: float) -> None:
    stages = {k: v for k, v in r["stages"].items() if k != "total"}
    cpu = r["stages_cpu"]
    print(f"\n== {r['name']}: {r['poses']} poses; whole process {r['wall_s']:.2f} s wall, {r['cpu_s']:.2f} s CPU "
          f"({r['cpu_s'] / anchor_cpu:.1f} anchors of {anchor_cpu:.2f} s CPU), peak RSS {r['rss_gb']:.3f} GB")
    print(f"   {'stage':<14}{'wall s':>9}{'CPU s':>9}")
    start = r["wall_s"] - r["stages"]["total"]
    for name, sec in stages.items():
        print(f"   {name:<14}{sec:>9.2f}{cpu.get(name, float('nan')):>9.2f}")
    for name, sec in r["alongside"].items():
        if name != "total":
            print(f"   {'+ ' + name:<14}{sec:>9.2f}{r['alongside_cpu'].get(name, float('nan')):>9.2f}   "
                  "(alongside post and report, in a forked process)")
    own_cpu = cpu.get("total", 0.0) + r["alongside_cpu"].get("total", 0.0)
    print(f"   {'start-up':<14}{start:>9.2f}{r['cpu_s'] - own_cpu:>9.2f}   (imports, job, outside the stages)")
    print(f"   planning kernel (plan_path, inside 'plan'): {r['kernel_s']:.3f} s CPU, {r['kernel_wall_s']:.3f} s wall "
          f"({r['poses'] / r['kernel_s']:,.0f} poses/s)")
    print(f"   whole run / kernel: {r['wall_s'] / r['kernel_s']:.1f}x wall, {r['cpu_s'] / r['kernel_s']:.1f}x CPU")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sample-only", action="store_true", help="skip the dense job (minutes)")
    ap.add_argument("--runs", type=int, default=1, help="runs of each job (the median is printed)")
    args = ap.parse_args()
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    jobs = [("sample", [])] + ([] if args.sample_only else [("dense", DENSE)])
    subprocess.run([sys.executable, "-m", "compileall", "-q", str(ROOT / "camtool"), str(ROOT / "postprocessors")],
                   check=True, stdout=subprocess.DEVNULL)   # as installed: each run loads, not compiles, camtool
    print(f"camtool run end to end ({os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f}); every check on")
    for name, extra in jobs:
        runs = []
        for _ in range(max(1, args.runs)):
            a = anchor(env)
            runs.append((run_job(name, extra, env), a))
        runs.sort(key=lambda ra: ra[0]["cpu_s"] / ra[1])
        r, a = runs[len(runs) // 2]
        print_job(r, a)
        t = TARGETS[name]
        verdict = [f"wall {r['wall_s']:.1f} s (target <= {t['wall_s']:g} s; CPU {r['cpu_s']:.1f} s)"]
        if "ratio" in t:
            verdict.append(f"run / kernel {r['wall_s'] / r['kernel_s']:.1f}x (target <= {t['ratio']:g}x)")
        if "rss_gb" in t:
            verdict.append(f"peak RSS {r['rss_gb']:.2f} GB (target <= {t['rss_gb']:g} GB)")
        print("   figures vs targets: " + "; ".join(verdict))


if __name__ == "__main__":
    main()
