"""The process map of several faces worked in one program (``faces.select``): a map per face, and all of them.

Each face gets its own map (``maps.surface_map``: a grid on an analytic face, its own mesh on
a free-form face) from the contacts on its own surface (within ``process.contact_tol_mm``),
with its own files (``process_map_face<N>.npz``, ``plots/process_map_face<N>.png``).
``MapSet`` is the ``SurfaceMap`` of all of them: its sites are the faces' sites one after
the other (each face's values flattened), so the run's headline figures are those of the
whole worked area, weighted by area on the surfaces, each site's edge distance taken from
its own face's edge. Its npz (``process_map.npz``) holds those flat arrays and the faces'
file names; report.html draws each face from its own file.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..path.toolpath import freeze_arrays
from .surface_map import SurfaceMap


FACE_FILE = "process_map_face{index}.npz"      # beside process_map.npz
FACE_PNG = "plots/process_map_face{index}.png"


@dataclass(frozen=True)
class MapSet(SurfaceMap):
    """The maps of the faces of ``surface`` (a ``FaceSet``): ``face_maps`` ((face index, ``ProcessMap``), ...), as
    one set of sites."""

    surface: object
    face_maps: tuple
    material: np.ndarray = field(init=False)
    area_mm2: np.ndarray = field(init=False)
    cell_mm: float = field(init=False)

    layout = "faces"

    def __post_init__(self):
        if not self.face_maps:
            raise ValueError("a MapSet holds the maps of one face or more")
        object.__setattr__(self, "material", np.concatenate([np.ravel(p.material) for p in self.parts]))
        object.__setattr__(self, "area_mm2", np.concatenate([np.ravel(p.area_mm2) for p in self.parts]))
        object.__setattr__(self, "cell_mm", float(min(p.cell_mm for p in self.parts)))
        freeze_arrays(self)

    @property
    def parts(self) -> tuple:
        return tuple(m.grid for _, m in self.face_maps)

    @property
    def shape(self) -> tuple[int]:
        return (len(self.material),)

    def per_face(self) -> tuple:
        return self.face_maps

    def sizes(self) -> list[int]:
        return [int(np.prod(p.shape)) for p in self.parts]

    def split(self, values: np.ndarray) -> list[np.ndarray]:
        """The set's flat ``values`` as each face's values, in that face's shape."""
        cuts = np.cumsum(self.sizes())[:-1]
        return [v.reshape(p.shape) for v, p in zip(np.split(np.asarray(values), cuts), self.parts)]

    @staticmethod
    def joined(values) -> np.ndarray:
        """The faces' values (each in its face's shape) as the set's flat values."""
        return np.concatenate([np.ravel(v) for v in values])

    def points_mm(self) -> np.ndarray:
        return np.concatenate([np.reshape(p.points_mm(), (-1, 3)) for p in self.parts])

    def edge_distance_mm(self) -> np.ndarray:
        return np.concatenate([np.ravel(p.edge_distance_mm()) for p in self.parts])

    def npz_arrays(self) -> dict:
        """The flat sites' material and area_mm2, each face's index, size and file (``FACE_FILE``), cell_mm,
        layout."""
        indices = [i for i, _ in self.face_maps]
        return {"material": self.material, "area_mm2": self.area_mm2, "face_indices": np.asarray(indices),
                "face_sizes": np.asarray(self.sizes()),
                "face_files": np.asarray([FACE_FILE.format(index=i) for i in indices], dtype=str),
                "cell_mm": self.cell_mm, "layout": self.layout}

    def draw(self, ax, values: np.ndarray):
        """Each face's map (``SurfaceMap.draw``) side by side in ``ax``, on the colour scale of all of them."""
        values = np.asarray(values)
        shown = values[self.material]
        lo, hi = (float(shown.min()), float(shown.max())) if len(shown) else (0.0, 1.0)
        ax.set_axis_off()
        n, first = len(self.face_maps), None
        for k, ((index, pmap), v) in enumerate(zip(self.face_maps, self.split(values))):
            sub = ax.inset_axes([k / n + 0.06 / n, 0.08, 0.88 / n, 0.84])
            drawn = pmap.grid.draw(sub, v)
            drawn.set_clim(lo, hi)
            sub.set_title(f"face {index} ({pmap.grid.surface.model})", fontsize=8)
            sub.tick_params(labelsize=7)
            first = drawn if first is None else first
        return first
