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
from dataclasses import dataclass, replace

import numpy as np

from ..errors import BadInput
from ..part.freeform_grid import triangles
from ..path.toolpath import freeze_arrays
from ..settings import ProcessSettings
from .footprint import Footprint
from .grid import MAX_CELLS, capped
from .integrate import QUANTITY, Contacts, ProcessMap, across_rows_mm, contacts_from_tcp
from .surface_map import SurfaceMap

RIPPLE_SAMPLES = 48         # samples per period across the rows: the samples are exact sums along the path, so half the
                            # grid map's 96 (grid.RIPPLE_SAMPLES) already puts the share within 0.05 pp of 96's
                            # (benchmarks/process_mesh_map.py) at half the cost
CONTACT_SPACINGS = 2.0      # a contact per this many lattice spacings of travel: each is summed along its stretch of
                            # path exactly (``_pairs``), so merging costs nothing on a smooth path and saves pairs
MAX_PAIRS = 30_000_000       # (contact, sample) pairs of a refined map at most, ~0.1 us each (a 1.3 m panel: ~3 s)
PAIRS_PER_BLOCK = 2_000_000  # (contact, vertex) pairs per vectorised block at most (memory)
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
    sub: tuple[int, int] | None = None  # (m_x, m_y): a refinement of a lattice m_x x m_y coarser (``refined_mesh``)
    cell_area_mm2: np.ndarray | None = None  # each vertex's whole cell on the surface when area_mm2 is its material's

    layout = "mesh"

    def __post_init__(self):
        freeze_arrays(self)

    @property
    def shape(self) -> tuple[int]:
        return (len(self.vertices_mm),)

    def points_mm(self) -> np.ndarray:
        return self.vertices_mm

    def spread_area_mm2(self) -> np.ndarray:
        """(N,) each vertex's cell on the surface, material or not: what a contact's footprint is normalised over."""
        return self.area_mm2 if self.cell_area_mm2 is None else self.cell_area_mm2

    def as_lattice(self, a: np.ndarray) -> np.ndarray:
        """(ny, nx, ...) the vertices' array ``a`` row by row over the lattice."""
        a = np.asarray(a)
        return a.reshape(len(self.ys), len(self.xs), *a.shape[1:])

    def expand(self, mask: np.ndarray) -> np.ndarray:
        """A mask of the lattice this one refines (``refined_mesh``), repeated onto this lattice's sub-samples."""
        m_x, m_y = self.sub
        coarse = np.asarray(mask).reshape(len(self.ys) // m_y, len(self.xs) // m_x)
        return np.repeat(np.repeat(coarse, m_y, axis=0), m_x, axis=1).ravel()

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
    xs, ys, s = lattice_axes(surface, cell_mm, pad_mm)
    lattice, material = _chart_sites(surface, xs, ys)
    return MeshMap(surface, xs, ys, lattice.reshape(-1, 3), triangles(len(xs), len(ys)), material,
                   vertex_areas_mm2(lattice, s, s), float(cell_mm), float(s))


def _chart_sites(surface, xs: np.ndarray, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """((ny, nx, 3) points, (ny * nx,) material) of the free-form face ``surface`` over the chart lattice xs, ys."""
    g = surface.grid
    X, Y = np.meshgrid(xs, ys)
    H = g.interp(surface.height, X, Y)          # extrapolated linearly past the face's grid: the surface continued
    e1, e2, e3 = surface.frame[:, 0], surface.frame[:, 1], surface.frame[:, 2]
    lattice = surface.origin_mm + X[..., None] * e1 + Y[..., None] * e2 + H[..., None] * e3
    fi = np.rint((X - g.x0) / g.g).astype(np.int64)
    fj = np.rint((Y - g.y0) / g.g).astype(np.int64)
    inside = (fi >= 0) & (fi < g.nx) & (fj >= 0) & (fj < g.ny)
    material = np.zeros(X.shape, bool)
    material[inside] = surface.material[fj[inside], fi[inside]]
    return lattice, material.ravel()


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
    lattice, material = _parametric_sites(surface, us, vs)
    return MeshMap(surface, us, vs, lattice.reshape(-1, 3), triangles(len(us), len(vs)), material,
                   vertex_areas_mm2(lattice, du, dv), float(cell_mm), float(cell_mm), ("u [deg]", "v [mm]"),
                   (180.0 / math.pi, 1.0))


def _parametric_sites(surface, us: np.ndarray, vs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """((nv, nu, 3) points, (nv * nu,) material inside the boundary) of a cylinder over its (u, v) lattice."""
    U, V = np.meshgrid(us, vs)
    return surface.point_mm(U, V), surface.boundary.contains(np.column_stack([U.ravel(), V.ravel()]))


def refined_mesh(mesh: MeshMap, m_x: int, m_y: int) -> MeshMap:
    """``mesh``'s lattice with every vertex's cell split into ``m_x`` x ``m_y`` sub-samples at the sub-cells'
    centres (points, material and areas of their own; no triangles: the fine samples are for the figures)."""
    def split(axis: np.ndarray, m: int) -> np.ndarray:
        step = float(axis[1] - axis[0]) if len(axis) > 1 else 1.0
        return (axis[:, None] + ((np.arange(m) + 0.5) / m - 0.5)[None, :] * step).ravel()

    xs, ys = split(mesh.xs, m_x), split(mesh.ys, m_y)
    dx = float(mesh.xs[1] - mesh.xs[0]) / m_x if len(mesh.xs) > 1 else 1.0
    dy = float(mesh.ys[1] - mesh.ys[0]) / m_y if len(mesh.ys) > 1 else 1.0
    if mesh.surface.model == "freeform":
        lattice, _ = _chart_sites(mesh.surface, xs, ys)
        share = material_share(mesh.surface, xs, ys, dx, dy)
        material = share > 0.0
    else:
        lattice, material = _parametric_sites(mesh.surface, xs, ys)
        share = material.astype(float)
    area = vertex_areas_mm2(lattice, dx, dy)
    return MeshMap(mesh.surface, xs, ys, lattice.reshape(-1, 3), np.zeros((0, 3), np.int64), material,
                   area * share, mesh.cell_mm, mesh.spacing_mm, mesh.labels, mesh.draw_scale,
                   (int(m_x), int(m_y)), area)


def material_share(surface, xs: np.ndarray, ys: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """(ny * nx,) the share of each sample's chart cell (``dx`` x ``dy`` round xs, ys) that lies on the free-form
    face's material (its nodes' cells), exactly: the material's area over a rectangle is the bilinear interpolation
    of its summed-area table at the node cells' corners (piecewise constant cells). A sample's nearest node alone
    would move the material's edge by up to half a sample (1 mm on a 2 mm lattice across its rows)."""
    g = surface.grid
    table = np.zeros((g.ny + 1, g.nx + 1))
    table[1:, 1:] = np.cumsum(np.cumsum(surface.material.astype(float), axis=0), axis=1)

    def corner(t, start, n):   # fractional index of t among the cells' corners, clamped to the table
        return np.clip((t - start) / g.g + 0.5, 0.0, float(n))

    def area_below(cx, cy):    # material cells (count) in (-inf, x] x (-inf, y], cx (nx,), cy (ny,) corner indices
        i0 = np.minimum(np.floor(cx).astype(np.int64), g.nx - 1)
        j0 = np.minimum(np.floor(cy).astype(np.int64), g.ny - 1)
        fx, fy = (cx - i0)[None, :], (cy - j0)[:, None]
        t = table
        return ((1 - fy) * ((1 - fx) * t[j0][:, i0] + fx * t[j0][:, i0 + 1])
                + fy * ((1 - fx) * t[j0 + 1][:, i0] + fx * t[j0 + 1][:, i0 + 1]))

    x0, x1 = corner(xs - 0.5 * dx, g.x0, g.nx), corner(xs + 0.5 * dx, g.x0, g.nx)
    y0, y1 = corner(ys - 0.5 * dy, g.y0, g.ny), corner(ys + 0.5 * dy, g.y0, g.ny)
    cells = area_below(x1, y1) - area_below(x0, y1) - area_below(x1, y0) + area_below(x0, y0)
    return np.clip(cells * g.g * g.g / (dx * dy), 0.0, 1.0).ravel()


def lattice_pad_mm(settings: ProcessSettings) -> float:
    """The lattice's margin round the material: a contact within reach of the material has its whole footprint
    within two reaches of it."""
    return 2.0 * REACH * 0.5 * settings.diameter_mm + 2.0 * settings.grid_mm


def _stretches(c: Contacts) -> np.ndarray:
    """(n, 3) the straight stretch of path each contact stands for, centred on it: its travel along the direction
    from its previous to its next neighbour in its run (one-sided at a run's ends; none for a tool at rest)."""
    p, n = c.point_mm, len(c.point_mm)
    if n < 2:
        return np.zeros((n, 3))
    same = (c.run[1:] == c.run[:-1])[:, None]
    step = np.where(same, np.diff(p, axis=0), 0.0)
    d = np.vstack([step, np.zeros((1, 3))]) + np.vstack([np.zeros((1, 3)), step])
    length = np.linalg.norm(d, axis=1, keepdims=True)
    return np.where(length > 0, d / np.maximum(length, 1e-300), 0.0) * c.travel_mm[:, None]


def _pairs(tree, coords, fp: Footprint, points_mm, normals, stretch):
    """(contact, vertex, footprint shape) of the vertices within reach of each contact: the footprint's mean along
    the contact's ``stretch`` of path (``Footprint.segment_shape``), at the vertex's offsets in the contact's tangent
    plane (``coords``: the vertices' x, y, z as three contiguous arrays; gathering those is faster than (N, 3)
    rows). Summed along the stretch, not at its centre: points at 1 mm along the rows put a 0.1 % ripple on the
    map (a far row's chord is short), which moves the share within +-5 % by a percentage point."""
    from scipy.spatial import cKDTree

    half = 0.5 * float(np.max(np.linalg.norm(stretch, axis=1), initial=0.0))
    pairs = cKDTree(points_mm).sparse_distance_matrix(tree, REACH * fp.radius_mm + half, output_type="ndarray")
    ci, vj, chord = (np.ascontiguousarray(pairs[k]) for k in ("i", "j", "v"))
    tangent = stretch - np.einsum("ij,ij->i", stretch, normals)[:, None] * normals
    # d = vertex - contact: (d.n) and (d.tangent) from the contacts' own products (tangent . n = 0), |d| the chord
    dn = -np.einsum("ij,ij->i", points_mm, normals)[ci]
    dt = -np.einsum("ij,ij->i", points_mm, tangent)[ci]
    for k in range(3):
        v = coords[k][vj]
        dn += v * np.ascontiguousarray(normals[:, k])[ci]
        dt += v * np.ascontiguousarray(tangent[:, k])[ci]
    alpha = np.einsum("ij,ij->i", tangent, tangent)[ci]
    # the segment from contact - tangent / 2 to contact + tangent / 2; r(t)^2 from its start, t in [0, 1]
    beta = -dt - 0.5 * alpha
    gamma = np.maximum(chord * chord - dn * dn + dt + 0.25 * alpha, 0.0)
    return ci, vj, fp.segment_shape(alpha, beta, gamma)


def pairs_per_contact(mesh: MeshMap, radius_mm: float) -> float:
    """About how many vertices of ``mesh`` lie within reach of one contact: the reach's disc over a vertex's area."""
    reach_mm = REACH * radius_mm + 0.5 * CONTACT_SPACINGS * mesh.spacing_mm   # a contact's stretch reaches farther
    return math.pi * reach_mm ** 2 / max(float(np.median(mesh.spread_area_mm2())), 1e-12)


def mesh_values(settings: ProcessSettings, mesh: MeshMap, c: Contacts) -> np.ndarray:
    """(N,) per vertex: amount per unit area (um), or for inspect the count of runs that cover it (contacts in
    blocks of about ``PAIRS_PER_BLOCK`` (contact, vertex) pairs: the memory stays bounded on a fine lattice)."""
    from scipy.spatial import cKDTree

    fp = Footprint.from_settings(settings)
    tree = cKDTree(mesh.vertices_mm)
    coords = tuple(np.ascontiguousarray(mesh.vertices_mm[:, k]) for k in range(3))
    N = len(mesh.vertices_mm)
    acc, hits, spread, stretch = np.zeros(N), [], mesh.spread_area_mm2(), _stretches(c)
    chunk = int(min(CHUNK, max(1, PAIRS_PER_BLOCK // pairs_per_contact(mesh, fp.radius_mm))))
    for s in range(0, len(c.amount), chunk):
        e = slice(s, s + chunk)
        ci, vj, w = _pairs(tree, coords, fp, c.point_mm[e], c.normal[e], stretch[e])
        if settings.kind == "inspect":
            on = w > 0
            hits.append(np.unique(c.run[e][ci[on]].astype(np.int64) * N + vj[on]))
            continue
        per_contact = np.bincount(ci, weights=w * spread[vj], minlength=len(c.amount[e]))
        acc += np.bincount(vj, weights=w * (c.amount[e] / np.maximum(per_contact, 1e-300))[ci], minlength=N)
    if settings.kind == "inspect" and hits:
        acc = np.bincount(np.unique(np.concatenate(hits)) % N, minlength=N).astype(float)
    return acc


def _lattice_mm(mesh: MeshMap, c: Contacts) -> np.ndarray:
    """(N, 2) the contacts on the mesh's lattice, in mm along its axes (a free-form face's chart; a cylinder's
    (R u, v))."""
    surface = mesh.surface
    if surface.model == "freeform":
        return (c.point_mm - surface.origin_mm) @ surface.frame[:, :2]
    return c.uv * np.array([float(surface.radius_mm), 1.0])


def mesh_refinement(settings: ProcessSettings, mesh: MeshMap, c: Contacts, spacing_mm: float) -> tuple[int, int]:
    """(m_x, m_y) sub-samples per lattice cell so that neighbouring samples are at most ``spacing_mm`` apart across
    the contacts' travel (``integrate.across_rows_mm`` on the lattice), as far as ``MAX_PAIRS`` (contact, sample)
    pairs and ``grid.MAX_CELLS`` samples allow."""
    across = across_rows_mm(mesh.surface, replace(c, uv=_lattice_mm(mesh, c)))
    m = np.maximum(np.ceil(mesh.spacing_mm * np.abs(across) / spacing_mm - 1e-9), 1.0)
    pairs = len(c.amount) * pairs_per_contact(mesh, Footprint.from_settings(settings).radius_mm)
    m = np.array(capped(m, pairs, MAX_PAIRS), float)
    return capped(m, float(len(mesh.vertices_mm)), MAX_CELLS)


def _cell_average(fine: MeshMap, values: np.ndarray) -> np.ndarray:
    """(N,) the area-weighted average of each coarse vertex's m_x x m_y sub-samples (``refined_mesh``)."""
    m_x, m_y = fine.sub
    a, v = fine.as_lattice(fine.spread_area_mm2()), fine.as_lattice(values)
    ny, nx = a.shape[0] // m_y, a.shape[1] // m_x

    def block_sum(x):
        return x.reshape(ny, m_y, nx, m_x).sum(axis=(1, 3)).ravel()

    return block_sum(v * a) / block_sum(a)


def mesh_process_map(settings: ProcessSettings, surface, t_s, tcp_mm, mesh: MeshMap, rows_mm: float = 0.0,
                     refine: bool = True) -> ProcessMap:
    """The map of a TCP track (``integrate.tcp_track``) on the surface's own mesh ``mesh``.

    ``rows_mm``: the rows' spacing (0 = not a raster: the footprint's radius). Except for inspect, the map is
    summed on the lattice refined across the rows to ``RIPPLE_SAMPLES`` samples per period (``mesh_refinement``,
    ``refined_mesh``); ``values`` are the sub-samples' averages over each vertex's cell and ``fine`` the refined
    map the figures are taken on. ``refine = False``: the values at the vertices themselves."""
    c = contacts_from_tcp(settings, surface, t_s, tcp_mm, spacing_mm=CONTACT_SPACINGS * mesh.spacing_mm)
    quantity, units = QUANTITY[settings.kind]
    made = (settings.kind, quantity, units, "mesh-direct", float(c.dt_s.sum()), float(c.travel_mm.sum()),
            int(len(t_s)))
    if refine and settings.kind != "inspect" and len(c.amount) > 0:  # coverage counts have no ripple to resolve
        period = rows_mm if rows_mm > 0 else 0.5 * settings.diameter_mm
        m_x, m_y = mesh_refinement(settings, mesh, c, period / RIPPLE_SAMPLES)
        if (m_x, m_y) != (1, 1):
            fine_mesh = refined_mesh(mesh, m_x, m_y)
            fine = ProcessMap(fine_mesh, mesh_values(settings, fine_mesh, c), *made)
            return ProcessMap(mesh, _cell_average(fine_mesh, fine.values), *made, fine=fine)
    return ProcessMap(mesh, mesh_values(settings, mesh, c), *made)
