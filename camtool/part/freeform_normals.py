"""A free-form face's normals averaged over a window measured on the surface, not in its chart plane.

``freeform_grid.normals_of`` averages the height field's normals with a Gaussian of the
chart plane: fast (separable), and right where the face is near level. Where it tilts by
theta from the chart plane, a chart distance d is d / cos(theta) along the surface, so the
chart's window is that much longer across the slope: on the noether panel's rolled rim
(56-80 deg from the chart) a 9.9 mm chart sigma averaged 20-30 mm of the surface, most of it
the flatter face inside, and a 1 M-point scan's tool axes stood 12 deg (p95) off the
panel's normal averaged over 12.5 mm (issue #46).

``surface_normals`` keeps the chart's average where the face is level and, where it tilts
(from ``STEEP_FROM_DEG``, fully from ``STEEP_FULL_DEG``), averages the height field's own
normals with a Gaussian of the 3-D distance between the nodes' surface points, each node
weighted by its cell's area on the surface (g^2 / cos(tilt)): the window of the part's own
normal, a disc on the surface. scipy's filters take one kernel for the whole grid, so the
varying window is summed here by hand, offset by offset, over the tilted nodes only.
"""
from __future__ import annotations

import math

import numpy as np

from .freeform_grid import normals_of

STEEP_FROM_DEG = 15.0   # below this tilt from the chart plane the chart's window is the surface's (cos 15 = 0.97)
STEEP_FULL_DEG = 25.0   # from this tilt on the surface's window alone (between: blended, no seam)
AGREE_DEG = 1.0         # a scan's wide window is kept where it agrees with the footprint's within this (1.5: the
                        # 1 M panel's axes 2.76 deg p95, the shell scan's cycle 160 s; 1.0: 2.37 deg, 167 s)
POINTS_FROM_DEG = 55.0  # a scan's node this steep starts to take its normal from its points (point_normals) ...
POINTS_FULL_DEG = 65.0  # ... and from this tilt on only from them
POINT_WINDOW_SIGMAS = 2.5  # the points' window reaches this many footprints (Gaussian sigmas)
MIN_WINDOW_POINTS = 20  # fewer points in it than this: the height field's normal kept
WINDOW_POINTS = 400     # a dense scan's points are thinned to about this many a window (its normal's noise: ~0.4 deg)
POINT_LATTICE_SIGMAS = 1.5  # the points' normals are taken every footprint / this nodes and interpolated
LATTICE_SIGMAS = 1.5    # the surface's window is evaluated every sigma / this nodes (at least 1) and interpolated


def raw_normals(h: np.ndarray, g: float, frame: np.ndarray) -> np.ndarray:
    """(ny, nx, 3) unit normals (world) of the height field's central differences, unaveraged."""
    return normals_of(h, g, frame, 0.0)


def scan_normals(h: np.ndarray, g: float, frame: np.ndarray, sigma_mm: float, footprint_mm: float,
                 known: np.ndarray | None = None) -> np.ndarray:
    """(ny, nx, 3) a scan's normals: ``surface_normals`` over ``sigma_mm`` (wide enough that the scan's noise does not
    wobble them) where they agree with those over the tool's footprint ``footprint_mm`` within ``AGREE_DEG``, the
    footprint's where they differ by twice that, the blend averaged over the wide window (a blend switching node by
    node with the noise wobbled the shell scan's axes: its cycle 157 -> 188 s). Where the part turns under the wide
    window its mean is not the footprint's: the panel's curl into its rim, 10-20 mm inside its edge, stood 4.3 deg
    (p95) off the part's normal over 12.5 mm at 9.9 mm, 1.5 deg at 6 mm."""
    from .freeform_grid import gaussian

    wide = surface_normals(h, g, frame, sigma_mm, known)
    if sigma_mm <= footprint_mm:
        return wide
    narrow = surface_normals(h, g, frame, footprint_mm, known)
    apart_deg = np.degrees(np.arccos(np.clip(np.einsum("...k,...k", wide, narrow), -1.0, 1.0)))
    t = np.clip(apart_deg / AGREE_DEG - 1.0, 0.0, 1.0)
    t = gaussian(t, sigma_mm / g)[..., None]
    mixed = (1 - t) * wide + t * narrow
    return mixed / np.linalg.norm(mixed, axis=-1, keepdims=True)


def surface_normals(h: np.ndarray, g: float, frame: np.ndarray, sigma_mm: float,
                    known: np.ndarray | None = None) -> np.ndarray:
    """(ny, nx, 3) unit normals (world, towards the tool) of the height field ``h`` averaged by a Gaussian of
    ``sigma_mm`` along the surface over the nodes with data (``known``); see the module doc."""
    from scipy.ndimage import binary_dilation, distance_transform_edt

    chart = normals_of(h, g, frame, sigma_mm, known)
    if sigma_mm <= 0:
        return chart
    have = np.ones(h.shape, bool) if known is None else np.asarray(known, bool)
    r = int(math.ceil(3.0 * sigma_mm / g))
    tilt_deg = np.degrees(np.arccos(np.clip(chart @ frame[:, 2], -1.0, 1.0)))
    blend = np.clip((tilt_deg - STEEP_FROM_DEG) / (STEEP_FULL_DEG - STEEP_FROM_DEG), 0.0, 1.0)
    # past the data by more than a window's sigma (the margin the leads run on) the chart's: the margin is the
    # surface continued, and those nodes would cost most of the work
    blend[distance_transform_edt(~have) > sigma_mm / g] = 0.0
    steep = blend > 0
    if not steep.any():
        return chart
    step = max(1, int(sigma_mm / (LATTICE_SIGMAS * g)))    # the lattice's nodes and the window's offsets
    lattice = np.zeros(h.shape, bool)
    lattice[::step, ::step] = True
    js, is_ = np.nonzero(lattice & binary_dilation(steep, iterations=2 * step))
    coarse = chart[::step, ::step].copy()
    coarse[js // step, is_ // step] = _surface_average(h, g, frame, sigma_mm, have, js, is_, step)
    jj, ii = np.nonzero(steep)
    own = _lattice_at(coarse, step, jj, ii)
    b = blend[jj, ii, None]
    mixed = (1 - b) * chart[jj, ii] + b * own
    out = chart.copy()
    out[jj, ii] = mixed / np.linalg.norm(mixed, axis=-1, keepdims=True)
    return out


def _lattice_at(coarse: np.ndarray, step: int, jj: np.ndarray, ii: np.ndarray) -> np.ndarray:
    """The lattice's values ``coarse`` (every ``step``-th node) at nodes (jj, ii): bilinear, clamped to it."""
    from .freeform_grid import Grid

    return Grid(0.0, 0.0, float(step), coarse.shape[1], coarse.shape[0]).interp(coarse, ii, jj, extrapolate=False)


def _surface_average(h, g, frame, sigma_mm, have, js, is_, step: int) -> np.ndarray:
    """(len(js), 3) unit normals at nodes (js, is_): the area-weighted mean of the raw normals of the nodes with
    data within 3 sigma, each weighted by the Gaussian of its 3-D distance (chart offset and height difference).
    The window is summed every ``step`` nodes over the raw normals pre-averaged over ``step`` / 2 nodes (a
    Gaussian of sigma >= 2.5 steps is summed as well so, and the noise of the raw normals averages as before)."""
    from .freeform_grid import gaussian

    raw = raw_normals(h, g, frame)
    area = np.where(have, 1.0 / np.maximum(raw @ frame[:, 2], 0.05), 0.0)   # the cell's area on the surface / g^2
    pre = 0.5 * step if step > 1 else 0.0
    NA, AA = gaussian(raw * area[..., None], pre), gaussian(area, pre)
    r = step * int(math.ceil(3.0 * sigma_mm / (g * step)))
    pad = ((r, r), (r, r))
    H = np.pad(h, pad, mode="edge")
    A = np.pad(AA, pad)                                     # padding: no data, weight 0
    N = np.pad(NA, pad + ((0, 0),))
    jc, ic = js + r, is_ + r
    h0 = H[jc, ic]
    num = np.zeros((len(js), 3))
    den = np.zeros(len(js))
    inv = 0.5 / (sigma_mm * sigma_mm)
    for dj in range(-r, r + 1, step):
        for di in range(-r, r + 1, step):
            d2 = (di * di + dj * dj) * g * g
            if d2 > 9.0 * sigma_mm * sigma_mm:
                continue
            j2, i2 = jc + dj, ic + di
            dh = H[j2, i2] - h0
            w = np.exp(-(d2 + dh * dh) * inv)
            num += w[:, None] * N[j2, i2]
            den += w * A[j2, i2]
    fallback = raw[js, is_]
    avg = np.where((den > 1e-9)[:, None], num, fallback)
    return avg / np.linalg.norm(avg, axis=-1, keepdims=True)


def point_normals(normals: np.ndarray, height: np.ndarray, grid, frame: np.ndarray, xyh: np.ndarray,
                  footprint_mm: float, face: np.ndarray) -> np.ndarray:
    """A scan's normals (ny, nx, 3) with its steep nodes' (from ``POINTS_FROM_DEG`` of tilt, fully from
    ``POINTS_FULL_DEG``) taken from its points (``xyh``, chart coordinates): the principal axis of least spread of
    the points within ``POINT_WINDOW_SIGMAS`` footprints in 3-D of the node's surface point, Gaussian-weighted by
    their distance (sigma ``footprint_mm``), on the ``face`` nodes and a footprint round them. A height field's
    window ends with the field where a rim rolls past the vertical; the points' does not (the 1 M-point panel's
    rim, tilted over 65 deg: 9.1 deg p95 off the part's normal over 12.5 mm from the height field, 1.8 from its
    points)."""
    from scipy.spatial import cKDTree

    g = grid.g
    tilt_deg = np.degrees(np.arccos(np.clip(normals @ frame[:, 2], -1.0, 1.0)))
    blend = np.clip((tilt_deg - POINTS_FROM_DEG) / (POINTS_FULL_DEG - POINTS_FROM_DEG), 0.0, 1.0)
    from scipy.ndimage import binary_dilation, distance_transform_edt

    blend[distance_transform_edt(~face) > footprint_mm / g] = 0.0
    if not (blend > 0).any():
        return normals
    radius = POINT_WINDOW_SIGMAS * footprint_mm

    step = max(1, int(footprint_mm / (POINT_LATTICE_SIGMAS * g)))
    lattice = np.zeros(blend.shape, bool)
    lattice[::step, ::step] = True

    near = binary_dilation(blend > 0, iterations=2 * step)
    js, is_ = np.nonzero(lattice & near)
    centre = np.stack([grid.x0 + is_ * g, grid.y0 + js * g, height[js, is_]], axis=1)
    reach = binary_dilation(near, iterations=int(math.ceil(radius / g)) + 1)
    pi = np.clip(np.rint((xyh[:, 0] - grid.x0) / g), 0, grid.nx - 1).astype(np.int64)
    pj = np.clip(np.rint((xyh[:, 1] - grid.y0) / g), 0, grid.ny - 1).astype(np.int64)
    pts = xyh[reach[pj, pi]]
    per_window = len(pts) / max(float(reach.sum()) * g * g, 1e-9) * math.pi * radius ** 2
    pts = pts[::max(1, int(per_window / WINDOW_POINTS))]       # every k-th point: about WINDOW_POINTS a window
    pairs = cKDTree(pts).query_ball_point(centre, radius, return_sorted=True)
    count = np.array([len(p) for p in pairs])
    q = np.repeat(np.arange(len(centre)), count)
    d = pts[np.concatenate(pairs).astype(np.int64)] - centre[q] if count.sum() else np.zeros((0, 3))
    w = np.exp(-0.5 * (d * d).sum(axis=1) / footprint_mm ** 2)
    W = np.bincount(q, w, len(centre))
    mean = np.stack([np.bincount(q, w * d[:, a], len(centre)) for a in range(3)], axis=1)
    mean /= np.maximum(W, 1e-12)[:, None]
    e = d - mean[q]
    cov = np.zeros((len(centre), 3, 3))
    for a in range(3):
        for b in range(a, 3):
            cov[:, a, b] = cov[:, b, a] = np.bincount(q, w * e[:, a] * e[:, b], len(centre))
    own = normals[js, is_] @ frame                                  # chart coordinates
    axis = np.linalg.eigh(cov)[1][:, :, 0]
    axis *= np.where((axis * own).sum(axis=1) < 0, -1.0, 1.0)[:, None]
    enough = count >= MIN_WINDOW_POINTS
    coarse = (normals[::step, ::step] @ frame).copy()
    coarse[js // step, is_ // step] = np.where(enough[:, None], axis, own)
    jj, ii = np.nonzero(blend > 0)
    b = blend[jj, ii, None]
    mixed = (1 - b) * (normals[jj, ii] @ frame) + b * _lattice_at(coarse, step, jj, ii)
    out = normals.copy()
    out[jj, ii] = (mixed / np.linalg.norm(mixed, axis=1, keepdims=True)) @ frame.T
    return out
