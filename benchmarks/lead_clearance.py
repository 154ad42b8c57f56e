"""Leads and self-motions against the part (issue 46): how far the raster's lead, self-motion and work poses lie in
front of the part's own mesh or scan (the motion check's part geometry), before and after ``path.lead_clearance``,
and the work chords' sag from the face (what the planner's arc model must add where the face bends tighter than its
smoothed normals turn).

    PYTHONPATH=. python benchmarks/lead_clearance.py JOB [SECTION.KEY=VALUE ...]

The Vito door's skin (benchmarks/parts/freeform/vito_door_cad.obj, not committed; units "m", face 0, the IRB2400,
the polisher at 150 mm, step 25, pitch 10, lead 15 mm, tool_x_world = [0, 0, 1], cell.workpiece_xyz_mm =
[1313.988, -120.537, 1161.704], workpiece_rpy_deg = [122.842, -72.228, -120.752]): before, 22 lead poses up to
4.6 mm inside the part and chords 4.2 mm into it; after, none (97 poses moved, at most 25.6 mm, no work pose).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from camtool.job import load_job  # noqa: E402
from camtool.path.raster import raster_path  # noqa: E402
from camtool.run.job_settings import JobSettings  # noqa: E402
from camtool.run.part_stages import PartHere  # noqa: E402
from camtool.run.stages import motion_check_part, part_for_checks, shaped_for_part  # noqa: E402


def _chord_min(geo, P: np.ndarray, zone: np.ndarray) -> float:
    """The smallest signed distance along the chords between consecutive non-work poses (7 points each)."""
    nonwork = np.flatnonzero(zone != "work")
    i = nonwork[:-1][np.isin(nonwork[:-1] + 1, nonwork)]
    t = np.linspace(0, 1, 9)[1:-1]
    Q = P[i, None] + t[None, :, None] * (P[i + 1] - P[i])[:, None]
    return float(geo.signed_distance(Q.reshape(-1, 3)).min())


def main() -> None:
    job = load_job(sys.argv[1], sys.argv[2:])
    settings = JobSettings.from_job(job)
    part = PartHere(job)
    wp, surface = part.workpiece(), part.surface()
    before = raster_path(surface, settings.raster)
    after = shaped_for_part(settings, surface, before, part_for_checks(settings, wp, surface))[0]   # no robot: no tilt
    geo = motion_check_part(settings, wp, before, surface)
    zone = np.array(before.zone_names())
    for name, path in (("before", before), ("after", after)):
        P = path.poses_mm[:, :3, 3]
        sd = geo.signed_distance(P)
        for z in ("lead_in", "lead_out", "self_motion"):
            k = zone == z
            print(f"{name:6s} {z:12s} {k.sum():5d} poses, nearest {sd[k].min():8.3f} mm, inside the part: {(sd[k] < 0).sum()}")
        print(f"{name:6s} non-work chords: nearest {_chord_min(geo, P, zone):8.3f} mm")
    moved = np.linalg.norm(after.poses_mm[:, :3, 3] - before.poses_mm[:, :3, 3], axis=1)
    print(f"moved poses {(moved > 0).sum()}, largest lift {moved.max():.2f} mm, work poses moved {(moved[zone == 'work'] > 0).sum()}")
    P = before.poses_mm[:, :3, 3]
    w = np.flatnonzero(zone == "work")
    pair = w[:-1][np.diff(w) == 1]
    uv = 0.5 * (surface.uv_from_points(P[pair]) + surface.uv_from_points(P[pair + 1]))
    sag = np.linalg.norm(surface.point_mm(*uv.T) - 0.5 * (P[pair] + P[pair + 1]), axis=1)
    print(f"work chords {len(sag)}: sag from the face max {sag.max():.3f} mm, > 0.1 mm: {(sag > 0.1).sum()}, "
          f"> 0.6 mm: {(sag > 0.6).sum()}")


if __name__ == "__main__":
    main()
