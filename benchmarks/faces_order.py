"""Several faces in one path (issue 26): the working order's air distance, and each face's coverage.

For every multi-face sample mesh (scripts/make_samples.py; 100k points) all its faces
are segmented and rastered (10 mm step-over, 5 mm pitch, 20 mm leads; the chamfered
plate, whose strips are 7-10 mm wide, at 2 mm and 2 mm), then ordered
by ``camtool.path.face_set.working_order`` (nearest neighbour from the largest face, then
2-opt). Printed: the air distance (straight, from each face's exit to the next face's
entry) in index order, greedy nearest neighbour, and the order taken; the seconds to
raster, order and join; and each face's coverage by its own rows.

    PYTHONPATH=. python benchmarks/faces_order.py
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from camtool.path.face_set import _ends_mm, air_mm, joined, working_order  # noqa: E402
from camtool.part.surface import FaceSet  # noqa: E402
from camtool.path.raster import coverage, raster_path  # noqa: E402
from camtool.part.segment import segment  # noqa: E402
from camtool.settings import RasterSettings  # noqa: E402
from camtool.part.workpiece import load_workpiece  # noqa: E402


def greedy(entries: np.ndarray, exits: np.ndarray) -> list[int]:
    """Nearest neighbour from face 0, without 2-opt."""
    order, left = [0], set(range(1, len(entries)))
    while left:
        nxt = min(left, key=lambda j: (float(np.linalg.norm(entries[j] - exits[order[-1]])), j))
        order.append(nxt)
        left.remove(nxt)
    return order


def main() -> None:
    for part in ("box_open", "pipe_half", "dome_cylinder", "plate_chamfer"):
        step = 2.0 if part == "plate_chamfer" else 10.0
        settings = RasterSettings.make(step_over_mm=step, pitch_mm=min(step, 5.0), lead_mm=20.0)
        seg = segment(load_workpiece(ROOT / "samples" / f"{part}.stl"))
        faces = list(seg.faces)
        t0 = time.perf_counter()
        fs = FaceSet(tuple(f.surface for f in faces), tuple(f.index for f in faces), tuple({} for _ in faces))
        paths = [raster_path(s, settings) for s in fs.surfaces]
        order = working_order(paths)
        path = joined(paths, order, fs.indices, settings)
        seconds = time.perf_counter() - t0
        entries, exits = _ends_mm(paths)
        print(f"{part:<14} {len(faces)} faces, {len(path)} poses: air mm index order "
              f"{air_mm(list(range(len(paths))), entries, exits):8.1f}, nearest neighbour "
              f"{air_mm(greedy(entries, exits), entries, exits):8.1f}, taken {air_mm(order, entries, exits):8.1f} "
              f"(order {[fs.indices[k] for k in order]}); raster + order + join {seconds:.2f} s")
        for k, f in enumerate(faces):
            print(f"    face {f.index} {f.model:<8} coverage {100 * coverage(f.surface, paths[k], step):6.2f} %")


if __name__ == "__main__":
    main()
