"""Raster coverage of the curved faces of the multi-face samples (issue 26), rows around and along.

Every sphere and cylinder face that ``camtool.segment`` finds on the sample meshes
(pipe_half, dome_cylinder; 100k points) is rastered at 10 mm step-over and 5 mm
pitch with ``raster.cylinder_rows`` "around" and "along"; printed: rows, segments,
work points and the coverage of the face's own boundary (``raster.coverage``).

    PYTHONPATH=. python benchmarks/faces_coverage.py
"""
from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from camtool.raster import raster_path, raster_summary  # noqa: E402
from camtool.segment import segment  # noqa: E402
from camtool.settings import RasterSettings  # noqa: E402
from camtool.workpiece import load_workpiece  # noqa: E402


def main() -> None:
    for part in ("pipe_half", "dome_cylinder"):
        seg = segment(load_workpiece(ROOT / "samples" / f"{part}.stl"))
        for face in seg.faces:
            if face.model == "plane":
                continue
            side = "inside" if face.surface.concave else "outside"
            for rows in ("around", "along"):
                path = raster_path(face.surface, RasterSettings.make(step_over_mm=10, pitch_mm=5, cylinder_rows=rows))
                s = raster_summary(path, face.surface)
                print(f"{part:<14} face {face.index} {face.model:<8} {side:<7} rows {rows:<6}: {s['rows']:>3} rows "
                      f"{s['segments']:>3} segments {s['work_points']:>5} work points, coverage "
                      f"{100 * s['coverage']:.2f} %")


if __name__ == "__main__":
    main()
