"""Sampling a free-form face onto its height grid: a mesh exactly, a scan smoothed.

- **Chart plane** (``chart_frame``): e3 is the tool side, the mean of the normals when
  they agree (a dome's axis), else the points' thinnest principal direction, signed by
  the normals' majority (world up on a tie: a soup of flipped triangles, a closed part).
  e1 and e2 follow the plane rule of ``fit._plane_surface``: rows horizontal on a wall,
  along world x on a floor.
- **A mesh** (``mesh_heights``) is rasterised into the grid as a z-buffer: every node
  inside a triangle's footprint takes the triangle's height there, the highest along e3
  where several skins cover it (a closed part's skin on the tool side). Positions are
  then exactly on the triangles; winding, duplicate vertices, non-manifold edges and
  degenerate triangles do not matter to it (a degenerate triangle covers no node).
- **A scan** (``cloud_heights``) is smoothed by local linear regression with a Gaussian
  window of ``sigma_mm`` (the smoothing scale): each node's height is the weighted
  least-squares plane of the points around it, evaluated at the node, so a one-sided
  window at the scan's edge is not biased by the slope; the curvature bias of the window,
  ``sigma^2 / 2 * laplacian(h)``, is taken off. Points farther from the first pass's
  surface than ``OUTLIER_SIGMAS`` robust standard deviations (1.4826 x MAD) are outliers
  and dropped before the second pass. Points are binned to their nearest node after
  moving each along the first pass's tangent plane to it, so the bins cost no accuracy.
"""
from __future__ import annotations

import numpy as np

from .freeform_grid import Grid, fill, gaussian, gradient_on

OUTLIER_SIGMAS = 4.0       # a scan point farther than this many robust sigmas from the surface is an outlier
OUTLIER_FLOOR_MM = 0.05    # ... and never nearer than this (an exact cloud has a MAD of ~0)
HELD_SHARE = 0.2           # a node's height is estimated where its window holds this share of the typical weight


def _typical(weight: np.ndarray) -> float:
    w = weight[weight > 1e-6]
    return float(np.median(w)) if len(w) else 0.0


def chart_frame(points_mm: np.ndarray, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
    """(origin (3,), frame (3x3, columns e1, e2, e3 = tool side), consistent) of a face's points and normals.

    ``consistent`` is False when the normals did not agree on a side (triangles wound both ways, a closed part):
    the side was then taken as world up (or +x, +y)."""
    P = np.asarray(points_mm, float)
    N = np.asarray(normals, float)
    origin = P.mean(axis=0)
    sub = P[np.linspace(0, len(P) - 1, min(len(P), 50_000)).astype(int)] - origin
    _, vecs = np.linalg.eigh(sub.T @ sub)
    pca = vecs[:, 0]
    good = np.isfinite(N).all(axis=1) & (np.linalg.norm(N, axis=1) > 0.5)
    mean = N[good].mean(axis=0) if good.any() else np.zeros(3)
    if np.linalg.norm(mean) > 0.3:
        e3, consistent = mean / np.linalg.norm(mean), True
    else:
        votes = np.sign(N[good] @ pca) if good.any() else np.zeros(0)
        share = abs(float(votes.sum())) / max(len(votes), 1)
        consistent = share > 0.2
        e3 = pca * (1.0 if votes.sum() >= 0 else -1.0)
        if not consistent:
            e3 = pca * _world_sign(pca)
    z = np.array([0.0, 0, 1])
    zp = z - (z @ e3) * e3
    if np.linalg.norm(zp) > 0.1:          # a tilted face (a wall): e2 up, rows horizontal
        e2 = zp / np.linalg.norm(zp)
        e1 = np.cross(e2, e3)
    else:                                  # a face seen from above: rows along world x (or y)
        x = np.array([1.0, 0, 0])
        xp = x - (x @ e3) * e3
        if np.linalg.norm(xp) < 0.1:
            xp = np.array([0.0, 1, 0]) - e3[1] * e3
        e1 = xp / np.linalg.norm(xp)
        e2 = np.cross(e3, e1)
    return origin, np.column_stack([e1, e2, e3]), consistent


def _world_sign(a: np.ndarray) -> float:
    for k in (2, 0, 1):
        if abs(a[k]) > 1e-6:
            return 1.0 if a[k] > 0 else -1.0
    return 1.0


def to_chart(points_mm: np.ndarray, origin: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """(N, 3) chart coordinates (x, y, h) of world points (mm)."""
    return (np.asarray(points_mm, float) - origin) @ frame


def mesh_heights(vertices_chart: np.ndarray, faces: np.ndarray, grid: Grid, chunk: int = 4_000_000) -> np.ndarray:
    """(ny, nx) heights of the highest triangle over each node (NaN where none), a z-buffer of the mesh given
    in chart coordinates (x, y, h)."""
    V = np.asarray(vertices_chart, float)
    F = np.asarray(faces, np.int64)
    tri = V[F]                                            # (M, 3, 3)
    x0, y0, g = grid.x0, grid.y0, grid.g
    lo = tri[:, :, :2].min(axis=1)
    hi = tri[:, :, :2].max(axis=1)
    i0 = np.maximum(np.ceil((lo[:, 0] - x0) / g - 1e-9), 0).astype(np.int64)
    i1 = np.minimum(np.floor((hi[:, 0] - x0) / g + 1e-9), grid.nx - 1).astype(np.int64)
    j0 = np.maximum(np.ceil((lo[:, 1] - y0) / g - 1e-9), 0).astype(np.int64)
    j1 = np.minimum(np.floor((hi[:, 1] - y0) / g + 1e-9), grid.ny - 1).astype(np.int64)
    ni, nj = np.maximum(i1 - i0 + 1, 0), np.maximum(j1 - j0 + 1, 0)
    a = tri[:, 1, :2] - tri[:, 0, :2]
    b = tri[:, 2, :2] - tri[:, 0, :2]
    det = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    scale = np.maximum(np.abs(a).sum(1) * np.abs(b).sum(1), 1e-300)
    use = (ni * nj > 0) & (np.abs(det) > 1e-12 * scale)   # a triangle seen edge-on covers no node
    top = np.full(grid.nx * grid.ny, -np.inf)
    idx = np.flatnonzero(use)
    count = (ni * nj)[idx]
    bounds = np.searchsorted(np.cumsum(count), np.arange(chunk, count.sum() + chunk, chunk), side="right")
    start = 0
    for stop in np.unique(np.append(bounds, len(idx))):
        part = idx[start:stop]
        start = stop
        if len(part) == 0:
            continue
        c = (ni * nj)[part]
        t = np.repeat(part, c)
        k = np.arange(len(t)) - np.repeat(np.cumsum(c) - c, c)
        ii = i0[t] + k % ni[t]
        jj = j0[t] + k // ni[t]
        px = x0 + ii * g - tri[t, 0, 0]
        py = y0 + jj * g - tri[t, 0, 1]
        d = det[t]
        l1 = (px * b[t, 1] - py * b[t, 0]) / d
        l2 = (a[t, 0] * py - a[t, 1] * px) / d
        inside = (l1 >= -1e-9) & (l2 >= -1e-9) & (l1 + l2 <= 1 + 1e-9)
        t, l1, l2 = t[inside], l1[inside], l2[inside]
        h = (1 - l1 - l2) * tri[t, 0, 2] + l1 * tri[t, 1, 2] + l2 * tri[t, 2, 2]
        np.maximum.at(top, jj[inside] * grid.nx + ii[inside], h)
    top[~np.isfinite(top)] = np.nan
    return top.reshape(grid.ny, grid.nx)


def _llr(grid: Grid, xyh: np.ndarray, sigma_mm: float):
    """Local linear regression of heights on the grid: (heights (ny, nx), window weight (ny, nx)).
    Each point counts at its nearest node (its height moved there beforehand)."""
    from scipy.ndimage import correlate1d

    g = grid.g
    i = np.clip(np.rint((xyh[:, 0] - grid.x0) / g), 0, grid.nx - 1).astype(np.int64)
    j = np.clip(np.rint((xyh[:, 1] - grid.y0) / g), 0, grid.ny - 1).astype(np.int64)
    flat = j * grid.nx + i
    n = grid.nx * grid.ny
    cnt = np.bincount(flat, minlength=n).reshape(grid.ny, grid.nx).astype(float)
    hs = np.bincount(flat, weights=xyh[:, 2], minlength=n).reshape(grid.ny, grid.nx)
    s = sigma_mm / g
    r = int(np.ceil(3 * s))
    off = np.arange(-r, r + 1, dtype=float)
    w0 = np.exp(-0.5 * (off / s) ** 2)
    kern = [w0, w0 * off * g, w0 * (off * g) ** 2]

    def conv(img, px, py):  # sum over bins k of img_k * w(d) dx^px dy^py, d = node_k - node
        out = correlate1d(img, kern[px], axis=1, mode="constant")
        return correlate1d(out, kern[py], axis=0, mode="constant")

    S0, Sx, Sy = conv(cnt, 0, 0), conv(cnt, 1, 0), conv(cnt, 0, 1)
    Sxx, Sxy, Syy = conv(cnt, 2, 0), conv(cnt, 1, 1), conv(cnt, 0, 2)
    T0, Tx, Ty = conv(hs, 0, 0), conv(hs, 1, 0), conv(hs, 0, 1)
    A = np.stack([np.stack([S0, Sx, Sy], -1), np.stack([Sx, Sxx, Sxy], -1), np.stack([Sy, Sxy, Syy], -1)], -2)
    rhs = np.stack([T0, Tx, Ty], -1)
    ok = S0 > 1e-6
    ridge = 1e-6 * np.maximum(S0, 1e-12)[..., None, None] * (np.eye(3) * np.array([1.0, g * g, g * g]))
    A = np.where(ok[..., None, None], A + ridge, np.eye(3))
    sol = np.linalg.solve(A, np.where(ok[..., None], rhs, 0.0)[..., None])[..., 0]
    h = np.where(ok, sol[..., 0], np.nan)
    return h, S0


def cloud_heights(xyh: np.ndarray, grid: Grid, sigma_mm: float):
    """A scan's smoothed heights on the grid: (heights (ny, nx, NaN where no point is near), window weight
    (ny, nx), inlier mask of the points, residuals (mm) of the inliers). See the module doc."""
    xyh = np.asarray(xyh, float)
    keep = np.ones(len(xyh), bool)
    h = None
    for _ in range(3):                                   # pass, reject, pass again (twice)
        pts = xyh[keep]
        if h is not None:                                # move each point to its node along the tangent plane
            have = np.isfinite(h)
            hx = gradient_on(np.where(have, h, 0.0), have, grid.g, axis=1)
            hy = gradient_on(np.where(have, h, 0.0), have, grid.g, axis=0)
            i = np.clip(np.rint((pts[:, 0] - grid.x0) / grid.g), 0, grid.nx - 1).astype(np.int64)
            j = np.clip(np.rint((pts[:, 1] - grid.y0) / grid.g), 0, grid.ny - 1).astype(np.int64)
            dx = pts[:, 0] - (grid.x0 + i * grid.g)
            dy = pts[:, 1] - (grid.y0 + j * grid.g)
            pts = pts.copy()
            pts[:, 2] -= hx[j, i] * dx + hy[j, i] * dy
        h, weight = _llr(grid, pts, sigma_mm)
        # a node whose window holds few points (past the scan's edge) is extrapolated: an outlier there would
        # be fitted, not found; such nodes are judged by the tangent plane of the nearest well-held node
        held = np.isfinite(h) & (weight >= HELD_SHARE * _typical(weight))
        h = np.where(held, h, np.nan)
        res = xyh[:, 2] - grid.interp(fill(h, held, grid.g), xyh[:, 0], xyh[:, 1])
        res = np.where(np.isfinite(res), res, np.inf)
        mad = float(np.median(np.abs(res[keep] - np.median(res[keep])))) if keep.any() else 0.0
        limit = max(OUTLIER_SIGMAS * 1.4826 * mad, OUTLIER_FLOOR_MM)
        keep = np.abs(res) <= limit
    # the window's curvature bias: a Gaussian of sigma (and the bins' g / sqrt(12)) raises h by sigma^2/2 lap h.
    # The Laplacian is taken of h blurred at the window's own scale: the bias varies on the part's scale, while
    # two differences of the filtered noise are rough (blurred by one node, the 1 mm-noise shell scan's rows had
    # 0.5 mm kinks 5 mm apart, more than a controller's 0.1 mm path tolerance)
    known = np.isfinite(h)
    hf = np.where(known, h, 0.0)
    blur = max(1.0, sigma_mm / grid.g)
    hs = gaussian(hf, blur)
    lap = (np.gradient(np.gradient(hs, grid.g, axis=1), grid.g, axis=1)
           + np.gradient(np.gradient(hs, grid.g, axis=0), grid.g, axis=0))
    var = sigma_mm ** 2 + grid.g ** 2 / 12.0
    from scipy.ndimage import binary_erosion

    inner = binary_erosion(known, iterations=int(np.ceil(3 * blur)) + 3)   # the blur and two differences: data only
    h = np.where(known & inner, h - 0.5 * var * lap, h)
    res = xyh[:, 2] - grid.interp(np.where(np.isfinite(h), h, 0.0), xyh[:, 0], xyh[:, 1])
    return h, weight, keep, res[keep]
