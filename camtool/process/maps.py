"""Which map a surface gets, and the map of a TCP track or of a timed trajectory on it.

An analytic surface (plane, sphere patch, cylinder) gets the (u, v) grid (``grid``,
``integrate``); a free-form face gets its own mesh (``mesh_map``). Both are a
``surface_map.SurfaceMap``, and the maps made here are ``integrate.ProcessMap``\\ s
the figures, files and report take alike. This is the one place that chooses.
"""
from __future__ import annotations

from ..settings import ProcessSettings
from .integrate import ProcessMap, process_map, tcp_track
from .mesh_map import lattice_pad_mm, mesh_map, mesh_process_map
from .surface_map import SurfaceMap

MESH_MODELS = frozenset({"freeform"})   # surfaces whose map lies on their own mesh


def on_mesh(surface) -> bool:
    """True when ``surface``'s map lies on its own mesh (a free-form face)."""
    return getattr(surface, "model", None) in MESH_MODELS


def surface_map(settings: ProcessSettings, surface) -> SurfaceMap:
    """The sites of ``surface``'s map at ``process.grid_mm``, padded by the footprint (as the maps make them)."""
    from .grid import map_grid

    if on_mesh(surface):
        return mesh_map(surface, settings.grid_mm, lattice_pad_mm(settings))
    return map_grid(surface, settings.grid_mm, 0.5 * settings.diameter_mm + 2 * settings.grid_mm)


def track_map(settings: ProcessSettings, surface, t_s, tcp_mm, sites: SurfaceMap | None = None) -> ProcessMap:
    """The map of a TCP track sampled at ``t_s`` over ``surface`` (on ``sites`` when given)."""
    if on_mesh(surface):
        return mesh_process_map(settings, surface, t_s, tcp_mm, mesh=sites)
    return process_map(settings, surface, t_s, tcp_mm, grid=sites)


def trajectory_surface_map(settings: ProcessSettings, surface, trajectory, robot, dt_s: float,
                           sites: SurfaceMap | None = None) -> ProcessMap:
    """The map of a timed trajectory as the controller runs it (resampled at ``dt_s``) over ``surface``."""
    t_s, tcp = tcp_track(trajectory, robot, dt_s)
    return track_map(settings, surface, t_s, tcp, sites)
