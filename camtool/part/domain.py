"""The parameter domain of a surface: its material boundary in (u, v), and the quality of its fit.

Shared by the analytic surfaces (``camtool.part.surface``) and the free-form one
(``camtool.part.freeform``); ``surface`` re-exports both names.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from matplotlib.path import Path as MplPath


@dataclass(frozen=True)
class Boundary:
    """Material region in the (u, v) domain: an outer polygon and holes (K x 2 each)."""

    outer_uv: np.ndarray
    holes_uv: tuple[np.ndarray, ...] = ()

    def contains(self, uv: np.ndarray) -> np.ndarray:
        """Boolean mask: which (u, v) rows lie on material (inside outer, outside holes)."""
        uv = np.atleast_2d(uv)
        inside = inside_polygon(self.outer_uv, uv)
        for hole in self.holes_uv:
            inside &= ~inside_polygon(hole, uv)
        return inside

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(min_uv, max_uv) of the outer polygon."""
        return self.outer_uv.min(axis=0), self.outer_uv.max(axis=0)

    def to_dict(self) -> dict:
        return {
            "outer_uv": np.asarray(self.outer_uv, float).tolist(),  # exact: a resumed raster must match a run
            "holes_uv": [np.asarray(h, float).tolist() for h in self.holes_uv],
        }

    @staticmethod
    def from_dict(d: dict) -> "Boundary":
        outer = np.asarray(d["outer_uv"], dtype=float).reshape(-1, 2)
        holes = tuple(np.asarray(h, dtype=float).reshape(-1, 2) for h in d.get("holes_uv", []))
        return Boundary(outer, holes)


CLEAR_REL = 1e-9   # a point this share of the polygon's extent from an edge's crossing, or its row from a vertex: asked
                   # of matplotlib (the crossing tests could round either way there)


def inside_polygon(polygon: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """matplotlib's ``Path.contains_points`` of a polygon (K x 2, closed from its last vertex to its first).

    Points on a grid's rows (the coverage's samples: 100 k points on 270 rows; a free-form face's outline has
    thousands of vertices) are decided a row at a time: the edges' crossings with the row, sorted, and the
    number left of each point (the even-odd rule, matplotlib's). A point within ``CLEAR_REL`` of a crossing,
    or on a row within it of a vertex, is asked of matplotlib, as are points on rows of their own: the
    answers are matplotlib's (0.38 -> 0.03 s on the hood's coverage grid, by hand because matplotlib tests
    every point against every edge)."""
    P = np.asarray(polygon, float)
    uv = np.asarray(uv, float)
    rows, row_of = np.unique(uv[:, 1], return_inverse=True)
    if len(P) < 3 or len(rows) * 8 > len(uv) or not np.isfinite(P).all() or not np.isfinite(uv).all():
        return MplPath(P).contains_points(uv)
    tol = CLEAR_REL * max(float(np.ptp(P, axis=0).max()), float(np.abs(P).max()), 1e-300)
    Q = np.roll(P, -1, axis=0)
    inside = np.zeros(len(uv), bool)
    ask = np.zeros(len(uv), bool)
    near_vertex = np.abs(rows[:, None] - P[None, :, 1]).min(axis=1) <= tol
    for r in np.flatnonzero(~near_vertex):
        y = rows[r]
        cross = (P[:, 1] > y) != (Q[:, 1] > y)
        x0, y0, x1, y1 = P[cross, 0], P[cross, 1], Q[cross, 0], Q[cross, 1]
        xs = np.sort(x0 + (y - y0) * (x1 - x0) / (y1 - y0))
        here = np.flatnonzero(row_of == r)
        x = uv[here, 0]
        k = np.searchsorted(xs, x)
        inside[here] = k % 2 == 1
        if len(xs):
            gap = np.minimum(np.abs(x - xs[np.minimum(k, len(xs) - 1)]), np.abs(x - xs[np.maximum(k - 1, 0)]))
            ask[here] = gap <= tol
    ask |= near_vertex[row_of]
    if ask.any():
        inside[ask] = MplPath(P).contains_points(uv[ask])
    return inside


@dataclass(frozen=True)
class FitStats:
    """Quality of a fit: inlier share, residuals (mm) and the number of points used."""

    inlier_ratio: float
    rms_mm: float
    max_residual_mm: float
    n_points: int
    n_inliers: int
