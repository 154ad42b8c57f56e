"""A free-form face as a height field over its chart plane: the grid, its interpolation, the fill.

A free-form face is sampled on a regular grid of its **chart plane** (origin, frame
columns e1, e2, e3; e3 points to the tool side): node (i, j) is at chart
``x = x0 + i g``, ``y = y0 + j g`` (mm) and holds the height ``h`` of the surface
along e3 there. Every face that one S-raster can work from one side is such a graph
(its normals stay within 90 deg of e3); a closed CAD part's two skins are not, and
only the skin on the tool side is taken (noether #95).

``interp`` evaluates a grid bilinearly and extrapolates it linearly past its edges
(the cell's fraction is not clamped): a lead run past the grid continues the edge
cells' tangent plane. Normals are not extrapolated (a linear extrapolation of a
turning normal field turns on, ever faster): past the grid they keep the edge's. ``fill`` gives nodes without data a height: holes by a
membrane (Laplace) fill, so rows cross a hole straight and are split at its edge;
the margin round the face by its nearest edge node's tangent plane, so leads run on
the surface continued.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


SLOPE_SIGMA_MM = 4.0   # the margin continues its nearest node's tangent plane with the slope averaged over this


@dataclass(frozen=True)
class Grid:
    """A regular grid of the chart plane: ``nx`` x ``ny`` nodes ``g`` mm apart from (x0, y0); arrays are (ny, nx)."""

    x0: float
    y0: float
    g: float
    nx: int
    ny: int

    @property
    def xs(self) -> np.ndarray:
        return self.x0 + self.g * np.arange(self.nx)

    @property
    def ys(self) -> np.ndarray:
        return self.y0 + self.g * np.arange(self.ny)

    def node_xy(self) -> np.ndarray:
        """(ny, nx, 2) chart coordinates of the nodes (mm)."""
        X, Y = np.meshgrid(self.xs, self.ys)
        return np.stack([X, Y], axis=-1)

    def interp(self, arr: np.ndarray, x, y, extrapolate: bool = True) -> np.ndarray:
        """Bilinear value of ``arr`` ((ny, nx) or (ny, nx, k)) at chart (x, y) (any matching shapes),
        extrapolated linearly from the edge cells outside the grid (``extrapolate=False``: the value at the
        grid's nearest edge point, constant outside)."""
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        if not extrapolate:
            x = np.clip(x, self.x0, self.x0 + self.g * (self.nx - 1))
            y = np.clip(y, self.y0, self.y0 + self.g * (self.ny - 1))
        fx = (x - self.x0) / self.g
        fy = (y - self.y0) / self.g
        fx = np.where(np.isfinite(fx), fx, 0.0)
        fy = np.where(np.isfinite(fy), fy, 0.0)
        i = np.clip(np.floor(fx), 0, self.nx - 2).astype(np.int64)
        j = np.clip(np.floor(fy), 0, self.ny - 2).astype(np.int64)
        a, b = fx - i, fy - j
        if arr.ndim == 3:
            a, b = a[..., None], b[..., None]
        return ((1 - a) * (1 - b) * arr[j, i] + a * (1 - b) * arr[j, i + 1]
                + (1 - a) * b * arr[j + 1, i] + a * b * arr[j + 1, i + 1])

    def to_dict(self) -> dict:
        return {"x0": self.x0, "y0": self.y0, "g": self.g, "nx": self.nx, "ny": self.ny}

    @staticmethod
    def from_dict(d: dict) -> "Grid":
        g = Grid(float(d["x0"]), float(d["y0"]), float(d["g"]), int(d["nx"]), int(d["ny"]))
        if not (g.g > 0 and 2 <= g.nx <= 20_000 and 2 <= g.ny <= 20_000 and math.isfinite(g.x0 + g.y0)):
            raise ValueError("freeform grid: a spacing > 0 and 2..20000 nodes each way")
        return g


def grid_over(xy_lo: np.ndarray, xy_hi: np.ndarray, g: float, margin_cells: int = 3) -> Grid:
    """The grid of spacing ``g`` over a box of the chart plane, ``margin_cells`` nodes beyond it each way."""
    n = np.ceil((np.asarray(xy_hi) - np.asarray(xy_lo)) / g).astype(int) + 1 + 2 * margin_cells
    x0, y0 = (np.asarray(xy_lo) - margin_cells * g)
    return Grid(float(x0), float(y0), float(g), int(max(n[0], 2)), int(max(n[1], 2)))


def triangles(nx: int, ny: int) -> np.ndarray:
    """(2 (nx-1)(ny-1), 3) triangles of the grid's nodes (row-major index j nx + i), the cells' diagonals
    alternating (a chequerboard): one diagonal direction everywhere biases fast marching along it."""
    idx = np.arange(nx * ny).reshape(ny, nx)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    I, J = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1))
    alt = ((I + J) % 2 == 0)[..., None]
    t1 = np.where(alt, np.stack([a, b, d], -1), np.stack([a, b, c], -1)).reshape(-1, 3)
    t2 = np.where(alt, np.stack([a, d, c], -1), np.stack([b, d, c], -1)).reshape(-1, 3)
    return np.concatenate([t1, t2])


def gaussian(arr: np.ndarray, sigma_cells: float) -> np.ndarray:
    """``arr`` (ny, nx[, k]) blurred by a Gaussian of ``sigma_cells`` nodes (edges: nearest value)."""
    if sigma_cells <= 0:
        return arr
    from scipy.ndimage import gaussian_filter

    sig = (sigma_cells, sigma_cells) + (0,) * (arr.ndim - 2)
    return gaussian_filter(arr, sig, mode="nearest", truncate=3.0)


def fill(h: np.ndarray, known: np.ndarray, g: float, slope_sigma_mm: float = SLOPE_SIGMA_MM) -> np.ndarray:
    """Heights for the nodes without data: holes (regions not touching the grid's edge) by a Laplace
    (membrane) fill from their rim; the rest (the margin round the face) by the tangent plane of the nearest
    node with data, its slope averaged over ``slope_sigma_mm`` of the nodes with data (a scan's edge node alone
    has a one-sided, noisy slope: the shell scan's margin rose 11 mm over 20 mm past a rim that falls), smoothed
    over a few nodes. Returns a finite copy of ``h``."""
    from scipy import ndimage

    out = np.where(known, h, 0.0)
    unknown = ~known
    if not unknown.any():
        return out
    labels, n = ndimage.label(unknown)
    edge_labels = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    outside = np.isin(labels, edge_labels[edge_labels > 0])
    holes = unknown & ~outside
    if holes.any():
        out = _laplace_fill(out, holes)
    if outside.any():
        have = known | holes
        gx, gy = _smoothed_slope(out, have, g, slope_sigma_mm)
        _, (jj, ii) = ndimage.distance_transform_edt(~have, return_indices=True)
        gx0, gy0 = gx[jj, ii], gy[jj, ii]
        # no steeper than the face itself (99th percentile): a noisy edge node's slope is not carried far out
        slope = np.hypot(gx, gy)
        most = float(np.percentile(slope[known], 99)) if known.any() else 0.0
        k = np.minimum(1.0, most / np.maximum(np.hypot(gx0, gy0), 1e-12))
        gx0, gy0 = gx0 * k, gy0 * k
        J, I = np.indices(out.shape)
        ext = out[jj, ii] + gx0 * (I - ii) * g + gy0 * (J - jj) * g
        out = np.where(outside, ext, out)
        # the nearest-node seams of the margin smoothed over a few nodes; the data nodes kept
        blurred = gaussian(out, 2.0)
        out = np.where(outside, blurred, out)
    return out


def _smoothed_slope(h: np.ndarray, have: np.ndarray, g: float, sigma_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """(dh/dx, dh/dy) at the nodes with data, each averaged by a Gaussian of ``sigma_mm`` over the nodes where it
    is defined (a normalised convolution: the margin's zeros do not pull it towards level)."""
    out = []
    for axis in (1, 0):
        d = gradient_on(h, have, g, axis=axis)
        ok = _defined(have, axis).astype(float)
        num, den = gaussian(d * ok, sigma_mm / g), gaussian(ok, sigma_mm / g)
        out.append(np.where(den > 1e-6, num / np.maximum(den, 1e-6), d))
    return out[0], out[1]


def _defined(have: np.ndarray, axis: int) -> np.ndarray:
    """Where ``gradient_on`` has a difference along ``axis``: a node with data beside another."""
    ok = np.zeros(have.shape, bool)
    a, b = [slice(None)] * 2, [slice(None)] * 2
    a[axis], b[axis] = slice(0, -1), slice(1, None)
    pair = have[tuple(a)] & have[tuple(b)]
    ok[tuple(a)] |= pair
    ok[tuple(b)] |= pair
    return ok


def gradient_on(h: np.ndarray, have: np.ndarray, g: float, axis: int) -> np.ndarray:
    """d h / d (axis) at the nodes with data: central differences, one-sided where a neighbour has none, 0 where
    neither has."""
    fwd = np.zeros(h.shape)
    bwd = np.zeros(h.shape)
    ok_f = np.zeros(h.shape, bool)
    ok_b = np.zeros(h.shape, bool)
    sl = [slice(None)] * 2
    a, b = list(sl), list(sl)
    a[axis], b[axis] = slice(0, -1), slice(1, None)
    a, b = tuple(a), tuple(b)
    fwd[a] = (h[b] - h[a]) / g
    ok_f[a] = have[a] & have[b]
    bwd[b] = (h[b] - h[a]) / g
    ok_b[b] = have[a] & have[b]
    both = ok_f & ok_b
    return np.where(both, 0.5 * (fwd + bwd), np.where(ok_f, fwd, np.where(ok_b, bwd, 0.0)))


def _laplace_fill(h: np.ndarray, holes: np.ndarray) -> np.ndarray:
    """The membrane over ``holes``: each hole node the mean of its four neighbours (sparse solve)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.linalg import spsolve

    ny, nx = h.shape
    idx = -np.ones(h.shape, np.int64)
    jj, ii = np.nonzero(holes)
    idx[jj, ii] = np.arange(len(jj))
    rows, cols, vals = [], [], []
    rhs = np.zeros(len(jj))
    deg = np.zeros(len(jj))
    for dj, di in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        j2, i2 = jj + dj, ii + di
        inside = (j2 >= 0) & (j2 < ny) & (i2 >= 0) & (i2 < nx)
        k = np.flatnonzero(inside)
        deg[k] += 1
        other = idx[j2[k], i2[k]]
        unk = other >= 0
        rows.append(k[unk])
        cols.append(other[unk])
        vals.append(-np.ones(int(unk.sum())))
        np.add.at(rhs, k[~unk], h[j2[k[~unk]], i2[k[~unk]]])
    rows.append(np.arange(len(jj)))
    cols.append(np.arange(len(jj)))
    vals.append(deg)
    A = coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                   shape=(len(jj), len(jj))).tocsc()
    out = h.copy()
    out[jj, ii] = spsolve(A, rhs)
    return out


def normals_of(h: np.ndarray, g: float, frame: np.ndarray, sigma_mm: float, known: np.ndarray | None = None) -> np.ndarray:
    """(ny, nx, 3) unit normals (world) of the height field ``h``, averaged by a Gaussian of ``sigma_mm`` over the
    nodes with data (``known``; a face's edge averages the face, not the filled margin): ``e3 - h_x e1 - h_y e2``
    normalised, then averaged. They all point to the tool side (positive along e3): no two neighbours flip."""
    hy, hx = np.gradient(h, g)
    n = frame[:, 2][None, None, :] - hx[..., None] * frame[:, 0] - hy[..., None] * frame[:, 1]
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    s = sigma_mm / g
    if known is None or known.all():
        avg = gaussian(n, s)
    else:
        w = known.astype(float)
        num, den = gaussian(n * w[..., None], s), gaussian(w, s)
        avg = np.where((den > 1e-3)[..., None], num / np.maximum(den, 1e-3)[..., None], gaussian(n, s))
    return avg / np.linalg.norm(avg, axis=-1, keepdims=True)
