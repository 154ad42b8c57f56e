"""Real STEP parts (issue 48): time and peak memory of ``camtool faces`` on each, beside an anchor.

For every part in ``benchmarks/parts/step/`` (real CAD exports, see its README) a job
like ``samples/pipe_half_step.toml`` with ``faces.select = "all"`` is written to a
temporary folder, and two child processes run one after the other:

- the anchor: OpenCASCADE alone (OCP) reads the file and tessellates it at camtool's
  deflection (``camtool.part.step.DEFLECTION_MM``, ``ANGLE_RAD``): the least any STEP
  reader of camtool's accuracy does;
- ``camtool faces JOB``: the load, the tessellation, the segmentation, the table.

Printed per part and run: the wall seconds, the CPU seconds (user + system) and the
peak resident memory (the child's ``ru_maxrss``). The machine is shared: wall seconds
grow with its load, CPU seconds much less; both are printed, with the load average.

    PYTHONPATH=. python benchmarks/step_scale.py [PART ...]
"""
from __future__ import annotations

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

ANCHOR = f"""
import sys
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
    own resource use, not the largest of all children so far)."""
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


def main(names: list[str]) -> None:
    parts = [PARTS / n for n in names] if names else sorted(
        (p for p in PARTS.iterdir() if p.suffix.lower() in (".step", ".stp")), key=lambda p: p.stat().st_size)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; deflection {DEFLECTION_MM} mm")
    print(f"{'part':32s} {'ADV.FACE':>8s} {'run':8s} {'wall s':>7s} {'CPU s':>7s} {'peak MB':>8s} exit  last line")
    with tempfile.TemporaryDirectory() as tmp:
        for step in parts:
            job = Path(tmp) / f"{step.stem}.toml"
            job.write_text(job_text(step))
            runs = (("anchor", [sys.executable, "-c", ANCHOR, str(step)]),
                    ("faces", [sys.executable, "-c", "from camtool.cli import main; main()", "faces", str(job)]))
            for what, argv in runs:
                wall, cpu, peak, code, last = measured(argv, env)
                print(f"{step.name:32s} {faces_in(step):8d} {what:8s} {wall:7.1f} {cpu:7.1f} {peak:8.0f} {code:4d}  "
                      f"{last[:70]}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
