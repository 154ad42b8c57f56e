"""A CAD mesh face's normals at the tool's scale, from its own triangles averaged on the surface (issue #46).

``freeform_grid.normals_of`` averages the height field's normals with a Gaussian of the chart plane. Where the
face tilts by theta from that plane, the window reaches 1 / cos(theta) further along the surface across the
slope, and where the face turns sharply under it (a fillet, a ship's bilge) the chart's nodes sample the turn
unevenly (a node's cell holds g / cos(theta) of the surface). On the 1:300 ship's hull (a 5 mm bilge between a
bottom and a side 75-85 deg from the chart) the tool axes stood 13 deg (p95) off the part's normal averaged over
12.5 mm.

A CAD mesh is exact, so its normal at the tool's scale is what the issue names: the area-weighted mean of the
face's own triangle normals over the tool's footprint, the part within ``radius_mm`` (3-D) of the node's surface
point, each turned to the node's own side. The footprint is a disc, not a Gaussian of the same second moment
(sigma = radius / 2): where the normal turns unevenly under it (within a radius of the face's open edge, a
blade's leading edge) the two means differ by the moments the Gaussian's tail adds. On the BladeX blade (522
triangles, 5.6 mm facets) the face's triangles under a 3-D Gaussian of 6 mm stood 2.2 deg (p95, 6.5 max) off
the part's normal over 12.5 mm, 4.0 off the one over 15 mm; under the 12.5 mm disc 0.4 deg (1.2 max), and 2.4
at most off the mean over 10 or 15 mm (the reference's own spread there). The disc's rim is a linear ramp one
piece wide (a piece's weight does not jump as it crosses it). The triangles are cut to edges of at most
``PIECE_RADII`` radii (trimesh's subdivision: a CAD tessellation's long slivers would otherwise put their whole
area at their centroid). The sum is taken every ``LATTICE_RADII``-th of a radius and interpolated; far from the
triangles (the margin the leads run on) the chart's normal takes over smoothly (``PRIOR_SHARE``). scipy's
KD-tree finds the pieces near each node; the weighted sum itself is a few lines of NumPy (no library sums over
a mesh's area in a ball).
"""
from __future__ import annotations

import math

import numpy as np

PIECE_RADII = 0.25      # triangles are cut to edges of at most this x the footprint's radius (the disc's quadrature)
LATTICE_RADII = 6.0     # the sum is taken every radius / this along the grid (at least every node)
PRIOR_SHARE = 0.01      # the chart's normal weighs this share of a full disc (it takes over ~a radius past the mesh)
HIDDEN_MM = 0.05        # a piece this far below the top-most triangle over it is another layer (float32 rays)
STEEP_KEPT_DEG = 80.0   # ... but a piece this steep from the chart is kept (a hull's side rolling under its bilge)
CHUNK_NODES = 2000      # nodes whose windows are summed at a time (memory)


def mesh_pieces(mesh, edge_mm: float):
    """(centroids (k, 3), unit normals (k, 3), areas (k,)) of a ``ChartMesh``'s triangles cut to edges of at most
    ``edge_mm``: the pieces the chart sees (none under another layer of the part by more than
    ``HIDDEN_MM``: a closed part's far skin), degenerate ones dropped; each piece keeps its triangle's plane."""
    import trimesh

    V, F = mesh.vertices, mesh.faces
    if len(F):
        V, F = trimesh.remesh.subdivide_to_size(V, F, max_edge=edge_mm, max_iter=20)
    T = V[F]
    cross = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    two_area = np.linalg.norm(cross, axis=1)
    cen = T.mean(axis=1)
    top = mesh.heights(cen[:, 0], cen[:, 1])
    n = cross / np.maximum(two_area, 1e-300)[:, None]
    steep = np.abs(n[:, 2]) < math.cos(math.radians(STEEP_KEPT_DEG))  # a wall rolling past the chart's vertical
    ok = (two_area > 1e-12) & (steep | ~(top - cen[:, 2] > HIDDEN_MM))   # NaN (edge-on to the chart): kept
    return cen[ok], cross[ok] / two_area[ok, None], 0.5 * two_area[ok]


def mesh_normals(chart_normals: np.ndarray, height: np.ndarray, grid, frame: np.ndarray, mesh,
                 radius_mm: float) -> np.ndarray:
    """(ny, nx, 3) unit normals (world, towards the tool): the face's triangles (``mesh``: a ``ChartMesh``) averaged
    over the footprint, the disc within ``radius_mm`` (3-D) of each node's surface point (module doc), where the
    chart's window holds a node tilted from ``STEEP_FROM_DEG`` (fully from ``STEEP_FULL_DEG``); elsewhere the chart's
    own (``chart_normals``, which also give each node its side and hold where no triangle is near)."""
    from scipy.ndimage import binary_dilation, maximum_filter

    from .freeform_normals import STEEP_FROM_DEG, STEEP_FULL_DEG, _lattice_at

    if radius_mm <= 0 or not len(mesh.faces):
        return chart_normals
    g = grid.g
    piece_mm = PIECE_RADII * radius_mm
    reach = int(math.ceil((radius_mm + 0.5 * piece_mm) / g))
    tilt_deg = np.degrees(np.arccos(np.clip(chart_normals @ frame[:, 2], -1.0, 1.0)))
    near_tilt = maximum_filter(tilt_deg, size=2 * reach + 1, mode="nearest")
    blend = np.clip((near_tilt - STEEP_FROM_DEG) / (STEEP_FULL_DEG - STEEP_FROM_DEG), 0.0, 1.0)
    if not (blend > 0).any():
        return chart_normals
    step = max(1, int(radius_mm / (LATTICE_RADII * g)))
    cen, nrm, area = mesh_pieces(_near(mesh, grid, binary_dilation(blend > 0, iterations=reach + 2 * step)), piece_mm)
    own = chart_normals @ frame                                     # chart coordinates
    coarse = own[::step, ::step].copy()
    lattice = np.zeros(height.shape, bool)
    lattice[::step, ::step] = True
    js, is_ = np.nonzero(lattice & binary_dilation(blend > 0, iterations=2 * step))
    if len(cen):
        nodes = np.stack([grid.x0 + is_ * g, grid.y0 + js * g, height[js, is_]], axis=1)
        v = _disc_sums(nodes, own[js, is_], cen, nrm, area, radius_mm, piece_mm)
        v += PRIOR_SHARE * math.pi * radius_mm ** 2 * own[js, is_]
        coarse[js // step, is_ // step] = v / np.linalg.norm(v, axis=1, keepdims=True)
    jj, ii = np.nonzero(blend > 0)
    b = blend[jj, ii, None]
    mixed = (1 - b) * own[jj, ii] + b * _lattice_at(coarse, step, jj, ii)
    out = chart_normals.copy()
    out[jj, ii] = (mixed / np.linalg.norm(mixed, axis=1, keepdims=True)) @ frame.T
    return out


def _near(mesh, grid, region: np.ndarray):
    """The ``ChartMesh`` of the triangles with a vertex over the grid's nodes ``region`` (the rest are out of
    every window that is summed)."""
    from .freeform_exact import ChartMesh

    V = mesh.vertices
    i = np.clip(np.rint((V[:, 0] - grid.x0) / grid.g), 0, grid.nx - 1).astype(np.int64)
    j = np.clip(np.rint((V[:, 1] - grid.y0) / grid.g), 0, grid.ny - 1).astype(np.int64)
    keep = region[j, i][mesh.faces].any(axis=1)
    return ChartMesh(V, mesh.faces[keep])


def _disc_sums(nodes: np.ndarray, sides: np.ndarray, cen: np.ndarray, nrm: np.ndarray, area: np.ndarray,
               radius_mm: float, rim_mm: float) -> np.ndarray:
    """(len(nodes), 3): the sum over the pieces within ``radius_mm`` of each node of area x normal, each normal
    turned to the node's side (``sides``), the rim a linear ramp ``rim_mm`` wide centred on the radius;
    ``CHUNK_NODES`` nodes at a time (memory)."""
    from scipy.spatial import cKDTree

    radius = radius_mm + 0.5 * rim_mm
    pieces = cKDTree(cen)
    out = np.zeros((len(nodes), 3))
    for start in range(0, len(nodes), CHUNK_NODES):
        block = nodes[start:start + CHUNK_NODES]
        pairs = cKDTree(block).sparse_distance_matrix(pieces, radius, output_type="ndarray")
        if not len(pairs):
            continue
        q, p = pairs["i"].astype(np.int64), pairs["j"].astype(np.int64)
        n = nrm[p] * np.where((nrm[p] * sides[start + q]).sum(axis=1) < 0, -1.0, 1.0)[:, None]
        w = area[p] * np.clip((radius - pairs["v"]) / rim_mm, 0.0, 1.0)
        for a in range(3):
            out[start:start + len(block), a] = np.bincount(q, w * n[:, a], len(block))
    return out
