"""The process map on a surface's own mesh (issue #46): a value per vertex, areas on the surface.

A free-form face (``camtool.part.freeform.FreeformSurface``) is a height field over its
chart plane, exact on a CAD mesh's triangles and the smoothed surface of a scan. Its
mesh for the map (``MeshMap``, ``mesh_map``) is that height field on a lattice of the chart plane:

- **vertices** ``spacing_mm`` apart on the chart: ``process.grid_mm`` times the cosine of the face's
  steep slopes (5th percentile, at least 0.5), so the vertices are about ``grid_mm`` apart on most of
  the surface; the lattice covers the face's material plus ``pad_mm`` (``lattice_pad_mm``: the whole
  footprint of every contact that reaches the material, on the surface continued), so no contact's
  normalisation is cut short by the lattice's edge;
- **triangles** two per lattice cell, their diagonals alternating (``freeform_grid.triangles``);
- **area_mm2**: each vertex's lattice cell on the surface, ``|dP/dx x dP/dy| dx dy`` (central differences):
  the area element of the surface, not of its projection (a third of each vertex's triangles would weight
  the chequerboard's vertices of eight triangles twice those of four);
- **material**: the vertices over the face's own nodes (holes and the margin are not worked).

A cylinder's (u, v) grid would need cells of ``grid_mm / R`` rad (the grid map's are mm), so it gets the
same kind of mesh (``parametric_mesh_map``): its (u, v) lattice ``grid_mm`` apart on the surface, the
points, areas and boundary the cylinder's own.

Each contact (``integrate.contacts_from_tcp``: the acting intervals of the TCP track) spreads
its amount over the vertices within ``REACH`` footprint radii of it (a scipy KD-tree): the
footprint at each vertex's distance in the contact's tangent plane (the tool complies with
the surface, as the grid map's direct sums), weighted by vertex area and normalised per contact
so each contact puts exactly its amount on the surface. For inspect a vertex counts the runs
whose footprint covers it. The figures are the grid map's (``figures.map_figures``), over the
material vertices weighted by their area; a vertex's distance from the edge is its 3-D
distance to the nearest vertex off the material.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import BadInput
from ..part.freeform_grid import triangles
from ..path.toolpath import freeze_arrays
from ..settings import ProcessSettings
from .footprint import Footprint
from .grid import MAX_CELLS
from .integrate import QUANTITY, Contacts, ProcessMap, contacts_from_tcp
from .surface_map import SurfaceMap

REACH = 1.25          # vertices within this many footprint radii (3-D) of a contact are candidates: a point of
                      # the tangent disc lies a little farther in 3-D on a curved surface (R >= 1.6 radii)
CHUNK = 2000          # contacts per vectorised block
MIN_SLOPE_COS = 0.5   # the chart spacing is at most halved for a steep face


@dataclass(frozen=True)
class MeshMap(SurfaceMap):
    """A surface's own mesh for the map: ``vertices_mm`` (N, 3) row-major over the lattice ``xs`` (nx,), ``ys``
    (ny,) (a free-form face's chart mm; a cylinder's (u rad, v mm)); ``faces`` (M, 3); ``material`` and
    ``area_mm2`` (N,)."""

    surface: object
    xs: np.ndarray
    ys: np.ndarray
    vertices_mm: np.ndarray
    faces: np.ndarray
    material: np.ndarray
    area_mm2: np.ndarray
    cell_mm: float
    spacing_mm: float
    labels: tuple[str, str] = ("chart x [mm]", "chart y [mm]")   # the lattice's axes as the PNG draws them
    draw_scale: tuple[float, float] = (1.0, 1.0)                 # lattice units -> drawn units

    layout = "mesh"

    def __post_init__(self):
        freeze_arrays(self)

    @property
    def shape(self) -> tuple[int]:
        return (len(self.vertices_mm),)

    def points_mm(self) -> np.ndarray:
        return self.vertices_mm

    def edge_distance_mm(self) -> np.ndarray:
        """(N,) 3-D distance of each vertex from the nearest vertex off the material (0 off the material)."""
        from scipy.spatial import cKDTree

        out = np.zeros(self.shape)
        off = ~self.material
        if off.any() and self.material.any():
            out[self.material] = cKDTree(self.vertices_mm[off]).query(self.vertices_mm[self.material])[0]
        return out

    def npz_arrays(self) -> dict:
        """vertices_mm, faces (int32), material, area_mm2, the lattice (lattice_x, lattice_y), cell_mm, layout."""
        return {"vertices_mm": self.vertices_mm, "faces": self.faces.astype(np.int32), "material": self.material,
                "area_mm2": self.area_mm2, "lattice_x": self.xs, "lattice_y": self.ys, "uv_unit": self.uv_unit(),
                "cell_mm": self.cell_mm, "surface_model": self.surface.model, "layout": self.layout}

    def draw(self, ax, values: np.ndarray):
        """A heat map over the lattice (a free-form face's chart plane, mm; a cylinder's (u, v), deg and mm)."""
        shown = np.ma.masked_where(~self.material, values).reshape(len(self.ys), len(self.xs))
        mesh = ax.pcolormesh(self.xs * self.draw_scale[0], self.ys * self.draw_scale[1], shown, shading="nearest",
                             cmap="viridis")
        ax.set_xlabel(self.labels[0])
        ax.set_ylabel(self.labels[1])
        ax.set_aspect("equal" if self.draw_scale == (1.0, 1.0) else "auto")
        return mesh


def vertex_areas_mm2(lattice_mm: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """(ny * nx,) the area on the surface of each vertex's lattice cell: ``|dP/dx x dP/dy| dx dy`` from the
    lattice's (ny, nx, 3) points by central differences (one-sided at its edge)."""
    px = np.gradient(lattice_mm, dx, axis=1)
    py = np.gradient(lattice_mm, dy, axis=0)
    return (np.linalg.norm(np.cross(px, py), axis=-1) * dx * dy).ravel()


def _chart_spacing_mm(surface, cell_mm: float) -> float:
    """``cell_mm`` times the cosine of the face's steep slopes (5th percentile, at least ``MIN_SLOPE_COS``)."""
    cos = np.abs(surface.normals[surface.material] @ surface.frame[:, 2])
    steep = float(np.percentile(cos, 5)) if len(cos) else 1.0
    return cell_mm * min(1.0, max(steep, MIN_SLOPE_COS))


def lattice_axes(surface, cell_mm: float, pad_mm: float) -> tuple[np.ndarray, np.ndarray, float]:
    """(xs, ys, spacing_mm): the chart lattice of the free-form face ``surface`` for a map at ``cell_mm``, counted
    before anything is allocated: BadInput past ``grid.MAX_CELLS`` vertices (checked before any planning)."""
    g = surface.grid
    s = _chart_spacing_mm(surface, cell_mm)
    xy = g.node_xy()[surface.material]
    lo, hi = xy.min(axis=0) - pad_mm, xy.max(axis=0) + pad_mm
    n = np.ceil((hi - lo) / s).astype(int) + 1
    if float(n[0]) * float(n[1]) > MAX_CELLS:
        raise BadInput(f"process.grid_mm = {cell_mm:g}: the process map would have {float(n[0]) * float(n[1]):.3g} "
                       f"vertices (limit {MAX_CELLS:.0e}); use a coarser process.grid_mm")
    centre = 0.5 * (lo + hi)
    xs = centre[0] + (np.arange(n[0]) - 0.5 * (n[0] - 1)) * s
    ys = centre[1] + (np.arange(n[1]) - 0.5 * (n[1] - 1)) * s
    return xs, ys, s


def mesh_map(surface, cell_mm: float, pad_mm: float) -> MeshMap:
    """The mesh of the free-form face ``surface`` for a map at ``cell_mm`` (see the module doc); BadInput when it
    would have more than ``grid.MAX_CELLS`` vertices."""
    g = surface.grid
    xs, ys, s = lattice_axes(surface, cell_mm, pad_mm)
    X, Y = np.meshgrid(xs, ys)
    H = g.interp(surface.height, X, Y)          # extrapolated linearly past the face's grid: the surface continued
    e1, e2, e3 = surface.frame[:, 0], surface.frame[:, 1], surface.frame[:, 2]
    lattice = surface.origin_mm + X[..., None] * e1 + Y[..., None] * e2 + H[..., None] * e3
    fi = np.rint((X - g.x0) / g.g).astype(np.int64)
    fj = np.rint((Y - g.y0) / g.g).astype(np.int64)
    inside = (fi >= 0) & (fi < g.nx) & (fj >= 0) & (fj < g.ny)
    material = np.zeros(X.shape, bool)
    material[inside] = surface.material[fj[inside], fi[inside]]
    return MeshMap(surface, xs, ys, lattice.reshape(-1, 3), triangles(len(xs), len(ys)), material.ravel(),
                   vertex_areas_mm2(lattice, s, s), float(cell_mm), float(s))


def parametric_axes(surface, cell_mm: float, pad_mm: float) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(us, vs, du, dv): the (u, v) lattice of a cylinder (u the angle about its axis, rad; v along it, mm) for a map
    at ``cell_mm``, ``cell_mm`` apart on the surface and padded by ``pad_mm``, never round the axis onto itself;
    BadInput past ``grid.MAX_CELLS`` vertices (checked before any planning)."""
    R = float(surface.radius_mm)
    lo, hi = surface.boundary.bounds()
    du, dv = cell_mm / R, float(cell_mm)
    span_u = min(hi[0] - lo[0] + 2 * pad_mm / R, 2 * math.pi - du)
    n = np.ceil(np.array([span_u / du, (hi[1] - lo[1] + 2 * pad_mm) / dv])).astype(int) + 1
    if float(n[0]) * float(n[1]) > MAX_CELLS:
        raise BadInput(f"process.grid_mm = {cell_mm:g}: the process map would have {float(n[0]) * float(n[1]):.3g} "
                       f"vertices (limit {MAX_CELLS:.0e}); use a coarser process.grid_mm")
    us = 0.5 * (lo[0] + hi[0]) + (np.arange(n[0]) - 0.5 * (n[0] - 1)) * du
    vs = 0.5 * (lo[1] + hi[1]) + (np.arange(n[1]) - 0.5 * (n[1] - 1)) * dv
    return us, vs, du, dv


def parametric_mesh_map(surface, cell_mm: float, pad_mm: float) -> MeshMap:
    """The mesh of a cylinder for a map at ``cell_mm``: its (u, v) lattice (``parametric_axes``), the points and
    areas (``|P_u x P_v| du dv``) from the surface itself, material inside its boundary."""
    us, vs, du, dv = parametric_axes(surface, cell_mm, pad_mm)
    U, V = np.meshgrid(us, vs)
    lattice = surface.point_mm(U, V)
    material = surface.boundary.contains(np.column_stack([U.ravel(), V.ravel()]))
    return MeshMap(surface, us, vs, lattice.reshape(-1, 3), triangles(len(us), len(vs)), material,
                   vertex_areas_mm2(lattice, du, dv), float(cell_mm), float(cell_mm), ("u [deg]", "v [mm]"),
                   (180.0 / math.pi, 1.0))


def lattice_pad_mm(settings: ProcessSettings) -> float:
    """The lattice's margin round the material: a contact within reach of the material has its whole footprint
    within two reaches of it."""
    return 2.0 * REACH * 0.5 * settings.diameter_mm + 2.0 * settings.grid_mm


def _pairs(tree, coords, fp: Footprint, points_mm, normals):
    """(contact, vertex, footprint shape) of the vertices within reach of each contact: the footprint at the
    vertex's distance in the contact's tangent plane, ``sqrt(chord^2 - (chord . n)^2)`` (``coords``: the
    vertices' x, y, z as three contiguous arrays; gathering those is faster than (N, 3) rows)."""
    from scipy.spatial import cKDTree

    pairs = cKDTree(points_mm).sparse_distance_matrix(tree, REACH * fp.radius_mm, output_type="ndarray")
    ci, vj, chord = (np.ascontiguousarray(pairs[k]) for k in ("i", "j", "v"))
    along = -np.einsum("ij,ij->i", points_mm, normals)[ci]            # (vertex - contact) . n
    for k in range(3):
        along += coords[k][vj] * np.ascontiguousarray(normals[:, k])[ci]
    return ci, vj, fp.shape(np.sqrt(np.maximum(chord * chord - along * along, 0.0)))


def mesh_values(settings: ProcessSettings, mesh: MeshMap, c: Contacts) -> np.ndarray:
    """(N,) per vertex: amount per unit area (um), or for inspect the count of runs that cover it."""
    from scipy.spatial import cKDTree

    fp = Footprint.from_settings(settings)
    tree = cKDTree(mesh.vertices_mm)
    coords = tuple(np.ascontiguousarray(mesh.vertices_mm[:, k]) for k in range(3))
    N = len(mesh.vertices_mm)
    acc, hits = np.zeros(N), []
    for s in range(0, len(c.amount), CHUNK):
        e = slice(s, s + CHUNK)
        ci, vj, w = _pairs(tree, coords, fp, c.point_mm[e], c.normal[e])
        if settings.kind == "inspect":
            on = w > 0
            hits.append(np.unique(c.run[e][ci[on]].astype(np.int64) * N + vj[on]))
            continue
        per_contact = np.bincount(ci, weights=w * mesh.area_mm2[vj], minlength=len(c.amount[e]))
        w = w / np.maximum(per_contact[ci], 1e-300) * c.amount[e][ci]
        acc += np.bincount(vj, weights=w, minlength=N)
    if settings.kind == "inspect" and hits:
        acc = np.bincount(np.unique(np.concatenate(hits)) % N, minlength=N).astype(float)
    return acc


def mesh_process_map(settings: ProcessSettings, surface, t_s, tcp_mm, mesh: MeshMap) -> ProcessMap:
    """The map of a TCP track (``integrate.tcp_track``) on the surface's own mesh ``mesh``."""
    c = contacts_from_tcp(settings, surface, t_s, tcp_mm, spacing_mm=0.5 * mesh.spacing_mm)
    quantity, units = QUANTITY[settings.kind]
    return ProcessMap(mesh, mesh_values(settings, mesh, c), settings.kind, quantity, units, "mesh-direct",
                      float(c.dt_s.sum()), float(c.travel_mm.sum()), int(len(t_s)))
