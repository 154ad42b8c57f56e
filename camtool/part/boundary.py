"""Material boundary of fitted points in a surface's (u, v) domain.

The inliers are mapped to a flat image plane in mm, rasterised into an
occupancy image (OpenCV), small gaps are closed morphologically, and the outer
contour and holes are traced with ``cv2.findContours(RETR_CCOMP)``, simplified
with ``approxPolyDP`` and mapped back to (u, v).

- Plane: the image plane is (u, v) itself (mm).
- Sphere: the image plane is the sinusoidal (equal-area) projection
  x = R u cos v, y = R v, so a cell is ``cell_mm`` on the surface everywhere
  and the point density per cell does not fall with elevation.

Outer polygons are counter-clockwise in (u, v), holes clockwise.
"""
from __future__ import annotations

import math

import cv2
import numpy as np

from ..errors import BadInput
from .surface import Boundary


def boundary_from_uv(uv: np.ndarray, radius_mm: float | None = None, cell_mm: float = 2.0,
                     close_gaps_mm: float = 6.0, simplify_mm: float = 0.5,
                     source: str = "") -> Boundary:
    """Boundary (outer polygon + holes) of points ``uv`` (N x 2).

    ``radius_mm`` None means a plane (uv in mm); otherwise uv are azimuth and
    elevation (rad) on a sphere of that radius. Cell, gap and tolerance in mm.
    """
    uv = np.asarray(uv, dtype=float)
    if len(uv) < 3:
        raise BadInput(f"{source}: too few surface points ({len(uv)}) to find a boundary")
    xy = _to_image_plane(uv, radius_mm)
    spacing_mm = _median_spacing_mm(xy)
    # a sparse scan (points farther apart than two cells): the cells grow with the spacing, and so does the
    # smoothing's overshoot past the last points, which is then cut back to half a step
    sparse = spacing_mm > 2.0 * cell_mm
    cell_mm = max(cell_mm, 4.0 * spacing_mm)  # >= ~3.5 points per cell
    lo = xy.min(axis=0)
    span = xy.max(axis=0) - lo
    close_px = int(math.ceil(close_gaps_mm / cell_mm)) if close_gaps_mm > 0 else 0
    pad = close_px + 2
    size = np.ceil(span / cell_mm).astype(int) + 1 + 2 * pad
    if size[0] * size[1] > 64_000_000:
        raise BadInput(f"{source}: the boundary image would be {size[0]} x {size[1]} cells; "
                       f"raise fit.boundary_cell_mm (now {cell_mm:g} mm)")
    ij = np.floor((xy - lo) / cell_mm).astype(int) + pad
    counts = np.bincount(ij[:, 1] * size[0] + ij[:, 0], minlength=size[0] * size[1])
    density = cv2.GaussianBlur(counts.reshape(size[1], size[0]).astype(np.float32), (7, 7), 1.5)
    # Material where the smoothed density reaches half the typical one: the edge of a
    # uniformly sampled region then falls on its true edge, not on the last sparse point.
    level = 0.5 * float(np.median(density[counts.reshape(size[1], size[0]) > 0]))
    img = np.where(density >= level, 255, 0).astype(np.uint8)
    if close_px > 0:
        k = 2 * ((close_px + 1) // 2) + 1  # odd disc at least one cell wider than the gap
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))
        img = cv2.morphologyEx(img, cv2.MORPH_CLOSE, kernel)
    contours, hierarchy = cv2.findContours(img, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_SIMPLE)
    if not contours:
        raise BadInput(f"{source}: no material region found for the boundary")
    hierarchy = hierarchy[0]
    outers = [i for i in range(len(contours)) if hierarchy[i][3] < 0]
    best = max(outers, key=lambda i: (cv2.contourArea(contours[i]), len(contours[i])))
    eps_px = max(simplify_mm / cell_mm, 1.0)  # steps finer than a cell are sampling noise

    def to_uv(c: np.ndarray, reach_mm: float | None = None) -> np.ndarray:
        if eps_px > 0:
            c = cv2.approxPolyDP(c, eps_px, True)
        px = c.reshape(-1, 2).astype(float)
        poly = (px - pad + 0.5) * cell_mm + lo
        if reach_mm is not None:
            poly = _within_reach_of_points(poly, xy, reach_mm)
        return _from_image_plane(poly, radius_mm)

    # a sparse scan: the material ends within half a sampling step of the last measured point
    outer = _oriented(to_uv(contours[best], 0.5 * spacing_mm if sparse else None), ccw=True)
    holes = []
    child = hierarchy[best][2]
    min_hole_px = max(9.0, (close_gaps_mm / cell_mm) ** 2)  # smaller: a sampling gap
    while child >= 0:
        if cv2.contourArea(contours[child]) >= min_hole_px and len(contours[child]) >= 3:
            hole = to_uv(contours[child])
            if len(hole) >= 3:
                holes.append(_oriented(hole, ccw=False))
        child = hierarchy[child][0]
    # Deterministic order of holes: by their first vertex.
    holes.sort(key=lambda h: (round(float(h[:, 0].min()), 9), round(float(h[:, 1].min()), 9)))
    return Boundary(outer, tuple(holes))


def _within_reach_of_points(poly: np.ndarray, xy: np.ndarray, reach_mm: float, step_mm: float | None = None):
    """The polygon (image plane, mm) densified and pulled in so no vertex lies farther than ``reach_mm`` from a
    data point: the density image's smoothing (a few cells of 4 sampling steps) must not invent material
    beyond a sparse scan's edge."""
    from scipy.spatial import cKDTree

    step = step_mm or max(reach_mm, 1e-3)
    closed = np.vstack([poly, poly[:1]])
    seg = np.diff(closed, axis=0)
    n = np.maximum(np.ceil(np.linalg.norm(seg, axis=1) / step).astype(int), 1)
    dense = np.concatenate([a + np.linspace(0, 1, k, endpoint=False)[:, None] * d
                            for a, d, k in zip(closed[:-1], seg, n)])
    dist, idx = cKDTree(xy).query(dense)
    far = dist > reach_mm
    if far.any():
        p = xy[idx[far]]
        dense[far] = p + (dense[far] - p) * (reach_mm / dist[far])[:, None]
    return dense


def _median_spacing_mm(xy: np.ndarray, sample: int = 20000, queries: int = 2000) -> float:
    """Median nearest-neighbour distance of the points (from a strided subsample, rescaled)."""
    from scipy.spatial import cKDTree

    m = min(len(xy), sample)
    sub = xy[np.linspace(0, len(xy) - 1, m).astype(int)]
    q = sub[np.linspace(0, m - 1, min(m, queries)).astype(int)]
    dist, _ = cKDTree(sub).query(q, k=2)
    return float(np.median(dist[:, 1])) * math.sqrt(m / len(xy))


def _to_image_plane(uv: np.ndarray, radius_mm: float | None) -> np.ndarray:
    if radius_mm is None:
        return uv
    return np.stack([radius_mm * uv[:, 0] * np.cos(uv[:, 1]), radius_mm * uv[:, 1]], axis=-1)


def _from_image_plane(xy: np.ndarray, radius_mm: float | None) -> np.ndarray:
    if radius_mm is None:
        return xy
    v = np.clip(xy[:, 1] / radius_mm, -math.pi / 2 + 1e-6, math.pi / 2 - 1e-6)
    u = xy[:, 0] / (radius_mm * np.cos(v))
    return np.stack([u, v], axis=-1)


def _signed_area(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _oriented(poly: np.ndarray, ccw: bool) -> np.ndarray:
    if (_signed_area(poly) > 0) != ccw:
        poly = poly[::-1]
    return np.ascontiguousarray(poly)
