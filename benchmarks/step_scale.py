"""Real STEP parts (issue 48): time and peak memory of ``camtool faces`` on each, against the targets, beside an anchor.

For every part in ``benchmarks/parts/step/`` (real CAD exports, see its README) a job
like ``samples/pipe_half_step.toml`` with ``faces.select = "all"`` is written to a
temporary folder, and two child processes run one after the other, ``--repeat`` times:

- the anchor: a process that starts as ``camtool faces`` does (the interpreter, ``camtool.cli``) and reads and
  tessellates the file with OpenCASCADE (OCP) alone, at camtool's deflection and angle
  (``camtool.part.step.DEFLECTION_MM``, ``ANGLE_RAD``): the least any STEP reader of camtool's accuracy does;
- ``camtool faces JOB``, the whole process: the start-up, the load, the tessellation, the segmentation, the table.

Printed per part: the wall seconds, the CPU seconds (user + system, the process and its children) and the peak
resident memory (``ru_maxrss``) of each, the fastest of the repeats; the ratio faces / anchor of the wall
seconds; and the targets of issue 48: at most 5 s for a 100-face part, 20 s for a 1000-face one (linear
between, by the file's ADVANCED_FACE count), 2 GB for any. The machine is shared: wall seconds grow with its
load, and so do the anchor's, so the ratio holds where the seconds do not. "scaled s" is the faces run's wall
seconds times the anchor's CPU over wall seconds: what it would take where the anchor ran unslowed (a shared
core slows both alike; on a loaded machine it overstates, as the faces run's forked children then wait too).
The verdict takes the smaller of the wall and the scaled seconds.

    PYTHONPATH=. python benchmarks/step_scale.py [--repeat N] [PART ...]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PARTS = ROOT / "benchmarks" / "parts" / "step"
sys.path.insert(0, str(ROOT))

from camtool.part.step import ANGLE_RAD, DEFLECTION_MM  # noqa: E402

PEAK_TARGET_MB = 2048.0
# (ADVANCED_FACE count, seconds): issue 48's two targets; linear between, flat outside
TIME_TARGETS = ((100, 5.0), (1000, 20.0))

ANCHOR = f"""
import sys
import camtool.cli  # noqa: F401  (the start-up camtool faces has)
from OCP.BRepMesh import BRepMesh_IncrementalMesh
from OCP.STEPControl import STEPControl_Reader
reader = STEPControl_Reader()
reader.ReadFile(sys.argv[1])
reader.TransferRoots()
BRepMesh_IncrementalMesh(reader.OneShape(), {DEFLECTION_MM!r}, False, {ANGLE_RAD!r}, True)
"""


def job_text(step: Path) -> str:
    """The pipe sample's job on this part, every face listed."""
    text = (ROOT / "samples" / "pipe_half_step.toml").read_text()
    text = text.replace('file = "pipe_half.step"', f'file = "{step}"')
    return text.replace("select = [0]", 'select = "all"')


def measured(argv: list[str], env: dict) -> tuple[float, float, float, int, str]:
    """(wall s, CPU s, peak MB, exit code, last line of its output) of one child process (``os.wait4``: its
    own resource use and its children's, not the largest of all children so far)."""
    with tempfile.TemporaryFile() as out:
        t0 = time.perf_counter()
        child = subprocess.Popen(argv, stdout=out, stderr=subprocess.STDOUT, env=env)
        _, status, use = os.wait4(child.pid, 0)
        wall = time.perf_counter() - t0
        child.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        lines = out.read().decode("utf-8", "replace").strip().splitlines()
    return wall, use.ru_utime + use.ru_stime, use.ru_maxrss / 1024.0, child.returncode, lines[-1] if lines else ""


def faces_in(step: Path) -> int:
    return step.read_bytes().count(b"ADVANCED_FACE")


def time_target_s(n_faces: int) -> float:
    """Issue 48's time target for a part of this many B-rep faces."""
    (n0, t0), (n1, t1) = TIME_TARGETS
    return float(min(max(t0 + (n_faces - n0) * (t1 - t0) / (n1 - n0), t0), t1))


def best_of(argv: list[str], env: dict, repeat: int) -> tuple[float, float, float, int, str]:
    """The fastest of ``repeat`` runs (wall), with the largest peak memory of them."""
    runs = [measured(argv, env) for _ in range(repeat)]
    fastest = min(runs, key=lambda r: r[0])
    return fastest[0], fastest[1], max(r[2] for r in runs), fastest[3], fastest[4]


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=1, help="runs of each process; the fastest counts")
    ap.add_argument("parts", nargs="*", help="file names in benchmarks/parts/step (default: all)")
    args = ap.parse_args(argv)
    parts = [PARTS / n for n in args.parts] if args.parts else sorted(
        (p for p in PARTS.iterdir() if p.suffix.lower() in (".step", ".stp")), key=lambda p: p.stat().st_size)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; deflection {DEFLECTION_MM} mm, "
          f"angle {ANGLE_RAD} rad; fastest of {args.repeat}")
    print(f"{'part':24s} {'faces':>5s} {'run':6s} {'wall s':>7s} {'CPU s':>6s} {'peak MB':>8s} {'ratio':>6s} "
          f"{'scaled s':>8s} {'target s':>8s}  verdict / last line")
    with tempfile.TemporaryDirectory() as tmp:
        for step in parts:
            job = Path(tmp) / f"{step.stem}.toml"
            job.write_text(job_text(step))
            n = faces_in(step)
            anchor = best_of([sys.executable, "-c", ANCHOR, str(step)], env, args.repeat)
            faces = best_of([sys.executable, "-c", "from camtool.cli import main; main()", "faces", str(job)],
                            env, args.repeat)
            target = time_target_s(n)
            print(f"{step.name[:24]:24s} {n:5d} {'anchor':6s} {anchor[0]:7.1f} {anchor[1]:6.1f} {anchor[2]:8.0f} "
                  f"{'1.00':>6s} {anchor[1]:8.1f} {'':8s}  exit {anchor[3]}", flush=True)
            ratio = faces[0] / anchor[0]
            scaled = faces[0] * min(anchor[1] / anchor[0], 1.0)
            ok = faces[3] == 0 and min(faces[0], scaled) <= target and faces[2] <= PEAK_TARGET_MB
            print(f"{'':24s} {'':5s} {'faces':6s} {faces[0]:7.1f} {faces[1]:6.1f} {faces[2]:8.0f} {ratio:6.2f} "
                  f"{scaled:8.1f} {target:8.1f}  {'meets' if ok else 'MISSES'} {target:.0f} s and "
                  f"{PEAK_TARGET_MB:.0f} MB; exit {faces[3]}: {faces[4][:40]}", flush=True)

if __name__ == "__main__":
    main(sys.argv[1:])
