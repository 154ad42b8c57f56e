"""``report.html``: one self-contained, interactive page of a run (docs/report-html.md).

Plotly figures with plotly.js embedded inline (opens offline, no external
script or stylesheet), fixed div ids and no timestamps, so the same inputs give
the same bytes. What is displayed is decimated (workpiece <= 20k points, path
<= 20k poses, feed and heat map bounded) and rounded (0.1 mm), which keeps a
100k-point job well under 15 MB.

Shown: the summary figures of report.json; a 3-D scene with the workpiece, the
fitted surface's boundary, the path coloured by zone (work poses by TCP feed
when a trajectory is given), reverse plans, retracts, singular, not-reached
and failing poses, the cell's obstacles, and the robot (its joint origins and the link
shapes the motion check measures) on a slider along the path;
TCP feed along the path length; joint use as a share of the limits (one heat
map, joint x time); and the redundancy map (``camtool.report.redundancy_map``).
"""
from __future__ import annotations

import html
from pathlib import Path as FsPath

import numpy as np

from ..collision.plot import obstacle_traces
from ..errors import BadInput
from ..robots.dh import MM_TO_M
from ..part.surface_base import Surface
from ..path.toolpath import WORK, ZONES

MAX_WORKPIECE_POINTS = 20_000
MAX_PATH_POINTS = 20_000
MAX_MARKERS = 5_000
ROBOT_FRAMES = 40
DEFAULT_TOOL_RADIUS_MM = 25.0   # the tool drawn when no motion check measured one (check.tool_radius_mm's default)
MAX_FEED_POINTS = 8_000
MAX_HEAT_COLUMNS = 1_500
ZONE_COLORS = {"work": "#1f77b4", "self_motion": "#ff7f0e", "lead_in": "#2ca02c", "lead_out": "#9467bd",
               "approach": "#8c564b", "depart": "#e377c2", "retract": "#d62728"}
PLOTLY_CONFIG = {"displaylogo": False, "responsive": True}
PROCESS_DIV = "camtool-process-map"  # only when the job has a [process]
FACES_DIV = "camtool-faces"           # only when the job works faces of a segmented part
DIV = {"scene": "camtool-scene", "feed": "camtool-feed", "joint_use": "camtool-joint-use",
       "redundancy": "camtool-redundancy"}
FAILING_NAME = "unreachable or failing poses"


def write_report_html(file, *, report: dict, robot, workpiece=None, surface=None, path=None, joint_path=None,
                      trajectory=None, failing_indices=(), redundancy=None, faces=None, world=None,
                      figures: list | None = None) -> FsPath:
    """Write the interactive report of a run (or of a failed plan) to ``file``; returns its path.

    Only ``report`` and ``robot`` are required: a failed job passes its path
    and ``failing_indices`` (path indices; ``report['unreachable']`` entries
    are marked too). ``redundancy`` is a ``RedundancyMap``; ``faces`` the job's
    ``faces.faces_report`` (a segmented part: its faces, numbered, the worked ones marked);
    ``world`` the job's ``CollisionWorld`` (the robot's link shapes drawn). ``figures``:
    ``figure_sections``' of these inputs, when rendered already (then not rendered again).
    """
    file = FsPath(file)
    sections = [_verdict_section(report), _summary_section(report, robot, surface, path, failing_indices)]
    process = _process_section(report, surface)
    if process is not None:
        sections.append(process)
    if faces is not None and workpiece is not None:
        sections.append(("Faces of the part", _FACES_NOTE, _faces_table(faces)
                         + fig_html(_faces_figure(faces, workpiece), FACES_DIV)))
        if faces.get("worked"):
            sections.append(("Each face worked", _WORKED_NOTE, _worked_table(faces["worked"], report)))
    if figures is None:
        figures = figure_sections(report, robot, workpiece=workpiece, surface=surface, path=path,
                                  joint_path=joint_path, trajectory=trajectory, failing_indices=failing_indices,
                                  redundancy=redundancy, world=world)
    sections += figures
    title = f"camtool report: {robot.name}"
    if report.get("status"):
        title += f" ({report['status']})"
    return write_html_page(file, title, sections)


def figure_sections(report: dict, robot, *, workpiece=None, surface=None, path=None, joint_path=None,
                    trajectory=None, failing_indices=(), redundancy=None, world=None) -> list[tuple[str, str, str]]:
    """The page's figures as sections (heading, note HTML, content HTML): the scene, the TCP feed and the
    joint use (or a note that there is no trajectory) and the redundancy map.

    Of ``report`` they show ``tcp_speed_mm_s``, ``unreachable`` and, without a ``world``, the cell's
    bodies (``motion_check.cell``); with one, its own. So a run renders them before its motion check
    has given its verdict (``write_report_html(figures=)``)."""
    feed = _feed(robot, trajectory) if trajectory is not None else None
    if world is not None:   # the bodies as the motion check reports them (``CollisionWorld.describe``)
        report = {**report, "motion_check": {**(report.get("motion_check") or {}), "cell": world.describe()}}
    sections = []
    scene = _scene_figure(report, robot, workpiece, surface, path, joint_path, feed, failing_indices, world)
    sections.append(("Workpiece, path and robot", _SCENE_NOTE, fig_html(scene, DIV["scene"])))
    if trajectory is not None:
        sections.append(("TCP feed along the path", _FEED_NOTE,
                         fig_html(_feed_figure(feed, report), DIV["feed"])))
        sections.append(("Joint use", _JOINT_NOTE,
                         fig_html(_joint_use_figure(robot, trajectory), DIV["joint_use"])))
    else:
        sections.append(("TCP feed and joint use", "", "<p>No trajectory: the plan or its timing did not "
                                                       "finish, so there is no feed or joint use to show.</p>"))
    if redundancy is not None:
        what = f"{redundancy.robot}: {redundancy.y_label} over the work poses"
        if redundancy.notes:
            what += " (" + "; ".join(redundancy.notes) + ")"
        sections.append(("Redundancy map", f'<p class="note"><b>{html.escape(what)}.</b></p>' + _REDUNDANCY_NOTE,
                         fig_html(_redundancy_figure(redundancy), DIV["redundancy"])))
    return sections


def write_html_page(file, title: str, sections: list[tuple[str, str, str]]) -> FsPath:
    """One self-contained page (plotly.js inlined, no network) of (heading, note HTML, content HTML) sections;
    written through a temporary file, never half-written. Returns the file."""
    from plotly.offline import get_plotlyjs

    file = FsPath(file)
    body = "\n".join(f'<section><h2>{html.escape(h)}</h2>{note}{content}</section>'
                     for h, note, content in sections)
    page = (f'<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
            f'<title>{html.escape(title)}</title>\n<style>{_CSS}</style>\n'
            f'<script type="text/javascript">{get_plotlyjs()}</script>\n</head>\n<body>\n'
            f'<h1>{html.escape(title)}</h1>\n{body}\n</body>\n</html>\n')
    file.parent.mkdir(parents=True, exist_ok=True)
    from .. import safe_io  # never half-written, never through a planted link

    return safe_io.write_file(file.parent, file.name, page)


def redundancy_figure(outdir, robot, path=None, joint_path=None, failing_indices=(), world=None, sweep=None):
    """(map, files): the redundancy map of ``path`` and ``OUTDIR/plots/redundancy_map.png``.

    The map is computed with failing poses included as columns and its collision
    layer from ``world`` (the job's ``CollisionWorld``), from ``sweep``'s cells where they
    serve (``redundancy_map.sweep_map``, made ahead); robots without closed-form
    IK families get none: ``(None, [])``.
    """
    from .redundancy_map import plot_redundancy_map_png, redundancy_kind, redundancy_map

    if path is None or not len(path) or redundancy_kind(robot) is None:
        return None, []
    try:
        rmap = redundancy_map(path, robot, joint_path, include=failing_indices, world=world, sweep=sweep)
    except BadInput:
        return None, []
    return rmap, [plot_redundancy_map_png(rmap, FsPath(outdir) / "plots" / "redundancy_map.png")]


def write_run_html(outdir, *, report: dict, robot, workpiece=None, surface=None, path=None, joint_path=None,
                   trajectory=None, failing_indices=(), faces=None, world=None, redundancy=None,
                   figures: list | None = None) -> list[FsPath]:
    """``OUTDIR/report.html`` and, for robots with closed-form IK, ``OUTDIR/plots/redundancy_map.png``.

    ``redundancy``: ``redundancy_figure``'s (map, files) when drawn already (alongside
    the post stage), else it is drawn here; ``figures``: ``figure_sections``' when rendered
    already. Returns the files written.
    """
    outdir = FsPath(outdir)
    rmap, files = redundancy if redundancy is not None else redundancy_figure(
        outdir, robot, path, joint_path, failing_indices, world)
    html_file = write_report_html(outdir / "report.html", report=report, robot=robot, workpiece=workpiece,
                                  surface=surface, path=path, joint_path=joint_path, trajectory=trajectory,
                                  failing_indices=failing_indices, redundancy=rmap, faces=faces, world=world,
                                  figures=figures)
    return [html_file, *files]


FACE_POINTS_DRAWN = 2000   # points drawn per face (a random subset, seeded)
_FACES_NOTE = ('<p class="note">The workpiece split into faces (planes, spheres, cylinders), numbered largest '
               'first as <code>camtool faces</code> numbers them and <code>[faces] select</code> names them; '
               "the faces this job works are marked. Each face's points in its own colour (at most "
               f'{FACE_POINTS_DRAWN} a face drawn); grey: points no face took.</p>')


def _faces_table(faces: dict) -> str:
    """The faces as a table: number, model, area, radius, inliers, RMS, worked."""
    rows = []
    for f in faces["faces"]:
        radius = f.get("radius_mm")
        rows.append(f"<tr><td>{int(f['index'])}</td><td>{html.escape(str(f['model']))}</td>"
                    f"<td>{f['area_mm2'] / 100.0:.1f}</td><td>{'' if radius is None else f'{radius:.2f}'}</td>"
                    f"<td>{int(f.get('inliers', 0))}</td><td>{f.get('rms_mm', float('nan')):.3f}</td>"
                    f"<td>{'worked' if f['selected'] else ''}</td></tr>")
    head = ("<tr><th>face</th><th>model</th><th>area cm²</th><th>radius mm</th><th>points</th>"
            "<th>RMS mm</th><th></th></tr>")
    return f'<table class="verdict">{head}{"".join(rows)}</table>'


_WORKED_NOTE = ('<p class="note">The faces this job works in one program, in the order they are worked '
                '(nearest entry next, then 2-opt), joined by a lift and a free move. Coverage: the share of '
                "the face within reach of its own rows' work points; feed: the TCP feed on the face's work, "
                "measured on the timed trajectory. The motion check covers the whole program, every face's "
                "work and the moves between them; per face, its worst figures over the face's segments: the "
                "work deviation, the deepest penetration into the part, the least clearance to the part off "
                "work, and its failing samples.</p>")


def _worked_table(worked: list, report: dict) -> str:
    """Per face worked: order, number, model, rows, contour runs, work points, step-over, coverage, feed within 1 %, min feed,
    and its motion-check figures."""
    ok = "passed" if report.get("motion_check", {}).get("ok") else "not run"

    def mm(value):
        return "" if value is None else f"{value:.3f}"

    rows = []
    for n, w in enumerate(worked, 1):
        feed = w.get("work_feed") or {}
        m = w.get("motion_check") or {}
        cov = w.get("coverage")
        rows.append(f"<tr><td>{n}</td><td>{int(w['index'])}</td><td>{html.escape(str(w['model']))}</td>"
                    f"<td>{int(w['rows'])}</td><td>{int(w.get('contour_runs', 0))}</td><td>{int(w['work_points'])}</td>"
                    f"<td>{w['step_over_mm']:g}</td>"
                    f"<td>{'' if cov is None else f'{100 * cov:.2f}'}</td>"
                    f"<td>{100 * feed.get('work_share_within_1pct', float('nan')):.1f}</td>"
                    f"<td>{feed.get('min_work_feed_mm_s', float('nan')):.1f}</td>"
                    f"<td>{mm(m.get('work_deviation_mm'))}</td><td>{mm(m.get('max_penetration_mm'))}</td>"
                    f"<td>{mm(m.get('min_clearance_mm'))}</td>"
                    f"<td>{sum(m.get('failing_samples', {}).values()) if m else ''}</td><td>{ok}</td></tr>")
    head = ("<tr><th>order</th><th>face</th><th>model</th><th>rows</th><th>contour runs</th><th>work points</th>"
            "<th>step-over mm</th>"
            "<th>coverage %</th><th>feed within 1 % (%)</th><th>min feed mm/s</th><th>deviation mm</th>"
            "<th>penetration mm</th><th>clearance mm</th><th>failing samples</th><th>motion check</th></tr>")
    return f'<table class="verdict">{head}{"".join(rows)}</table>'


def _faces_figure(faces: dict, workpiece):
    """3-D scatter of the workpiece points coloured by face, each face named in the legend."""
    import plotly.graph_objects as go

    P = np.asarray(workpiece.points_mm, float)
    labels = np.asarray(faces["labels"])
    rng = np.random.default_rng(0)
    fig = go.Figure()
    groups = [(-1, "no face", False)] + [(int(f["index"]), f"face {f['index']}: {f['model']}", f["selected"])
                                         for f in faces["faces"]]
    for k, name, worked in groups:
        idx = np.flatnonzero(labels == k)
        if not len(idx):
            continue
        if len(idx) > FACE_POINTS_DRAWN:
            idx = np.sort(rng.choice(idx, FACE_POINTS_DRAWN, replace=False))
        Q = P[idx]
        marker = dict(size=2, color="#bbbbbb") if k < 0 else dict(size=3 if worked else 2)
        fig.add_trace(go.Scatter3d(x=Q[:, 0], y=Q[:, 1], z=Q[:, 2], mode="markers", marker=marker,
                                   name=name + (" (worked)" if worked else "")))
    fig.update_layout(scene=dict(aspectmode="data", xaxis_title="x mm", yaxis_title="y mm", zaxis_title="z mm"),
                      height=520, margin=dict(l=0, r=0, t=30, b=0), legend=dict(itemsizing="constant"))
    return fig


# ----------------------------------------------------------------------------- helpers

def fig_html(fig, div_id: str) -> str:
    """A figure (plotly Figure, or a figure dict from ``_with_traces``) as a div with a fixed id (plotly.js
    comes once, in the page head). A dict is not validated again: its layout was, its traces are plain data."""
    import plotly.io as pio

    return pio.to_html(fig, include_plotlyjs=False, full_html=False, div_id=div_id, config=PLOTLY_CONFIG,
                       validate=not isinstance(fig, dict))


def _trace(kind: str, **props) -> dict:
    """A plotly trace as a plain dict (``type`` = ``kind``): plotly's validators walk every value of a list
    one by one in Python (seconds for a 20k-point scene), so the traces' data skip them."""
    return {"type": kind, **props}


def _with_traces(fig, traces: list) -> dict:
    """The figure dict of a plotly Figure's layout (validated; small) and plain-dict ``traces``."""
    return {"data": list(traces), "layout": fig.to_plotly_json()["layout"]}


def _list(a, decimals: int) -> list:
    """Rounded values as a JSON-friendly list, NaN / inf as None (plotly leaves a gap)."""
    a = np.round(np.asarray(a, dtype=float), decimals)
    out = a.tolist()
    for i in np.flatnonzero(~np.isfinite(a)).tolist():
        out[i] = None
    return out


def _xyz(p: np.ndarray) -> dict:
    """Scatter3d coordinates of (N, 3) points in mm, rounded to 0.1 mm."""
    p = np.asarray(p, float).reshape(-1, 3)
    return {"x": _list(p[:, 0], 1), "y": _list(p[:, 1], 1), "z": _list(p[:, 2], 1)}


def subsample(n: int, limit: int) -> np.ndarray:
    """Evenly spread indices (at most ``limit``, first and last kept) of n items: deterministic."""
    if n <= limit:
        return np.arange(n)
    return np.unique(np.round(np.linspace(0, n - 1, limit)).astype(int))


def _world(robot, p_base: np.ndarray) -> np.ndarray:
    T = robot.base_T_mm
    return np.asarray(p_base) @ T[:3, :3].T + T[:3, 3]


def tcp_positions(robot, q: np.ndarray) -> np.ndarray:
    """(N, 3) TCP positions (world frame, mm) at joint rows q (vectorised FK, ``timing.feed``)."""
    from ..timing.feed import tcp_positions_world

    return tcp_positions_world(robot, np.asarray(q, float).reshape(-1, robot.dof))


def joint_origins(robot, q) -> np.ndarray:
    """Stick-figure points (world, mm): base, every joint frame origin, flange, TCP."""
    import pinocchio as pin

    data = robot.model.createData()
    qp = np.where(robot.prismatic, np.asarray(q, float) * MM_TO_M, np.asarray(q, float))
    pin.framesForwardKinematics(robot.model, data, qp)
    pts = [np.zeros(3)]
    pts += [np.array(data.oMi[i].translation) / MM_TO_M for i in range(1, robot.model.njoints)]
    pts.append(np.array(data.oMf[robot.flange_frame_id].translation) / MM_TO_M)
    pts.append(robot.fk_tcp(q)[:3, 3])
    return _world(robot, np.array(pts))


def _feed(robot, trajectory) -> dict:
    """TCP feed (mm/s) per trajectory waypoint from FK: central difference of position over time."""
    p = tcp_positions(robot, trajectory.q)
    t = np.asarray(trajectory.t_s, float)
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    n = len(t)
    lo, hi = np.maximum(np.arange(n) - 1, 0), np.minimum(np.arange(n) + 1, n - 1)
    dt = t[hi] - t[lo]
    with np.errstate(invalid="ignore", divide="ignore"):
        v = np.where(dt > 0, (s[hi] - s[lo]) / np.where(dt > 0, dt, 1.0), np.nan)
    return {"p": p, "s": s, "t": t, "v": v, "zone": np.asarray(trajectory.zone),
            "path_index": np.asarray(trajectory.path_index)}


# ----------------------------------------------------------------------------- summary

def _flatten(report: dict) -> list[tuple[str, str]]:
    rows = []

    def fmt(v):
        if isinstance(v, float):
            return f"{v:.6g}"
        if isinstance(v, (np.floating,)):
            return f"{float(v):.6g}"
        return str(v)

    def walk(prefix, v):
        if isinstance(v, dict):
            for k, x in v.items():
                walk(f"{prefix}.{k}" if prefix else str(k), x)
        elif isinstance(v, (list, tuple)):
            if v and all(isinstance(x, dict) for x in v):
                rows.append((prefix, f"{len(v)} entr{'y' if len(v) == 1 else 'ies'}"))
            elif len(v) > 12:
                rows.append((prefix, f"{len(v)} values"))
            else:
                rows.append((prefix, ", ".join(fmt(x) for x in v) if v else "none"))
        else:
            rows.append((prefix, fmt(v)))

    walk("", report)
    return rows


def _summary_section(report, robot, surface, path, failing_indices):
    rows = _flatten(report)
    extra = [("robot.dof", str(robot.dof)), ("robot.joints", ", ".join(robot.joint_names))]
    if surface is not None:
        extra.append(("surface.model", str(getattr(surface, "model", type(surface).__name__))))
        if isinstance(surface, Surface):
            extra.extend(surface.summary_rows())
        if getattr(surface, "stats", None) is not None:
            extra.append(("surface.rms_mm", f"{surface.stats.rms_mm:.4g}"))
    if path is not None:
        extra.append(("path.length_mm", f"{path.length_mm():.1f}"))
    if len(failing_indices):
        extra.append(("failing_poses", str(len(failing_indices))))
    body = "".join(f'<div class="kv"><span class="k">{html.escape(k)}</span> '
                   f'<span class="v">{html.escape(v)}</span></div>' for k, v in rows + extra)
    return ("Summary (report.json)", "", f'<details><summary>Every key of report.json ({len(rows)}) and the '
            f'surface</summary><div class="summary">{body}</div></details>')


# ----------------------------------------------------------------------------- verdict and process map

def _verdict_rows(report: dict) -> list[tuple[str, str]]:
    """The figures a process engineer asks first, as (label, text); missing ones are left out."""
    rows = []
    status = report.get("status") or "unknown"
    rows.append(("Status", status + ("" if status == "ok" else f": {report.get('reason', '')}")))
    if report.get("cycle_time_s") is not None:
        work = report.get("work_time_s")
        rows.append(("Cycle time", f"{report['cycle_time_s']:.1f} s" + (f" ({work:.1f} s on work)" if work else "")))
    feed = report.get("work_feed") or {}
    if feed.get("work_share_within_1pct") is not None:
        rows.append(("Feed held", f"{100 * feed['work_share_within_1pct']:.1f} % of {feed.get('work_length_mm', 0) / 1000:.1f} m "
                                  f"within 1 % of {feed.get('commanded_feed_mm_s', 0):g} mm/s "
                                  f"(min {feed.get('min_work_feed_mm_s', 0):.1f} mm/s)"))
    mc = report.get("motion_check") or {}
    if mc.get("min_clearance_mm") is not None:
        at = mc.get("min_clearance_at") or {}
        rows.append(("Closest approach to the part", f"{mc['min_clearance_mm']:.1f} mm off work ({at.get('body', '?')}, "
                                                     f"{at.get('zone', '?')} at {at.get('t_s', 0):.1f} s); TCP "
                                                     f"{mc.get('tcp_min_clearance_mm', float('nan')):.1f} mm; deepest "
                                                     f"{mc.get('max_penetration_mm', float('nan')):.3f} mm behind the surface"))
    pairs = [p for p in mc.get("cell_pairs") or () if isinstance(p, dict) and p.get("min_distance_mm") is not None]
    # the collision world's pairs: robot and tool against the cell (obstacles, floor), and link against link
    for label, kind, none in (("Closest approach to the cell", "environment", "no cell obstacles in the check"),
                              ("Closest approach between links", "self", "no link pair checked")):
        of_kind = [p for p in pairs if p.get("kind", "environment") == kind]
        if of_kind:
            best = min(of_kind, key=lambda p: p["min_distance_mm"])
            rows.append((label, f"{best['min_distance_mm']:.1f} mm ({best.get('a', '?')} x {best.get('b', '?')}, "
                                f"{len(of_kind)} pairs checked)"))
        else:
            rows.append((label, none))
    pm = report.get("process_map") or {}
    if pm.get("mean") is not None:
        rows.append(("Process uniformity", f"{100 * pm['uniformity_within_5pct']:.1f} % of the worked area within ±5 % "
                                           f"of the mean {pm['mean']:.4g} {pm.get('units', '')} (target "
                                           f"{100 * pm.get('uniformity_target', 0.95):.0f} %: "
                                           f"{'met' if pm.get('meets_uniformity_target') else 'not met'}); "
                                           f"uncovered {pm.get('uncovered_area_mm2', 0):.0f} mm²"))
    failed = []
    if status != "ok":
        if report.get("unreachable_count"):
            failed.append(f"{report['unreachable_count']} unreachable poses (marked in the scene)")
        findings = mc.get("findings") or []
        if findings:
            failed.append(f"{len(findings)} motion-check finding(s); first: {findings[0]}")
        if not failed and report.get("reason"):
            failed.append(str(report["reason"]))
    if failed:
        rows.append(("Where it failed", "; ".join(failed)))
    return rows


def _verdict_section(report: dict):
    """The page's opening: the verdict and the first figures (``_verdict_rows``)."""
    rows = _verdict_rows(report)
    body = "".join(f'<tr><th>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>' for k, v in rows)
    return ("Verdict", "", f'<table class="verdict">{body}</table>')


def _process_section(report: dict, surface):
    """The process map on the 3-D surface (``camtool.process.html``), or None without one."""
    from ..process.html import process_heat_map_figure, process_note

    figures = report.get("process_map")
    fig = process_heat_map_figure(figures, surface) if figures else None
    if fig is None:
        return None
    return (f"Process map: {figures.get('quantity', '')}", process_note(figures), fig_html(fig, PROCESS_DIV))


# ----------------------------------------------------------------------------- 3-D scene

def _boundary_lines(surface) -> np.ndarray | None:
    """The material boundary on the fitted surface (every face of a ``FaceSet``) as polylines (None-separated
    rows of NaN)."""
    from ..part.surface import FaceSet

    if isinstance(surface, FaceSet):
        parts = [p for p in (_boundary_lines(s) for s in surface.surfaces) if p is not None]
        return np.vstack(parts) if parts else None
    b = getattr(surface, "boundary", None)
    if b is None:
        return None
    out = []
    for poly in (b.outer_uv, *b.holes_uv):
        poly = np.asarray(poly, float)
        if len(poly) < 2:
            continue
        closed = np.vstack([poly, poly[:1]])
        uv = np.vstack([np.linspace(a, c, 8, endpoint=False) for a, c in zip(closed[:-1], closed[1:])]
                       + [closed[-1:]])
        out.append(surface.point_mm(uv[:, 0], uv[:, 1]))
        out.append(np.full((1, 3), np.nan))
    return np.vstack(out) if out else None


def _row_points(robot, path, joint_path, rows: np.ndarray) -> np.ndarray:
    """World TCP positions of joint-path rows: the path pose, or FK for inserted rows."""
    idx = joint_path.path_index[rows]
    p = np.empty((len(rows), 3))
    on = idx >= 0
    if path is not None and on.any():
        p[on] = path.poses_mm[idx[on]][:, :3, 3]
    else:
        on[:] = False
    if (~on).any():
        p[~on] = tcp_positions(robot, joint_path.q[rows[~on]])
    return p


def _marker(go, name, p, symbol, color, size=4):
    keep = subsample(len(p), MAX_MARKERS)
    return _trace("scatter3d", mode="markers", name=f"{name} ({len(p)})", **_xyz(p[keep]),
                        marker={"symbol": symbol, "color": color, "size": size}, hoverinfo="name+x+y+z")


def _scene_figure(report, robot, workpiece, surface, path, joint_path, feed, failing_indices, world=None):
    import plotly.graph_objects as go

    traces = []
    if workpiece is not None and workpiece.n_points:
        n = workpiece.n_points
        keep = np.sort(np.random.default_rng(0).choice(n, MAX_WORKPIECE_POINTS, replace=False)) \
            if n > MAX_WORKPIECE_POINTS else np.arange(n)
        traces.append(_trace("scatter3d", mode="markers", name=f"workpiece ({len(keep)} of {n} points)",
                                   **_xyz(workpiece.points_mm[keep]), hoverinfo="skip",
                                   marker={"size": 1.2, "color": "#b0b0b0", "opacity": 0.5}))
    if surface is not None:
        lines = _boundary_lines(surface)
        if lines is not None:
            traces.append(_trace("scatter3d", mode="lines", name="fitted surface boundary", **_xyz(lines),
                                       line={"color": "#444444", "width": 3}, hoverinfo="skip"))
    if path is not None and len(path):
        traces += _path_traces(go, path, feed)
    traces += _event_traces(go, report, robot, path, joint_path, failing_indices)
    traces += obstacle_traces(go, report)   # the cell's obstacles (camtool.collision)
    robot_traces, steps = _robot_traces(go, robot, path, joint_path, _robot_shapes(report, robot, world))
    first_robot = len(traces)
    traces += robot_traces
    fig = go.Figure()
    fig.update_layout(height=780, margin={"l": 0, "r": 0, "t": 30, "b": 0},
                      legend={"itemsizing": "constant", "x": 0.0, "y": 1.0, "bgcolor": "rgba(255,255,255,0.7)"},
                      scene={"aspectmode": "data", "xaxis_title": "x [mm]", "yaxis_title": "y [mm]",
                             "zaxis_title": "z [mm]"}, uirevision="scene")
    figure = _with_traces(fig, traces)
    if steps:   # plain data as the traces: its restyle arguments are every step's vertices
        figure["layout"]["sliders"] = [{"active": 0, "currentvalue": {"prefix": "robot at "}, "pad": {"t": 10},
                                        "steps": [dict(s, args=[s["args"][0], list(range(first_robot, len(traces)))])
                                                  for s in steps]}]
    return figure


def _path_traces(go, path, feed) -> list:
    p = path.poses_mm[:, :3, 3]
    shown = subsample(len(path), MAX_PATH_POINTS)
    traces = [_trace("scatter3d", mode="lines", name="path order", **_xyz(p[shown]), hoverinfo="skip",
                           line={"color": "#cccccc", "width": 1}, visible="legendonly")]
    zone = path.zone[shown]
    v_path = None
    if feed is not None:  # feed per path index from the waypoints that carry it
        v_path = np.full(len(path), np.nan)
        pi = feed["path_index"]
        ok = (pi >= 0) & (pi < len(path))
        v_path[pi[ok][::-1]] = feed["v"][ok][::-1]   # the first waypoint of each path index wins
    for code, name in enumerate(ZONES):
        sel = shown[zone == code]
        if not len(sel):
            continue
        if code == WORK and v_path is not None and np.isfinite(v_path[sel]).any():
            v_path[sel] = np.where(np.isfinite(v_path[sel]), v_path[sel], np.nanmedian(v_path[sel]))
            traces.append(_trace("scatter3d", 
                mode="markers", name=f"work: TCP feed ({int(np.count_nonzero(path.zone == code))} poses)",
                **_xyz(p[sel]), marker={"size": 2, "color": _list(v_path[sel], 1), "colorscale": "Turbo",
                                        "colorbar": {"title": {"text": "feed [mm/s]"}, "x": 1.0, "len": 0.6}},
                customdata=sel.tolist(),
                hovertemplate="pose %{customdata}<br>feed %{marker.color} mm/s<extra>work</extra>"))
        else:
            traces.append(_trace("scatter3d", 
                mode="markers", name=f"{name} ({int(np.count_nonzero(path.zone == code))} poses)", **_xyz(p[sel]),
                marker={"size": 2 if code == WORK else 1.6, "color": ZONE_COLORS.get(name, "#333333")},
                customdata=sel.tolist(), hovertemplate=f"pose %{{customdata}}<extra>{name}</extra>"))
    return traces


def _event_traces(go, report, robot, path, joint_path, failing_indices) -> list:
    traces = []
    if joint_path is not None:
        for flag, name, symbol, color in ((joint_path.reverse_planned, "reverse planned", "diamond", "#17becf"),
                                          (joint_path.retract, "retract", "square", "#8c564b"),
                                          (joint_path.singular, "singular", "x", "#d62728"),
                                          (~joint_path.reached, "not reached (IK)", "circle-open", "#000000")):
            rows = np.flatnonzero(flag)
            if len(rows):
                traces.append(_marker(go, name, _row_points(robot, path, joint_path, rows), symbol, color, 4))
    failing = {}
    for u in report.get("unreachable", []) or []:
        if "xyz_mm" in u:
            failing[int(u.get("index", -1 - len(failing)))] = np.asarray(u["xyz_mm"], float)
    if path is not None:
        for i in failing_indices:
            i = int(i)
            if 0 <= i < len(path) and i not in failing:
                failing[i] = path.poses_mm[i][:3, 3]
    if failing:
        keys = sorted(failing)
        traces.append(_marker(go, FAILING_NAME, np.array([failing[k] for k in keys]), "cross", "#ff0000", 5))
    return traces


def _robot_shapes(report: dict, robot, world=None):
    """The robot's bodies as the motion check measured them: the job's collision world, else one made
    with the tool report.json's cell bodies describe."""
    from ..collision.plot import RobotShapes
    from ..collision.world import CellSettings, CollisionWorld

    if world is None:
        cell = (report.get("motion_check") or {}).get("cell") or {}
        tool = next((b for b in cell.get("bodies", []) if b.get("kind") == "tool"), None)
        radius = float(tool["size_mm"][0]) if tool and tool.get("shape") == "cylinder" else DEFAULT_TOOL_RADIUS_MM
        points = np.asarray(tool["points_mm"], float) if tool and tool.get("points_mm") else None
        try:
            world = CollisionWorld(robot, CellSettings(tool_points_mm=points), radius)
        except BadInput:   # a URDF robot whose meshes cannot be read: the joints alone
            return None
    return RobotShapes(world)


def _robot_traces(go, robot, path, joint_path, shapes=None):
    """The stick figure and the link shapes (first slider pose), and the slider's restyle steps."""
    line = {"color": "#222222", "width": 7}
    marker = {"size": 3, "color": "#222222"}
    ok = np.flatnonzero(joint_path.reached) if joint_path is not None else np.zeros(0, int)
    if not len(ok):
        q0 = np.clip(np.zeros(robot.dof), robot.limits.lower, robot.limits.upper)
        traces = [_trace("scatter3d", mode="lines+markers", name="robot (zero joint values; no plan)",
                         **_xyz(joint_origins(robot, q0)), line=line, marker=marker)]
        if shapes is not None:
            traces.append(shapes.trace(go, q0, "robot link shapes (zero joint values)"))
        return traces, []
    rows = ok[subsample(len(ok), ROBOT_FRAMES)]   # reached rows only
    steps = []
    first = None
    for k in rows:
        pts = _xyz(joint_origins(robot, joint_path.q[k]))
        first = first or pts
        args = {a: [pts[a]] for a in "xyz"}
        if shapes is not None:
            V = np.round(shapes.vertices_mm(joint_path.q[k]), 1)
            for c, a in enumerate("xyz"):
                args[a].append(V[:, c].tolist())
        i = int(joint_path.path_index[k])
        zone = ZONES[joint_path.zone[k]]
        label = f"pose {i} ({zone})" if i >= 0 else f"row {int(k)} ({zone})"
        steps.append({"args": [args], "label": label, "method": "restyle"})   # keys in plotly's order
    traces = [_trace("scatter3d", mode="lines+markers", name="robot joints (slider below)", **first, line=line,
                     marker=marker, hoverinfo="skip")]
    if shapes is not None:
        traces.append(shapes.trace(go, joint_path.q[rows[0]], "robot link shapes (slider below)"))
    return traces, steps


# ----------------------------------------------------------------------------- feed, joint use

def _feed_figure(feed, report):
    import plotly.graph_objects as go

    s, v, zone = feed["s"], feed["v"], feed["zone"]
    n = len(s)
    if n > MAX_FEED_POINTS:  # the lowest feed per display bin, so slowdowns stay visible
        pick = _lowest_per_bin(v, np.round(np.linspace(0, n, MAX_FEED_POINTS + 1)).astype(int))
    else:
        pick = np.arange(n)
    s, v, zone = s[pick], v[pick], zone[pick]
    work_v = np.where(zone == WORK, v, np.nan)
    traces = [_trace("scattergl", x=_list(s, 1), y=_list(v, 1), mode="lines", name="all zones",
                           line={"color": "#bbbbbb", "width": 1}),
              _trace("scattergl", x=_list(s, 1), y=_list(work_v, 1), mode="lines", name="work",
                           line={"color": "#1f77b4", "width": 2}, connectgaps=False)]
    fig = go.Figure()
    target = report.get("tcp_speed_mm_s")
    if isinstance(target, (int, float)):
        fig.add_hline(y=float(target), line={"color": "#d62728", "dash": "dot"},
                      annotation_text=f"tcp_speed_mm_s = {target:g}")
    fig.update_layout(height=360, margin={"l": 60, "r": 20, "t": 30, "b": 50},
                      xaxis_title="TCP path length [mm]", yaxis_title="TCP feed [mm/s]")
    return _with_traces(fig, traces)


def _lowest_per_bin(v: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Per bin [edges[i], edges[i+1]) that is not empty, the index of its first lowest value (NaN ignored;
    a bin of NaN only: its first index)."""
    start = np.unique(edges[:-1][edges[1:] > edges[:-1]])
    low = np.fmin.reduceat(v, start)
    bin_of = np.repeat(np.arange(len(start)), np.diff(np.append(start, len(v))))
    at_low = np.flatnonzero(v == low[bin_of])     # NaN equals nothing: only a finite lowest value is found
    first = at_low[np.minimum(np.searchsorted(at_low, start), len(at_low) - 1)] if len(at_low) else start
    return np.where(np.isfinite(low), first, start)


def _joint_use_figure(robot, trajectory):
    import plotly.graph_objects as go

    L = robot.limits
    cols = subsample(len(trajectory.t_s), MAX_HEAT_COLUMNS)
    q = trajectory.q[cols]
    mid, half = 0.5 * (L.lower + L.upper), 0.5 * (L.upper - L.lower)
    share = ((q - mid) / np.where(half > 0, half, 1.0)).T                # (dof, T): -1 lower, +1 upper limit
    names = [f"{n} [{'mm' if p else 'deg'}]" for n, p in zip(robot.joint_names, robot.prismatic)]
    work = (np.asarray(trajectory.zone)[cols] == WORK).astype(float)
    traces = [
        _trace("heatmap", x=_list(trajectory.t_s[cols], 3), y=names, z=[_list(r, 3) for r in share], zmin=-1, zmax=1,
                   colorscale="RdBu", reversescale=True,
                   colorbar={"title": {"text": "share of limit"}, "tickvals": [-1, -0.5, 0, 0.5, 1],
                             "ticktext": ["lower", "-0.5", "mid", "0.5", "upper"]},
                   hovertemplate="%{y}<br>t %{x} s<br>%{z}<extra></extra>"),
        _trace("heatmap", x=_list(trajectory.t_s[cols], 3), y=["work zone"], z=[_list(work, 0)], zmin=0, zmax=1,
                   colorscale=[[0, "#ffffff"], [1, "#1f77b4"]], showscale=False, yaxis="y2",
                   hovertemplate="t %{x} s<extra>work</extra>"),
    ]
    fig = go.Figure()
    fig.update_layout(height=120 + 28 * robot.dof, margin={"l": 90, "r": 20, "t": 20, "b": 50},
                      xaxis_title="time [s]", yaxis={"domain": [0.0, 0.86], "autorange": "reversed"},
                      yaxis2={"domain": [0.9, 1.0], "showticklabels": True})
    return _with_traces(fig, traces)


# ----------------------------------------------------------------------------- redundancy map

def _redundancy_figure(rmap):
    import plotly.graph_objects as go

    from .redundancy_map import BAD_COLORS, IN_COLLISION, NO_IK, OUTSIDE_LIMITS

    x, y = _list(rmap.x, 0), _list(rmap.y, 2)
    bad = np.select([rmap.code == NO_IK, rmap.code == OUTSIDE_LIMITS, rmap.code == IN_COLLISION],
                    [0.0, 1.0, 2.0], np.nan)
    grey, red, orange = BAD_COLORS
    planned = np.asarray(rmap.planned, float).copy()
    if rmap.kind != "track":  # no line across the +-180 deg wrap
        jump = np.flatnonzero(np.abs(np.diff(planned)) > 180.0)
        planned = np.insert(planned, jump + 1, np.nan)
        xs = np.insert(rmap.x.astype(float), jump + 1, np.nan)
    else:
        xs = rmap.x.astype(float)
    traces = [
        _trace("heatmap", x=x, y=y, z=[_list(r, 0) for r in bad], zmin=0, zmax=2, showscale=False, name="unreachable",
                   colorscale=[[0, grey], [1 / 3, grey], [1 / 3, red], [2 / 3, red], [2 / 3, orange], [1, orange]],
                   hovertemplate="pose %{x}<br>%{y}<br>%{z}<extra>0 no IK, 1 outside limits, 2 in collision</extra>"),
        _trace("heatmap", x=x, y=y, z=[_list(r, 3) for r in rmap.margin], zmin=0, zmax=0.5, colorscale="Viridis",
                   name="joint-limit margin", colorbar={"title": {"text": "margin"}},
                   hovertemplate="pose %{x}<br>%{y}<br>margin %{z}<extra></extra>"),
        _trace("heatmap", x=x, y=y, z=[_list(r, 3) for r in rmap.manipulability], zmin=0, zmax=1,
                   colorscale="Viridis", name="manipulability", visible=False,
                   colorbar={"title": {"text": "manip."}},
                   hovertemplate="pose %{x}<br>%{y}<br>manipulability %{z}<extra></extra>"),
    ]
    if np.isfinite(planned).any():
        traces.append(_trace("scatter", x=_list(xs, 0), y=_list(planned, 2), mode="lines+markers", name="planned",
                                 line={"color": "#000000", "width": 1.5}, marker={"size": 3},
                                 connectgaps=False))
    n = len(traces)
    vis_margin = [True, True, False] + [True] * (n - 3)
    vis_manip = [True, False, True] + [True] * (n - 3)
    fig = go.Figure()
    fig.update_layout(
        height=480, margin={"l": 70, "r": 20, "t": 50, "b": 50},
        xaxis_title="path index (work poses)", yaxis_title=rmap.y_label,
        updatemenus=[{"type": "buttons", "direction": "right", "x": 0.0, "y": 1.02, "xanchor": "left",
                      "yanchor": "bottom",
                      "buttons": [{"label": "joint-limit margin", "method": "restyle",
                                   "args": [{"visible": vis_margin}]},
                                  {"label": "manipulability", "method": "restyle",
                                   "args": [{"visible": vis_manip}]}]}])
    return _with_traces(fig, traces)


# ----------------------------------------------------------------------------- page text

_CSS = ("body{font-family:system-ui,sans-serif;margin:1.2em;color:#222}h1{font-size:1.4em}"
        "h2{font-size:1.15em;margin-top:1.6em;border-bottom:1px solid #ddd}"
        "div.summary{column-width:24em;column-gap:2em;font-size:0.85em}"
        "div.kv{break-inside:avoid;display:flex;justify-content:space-between;border-bottom:1px dotted #e4e4e4}"
        "span.k{color:#555;padding-right:1em}span.v{font-family:monospace;text-align:right;overflow-wrap:anywhere}"
        "p.note{font-size:0.9em;color:#444;max-width:70em}"
        "table.verdict{border-collapse:collapse}table.verdict th{text-align:left;padding:0.2em 1.5em 0.2em 0;"
        "color:#555;font-weight:normal}table.verdict td{padding:0.2em 0}")
_SCENE_NOTE = ('<p class="note">World frame, mm. Workpiece points decimated for display; the path coloured by zone, '
               'work poses by TCP feed when the run was timed. Markers: reverse planned (diamond), retract '
               '(square), singular (x), not reached (open circle), unreachable or failing (red cross). '
               'Obstacles in orange. The slider moves the robot along the path: its joint origins (base, joint '
               'frames, flange, TCP) and, in blue, the link and tool shapes the motion check measures (hulls drawn '
               'from at most 64 of their vertices). Click a legend entry to hide or show it.</p>')
_FEED_NOTE = ('<p class="note">TCP speed from forward kinematics of the timed waypoints (distance / time), '
              'against the length the TCP has travelled; work zones in blue. Long runs show the lowest '
              'feed per display bin, so slowdowns stay visible.</p>')
_JOINT_NOTE = ('<p class="note">Each joint\'s position as a share of its range: -1 at the lower limit, 0 at '
               'mid-range, +1 at the upper limit. The top strip marks work zones.</p>')
_REDUNDANCY_NOTE = ('<p class="note">Columns: work poses (subsampled); rows: the robot\'s redundant parameter. '
                    'Grey: no IK solution; red: solutions only outside the joint limits; orange: the best solution '
                    'collides with the cell or the robot itself; coloured: reachable, '
                    'by joint-limit margin (share of range, 0.5 = every joint mid-range) or normalised '
                    'manipulability (buttons). The black curve is the planned solution. '
                    'See docs/report-html.md.</p>')

