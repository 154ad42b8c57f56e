"""A CAD mesh face's rows with a pose at every facet edge they cross: a path modifier (issue #46).

On a CAD mesh's free-form face the raster's work poses lie on the part's own facets (``FreeformSurface.project_mm``),
``raster.pitch_mm`` apart. A row's trace on the facets is a polyline that kinks at every facet edge it crosses, and
with poses at an even pitch those kinks fall inside the steps: the chord of such a step runs behind a crest (or in
front of a trough) by up to a quarter of the step times the kink (a 5 mm step over a 6 deg kink: 0.13 mm, the sag's
tolerance is ``planner.chord_tol_mm / 2`` = 0.025 mm). The planner's sag (``plan.sag``) and the timed spline's
depth check (``plan.spline_bow``) then split those steps down to 0.6-1.25 mm pieces around each kink, and the
joint jerk of the time law's spline grows as 1 / h^2 there: the bezier ocean sheet (15-22 mm facets) held a
median work feed of 21.5 of 100 mm/s.

Here each work run on such a face is traced on the facets (its steps' chords, sampled every ``trace_step_mm``,
taken onto the face along the step's mean tool axis), the trace is reduced to the fewest vertices whose chords stay
within ``band_mm`` of it (Ramer-Douglas-Peucker: the kinks, the facet edges the row crosses), and the run is
sampled again on that polyline: every vertex a pose, the chord between two vertices cut into the fewest equal
steps no longer than the pitch, each new point taken onto the face. Every step then lies on one facet (within the
band), the sag and the spline check find nothing to add, and each kink sits at a pose with steps of up to the
pitch on both sides: under a band this narrow (a blend of a 6 deg kink within 0.025 mm is 2 mm long) no smooth
curve through poses a pitch apart turns more gently than that. The tool axes are the raster's own, slerped by the
distance along the trace (they come from the face's smoothed normals, not from the facets).

A run whose trace leaves the face (a hole under a step, another layer of a face that overhangs its chart plane)
keeps its poses. Leads, connectors, analytic faces and scans keep theirs.

Why by hand: no library resamples a tool path at a mesh's facet edges; numpy does the trace and the simplification,
scipy the slerp, the face's own projector (open3d's ray casting) the points on the facets.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable, Sequence

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from .toolpath import WORK, Path

Projector = Callable[..., np.ndarray]   # points (m, 3) mm onto a face (``along=`` unit lines; NaN where none)


@dataclass(frozen=True)
class FacetRowSettings:
    """The longest step (mm, ``raster.pitch_mm``), how far a step's chord may leave the row's trace on the facets
    (mm: the sag's tolerance, ``planner.chord_tol_mm / 2``), and how finely the trace is sampled (mm)."""

    pitch_mm: float
    band_mm: float
    trace_step_mm: float = 0.1


@dataclass(frozen=True)
class FacetRowFigures:
    """What ``facet_rows`` did: runs sampled again, runs kept (their trace left the face), work poses before and
    after."""

    runs: int = 0
    kept: int = 0
    poses_before: int = 0
    poses_after: int = 0

    def to_dict(self) -> dict:
        return {"runs": self.runs, "kept": self.kept, "poses_before": self.poses_before,
                "poses_after": self.poses_after}


def work_runs(path: Path, mask: np.ndarray) -> list[tuple[int, int]]:
    """[(a, b)] inclusive bounds of each run of at least two consecutive work poses of one segment within
    ``mask``."""
    zone, seg = np.asarray(path.zone), np.asarray(path.segment)
    on = (zone == WORK) & np.asarray(mask, bool)
    link = on[:-1] & on[1:] & (seg[:-1] == seg[1:])
    runs, a = [], None
    for k in range(len(on)):
        if a is None and on[k]:
            a = k
        if a is not None and (k == len(on) - 1 or not link[k]):
            if k > a:
                runs.append((a, k))
            a = None
    return runs


def row_trace(P: np.ndarray, axis: np.ndarray, project: Projector, step_mm: float) -> tuple | None:
    """(trace (m, 3) mm on the face, the index into it of each pose) of the poses ``P`` (n, 3) with tool axes
    ``axis`` (n, 3): each step's chord sampled at most ``step_mm`` apart and taken onto the face along the step's
    mean axis; None where a sample has no face under it or lands farther than half its step from the chord."""
    pieces, at = [P[:1]], [0]
    for i in range(len(P) - 1):
        c = float(np.linalg.norm(P[i + 1] - P[i]))
        m = max(int(math.ceil(c / step_mm)), 1)
        f = np.arange(1, m)[:, None] / m
        chord = P[i] + f * (P[i + 1] - P[i])
        mean = axis[i] + axis[i + 1]
        mean = mean / max(float(np.linalg.norm(mean)), 1e-12)
        onto = project(chord, along=np.broadcast_to(mean, chord.shape))
        with np.errstate(invalid="ignore"):
            if not (np.linalg.norm(onto - chord, axis=1) <= 0.5 * c).all():
                return None
        pieces += [onto, P[i + 1:i + 2]]
        at.append(at[-1] + m)
    return np.concatenate(pieces), np.asarray(at)


def simplified(trace: np.ndarray, band_mm: float) -> np.ndarray:
    """Indices of the fewest trace points (its ends kept) whose chords stay within ``band_mm`` of every trace
    point between them (Ramer-Douglas-Peucker, by hand: a few lines of numpy; the kinks of a polyline on facets)."""
    keep = np.zeros(len(trace), bool)
    keep[[0, -1]] = True
    stack = [(0, len(trace) - 1)]
    while stack:
        a, b = stack.pop()
        if b - a < 2:
            continue
        d = _distance_to_segment(trace[a + 1:b], trace[a], trace[b])
        k = int(np.argmax(d))
        if d[k] > band_mm:
            keep[a + 1 + k] = True
            stack += [(a, a + 1 + k), (a + 1 + k, b)]
    return np.flatnonzero(keep)


def _corners(trace: np.ndarray, vertices: np.ndarray, step_mm: float) -> np.ndarray:
    """(len(vertices), 3) the polyline's vertices, each inner one moved onto the facet edge it stands for: the
    meeting point of the trace's lines on either side of it (the trace is sampled ``step_mm`` apart, so the edge
    lies within a sample of the vertex), where those lines are found and meet within a sample of it."""
    out = trace[vertices].copy()
    for k in range(1, len(vertices) - 1):
        p, j, n = vertices[k - 1], vertices[k], vertices[k + 1]
        if j - 1 <= p or j + 1 >= n:
            continue
        meet = _meeting_point(trace[p], trace[j - 1], trace[j + 1], trace[n])
        if meet is not None and np.linalg.norm(meet - trace[j]) <= step_mm:
            out[k] = meet
    return out


def _meeting_point(a0, a1, b0, b1) -> np.ndarray | None:
    """The midpoint of the closest points of the lines a0-a1 and b0-b1 (None: parallel)."""
    u, v, w = a1 - a0, b1 - b0, a0 - b0
    uu, uv, vv, uw, vw = u @ u, u @ v, v @ v, u @ w, v @ w
    det = uu * vv - uv * uv
    if det <= 1e-12 * uu * vv:
        return None
    s, t = (uv * vw - vv * uw) / det, (uu * vw - uv * uw) / det
    return 0.5 * (a0 + s * u + b0 + t * v)


def _distance_to_segment(X: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(m,) distance of points X (m, 3) from the segment a-b."""
    ab = b - a
    t = np.clip((X - a) @ ab / max(float(ab @ ab), 1e-300), 0.0, 1.0)
    return np.linalg.norm(X - (a + t[:, None] * ab), axis=1)


def resampled_run(poses: np.ndarray, project: Projector, settings: FacetRowSettings) -> np.ndarray | None:
    """(k, 4, 4) the run's poses sampled again on its facet polyline (module doc), or None: its trace leaves the
    face."""
    P, axis = poses[:, :3, 3], poses[:, :3, 2]
    traced = row_trace(P, axis, project, settings.trace_step_mm)
    if traced is None:
        return None
    trace, at = traced
    s_trace = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(trace, axis=0), axis=1))]
    vertices = simplified(trace, settings.band_mm)
    corners = _corners(trace, vertices, settings.trace_step_mm)
    points, s_new = [trace[:1]], [np.zeros(1)]
    for k, (a, b) in enumerate(zip(vertices[:-1], vertices[1:])):
        A, B = corners[k], corners[k + 1]
        n = max(int(math.ceil(np.linalg.norm(B - A) / settings.pitch_mm - 1e-9)), 1)
        f = np.arange(1, n + 1)[:, None] / n
        points.append(A + f * (B - A))
        s_new.append(s_trace[a] + f[:, 0] * (s_trace[b] - s_trace[a]))
    X, s = np.concatenate(points), np.concatenate(s_new)
    rot = Slerp(s_trace[at], Rotation.from_matrix(poses[:, :3, :3]))(np.clip(s, 0.0, s_trace[-1])).as_matrix()
    inner = np.arange(1, len(X) - 1)   # the run's ends stay where they were (its leads start there)
    if len(inner):
        onto = project(X[inner], along=rot[inner, :, 2])
        with np.errstate(invalid="ignore"):
            near = np.linalg.norm(onto - X[inner], axis=1) <= settings.band_mm
        X[inner[near]] = onto[near]
    out = np.broadcast_to(np.eye(4), (len(X), 4, 4)).copy()
    out[:, :3, :3], out[:, :3, 3] = rot, X
    out[0], out[-1] = poses[0], poses[-1]
    return out


def facet_rows(path: Path, faces: Sequence[tuple[np.ndarray, Projector]],
               settings: FacetRowSettings) -> tuple[Path, FacetRowFigures]:
    """(``path`` with every work run on one of ``faces`` (mask of its poses, projector onto its facets) sampled
    again with a pose at each facet edge it crosses (module doc), the figures). A path with nothing to change
    comes back as the same object."""
    P = np.asarray(path.poses_mm, float)
    new, runs, kept, before, after = {}, 0, 0, 0, 0
    for mask, project in faces:
        for a, b in work_runs(path, mask):
            out = resampled_run(P[a:b + 1], project, settings)
            if out is None:
                kept += 1
                continue
            new[a] = (b, out)
            runs, before, after = runs + 1, before + b + 1 - a, after + len(out)
    figures = FacetRowFigures(runs, kept, before, after)
    return (path if not new else _with_runs(path, new)), figures


def _with_runs(path: Path, new: dict) -> Path:
    """``path`` with the poses a..b of each run replaced by its new poses (``new``: {a: (b, poses)}), which carry
    pose a's segment, zone, face and contour flag; the work points of each segment numbered 1.. again."""
    src, poses, k = [], [], 0
    P = np.asarray(path.poses_mm, float)
    for a in sorted(new):
        b, out = new[a]
        src += list(range(k, a)) + [a] * len(out)
        poses += [P[k:a], out]
        k = b + 1
    src += list(range(k, len(path)))
    poses.append(P[k:])
    src = np.asarray(src)

    def take(x):
        return None if x is None else np.asarray(x)[src]
    seg, zone, point = take(path.segment), take(path.zone), take(path.point)
    for s in np.unique(np.asarray(path.segment)[list(new)]):
        rows = (zone == WORK) & (seg == s)
        point[rows] = np.arange(1, rows.sum() + 1)
    return replace(path, poses_mm=np.concatenate(poses), segment=seg, point=point, zone=zone, face=take(path.face),
                   contour=take(path.contour))
