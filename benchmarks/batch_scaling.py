"""Batch scaling: 8 sphere jobs with `camtool batch -j 1` and `-j 2`, plus an anchor,
the same 8 jobs one after another with plain `camtool run` in a shell loop
(prints figures, never asserts).

    .venv/bin/python benchmarks/batch_scaling.py            # the full sample sphere job
    .venv/bin/python benchmarks/batch_scaling.py --quick    # coarse raster, a quick look

The 8 jobs are samples/sphere.toml with step-over 10, 11, ... 17 mm (so they are
8 different programs), written into a temporary folder. Every batch runs with
--force, so nothing is cached. Goal: wall(-j 2) / wall(-j 1) <= 0.6 on 2 free cores.
"""
import argparse
import os
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
N_JOBS = 8


def write_jobs(folder: Path, quick: bool) -> list[Path]:
    text = (ROOT / "samples" / "sphere.toml").read_text()
    text = text.replace('file = "sphere_patch.stl"', f'file = "{ROOT / "samples" / "sphere_patch.stl"}"')
    jobs = []
    for i in range(N_JOBS):
        step = (40 + 2 * i) if quick else (10 + i)
        t = text.replace("step_over_mm = 10.0", f"step_over_mm = {step}.0")
        if quick:
            t = t.replace("pitch_mm = 5.0", "pitch_mm = 20.0")
        jobs.append(folder / f"sphere_{i + 1}.toml")
        jobs[-1].write_text(t)
    return jobs


def camtool_cmd() -> list[str]:
    exe = Path(sys.executable).parent / "camtool"
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "camtool.cli"]


def timed(cmd, shell=False) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, shell=shell, check=False, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="coarse raster (step-over 40+ mm, pitch 20 mm)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="camtool-batch-bench-") as tmp:
        tmp = Path(tmp)
        (tmp / "jobs").mkdir()
        jobs = write_jobs(tmp / "jobs", args.quick)
        cmd = camtool_cmd()
        loop = "; ".join(f"{shlex.join(cmd)} run {shlex.quote(str(j))} -o {shlex.quote(str(tmp / 'loop' / j.stem))}"
                         " >/dev/null 2>&1" for j in jobs)
        anchor = timed(loop, shell=True)
        serial = timed([*cmd, "batch", str(tmp / "jobs"), "-o", str(tmp / "j1"), "-j", "1", "--force"])
        parallel = timed([*cmd, "batch", str(tmp / "jobs"), "-o", str(tmp / "j2"), "-j", "2", "--force"])
        ok = sum(1 for j in jobs for d in ("j1", "j2") if (tmp / d / j.stem / "SPHERE.mod").is_file())
        print(f"{N_JOBS} sphere jobs ({'quick' if args.quick else 'full'}), {os.cpu_count()} CPU(s); "
              f"programs written: {ok}/{2 * N_JOBS}")
        print(f"  shell loop of `camtool run` : {anchor:7.1f} s")
        print(f"  camtool batch -j 1          : {serial:7.1f} s")
        print(f"  camtool batch -j 2          : {parallel:7.1f} s")
        print(f"  ratio -j 2 / -j 1           : {parallel / serial:7.2f}  (goal <= 0.6)")


if __name__ == "__main__":
    main()
