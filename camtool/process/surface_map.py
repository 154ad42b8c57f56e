"""The declared interface of "a map over a surface": the sites a process map holds its values at.

Two kinds implement it: ``grid.MapGrid`` (cells of a regular (u, v) grid: planes,
sphere patches) and ``mesh_map.MeshMap`` (vertices of a free-form face's own mesh).
A map's ``values`` have the shape of its sites; every figure (``figures``), file
(``process_map.npz``, the PNG) and the report's 3-D view is made through this
interface, so none of them asks which kind a map is:

- ``surface``, ``cell_mm``: the surface and the sites' spacing (mm on the surface);
- ``material`` (bool) and ``area_mm2``: the worked sites and each site's area on the surface,
  both of the values' shape (figures are taken over the material, weighted by area);
- ``edge_distance_mm()``: each site's distance from the material's edge (mm);
- ``points_mm()``: the sites on the surface (world mm, the values' shape + (3,));
- ``npz_arrays()``: the map's geometry as ``process_map.npz`` stores it, with ``layout`` naming the kind
  (``camtool.process.html`` draws a stored map by its layout);
- ``draw(ax, values)``: the map on a matplotlib axis (the PNG);
- ``as_lattice(a)``: the sites' array on their 2-D lattice (a mesh's vertices row by row), where the figures
  take the map linear between neighbouring samples;
- ``per_face()``: the maps of the faces a map of several faces holds (``map_set.MapSet``), each with its own
  files; none for one surface's map.
"""
from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np


class SurfaceMap(ABC):
    """Sites over a surface that a process map holds values at (see the module doc)."""

    layout: str = ""

    @property
    @abstractmethod
    def shape(self) -> tuple[int, ...]:
        """The shape of the map's values."""

    @abstractmethod
    def points_mm(self) -> np.ndarray:
        """The sites on the surface (world mm), of shape ``shape + (3,)``."""

    @abstractmethod
    def edge_distance_mm(self) -> np.ndarray:
        """Each site's distance from the nearest site off the material (mm), of shape ``shape``."""

    @abstractmethod
    def npz_arrays(self) -> dict:
        """The map's geometry for ``process_map.npz`` (with ``layout``), without the values."""

    @abstractmethod
    def draw(self, ax, values: np.ndarray):
        """Draw ``values`` over the material on the matplotlib axis ``ax``; returns the colour mappable."""

    def per_face(self) -> tuple:
        """((face index, ``integrate.ProcessMap``), ...) of the faces this map holds; () for one surface's map."""
        return ()

    def as_lattice(self, a: np.ndarray) -> np.ndarray:
        """The sites' array ``a`` laid out on the map's 2-D lattice (rows across v): a grid's own shape."""
        return a

    def uv_unit(self) -> str:
        return getattr(self.surface, "uv_unit", "mm")
