"""Which lever holds the work feed on a free-form face (issue #46): the facets under the rows, or the tool axes?

    PYTHONPATH=. python benchmarks/feed_levers.py JOB.toml [--levers raster,axes_lowpass,facet_knots] [--sigma-mm 10]

Rasters JOB as ``camtool run`` shapes it (``run.stages.path_for_job`` with its workpiece), plans it with every
insert (``run.stages.plan_for_job``: the sag's, densify's and the timed spline's midposes), and prints the rows
each of them inserted and ``feed_budget``'s row feed bounds (every row, and the Path's own poses only) for:

- ``raster``: the path as ``camtool run`` plans it (since ``path.axis_lowpass``, its orientations low-passed along
  the rows over 10 mm);
- ``axes_lowpass``: the same with each work run's tool orientations low-passed (again) along the row (a Gaussian of
  ``--sigma-mm`` over the quaternions, ends held; positions kept): what smoother tool axes would give. The axis
  tolerance of issue #46 (p95 3 deg off the normal averaged over 10-15 mm) is not checked here;
- ``facet_knots``: each work run of a CAD mesh's face sampled again with a pose at every facet edge it crosses
  (``facet_rows`` below: every step on one facet, so the sag has nothing to split), its orientations from scipy's
  C2 ``RotationSpline`` through the raster's own.

No time law is planned (``feed_budget``'s bounds; the S-curves' ramps only lower the feed). Measured before
``path.axis_lowpass`` (main at 4e6ea6d, irb2400, 100 mm/s, sigma 10 mm) on the noether wavy sheet (9 mm facets,
the benchmark's generic placement) and the bezier ocean sheet (15-22 mm facets, ``camtool place``'s placement;
judged a scan by ``part.roughness``: its sag takes the arc through the tool axes, so the facet lever does not apply):

    part / lever          sag rows  densify rows  spline rows  row bound median: every row / Path's poses only
    wavy  raster              1117           781           23      20.7 / 52.9 mm/s  (report.json's p50: 20.7)
    wavy  axes_lowpass        1018           440           47      31.3 / 68.9
    wavy  facet_knots           13           890           63      21.3 / 45.5   (axes slerped instead: 21.6 / 32.0)
    ocean raster               869          2155            0      27.9 / 59.2       (report.json's p50: 21.5)
    ocean axes_lowpass         679          1974            0      35.7 / 47.7

So the facets are not what holds the feed down: the knots at the facet edges take the sag's 1117 midposes away,
but the joint jerk of j4 still binds where densify's midposes go (the wrist swings: up to 4.6 deg of j4 in a 5 mm
step, j5 within 15-20 deg on 10 % of the wavy's work), and low-passing the wavy's positions by 10 mm (off the
facets, tolerance ignored) leaves its Path's-poses bound at 52.9. The tool axes are the lever: low-passed over
10 mm they lift the every-row bound by half on the wavy, by 28 % on the ocean, and the dome scan's from 30.7 to
46.1 (``path.axis_lowpass`` does it in ``camtool run`` now). Re-sampling the rows at the facet edges with the axes
slerped between the old poses lowered the bound (32.0): a slerp kinks the axes at every old pose, and new poses
near those kinks sharpen them for the time law's cubic spline.
"""
from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass, replace
from pathlib import Path as FilePath
from typing import Callable, Sequence

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial.transform import Rotation, RotationSpline, Slerp

sys.path.insert(0, str(FilePath(__file__).resolve().parent))
import feed_budget  # noqa: E402

from camtool.path.toolpath import WORK, ZONES, Path  # noqa: E402

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
    R = Rotation.from_matrix(poses[:, :3, :3])   # a C2 rotation spline: a slerp kinks the axes at every old pose
    rot = (RotationSpline(s_trace[at], R) if len(poses) > 2 else Slerp(s_trace[at], R))(
        np.clip(s, 0.0, s_trace[-1])).as_matrix()
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


# --- the levers, measured ----------------------------------------------------------------------------------------
def axes_lowpassed(path: Path, sigma_mm: float) -> Path:
    """``path`` with each work run's orientations low-passed along it (a Gaussian of ``sigma_mm`` over the
    quaternions, the pitch apart; its end poses kept)."""
    P = np.asarray(path.poses_mm, float).copy()
    for a, b in work_runs(path, np.ones(len(path), bool)):
        q = Rotation.from_matrix(P[a:b + 1, :3, :3]).as_quat()
        q *= np.sign(q @ q[0])[:, None]
        q = gaussian_filter1d(q, sigma_mm / max(path.pitch_mm, 1e-9), axis=0, mode="nearest")
        P[a + 1:b, :3, :3] = Rotation.from_quat(q / np.linalg.norm(q, axis=1)[:, None]).as_matrix()[1:-1]
    return replace(path, poses_mm=P)


def on_facet_edges(settings, surface, path: Path) -> Path:
    """``path`` with its CAD mesh faces' work runs sampled again at the facet edges (``facet_rows``)."""
    from camtool.part.surface import FaceSet

    faces = surface.surfaces if isinstance(surface, FaceSet) else (surface,)
    on = [(np.ones(len(path), bool) if not isinstance(surface, FaceSet) else path.face == i, f.project_mm)
          for i, f in zip(getattr(surface, "indices", [0]), faces) if getattr(f, "on_mesh_facets", False)]
    return facet_rows(path, on, FacetRowSettings(path.pitch_mm, 0.5 * settings.planner.chord_tol_mm))[0]


def measured(name: str, path: Path, job, settings, wp, surface, robot) -> None:
    """Plan ``path`` with every insert and print the inserts and the row feed bounds."""
    from camtool.run import stages
    from camtool.timing.feed import tcp_positions_world

    jp = stages.plan_for_job(settings, path, robot, workpiece=stages.part_for_checks(settings, wp, surface),
                             surface=surface)
    rows = {k: jp.events.get(k, {}).get("rows") for k in ("sag_steps", "densified_steps", "spline_steps")}
    pidx = np.asarray(jp.path_index)
    q = np.asarray(jp.q, float)
    d = {"zone": np.array([ZONES[c] for c in jp.zone]), "path_index": pidx, "q": q,
         "segment": np.asarray(path.segment)[np.maximum.accumulate(np.where(pidx >= 0, pidx, 0))],
         "xyz": tcp_positions_world(robot, q)}
    feed = settings.timing.tcp_speed_mm_s
    r = [feed_budget.budget(d, feed_budget.surface_runs(d), robot.limits, feed, only) for only in (False, True)]
    print(f"{name:14s} inserted rows: sag {rows['sag_steps']}, densify {rows['densified_steps']}, spline "
          f"{rows['spline_steps']}; row bound median every row {r[0]['median']:.1f} (least {r[0]['least']:.1f}), "
          f"Path's poses only {r[1]['median']:.1f} mm/s", flush=True)


def main() -> None:
    from camtool.job import load_job
    from camtool.run import stages
    from camtool.run.job_settings import JobSettings

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("job")
    ap.add_argument("--levers", default="raster,axes_lowpass,facet_knots")
    ap.add_argument("--sigma-mm", type=float, default=10.0)
    a = ap.parse_args()
    job = load_job(a.job, [])
    wp = stages.workpiece_for_job(job)
    surface = stages.surface_for_job(job, wp)
    robot = stages.robot_for_job(job)
    settings = stages.with_scan_verdict(JobSettings.from_job(job), wp)
    path = stages.path_for_job(job, surface, wp)
    levers = {"raster": lambda: path, "axes_lowpass": lambda: axes_lowpassed(path, a.sigma_mm),
              "facet_knots": lambda: on_facet_edges(settings, surface, path)}
    for name in a.levers.split(","):
        measured(name, levers[name](), job, settings, wp, surface, robot)


if __name__ == "__main__":
    main()
