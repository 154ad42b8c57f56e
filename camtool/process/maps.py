"""Which map a surface gets, and the map of a TCP track or of a timed trajectory on it.

A plane or a sphere patch gets the (u, v) grid (``grid``, ``integrate``); a free-form face
and a cylinder get their own mesh (``mesh_map``); several faces worked in
one program (a ``FaceSet``) get a map per face, together a ``map_set.MapSet``. Each is a
``surface_map.SurfaceMap``, and the maps made here are ``integrate.ProcessMap``\\ s the
figures, files and report take alike. This is the one place that chooses.
"""
from __future__ import annotations

import numpy as np

from ..settings import ProcessSettings
from .integrate import QUANTITY, ProcessMap, process_map, tcp_track
from .map_set import MapSet
from .mesh_map import (lattice_axes, lattice_pad_mm, mesh_map, mesh_process_map, parametric_axes,
                       parametric_mesh_map)
from .surface_map import SurfaceMap

# surfaces whose map lies on their own mesh: (its size check, its mesh), both (surface, cell_mm, pad_mm)
MESHES = {"freeform": (lattice_axes, mesh_map), "cylinder": (parametric_axes, parametric_mesh_map)}
SET_MODELS = frozenset({"faces"})       # several faces in one program (part.surface.FaceSet)


def on_mesh(surface) -> bool:
    """True when ``surface``'s map lies on its own mesh (a free-form face, a cylinder)."""
    return getattr(surface, "model", None) in MESHES


def _grid_pad_mm(settings: ProcessSettings) -> float:
    return 0.5 * settings.diameter_mm + 2 * settings.grid_mm


def faces_of(surface) -> tuple:
    """The surfaces a map is made on: a ``FaceSet``'s faces, or the one surface."""
    return tuple(surface.surfaces) if getattr(surface, "model", None) in SET_MODELS else (surface,)


def check_map_size(settings: ProcessSettings, surface) -> None:
    """Before any planning: BadInput when a face's map would be too fine (``grid.MAX_CELLS`` sites)."""
    from .grid import grid_shape

    for face in faces_of(surface):
        if on_mesh(face):
            MESHES[face.model][0](face, settings.grid_mm, lattice_pad_mm(settings))
        else:
            grid_shape(face, settings.grid_mm, _grid_pad_mm(settings))


def surface_map(settings: ProcessSettings, surface) -> SurfaceMap:
    """The sites of one surface's map at ``process.grid_mm``, padded by the footprint (as the maps make them)."""
    from .grid import map_grid

    if on_mesh(surface):
        return MESHES[surface.model][1](surface, settings.grid_mm, lattice_pad_mm(settings))
    return map_grid(surface, settings.grid_mm, _grid_pad_mm(settings))


def _face_set_map(settings: ProcessSettings, face_set, t_s, tcp_mm, rows_mm: float = 0.0) -> ProcessMap:
    """A map per face of ``face_set`` (each from the contacts on its own surface) and all of them as one."""
    maps = tuple((int(i), track_map(settings, face, t_s, tcp_mm, rows_mm=rows_mm))
                 for i, face in zip(face_set.indices, face_set.surfaces))
    sites = MapSet(face_set, maps)
    quantity, units = QUANTITY[settings.kind]
    method = ", ".join(sorted({m.method for _, m in maps}))
    return ProcessMap(sites, MapSet.joined([m.values for _, m in maps]), settings.kind, quantity, units, method,
                      float(np.sum([m.contact_time_s for _, m in maps])),
                      float(np.sum([m.contact_length_mm for _, m in maps])), int(len(t_s)))


def track_map(settings: ProcessSettings, surface, t_s, tcp_mm, sites: SurfaceMap | None = None,
              rows_mm: float = 0.0) -> ProcessMap:
    """The map of a TCP track sampled at ``t_s`` over ``surface`` (on ``sites`` when given). ``rows_mm``: the
    rows' spacing, which the map is refined to resolve (``integrate.process_map``, ``mesh_map.mesh_process_map``)."""
    if getattr(surface, "model", None) in SET_MODELS:
        return _face_set_map(settings, surface, t_s, tcp_mm, rows_mm)
    if on_mesh(surface):
        return mesh_process_map(settings, surface, t_s, tcp_mm, sites if sites is not None
                                else surface_map(settings, surface), rows_mm)
    return process_map(settings, surface, t_s, tcp_mm, grid=sites, rows_mm=rows_mm)


def trajectory_surface_map(settings: ProcessSettings, surface, trajectory, robot, dt_s: float,
                           sites: SurfaceMap | None = None, rows_mm: float = 0.0) -> ProcessMap:
    """The map of a timed trajectory as the controller runs it (resampled at ``dt_s``) over ``surface``."""
    t_s, tcp = tcp_track(trajectory, robot, dt_s)
    return track_map(settings, surface, t_s, tcp, sites, rows_mm)
