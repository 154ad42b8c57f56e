"""Arcs as arcs (issue #22): motion instructions of the RAPID and INFORM programs.

For the irb2400 line-and-arc sample and the irb2400 job on a 300 mm sphere patch
(the irb2400 case of benchmarks/motion_safety.py) it runs the whole pipeline
in-process and prints, per format, the motion instructions by kind (MoveAbsJ /
MoveJ / MoveL / MoveC; MOVJ / MOVL / MOVC), the simulated work length and the
motion instructions per metre of work, and the simulator's worst deviation from
the plan (the anchor: post.path_tol_mm, 0.1 mm by default).

    .venv/bin/python benchmarks/program_arcs.py
"""
from __future__ import annotations

import re
import sys
import tempfile
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from camtool.errors import CamtoolError  # noqa: E402
from camtool.job import load_job  # noqa: E402
from camtool.run.pipeline import run_job  # noqa: E402
from motion_safety import job_file, sphere_patch  # noqa: E402

RAPID_RE = re.compile(r"^\s*(MoveAbsJ|MoveJ|MoveL|MoveC)\b", re.M)
INFORM_RE = re.compile(r"^(MOVJ|MOVL|MOVC)\b", re.M)
FORMATS = 'post.formats=["rapid", "csv"]'


def count(folder: Path) -> dict[str, Counter]:
    out = {"rapid": Counter(), "inform": Counter()}
    for f in sorted(folder.iterdir()):
        if f.suffix.lower() == ".mod":
            out["rapid"].update(RAPID_RE.findall(f.read_text(encoding="latin-1")))
        elif f.suffix.lower() == ".jbi":
            out["inform"].update(INFORM_RE.findall(f.read_text(encoding="latin-1")))
    return out


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        small = tmp / "small.stl"
        sphere_patch(300.0, (-40, 40), (-20, 40)).export(small)
        tool = '[tool]\ntcp_xyz_mm = [0.0, 0.0, 120.0]\n'
        # the issue's placement (1150, 0, 700) needs the forearm 73-86 deg down, beyond the IRB2400's
        # coupled axis 3 (-60..65 deg on the controller, #23): refused, naming rax_3; the patch placed
        # inside it, at (1250, 0, 900), crosses the wrist singularity on 12 of its 34 rows
        cases = [("irb2400 line and arc", ROOT / "samples" / "irb2400_line_arc.toml", []),
                 ("irb2400, sphere (1150,0,700)", job_file(tmp, "irb", small, "irb2400", (1150, 0, 700), tool), []),
                 ("irb2400, sphere (1250,0,900)", job_file(tmp, "irb_up", small, "irb2400", (1250, 0, 900), tool), [])]
        for name, job_path, overrides in cases:
            out = tmp / re.sub(r"\W+", "_", name)
            try:
                result = run_job(load_job(job_path, overrides + [FORMATS]), out)
            except CamtoolError as exc:
                print(f"{name:28s} refused: {str(exc)[:160]}")
                continue
            sim = result.outputs["report"].get("programs_simulated", {})
            counts = count(out)
            for fmt in [f for f in ("rapid", "inform") if counts[f]]:
                c = counts[fmt]
                n = sum(c.values())
                s = sim.get(fmt, {})
                length_m = s.get("work_length_mm", 0.0) / 1000.0
                per_m = n / length_m if length_m else float("nan")
                kinds = ", ".join(f"{k} {v}" for k, v in sorted(c.items()))
                on_work = s.get("moves_on_work", 0)
                print(f"{name:28s} {fmt:6s} motion instructions {n:5d} ({kinds}); work {length_m:.3f} m; "
                      f"{per_m:.1f} per m ({on_work / length_m if length_m else float('nan'):.1f} per m on work); "
                      f"max deviation {s.get('max_deviation_mm', float('nan')):.4f} mm")


if __name__ == "__main__":
    main()
