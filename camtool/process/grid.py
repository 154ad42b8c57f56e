"""The map's grid over a surface's (u, v) domain.

A regular grid in (u, v): on a plane u and v are mm and the cells are
``cell_mm`` squares; on a sphere patch u (azimuth) and v (elevation) are rad,
the v step is ``cell_mm / R`` and the u step ``cell_mm / (R cos v)`` at the
elevation nearest the equator, so no cell is wider than ``cell_mm``. The grid
covers the material boundary's bounds plus ``pad_mm`` on every side (the
footprint of a tool at the edge); ``material`` marks the cells whose centre
lies on material (inside the outer polygon, outside the holes): the worked
area every figure is taken over. ``area_mm2`` is each cell's area on the surface.

``refined`` splits every cell into ``m_u`` x ``m_v`` sub-cells (the same
domain, finer samples): the map is integrated there and its figures taken
there, so the ripple between passes is resolved (``refinement`` chooses the
factors from the rows' spacing and direction: ``RIPPLE_SAMPLES`` samples per
period across the rows, within ``MAX_CELLS``); the saved map is the
sub-cells' average over each cell.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import BadInput
from ..path.toolpath import freeze_arrays
from .surface_map import SurfaceMap

MAX_CELLS = 4_000_000  # a finer grid is refused: coarsen process.grid_mm
RIPPLE_SAMPLES = 96     # samples per period of the ripple across the rows (figures within 0.5 pp: docs/process.md)


@dataclass(frozen=True)
class MapGrid(SurfaceMap):
    """Cell centres ``u`` (nu,) and ``v`` (nv,) in the surface's uv unit; arrays are (nv, nu)."""

    layout = "grid"

    surface: object
    u: np.ndarray
    v: np.ndarray
    cell_mm: float
    material: np.ndarray   # (nv, nu) bool
    area_mm2: np.ndarray   # (nv, nu)
    sub: tuple[int, int] = (1, 1)  # (m_u, m_v): a refinement of a grid of m_u x m_v larger cells (``refined``)

    def __post_init__(self):
        freeze_arrays(self)

    @property
    def du(self) -> float:
        return float(self.u[1] - self.u[0]) if len(self.u) > 1 else 1.0

    @property
    def dv(self) -> float:
        return float(self.v[1] - self.v[0]) if len(self.v) > 1 else 1.0

    @property
    def shape(self) -> tuple[int, int]:
        return len(self.v), len(self.u)

    def expand(self, mask: np.ndarray) -> np.ndarray:
        """A mask of the grid this one refines (``refined``), repeated onto this grid's sub-cells."""
        return np.repeat(np.repeat(mask, self.sub[1], axis=0), self.sub[0], axis=1)

    def points_mm(self) -> np.ndarray:
        """(nv, nu, 3) cell centres on the surface (world frame)."""
        U, V = np.meshgrid(self.u, self.v)
        return self.surface.point_mm(U, V)

    def index_of(self, uv: np.ndarray) -> np.ndarray:
        """(N, 2) fractional (i_u, i_v) cell coordinates of uv rows (0 = the first centre)."""
        uv = np.atleast_2d(uv)
        return np.stack([(uv[:, 0] - self.u[0]) / self.du, (uv[:, 1] - self.v[0]) / self.dv], axis=-1)

    def edge_distance_mm(self) -> np.ndarray:
        """(nv, nu) distance of each cell from the nearest off-material cell (mm, approximate on a sphere)."""
        from scipy.ndimage import distance_transform_edt

        if self.surface.model == "sphere":
            R = float(self.surface.radius_mm)
            v_mid = float(np.mean(self.v[np.any(self.material, axis=1)])) if self.material.any() else 0.0
            sampling = (R * self.dv, R * math.cos(v_mid) * self.du)
        else:
            sampling = (self.dv, self.du)
        padded = np.pad(self.material, 1, constant_values=False)
        return distance_transform_edt(padded, sampling=sampling)[1:-1, 1:-1]

    def npz_arrays(self) -> dict:
        """u, v (cell centres, uv unit), material, area_mm2, uv_unit, cell_mm, surface_model, layout."""
        return {"u": self.u, "v": self.v, "material": self.material, "area_mm2": self.area_mm2,
                "uv_unit": self.uv_unit(), "cell_mm": self.cell_mm, "surface_model": self.surface.model,
                "layout": self.layout}

    def draw(self, ax, values: np.ndarray):
        """A heat map in (u, v): mm, or deg on a sphere."""
        sphere = self.surface.model == "sphere"
        u = np.degrees(self.u) if sphere else np.asarray(self.u)
        v = np.degrees(self.v) if sphere else np.asarray(self.v)
        mesh = ax.pcolormesh(u, v, np.ma.masked_where(~self.material, values), shading="nearest", cmap="viridis")
        unit = "deg" if sphere else "mm"
        ax.set_xlabel(f"u [{unit}]")
        ax.set_ylabel(f"v [{unit}]")
        ax.set_aspect("auto" if sphere else "equal")
        return mesh


def grid_shape(surface, cell_mm: float, pad_mm: float) -> tuple[int, int, float, float]:
    """(nu, nv, du, dv) of the map grid, counted before anything is allocated: BadInput past ``MAX_CELLS``
    (checked before any planning, ``dwell.check_target_inputs``)."""
    lo, hi = surface.boundary.bounds()
    if surface.model == "sphere":
        R = float(surface.radius_mm)
        v_near = 0.0 if lo[1] <= 0.0 <= hi[1] else min(abs(lo[1]), abs(hi[1]))
        dv = cell_mm / R
        du = cell_mm / (R * math.cos(v_near))
        pad_v = pad_mm / R
        pad_u = pad_mm / (R * max(math.cos(max(abs(lo[1]), abs(hi[1])) + pad_v), 0.05))
    else:
        du = dv = cell_mm
        pad_u = pad_v = pad_mm
    cells_u = (hi[0] - lo[0] + 2 * pad_u) / du
    cells_v = (hi[1] - lo[1] + 2 * pad_v) / dv
    if not (math.isfinite(cells_u) and math.isfinite(cells_v)) or (cells_u + 1) * (cells_v + 1) > MAX_CELLS:
        raise BadInput(f"process.grid_mm = {cell_mm:g}: the process map would have {(cells_u + 1) * (cells_v + 1):.3g} "
                       f"cells (limit {MAX_CELLS:.0e}); use a coarser process.grid_mm")
    return int(math.ceil(cells_u)) + 1, int(math.ceil(cells_v)) + 1, du, dv


def map_grid(surface, cell_mm: float, pad_mm: float) -> MapGrid:
    """The grid of ``surface`` at ``cell_mm`` (see the module doc); BadInput when it would be too fine."""
    lo, hi = surface.boundary.bounds()
    nu, nv, du, dv = grid_shape(surface, cell_mm, pad_mm)
    cu, cv = 0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])
    u = cu + (np.arange(nu) - 0.5 * (nu - 1)) * du
    v = cv + (np.arange(nv) - 0.5 * (nv - 1)) * dv
    material, area = _material_and_area(surface, u, v, du, dv)
    return MapGrid(surface, u, v, float(cell_mm), material, area)


def _material_and_area(surface, u: np.ndarray, v: np.ndarray, du: float, dv: float) -> tuple[np.ndarray, np.ndarray]:
    """(nv, nu) material mask (centres inside the boundary) and cell areas on the surface (mm^2)."""
    U, V = np.meshgrid(u, v)
    material = surface.boundary.contains(np.column_stack([U.ravel(), V.ravel()])).reshape(U.shape)
    if surface.model == "sphere":
        area = (surface.radius_mm ** 2) * np.cos(V) * du * dv
    else:
        area = np.full(U.shape, du * dv)
    return material, area


def refinement(grid: MapGrid, spacing_mm: float, across_mm: np.ndarray) -> tuple[int, int]:
    """(m_u, m_v) sub-cells per cell so that neighbouring samples are at most ``spacing_mm`` apart along the unit
    direction ``across_mm`` (across the rows, in mm along u and v), as far as ``MAX_CELLS`` allows."""
    n = np.abs(np.asarray(across_mm, float))
    m = np.maximum(np.ceil(grid.cell_mm * n / spacing_mm - 1e-9), 1.0)
    return capped(m, float(grid.u.size * grid.v.size), MAX_CELLS)


def capped(m: np.ndarray, sites: float, limit: float) -> tuple[int, int]:
    """Sub-samples per axis ``m`` (2,) reduced so that ``sites * m_0 * m_1`` stays within ``limit``: the same share
    of the bound on each refined axis."""
    if sites * m[0] * m[1] > limit:
        shrink = math.sqrt(limit / (sites * m[0] * m[1])) if m.min() > 1 else limit / (sites * m.prod())
        m = np.maximum(np.floor(m * shrink), 1.0)
    return int(m[0]), int(m[1])


def refined(grid: MapGrid, m_u: int, m_v: int) -> MapGrid:
    """``grid`` with every cell split into ``m_u`` x ``m_v`` sub-cells (centres, material and areas of their own)."""
    surface = grid.surface
    du, dv = grid.du / m_u, grid.dv / m_v
    u = (grid.u[:, None] + ((np.arange(m_u) + 0.5) / m_u - 0.5)[None, :] * grid.du).ravel()
    v = (grid.v[:, None] + ((np.arange(m_v) + 0.5) / m_v - 0.5)[None, :] * grid.dv).ravel()
    material, area = _material_and_area(surface, u, v, du, dv)
    return MapGrid(surface, u, v, grid.cell_mm, material, area, (m_u, m_v))


def block_mean(fine: np.ndarray, m_u: int, m_v: int) -> np.ndarray:
    """(nv, nu) average of each cell's m_v x m_u sub-cells of a ``refined`` grid's (nv m_v, nu m_u) array."""
    nv, nu = fine.shape[0] // m_v, fine.shape[1] // m_u
    return fine.reshape(nv, m_v, nu, m_u).mean(axis=(1, 3))
