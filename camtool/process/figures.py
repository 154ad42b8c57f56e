"""The figures of a process map (report.json ``process_map``), its PNG and its npz file.

All figures are taken over the worked area (the map's sites on material: grid
cells, or a free-form face's mesh vertices; ``surface_map.SurfaceMap``), weighted
by their area on the surface; on a grid the value figures (mean, PV, RMS,
uniformity) are taken on the map's refined grid (``ProcessMap.fine``, samples
``RIPPLE_SAMPLES`` per ripple period across the rows) when it has one:

- ``mean``, ``pv`` (max - min), ``rms`` (RMS deviation from the mean) and ``rms_pct`` of the mean;
- ``uniformity_within_5pct`` / ``_10pct``: the share of the worked area within +-5 % / +-10 % of the mean,
  i.e. the area of {x on material : |h(x) - mean| <= 0.05 mean} over the material's area, h the map taken
  linear between neighbouring samples across the rows (``share_within``: each sample's cell is split at its
  centre and each half holds the segment to the midpoint with its neighbour; constant up to an edge);
- ``edge_rolloff_width_mm``: how far in from the material's edge the map stays short of the mean by more
  than the band (``process.uniformity_band_pct``): the cells are binned by their distance from the edge
  (one cell per bin) and the width is where the first bin from the edge whose mean is within the band
  starts (0 = the edge itself is within it);
- ``uncovered_area_mm2`` / ``uncovered_share``: worked area the tool never reached (below 1 % of the mean;
  for inspect, count 0).
"""
from __future__ import annotations

import io
import math
import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from ..files import output_file
from .integrate import ProcessMap

UNCOVERED_SHARE_OF_MEAN = 0.01


def _weighted(values, weights):
    return float(np.sum(values * weights) / np.sum(weights))


def edge_distance_mm(pmap: ProcessMap) -> np.ndarray:
    """Each site's distance from the nearest off-material site (mm; ``SurfaceMap.edge_distance_mm``)."""
    return pmap.grid.edge_distance_mm()


def _linear_share(a: np.ndarray, b: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Share of a segment where a function linear from ``a`` to ``b`` lies within [lo, hi] (elementwise)."""
    d = b - a
    flat = d == 0
    step = np.where(flat, 1.0, d)
    t0, t1 = (lo - a) / step, (hi - a) / step
    part = np.clip(np.minimum(np.maximum(t0, t1), 1.0) - np.maximum(np.minimum(t0, t1), 0.0), 0.0, 1.0)
    return np.where(flat, ((a >= lo) & (a <= hi)).astype(float), part)


def share_within(values: np.ndarray, material: np.ndarray, area: np.ndarray, lo: float, hi: float,
                 axis: int = 0) -> float:
    """Area share of the material where the map lies within [lo, hi], the map taken linear between neighbouring
    cell centres along ``axis`` (0 = v, across the rows) and constant up to the material's edge."""
    f, on = np.moveaxis(values, axis, 0), np.moveaxis(material, axis, 0)
    frac = np.zeros(f.shape)
    for shift in (1, -1):  # the half-cell towards the next and the previous neighbour
        nb = np.roll(f, -shift, axis=0)
        nb_on = np.roll(on, -shift, axis=0)
        nb_on[-1 if shift == 1 else 0] = False
        frac += 0.5 * _linear_share(f, np.where(nb_on, 0.5 * (f + nb), f), lo, hi)
    w = np.moveaxis(area, axis, 0)[on]
    return float(np.sum(w * frac[on]) / np.sum(w))


def _finest(pmap: ProcessMap) -> list:
    """The maps the value figures are taken on: each face's (several faces) or the map's own, refined if it is."""
    faces = pmap.grid.per_face()
    maps = [m for _, m in faces] if faces else [pmap]
    return [m.fine if m.fine is not None else m for m in maps]


def _share(m: ProcessMap, lo: float, hi: float) -> tuple[float, float]:
    """(area within [lo, hi], worked area) of one map: linear across the rows on a grid or a refined mesh's lattice
    (``share_within``), the sites' areas on an unrefined mesh."""
    g = m.grid
    w = g.area_mm2[g.material]
    sub = getattr(g, "sub", None)
    lattice = g.as_lattice(m.values)
    if sub is None or lattice.ndim != 2:
        v = m.values[g.material]
        return float(np.sum(w * ((v >= lo) & (v <= hi)))), float(np.sum(w))
    share = share_within(lattice, g.as_lattice(g.material), g.as_lattice(g.area_mm2), lo, hi,
                         0 if sub[1] >= sub[0] else 1)
    return share * float(w.sum()), float(w.sum())


def _value_figures(pmap: ProcessMap) -> dict:
    """mean, rms, min, max, the worked area and the uniformity shares (a function of the band) over the finest
    samples there are (``_finest``)."""
    maps = _finest(pmap)
    v = np.concatenate([m.values[m.grid.material] for m in maps])
    w = np.concatenate([m.grid.area_mm2[m.grid.material] for m in maps])
    mean = _weighted(v, w)
    scale = abs(mean) if mean else 1.0

    def within(b):
        if mean <= 0:
            return 0.0  # nothing was done: no share is uniform
        parts = np.array([_share(m, mean - b * scale, mean + b * scale) for m in maps])
        return round(float(parts[:, 0].sum() / parts[:, 1].sum()), 5)

    return {"mean": mean, "rms": math.sqrt(_weighted((v - mean) ** 2, w)), "min": float(v.min()),
            "max": float(v.max()), "within": within, "scale": scale, "area_mm2": float(w.sum())}


def map_figures(pmap: ProcessMap, band: float = 0.05) -> dict:
    """The figures of ``pmap`` (see the module doc); values rounded for report.json."""
    g = pmap.grid
    worked = g.material
    out = {"kind": pmap.kind, "quantity": pmap.quantity, "units": pmap.units, "method": pmap.method,
           "grid_mm": g.cell_mm, "cells": int(worked.sum()), "worked_area_mm2": round(float(g.area_mm2[worked].sum()), 1),
           "contact_time_s": round(pmap.contact_time_s, 3), "contact_length_mm": round(pmap.contact_length_mm, 1),
           "samples": pmap.samples}
    if not worked.any():
        return {**out, "mean": None}
    v, w = pmap.values[worked], g.area_mm2[worked]
    vf = _value_figures(pmap)
    mean, rms, scale, within = vf["mean"], vf["rms"], vf["scale"], vf["within"]
    uncovered = (v <= 0.0) if pmap.kind == "inspect" else (v <= UNCOVERED_SHARE_OF_MEAN * scale)
    dist = edge_distance_mm(pmap)[worked]
    width = 0.0
    if mean > 0:
        bins = np.maximum(np.floor(dist / g.cell_mm - 0.5), 0).astype(int)  # cell centre to edge
        for b in range(int(bins.max()) + 1):
            sel = bins == b
            if not sel.any():
                continue
            if _weighted(v[sel], w[sel]) >= (1.0 - band) * mean:
                width = float(b * g.cell_mm)
                break
        else:
            width = float(dist.max())
    sig = 6
    return {**out, "mean": round(mean, sig), "pv": round(vf["max"] - vf["min"], sig), "rms": round(rms, sig),
            "rms_pct": round(100.0 * rms / scale, 3), "min": round(vf["min"], sig), "max": round(vf["max"], sig),
            "samples_across_rows_mm": round(_across_mm(pmap), 4), "worked_area_mm2": round(vf["area_mm2"], 1),
            "uniformity_within_5pct": within(0.05), "uniformity_within_10pct": within(0.10),
            "uniformity_within_band": within(band),
            "edge_rolloff_width_mm": round(width, 2),
            "uncovered_area_mm2": round(float(w[uncovered].sum()), 1),
            "uncovered_share": round(float(w[uncovered].sum() / w.sum()), 5)}


def _across_mm(pmap: ProcessMap) -> float:
    """The spacing of the samples the value figures are taken on, along the axis of the most sub-samples (mm)."""
    return min(getattr(m.grid, "spacing_mm", m.grid.cell_mm) / max(getattr(m.grid, "sub", None) or (1, 1))
               for m in _finest(pmap))


def _atomic(file: Path, write) -> Path:
    """Write through a temporary file in the same folder and a rename (never half-written), mode 0644."""
    file = output_file(file)
    fd, tmp = tempfile.mkstemp(dir=file.parent, prefix=".tmp-", suffix=file.suffix)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, 0o644)
        os.replace(tmp, file)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return file


def save_map_npz(pmap: ProcessMap, file) -> Path:
    """``process_map.npz``: the map's geometry (``SurfaceMap.npz_arrays``: u, v, material, area_mm2 ... for a grid;
    vertices, faces ... for a mesh), values (the sites' shape) and the units."""
    g = pmap.grid

    arrays = {**g.npz_arrays(), "values": pmap.values, "units": pmap.units, "quantity": pmap.quantity,
              "kind": pmap.kind}

    def write(tmp):
        # np.savez's layout (one .npy per name in a zip) with a fixed time stamp: the same map, the same bytes
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_STORED) as z:
            for name, value in arrays.items():
                buf = io.BytesIO()
                np.lib.format.write_array(buf, np.asarray(value), allow_pickle=False)
                z.writestr(zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0)), buf.getvalue())

    return _atomic(Path(file), write)


def plot_map_png(pmap: ProcessMap, figures: dict, file, title: str = "") -> Path:
    """A heat map of the worked area (``SurfaceMap.draw``: (u, v) of a grid, the chart of a mesh), with the headline
    figures."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 6))
    mesh = pmap.grid.draw(ax, pmap.values)
    fig.colorbar(mesh, ax=ax, label=f"{pmap.quantity} [{pmap.units}]")
    if figures.get("mean") is not None:
        ax.set_title(f"{title}\nmean {figures['mean']:.4g} {pmap.units}, RMS {figures['rms_pct']:.2f} %, "
                     f"within 5 %: {100 * figures['uniformity_within_5pct']:.1f} % of the area, "
                     f"uncovered {figures['uncovered_area_mm2']:.0f} mm²", fontsize=9)
    fig.tight_layout()
    _atomic(Path(file), lambda tmp: fig.savefig(tmp, dpi=90, format="png"))
    plt.close(fig)
    return Path(file)
