"""The process map in report.html: a heat map on the 3-D surface, read back from ``process_map.npz``.

The file's ``layout`` (``surface_map.SurfaceMap``) says how it is drawn: a grid
(``"grid"``, and files without a layout) as a plotly surface over the analytic
surface's (u, v); a map on a surface's own mesh (``"mesh"``: a free-form face, a
cylinder) as a plotly mesh3d of its vertices with a colour per vertex; several
faces in one program (``"faces"``) as each face's own map, from its own file, on
one colour scale. Each is decimated to at most ``MAX_SIDE`` sites a side for display and rounded (0.1 mm, 4 significant
digits), so the page stays small and the same map gives the same bytes; sites
off material are left out (NaN cells, or the triangles not wholly on material).
"""
from __future__ import annotations

import html
from pathlib import Path

import numpy as np

MAX_SIDE = 160
NOTE = ('<p class="note">{quantity} [{units}] over the worked surface, integrated over the program as the '
        'controller runs it (4 ms samples; leads, corners and dwell count). Mean {mean}, RMS {rms_pct} % of the '
        'mean, {within5} % of the worked area within ±5 % ({within10} % within ±10 %), edge roll-off '
        '{rolloff} mm, uncovered {uncovered} mm². The same map: process_map.npz and plots/process_map.png '
        '(docs/process.md).</p>')


def _load(file) -> dict | None:
    from .. import safe_io
    from ..errors import BadInput

    try:  # camtool's own map, still read once through safe_io (regular file, capped inflation)
        return safe_io.load_npz(safe_io.read_input_bytes(Path(file), "stage"), file, safe_io.size_cap_bytes("stage"))
    except (BadInput, OSError, ValueError):
        return None


def _rounded(values: np.ndarray) -> np.ndarray:
    return np.vectorize(lambda x: float(f"{x:.4g}") if np.isfinite(x) else np.nan, otypes=[float])(values)


def _grid_trace(data: dict, surface, folder: Path):
    """[A plotly surface of a grid map over ``surface``'s (u, v)], or [] without the surface."""
    import plotly.graph_objects as go

    if surface is None:
        return []
    u, v, values, material = data["u"], data["v"], data["values"], data["material"]
    su = max(1, int(np.ceil(len(u) / MAX_SIDE)))
    sv = max(1, int(np.ceil(len(v) / MAX_SIDE)))
    u, v, values, material = u[::su], v[::sv], values[::sv, ::su], material[::sv, ::su]
    U, V = np.meshgrid(u, v)
    P = np.round(surface.point_mm(U, V), 1)
    shown = _rounded(np.where(material, values, np.nan))
    units = str(data["units"])
    return [go.Surface(x=np.where(material, P[..., 0], np.nan), y=np.where(material, P[..., 1], np.nan),
                       z=np.where(material, P[..., 2], np.nan), surfacecolor=shown,
                       colorscale="Viridis", colorbar={"title": f"{data['quantity']} [{units}]"},
                       hovertemplate=f"%{{surfacecolor:.4g}} {units}<extra></extra>")]


def _mesh_trace(data: dict, surface, folder: Path):
    """[A plotly mesh3d of a map on a surface's own mesh]: its vertices, a colour per vertex (no surface needed)."""
    import plotly.graph_objects as go

    from ..part.freeform_grid import triangles

    nx, ny = len(data["lattice_x"]), len(data["lattice_y"])
    sx, sy = max(1, int(np.ceil(nx / MAX_SIDE))), max(1, int(np.ceil(ny / MAX_SIDE)))
    keep = np.arange(nx * ny).reshape(ny, nx)[::sy, ::sx]
    P = np.round(data["vertices_mm"][keep.ravel()], 1)
    material = data["material"][keep.ravel()]
    F = triangles(keep.shape[1], keep.shape[0])
    F = F[material[F].all(axis=1)]
    used = np.unique(F)
    new_index = np.full(len(P), -1)
    new_index[used] = np.arange(len(used))
    F = new_index[F]
    units = str(data["units"])
    return [go.Mesh3d(x=P[used, 0], y=P[used, 1], z=P[used, 2], i=F[:, 0], j=F[:, 1], k=F[:, 2],
                      intensity=_rounded(data["values"][keep.ravel()][used]), intensitymode="vertex",
                      colorscale="Viridis", colorbar={"title": f"{data['quantity']} [{units}]"},
                      hovertemplate=f"%{{intensity:.4g}} {units}<extra></extra>")]


def _faces_traces(data: dict, surface, folder: Path):
    """Each face's map (of several in one program) from its own file, on the colour scale of all of them."""
    faces = dict(zip(getattr(surface, "indices", ()), getattr(surface, "surfaces", ())))
    traces = []
    for index, name in zip(data["face_indices"], data["face_files"]):
        face = _load(folder / str(name))
        if face is not None and ("layout" not in face or str(face["layout"]) != "faces"):  # one level, no loop
            traces += _traces(face, faces.get(int(index)), folder)
    shown = data["values"][data["material"]]
    lo, hi = (float(f"{shown.min():.4g}"), float(f"{shown.max():.4g}")) if len(shown) else (0.0, 1.0)
    for k, trace in enumerate(traces):
        trace.update(cmin=lo, cmax=hi, showscale=k == 0)
    return traces


TRACES = {"grid": _grid_trace, "mesh": _mesh_trace, "faces": _faces_traces}   # by process_map.npz's layout


def _traces(data: dict, surface, folder: Path) -> list:
    layout = str(data["layout"]) if "layout" in data else "grid"
    return TRACES[layout](data, surface, folder) if layout in TRACES else []


def process_heat_map_figure(figures: dict, surface):
    """A plotly figure of the map on the 3-D surface, or None when the map's file (or a grid map's surface) is
    missing."""
    import plotly.graph_objects as go

    file = Path(figures.get("file", "")) if figures else None
    data = None if file is None else _load(file)
    traces = [] if data is None else _traces(data, surface, file.parent)
    if not traces:
        return None
    fig = go.Figure(traces)
    fig.update_layout(scene={"aspectmode": "data", "xaxis_title": "x [mm]", "yaxis_title": "y [mm]",
                             "zaxis_title": "z [mm]"}, height=600, margin={"l": 0, "r": 0, "t": 30, "b": 0})
    return fig


def process_note(figures: dict) -> str:
    """The section's note: what the map is and its headline figures."""
    def g(key, scale=1.0, fmt="{:.3g}"):
        x = figures.get(key)
        return "n/a" if x is None else fmt.format(x * scale)

    return NOTE.format(quantity=html.escape(str(figures.get("quantity", ""))).capitalize(),
                       units=html.escape(str(figures.get("units", ""))),
                       mean=g("mean", fmt="{:.4g}") + " " + html.escape(str(figures.get("units", ""))),
                       rms_pct=g("rms_pct"), within5=g("uniformity_within_5pct", 100, "{:.1f}"),
                       within10=g("uniformity_within_10pct", 100, "{:.1f}"), rolloff=g("edge_rolloff_width_mm"),
                       uncovered=g("uncovered_area_mm2", fmt="{:.0f}"))
