"""Faces of a job's workpiece: the segmentation the job asks for, the selection, the picture.

``[faces] select`` (docs/faces.md) decides:

- ``"single"`` (the default): no segmentation; [fit] finds one surface, as before;
- ``"all"``, a model name, ``[indices]``, ``{largest = N}``, ``{nearest_mm = [x, y, z]}``:
  the placed workpiece is split into faces (``camtool.segment``), numbered
  largest first, and the selection picks from them.

A job works one face for now; a selection of several faces is refused with
the list of what it selected (``camtool faces JOB`` shows them).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .errors import BadInput
from .job import Job
from .segment import Face, Segmentation, SegmentSettings, segment


def segmented(job: Job) -> bool:
    """True when the job works faces of a segmentation (``faces.select`` is not 'single')."""
    return job.faces.select != "single"


def segment_settings(job: Job) -> SegmentSettings:
    """The segmentation settings of a job: [faces] keys, with [fit]'s threshold, seed and boundary keys."""
    f, fit = job.faces, job.fit
    return SegmentSettings(threshold_mm=float(fit.threshold_mm), normal_tol_rad=math.radians(f.normal_tol_deg),
                           min_area_mm2=float(f.min_area_mm2), small_faces=f.small_faces,
                           max_faces=int(f.max_faces), seed=int(fit.seed),
                           boundary_cell_mm=float(fit.boundary_cell_mm), close_gaps_mm=float(fit.close_gaps_mm),
                           simplify_mm=float(fit.simplify_mm))


def segment_job(job: Job, workpiece) -> Segmentation:
    """The faces of the job's placed workpiece."""
    return segment(workpiece, segment_settings(job))


def _distance_mm(face: Face, workpiece, point_mm: np.ndarray) -> float:
    pts = np.asarray(workpiece.points_mm)[face.inliers]
    return float(np.min(np.linalg.norm(pts - point_mm, axis=1)))


def select_faces(seg: Segmentation, select, workpiece=None, source: str = "job") -> list[Face]:
    """The faces ``select`` names (see the module docstring), in index order; BadInput when none."""
    faces = list(seg.faces)
    if select == "all":
        chosen = faces
    elif isinstance(select, str):
        chosen = [f for f in faces if f.model == select]
    elif isinstance(select, list):
        missing = [i for i in select if i >= len(faces)]
        if missing:
            raise BadInput(f"{source}: faces.select names face {missing[0]}, but the workpiece has {len(faces)} "
                           f"faces (0..{len(faces) - 1}); see `camtool faces JOB`")
        chosen = [faces[i] for i in sorted(select)]
    elif "largest" in select:
        chosen = faces[:select["largest"]]
    else:
        p = np.asarray(select["nearest_mm"], float)
        chosen = [min(faces, key=lambda f: (_distance_mm(f, workpiece, p), f.index))]
    if not chosen:
        raise BadInput(f"{source}: faces.select = {select!r} selects no face (the workpiece has "
                       f"{', '.join(f'{f.index}: {f.model}' for f in faces)}); see `camtool faces JOB`")
    return chosen


def face_surface_for_job(job: Job, workpiece):
    """The surface of the job's one selected face (world frame); BadInput when the selection holds several."""
    seg = segment_job(job, workpiece)
    chosen = select_faces(seg, job.faces.select, workpiece, str(job.path))
    if len(chosen) > 1:
        raise BadInput(f"{job.path}: faces.select = {job.faces.select!r} selects {len(chosen)} faces "
                       f"({', '.join(str(f.index) for f in chosen)}); a job works one face for now: "
                       "select one, e.g. select = [" + str(chosen[0].index) + "]")
    return chosen[0].surface


def faces_png(seg: Segmentation, workpiece, path: Path, title: str = "") -> Path:
    """A picture of the faces: the points coloured by face, each face numbered at its middle (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .files import output_file

    P = np.asarray(workpiece.points_mm)
    fig = plt.figure(figsize=(8, 7), dpi=110)
    ax = fig.add_subplot(projection="3d")
    cmap = plt.get_cmap("tab20")
    rng = np.random.default_rng(0)
    for f in seg.faces:
        idx = f.inliers
        if len(idx) > 4000:
            idx = np.sort(rng.choice(idx, 4000, replace=False))
        Q = P[idx]
        ax.scatter(Q[:, 0], Q[:, 1], Q[:, 2], s=1, color=cmap(f.index % 20), depthshade=False)
        mid = P[f.inliers].mean(axis=0)
        ax.text(*mid, f"{f.index}: {f.model}", fontsize=9, weight="bold", color="black")
    lo, hi = P.min(axis=0), P.max(axis=0)
    half = 0.5 * float((hi - lo).max())
    c = 0.5 * (lo + hi)
    ax.set_xlim(c[0] - half, c[0] + half)
    ax.set_ylim(c[1] - half, c[1] + half)
    ax.set_zlim(c[2] - half, c[2] + half)
    ax.set_xlabel("x mm")
    ax.set_ylabel("y mm")
    ax.set_zlabel("z mm")
    ax.set_title(title or f"{len(seg.faces)} faces")
    out = output_file(path)
    fig.savefig(out)
    plt.close(fig)
    return out
