"""A target removal map met by modulating the feed along the rows (dwell time), as in optical figuring.

The removal of a tool whose rate does not depend on the feed (a spinning or
orbiting abrasive, ``process.relative_speed_m_s`` > 0, or a spray gun) is its
footprint convolved with the dwell-time map. Each surface pose k of the path
stands for the length ``l_k`` of row around it (half the way to each
neighbour) and dwells ``d_k = l_k / (feed * f_k)`` there, f_k the feed factor.
The map is ``M = A d``: the dwells binned at the poses' (u, v) and convolved
with the footprint (plane surfaces: the operator and its adjoint are FFT
convolutions). The work poses' dwells are solved for by the multiplicative
(Richardson-Lucy) update for non-negative systems,

    d <- clip(d * (A^T T) / (A^T A d), l / feed, l / (feed * feed_factor_min)),

which keeps every feed between ``feed_factor_min`` times the commanded feed and
the commanded feed itself (never faster: the commanded feed is what the joint
limits were checked at); lead poses keep the commanded feed. The residual
``M - T`` is measured over the clear aperture (worked cells at least a footprint
radius from the material's edge, where the tool can reach every point from all
sides) and over the whole worked area, before (constant feed) and after, with
the RMS after every iteration (convergence).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path as FsPath

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from .. import safe_io
from ..errors import BadInput
from ..settings import ProcessSettings
from ..path.toolpath import SURFACE_CODES, WORK
from .figures import edge_distance_mm
from .footprint import Footprint
from .grid import MapGrid, map_grid
from .maps import check_map_size
from .integrate import ProcessMap, _bin_bilinear, _fftconvolve, amounts


MAX_TARGET_BYTES = 200_000_000


@dataclass(frozen=True)
class DwellPlan:
    """Feed factors per path pose (1 where not modulated) and the solve's figures."""

    feed_factor: np.ndarray
    before: ProcessMap
    after: ProcessMap
    target: np.ndarray
    figures: dict


def load_target(file, grid: MapGrid) -> np.ndarray:
    """The target removal (um) on ``grid``: an .npz with ``u``, ``v`` (the surface's uv unit) and ``values_um``
    (or ``values``, as process_map.npz has), linear between its cells; BadInput naming the file otherwise."""
    p = FsPath(file)
    # opened once through safe_io (regular file, size cap, no FIFO hang), never np.load by name, and what
    # the archive inflates to capped before anything is allocated
    try:
        d = safe_io.load_npz(safe_io.read_input_bytes(p, "stage"), f"{p}: process.target_removal_file",
                             MAX_TARGET_BYTES)
    except BadInput as exc:
        msg = str(exc)
        raise BadInput(msg if "target_removal_file" in msg else f"process.target_removal_file: {msg}") from None
    try:
        u, v = np.asarray(d["u"], float), np.asarray(d["v"], float)
        values = np.asarray(d["values_um"] if "values_um" in d else d["values"], float)
    except (ValueError, KeyError, TypeError) as exc:
        raise BadInput(f"{p}: process.target_removal_file: expected an .npz with u, v and values_um "
                       f"({type(exc).__name__})") from None
    if u.ndim != 1 or v.ndim != 1:
        raise BadInput(f"{p}: process.target_removal_file: u and v must be 1-D")
    if values.shape != (len(v), len(u)) or len(u) < 2 or len(v) < 2 or not np.all(np.isfinite(values)):
        raise BadInput(f"{p}: process.target_removal_file: values_um must be finite, shaped (len(v), len(u)) = "
                       f"({len(v)}, {len(u)}), found {values.shape}")
    if np.any(np.diff(u) <= 0) or np.any(np.diff(v) <= 0):
        raise BadInput(f"{p}: process.target_removal_file: u and v must increase")
    if np.any(values < 0):
        raise BadInput(f"{p}: process.target_removal_file: a removal cannot be negative")
    interp = RegularGridInterpolator((v, u), values, bounds_error=False, fill_value=None)
    V, U = np.meshgrid(grid.v, grid.u, indexing="ij")
    return interp(np.stack([V.ravel(), U.ravel()], axis=-1)).reshape(grid.shape)


def _gather_bilinear(grid: MapGrid, field: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Adjoint of ``_bin_bilinear``: the field's bilinear value at uv (0 off the grid)."""
    nv, nu = grid.shape
    f = grid.index_of(uv)
    i0 = np.floor(f).astype(np.int64)
    fr = f - i0
    out = np.zeros(len(uv))
    for du, dv in ((0, 0), (1, 0), (0, 1), (1, 1)):
        iu, iv = i0[:, 0] + du, i0[:, 1] + dv
        w = (fr[:, 0] if du else 1 - fr[:, 0]) * (fr[:, 1] if dv else 1 - fr[:, 1])
        ok = (iu >= 0) & (iu < nu) & (iv >= 0) & (iv < nv)
        out[ok] += w[ok] * field[iv[ok], iu[ok]]
    return out


def _pose_lengths(path, on: np.ndarray) -> np.ndarray:
    """Length of row each surface pose stands for: half the way to each neighbour of the same run (mm)."""
    P = path.poses_mm[:, :3, 3]
    step = np.linalg.norm(np.diff(P, axis=0), axis=1)
    same = on[:-1] & on[1:] & (path.segment[:-1] == path.segment[1:])
    half = np.where(same, 0.5 * step, 0.0)
    length = np.zeros(len(P))
    length[:-1] += half
    length[1:] += half
    return length


def _rms(x, mask):
    return float(np.sqrt(np.mean(x[mask] ** 2))) if mask.any() else float("nan")


def check_target_inputs(job, process: ProcessSettings | None, surface) -> None:
    """Before any planning: BadInput when ``process.target_removal_file`` cannot be met on this job (the file,
    the surface, a removal that follows dwell)."""
    if process is None or not process.enabled:
        return
    # the map's size, counted before any planning (a grid_mm of 0.001 is one line now, not after the plan); each
    # face's of several, a free-form face's mesh
    check_map_size(process, surface)
    if not process.target_removal_file:
        return
    _check_model(surface, process)
    fp = Footprint.from_settings(process)
    load_target(job.resolve(process.target_removal_file),
                map_grid(surface, process.grid_mm, fp.radius_mm + 2 * process.grid_mm))


def _check_model(surface, process: ProcessSettings) -> None:
    if surface.model != "plane":
        raise BadInput("process.target_removal_file: dwell-time figuring is implemented for plane surfaces; "
                       f"this surface is a {surface.model}")
    if process.kind in ("polish", "grind") and process.relative_speed_m_s <= 0:
        raise BadInput("process.target_removal_file: with process.relative_speed_m_s = 0 the removal follows the "
                       "distance slid, not the dwell, so no feed meets a target; give the abrasive's speed")
    if process.kind == "inspect":
        raise BadInput("process.target_removal_file: an inspection removes nothing")


def plan_dwell(surface, path, process: ProcessSettings, feed_mm_s: float, target_file=None,
               target: np.ndarray | None = None, grid: MapGrid | None = None) -> DwellPlan:
    """Feed factors along the rows of ``path`` that make its map meet the target (see the module doc)."""
    _check_model(surface, process)
    fp = Footprint.from_settings(process)
    if grid is None:
        grid = map_grid(surface, process.grid_mm, fp.radius_mm + 2 * process.grid_mm)
    if target is None:
        target = load_target(target_file, grid)
    on = np.isin(path.zone, SURFACE_CODES)
    length = _pose_lengths(path, on)
    keep = on & (length > 0)
    uv = surface.uv_from_points(path.poses_mm[keep, :3, 3])
    free = (path.zone[keep] == WORK)
    rate = float(amounts(process, np.array([1.0]), np.array([0.0]))[0])  # um * mm^2 per second of dwell
    kernel = fp.kernel(grid.cell_mm)
    flipped = kernel[::-1, ::-1]

    def forward(d):
        return _fftconvolve(_bin_bilinear(grid, uv, rate * d), kernel, mode="same") / grid.area_mm2

    def adjoint(field):
        return rate * _gather_bilinear(grid, _fftconvolve(field / grid.area_mm2, flipped, mode="same"), uv)

    d_min = length[keep] / feed_mm_s
    d_max = d_min / process.feed_factor_min
    d = d_min.copy()
    worked = grid.material
    aperture = worked & (edge_distance_mm(_as_map(grid, target, process)) >= fp.radius_mm)
    weight = np.where(worked, 1.0, 0.0)
    tgt = np.where(worked, target, 0.0)
    At = adjoint(weight * tgt)
    before = forward(d)
    history = [_rms(before - target, aperture)]
    for _ in range(process.dwell_iterations):
        m = forward(d)
        ratio = At / np.maximum(adjoint(weight * m), 1e-300)
        d = np.where(free, np.clip(d * ratio, d_min, d_max), d)
        history.append(_rms(forward(d) - target, aperture))
    after = forward(d)
    factor = np.ones(len(path))
    factor[np.flatnonzero(keep)] = np.where(free, d_min / d, 1.0)
    t_mean = float(np.mean(target[aperture])) if aperture.any() else float("nan")
    figures = {
        "target_file": None if target_file is None else str(target_file),
        "target_mean_um": round(t_mean, 6),
        "residual_rms_before_um": round(history[0], 6), "residual_rms_after_um": round(history[-1], 6),
        "residual_rms_before_pct": round(100 * history[0] / t_mean, 3) if t_mean > 0 else None,
        "residual_rms_after_pct": round(100 * history[-1] / t_mean, 3) if t_mean > 0 else None,
        "residual_rms_after_worked_um": round(_rms(after - target, worked), 6),
        "convergence_rms_um": [round(h, 6) for h in history],
        "iterations": process.dwell_iterations, "clear_aperture_area_mm2": round(float(grid.area_mm2[aperture].sum()), 1),
        "feed_factor_min": round(float(factor[keep][free].min()), 4) if free.any() else 1.0,
        "feed_factor_max": round(float(factor[keep][free].max()), 4) if free.any() else 1.0,
        "work_time_before_s": round(float(d_min[free].sum()), 3), "work_time_after_s": round(float(d[free].sum()), 3),
    }
    quantity, units = ("removal depth", "um") if process.kind != "paint" else ("film thickness", "um")
    mk = lambda vals: ProcessMap(grid, vals, process.kind, quantity, units, "convolution", 0.0, 0.0, 0)  # noqa: E731
    return DwellPlan(factor, mk(before), mk(after), target, figures)


def _as_map(grid, values, process):
    return ProcessMap(grid, values, process.kind, "", "", "", 0.0, 0.0, 0)


def target_removal(settings) -> bool:
    """Whether the job gives a target removal map (``process.target_removal_file``): its trajectory is timed
    again for it (``retime_for_target``)."""
    process = settings.process
    return process is not None and process.enabled and bool(process.target_removal_file)


def retime_for_target(job, settings, surface, path, joint_path, robot):
    """(trajectory, plan) with ``process.target_removal_file``: the dwell plan of ``path`` and the joint path timed
    again with its feed factors as caps (``timing.feed = "max"``: the speed follows them within the joint
    limits; the timing's own 4 ms check and the motion check run on the result as on any other), or
    (None, None) without a target."""
    from dataclasses import replace

    from ..timing import time_trajectory

    process = settings.process
    if not target_removal(settings):
        return None, None
    plan = plan_dwell(surface, path, process, settings.timing.tcp_speed_mm_s,
                      target_file=job.resolve(process.target_removal_file))
    timing = replace(settings.timing, feed="max", feed_factor=tuple(float(x) for x in plan.feed_factor))
    return time_trajectory(joint_path, path, robot, timing), plan


def run_residual(plan: DwellPlan, values: np.ndarray, radius_mm: float) -> dict:
    """The residual of a run's map (on the plan's grid) against the target: RMS over the clear aperture."""
    grid = plan.before.grid
    aperture = grid.material & (edge_distance_mm(plan.before) >= radius_mm)
    t_mean = float(np.mean(plan.target[aperture])) if aperture.any() else float("nan")
    rms = _rms(values - plan.target, aperture)
    return {"residual_rms_run_um": round(rms, 6),
            "residual_rms_run_pct": round(100 * rms / t_mean, 3) if t_mean > 0 else None}
