"""The interface every face the raster works declares (``Surface``): the analytic ones (``part.surface``) and the
free-form face (``part.freeform``).

The stages downstream ask a face what it is through these members, never by probing for attributes: a scan's face
carries a noise band its leads rise by (``lead_band_mm``) and a rounded contour (``scanned``); a CAD mesh's face
takes the sag's midposes onto its own facets (``on_mesh_facets``)."""
from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np


class Surface(ABC):
    """A face with a 2-D parameter domain (u, v), a material boundary (``boundary``: ``domain.Boundary`` in (u, v))
    and a normal towards the tool side. ``model`` names it ("plane", "sphere", "cylinder", "freeform"),
    ``uv_unit`` the unit of (u, v)."""

    model: str
    uv_unit: str

    @abstractmethod
    def point_mm(self, u, v) -> np.ndarray:
        """Points (..., 3) mm at parameters (u, v)."""

    @abstractmethod
    def normal_at(self, u, v) -> np.ndarray:
        """Unit normals (..., 3) at (u, v), towards the tool side."""

    @abstractmethod
    def uv_from_points(self, points_mm: np.ndarray) -> np.ndarray:
        """Parameters (n, 2) of the surface's points nearest ``points_mm`` (n, 3)."""

    @abstractmethod
    def metric_scale(self, uv: np.ndarray) -> np.ndarray:
        """(n, 2) mm per unit of u and of v at ``uv``."""

    @abstractmethod
    def to_dict(self) -> dict:
        """The surface as JSON-able data (``surface_from_dict`` reads it back)."""

    @property
    def scanned(self) -> bool:
        """Whether the face is a scan's smoothed surface (its points scatter about it in the scan's noise)."""
        return False

    @property
    def on_mesh_facets(self) -> bool:
        """Whether the face's points lie on a mesh's own triangles (a CAD mesh's free-form face)."""
        return False

    @property
    def lead_band_mm(self) -> float:
        """How far past the face's edge the leads rise above the part's roughness (0: an analytic face's leads
        follow its surface or tangent)."""
        return 0.0

    def summary_rows(self) -> list[tuple[str, str]]:
        """(name, value) rows the report's summary shows for this face's geometry."""
        return []
