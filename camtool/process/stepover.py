"""``raster.step_over_mm = "auto"``: the largest step-over whose predicted map meets the uniformity target.

The prediction is the map of the raster itself, run at constant feed: the
rows' surface poses (work and the leads that stay within the contact
tolerance), densified to half a map cell, each row a separate pass
(``predicted_map``, refined across the rows at the candidate's step-over, so
its share agrees with the exact reference: docs/process.md). A larger step-over means fewer rows and a shorter cycle,
so the largest one that meets ``process.uniformity_target`` (the share of the
worked area within ``uniformity_band_pct`` of the mean) is taken:

1. the ripple between rows bounds it from above: the cross-row profile of
   infinitely many straight passes ``sum_j P(y - j s)`` (``Footprint.pass_profile``)
   must have the target share of its period within the band (``ripple_limit_mm``);
2. from that bound downwards (steps of ``STEP_FRACTION`` of it, to ``MIN_FRACTION``
   of the footprint's diameter), the predicted map of the real raster on the real
   surface is evaluated until one meets the target.

The record says what limits the choice: ``ripple`` (the first candidate met the
target, the rows' overlap decides), ``curvature`` (on a curved surface, the first
candidate already fails away from the edges: the rows' spacing and the
footprint change over the patch) or ``edges`` (the roll-off at the material's
edges needed a smaller step-over than the ripple alone); when no candidate
met the target, the best one is taken and a note gives its share. On a
sphere patch, a cylinder and a free-form face (the last two: the map on their own
mesh, ``mesh_map``) the surface's curvature is part of the predicted map. Reach is
not part of the choice: the chosen raster is planned like any other.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..settings import ProcessSettings, RasterSettings
from ..path.toolpath import SURFACE_CODES
from .figures import edge_distance_mm, map_figures, share_within
from .footprint import Footprint
from .maps import track_map

STEP_FRACTION = 0.06   # each further candidate is this share of the ripple bound smaller
MIN_FRACTION = 0.05    # the smallest candidate, as a share of the footprint's diameter
MAX_CANDIDATES = 12    # full-map evaluations at most
CURVED_MODELS = ("sphere", "cylinder", "freeform")  # surfaces whose curvature the predicted map holds


def ripple_share(fp: Footprint, step_mm: float, band: float, samples: int = 400) -> float:
    """Share of one period of the cross-row profile of infinitely many passes within ``band`` of its mean."""
    y = (np.arange(samples) + 0.5) / samples * step_mm
    reach = int(math.ceil(fp.radius_mm / step_mm)) + 1
    h = sum(fp.pass_profile(y - j * step_mm) for j in range(-reach, reach + 1))
    mean = 1.0 / step_mm
    return float(np.mean(np.abs(h - mean) <= band * mean))


def ripple_limit_mm(fp: Footprint, target: float, band: float) -> float:
    """The largest step-over (to 0.1 mm, at most the diameter) whose ripple alone meets ``target``."""
    steps = np.arange(max(1, int(20 * fp.radius_mm)), 0, -1) * 0.1  # diameter down to 0.1 mm
    for s in steps:
        if ripple_share(fp, float(s), band) >= target:
            return float(s)
    return 0.1


def _track(path, feed_mm_s: float, spacing_mm: float, lift_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """(t_s, TCP mm): the path's surface poses at constant feed, densified to ``spacing_mm``; a lifted pose
    between runs so no pass joins the next."""
    P = path.poses_mm[:, :3, 3]
    Z = path.poses_mm[:, :3, 2]
    on = np.isin(path.zone, SURFACE_CODES)
    pieces, t0 = [], 0.0
    times = []
    idx = np.flatnonzero(on)
    breaks = np.flatnonzero((np.diff(idx) > 1) | (np.diff(path.segment[idx]) != 0)) + 1
    for run in np.split(idx, breaks):
        if len(run) < 2:
            continue
        p = P[run]
        seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
        n = np.maximum(np.ceil(seg / spacing_mm).astype(int), 1)
        f = np.concatenate([np.arange(k) / k for k in n] + [np.array([0.0])])
        i = np.concatenate([np.full(k, j) for j, k in enumerate(n)] + [np.array([len(p) - 1])])
        nxt = np.minimum(i + 1, len(p) - 1)
        dense = p[i] + f[:, None] * (p[nxt] - p[i])
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
        lifted = dense[-1] - Z[run[-1]] * lift_mm  # tool z points into the surface
        pieces += [dense, lifted[None, :]]
        times += [t0 + s / feed_mm_s, np.array([t0 + s[-1] / feed_mm_s + 0.1])]
        t0 = times[-1][-1] + 0.1
    return np.concatenate(times), np.vstack(pieces)


def predicted_map(surface, raster: RasterSettings, process: ProcessSettings, feed_mm_s: float):
    """(path, map) of the raster of ``surface`` with ``raster`` run at constant feed (see the module doc)."""
    from ..path.raster import raster_path

    path = raster_path(surface, raster)
    t, tcp = _track(path, feed_mm_s, 0.5 * process.grid_mm, 10.0 * process.contact_tol_mm + 1.0)
    return path, track_map(process, surface, t, tcp, rows_mm=raster.step_over_mm)


def _interior_share(pmap, fp: Footprint, band: float, kind: str) -> float:
    """Share within the band of the mean, over the sites at least a footprint radius from the material's edge
    (on a grid map's refined samples when it has them, as ``map_figures`` takes its share)."""
    inner = pmap.grid.material & (edge_distance_mm(pmap) >= fp.radius_mm)
    fine = getattr(pmap, "fine", None)
    if fine is not None and kind != "inspect":
        inner = fine.grid.expand(inner) & fine.grid.material
        pmap = fine
    if not inner.any():
        return 0.0
    g = pmap.grid
    v, w = pmap.values[inner], g.area_mm2[inner]
    if kind == "inspect":
        return float(np.sum(w[v > 0]) / np.sum(w))
    mean = float(np.sum(v * w) / np.sum(w))
    if mean <= 0:
        return 0.0
    if fine is None:
        return round(float(np.sum(w[np.abs(v - mean) <= band * mean]) / np.sum(w)), 5)
    axis = 0 if g.sub[1] >= g.sub[0] else 1
    return round(share_within(g.as_lattice(pmap.values), g.as_lattice(inner), g.as_lattice(g.area_mm2),
                              (1 - band) * mean, (1 + band) * mean, axis), 5)


def choose_step_over(surface, raster: RasterSettings, process: ProcessSettings, feed_mm_s: float
                     ) -> tuple[RasterSettings, dict]:
    """(raster settings with the chosen step_over_mm, the record for report.json) for ``step_over_mm = "auto"``."""
    from ..errors import BadInput

    if not process.enabled:
        raise BadInput('raster.step_over_mm = "auto" chooses the step-over for the tool\'s footprint: set '
                       'process.kind (polish, grind, paint or inspect) and the footprint (docs/process.md)')
    fp = Footprint.from_settings(process)
    band, target = process.uniformity_band, process.uniformity_target
    if process.kind == "inspect":
        bound = 2.0 * fp.radius_mm * 0.9  # coverage: every point seen once needs rows closer than the diameter
    else:
        bound = ripple_limit_mm(fp, target, band)
    tried, best = [], None
    s = bound
    floor = max(MIN_FRACTION * 2 * fp.radius_mm, 0.1)
    while s >= floor and len(tried) < MAX_CANDIDATES:
        candidate = replace(raster, step_over_mm=round(s, 2), step_over_auto=False)
        try:
            _, pmap = predicted_map(surface, candidate, process, feed_mm_s)
        except BadInput:
            s -= STEP_FRACTION * bound
            continue
        fig = map_figures(pmap, band)
        share = fig["uniformity_within_band"] if process.kind != "inspect" else 1.0 - fig["uncovered_share"]
        tried.append({"step_over_mm": candidate.step_over_mm, "share_within_band": share,
                      "interior_share_within_band": _interior_share(pmap, fp, band, process.kind),
                      "edge_rolloff_width_mm": fig["edge_rolloff_width_mm"], "rms_pct": fig["rms_pct"]})
        if best is None or share > best[1]:
            best = (candidate, share)
        if share >= target:
            break
        s -= STEP_FRACTION * bound
    if best is None:
        raise BadInput(f'raster.step_over_mm = "auto": no step-over from {bound:.3g} mm down to {floor:.3g} mm '
                       'gives a raster of this surface')
    chosen, share = best
    met = share >= target
    first = tried[0]
    if met and chosen.step_over_mm == first["step_over_mm"]:
        limit = "ripple"
    elif first["interior_share_within_band"] < target:
        limit = "curvature" if surface.model in CURVED_MODELS else "ripple"  # away from the edges it already fails
    else:
        limit = "edges"
    record = {"step_over_mm": chosen.step_over_mm, "predicted_share_within_band": share, "target": target,
              "band_pct": round(100 * band, 6), "met": met, "limited_by": limit,
              "ripple_bound_mm": round(bound, 2), "surface": surface.model, "candidates": tried}
    if not met:
        record["note"] = (f"no step-over met the target ({limit}): the best keeps {100 * (1 - share):.1f} % "
                          f"of the area outside +-{100 * band:g} %; the best candidate is used")
    return chosen, record


def auto_step_over(settings, surface):
    """(job settings with the raster's step-over chosen, the record) when ``step_over_mm = "auto"``, else
    (settings, None)."""
    if not settings.raster.step_over_auto:
        return settings, None
    raster, record = choose_step_over(surface, settings.raster, settings.process, settings.timing.tcp_speed_mm_s)
    return replace(settings, raster=raster), record
