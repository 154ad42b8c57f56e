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
        inside = MplPath(self.outer_uv).contains_points(uv)
        for hole in self.holes_uv:
            inside &= ~MplPath(hole).contains_points(uv)
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


@dataclass(frozen=True)
class FitStats:
    """Quality of a fit: inlier share, residuals (mm) and the number of points used."""

    inlier_ratio: float
    rms_mm: float
    max_residual_mm: float
    n_points: int
    n_inliers: int
