"""The real folded sheet rastered at several world orientations: its poses and the raster's estimate (issue #46).

``bezier_complex_shape_cad`` (benchmarks/freeform.py's generic placement, its step-over and pitch) turned about its
mesh centre by world roll / pitch (deg about x, y) and yawed about its workpiece frame's origin, as `camtool place`
tilts a part (placement/tilt.py), then fitted and rastered as `camtool raster` does. The rows follow the world
(a free-form chart's e1), so the poses may differ by a few %; the estimate (``raster.max_poses``'s check) is the
face's own. Before #46 the last placement was refused for "about 1.49e6 poses".

    PYTHONPATH=$PWD python benchmarks/raster_orientation.py
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

import freeform as bf  # noqa: E402
from camtool.job import load_job  # noqa: E402
from camtool.path import raster as R  # noqa: E402
from camtool.placement.tilt import tilt_matrix  # noqa: E402
from camtool.settings import RasterSettings  # noqa: E402
from camtool.run.stages import path_for_job, surface_for_job, workpiece_for_job  # noqa: E402
from camtool.transforms import matrix_from_xyz_rpy  # noqa: E402

NAME = "bezier_complex_shape_cad"
# (dx, dy, dz mm, yaw, roll, pitch deg): the generic placement, yawed, rolled, pitched, and the tilt helper's
OFFSETS = [(0, 0, 0, 0, 0, 0), (0, 0, 0, 45, 0, 0), (0, 0, 0, 0, 90, 0), (0, 0, 0, 0, 0, 90),
           (-375, -250, -250, 45, 90, 90)]


def placed(T: np.ndarray, centre: np.ndarray, offset) -> np.ndarray:
    """World <- part at ``offset``: D = shift . Rz(yaw) about the frame's origin . Ry(pitch) Rx(roll) about centre."""
    dx, dy, dz, yaw, roll, pitch = offset
    Z = matrix_from_xyz_rpy([0.0, 0.0, 0.0], [0.0, 0.0, yaw])
    Z[:3, 3] = T[:3, 3] - Z[:3, :3] @ T[:3, 3]
    S = np.eye(4)
    S[:3, 3] = [dx, dy, dz]
    return S @ Z @ tilt_matrix(roll, pitch, centre) @ T


def estimate(surface, settings) -> float:
    """The raster's pose estimate, as ``raster_path`` makes it before any work."""
    s = surface.rows_at(settings.angle_rad) if surface.model == "freeform" else surface
    chart, _, rate = R._chart_for(s, 0.0)
    e0, _ = R._polygon_edges_st(s.boundary, chart)
    rows = R._row_offsets(e0[:, 1].min(), e0[:, 1].max(), settings.step_over_mm, settings.edge_margin)
    per_row = np.ptp(e0[:, 0]) * rate / settings.pitch_mm
    return len(rows) * (per_row + 2 * (settings.lead_mm / settings.pitch_mm + 1) + settings.transition_points)


def main() -> None:
    fname, _, _, step, pitch = bf.PARTS[NAME]
    path = bf.PARTS_DIR / fname
    mesh = bf.fm.load_mesh(path, 1000.0)
    _, _, vt = np.linalg.svd(mesh.vertices - mesh.vertices.mean(0), full_matrices=False)
    T = bf.placement(mesh, bf.fm.face_region(mesh, up=vt[2], max_tilt_deg=60.0))
    centre = T[:3, :3] @ mesh.vertices.mean(axis=0) + T[:3, 3]
    out = Path(tempfile.mkdtemp(prefix="rasterorient-"))
    print(f"{NAME}: step-over {step:g} mm, pitch {pitch:g} mm")
    print(f"{'dx dy dz (mm), yaw roll pitch (deg)':<40}{'poses':>8}{'work':>8}{'estimate':>10}")
    for k, offset in enumerate(OFFSETS):
        job_file = out / f"job{k}.toml"
        job_file.write_text(bf.job_text(NAME, path, placed(T, centre, offset), step, pitch))
        job = load_job(job_file, [])
        wp = workpiece_for_job(job)
        surface = surface_for_job(job, wp)
        p = path_for_job(job, surface, wp)
        settings = RasterSettings.from_section(job.raster)
        label = " ".join(f"{v:g}" for v in offset)
        print(f"{label:<40}{len(p.zone):>8}{int((p.zone == 0).sum()):>8}{estimate(surface, settings):>10.0f}")


if __name__ == "__main__":
    main()
