"""mesh_normals: a CAD mesh face's normals at the tool's scale, against a closed form on a generated bilge."""
import math

import numpy as np
import trimesh

from camtool.part.freeform import FOOTPRINT_RADIUS_MM, NORMAL_SMOOTHING_MM, freeform_surface
from camtool.part.workpiece import Workpiece
from camtool.settings import FitSettings

FIT = FitSettings(model="freeform", threshold_mm=1.0, iterations=100, min_inlier_ratio=0.5, seed=0,
                  boundary_cell_mm=5.0, close_gaps_mm=5.0, simplify_mm=0.5)
R_MM = 5.0            # the bilge's radius (the 1:300 ship's hull)
WALL_DEG = 85.0       # the wall leans this far from the bottom (the chart's plane leans 25 deg: the wall 60 deg)
FLAT_MM = 60.0        # the bottom's width beside the bilge
WALL_MM = 25.0        # the wall's
LENGTH_MM = 80.0      # along the bilge's axis (y)


def _profile(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x, z) points and unit normals of the bilge's cross-section at arc length ``s`` (mm): the bottom (z = 0, x <
    0), a circular arc of R_MM turning WALL_DEG, then the straight wall."""
    a = math.radians(WALL_DEG)
    arc = R_MM * a
    t = np.clip(s, 0.0, arc) / R_MM                                  # the normal's turn so far (rad)
    x = np.where(s < 0, s, R_MM * np.sin(t)) + np.where(s > arc, (s - arc) * math.cos(a), 0.0)
    z = np.where(s < 0, 0.0, R_MM * (1 - np.cos(t))) + np.where(s > arc, (s - arc) * math.sin(a), 0.0)
    n = np.stack([-np.sin(t), np.cos(t)], axis=-1)
    return np.stack([x, z], axis=-1), n


def _surface_points(s, y):
    xz, n = _profile(s)
    P = np.stack([xz[..., 0], y, xz[..., 1]], axis=-1)
    N = np.stack([n[..., 0], 0 * y, n[..., 1]], axis=-1)
    return P, N


def _bilge_mesh(ds_mm: float = 0.5) -> trimesh.Trimesh:
    arc = R_MM * math.radians(WALL_DEG)
    s = np.unique(np.concatenate([np.linspace(-FLAT_MM, 0, 31), np.arange(0, arc, ds_mm), [arc],
                                  np.linspace(arc, arc + WALL_MM, 11)]))
    y = np.linspace(0, LENGTH_MM, 41)
    S, Y = np.meshgrid(s, y, indexing="ij")
    P, _ = _surface_points(S, Y)
    ns, ny = S.shape
    i = (np.arange(ns - 1)[:, None] * ny + np.arange(ny - 1)[None, :]).ravel()
    F = np.vstack([np.stack([i, i + 1, i + ny], 1), np.stack([i + 1, i + ny + 1, i + ny], 1)])
    m = trimesh.Trimesh(P.reshape(-1, 3), F, process=True)
    if (m.face_normals @ [0, 0, 1]).mean() < 0:
        m.invert()
    return m


def _exact_mean(points: np.ndarray, sigma_mm: float, disc_mm: float | None = None) -> np.ndarray:
    """The exact surface's normal averaged round each point (mid-length), from its closed form sampled finely (0.1
    mm of arc, 0.25 mm along y, within 20 mm of mid-length: past the Gaussian's 3 sigma): weighted by the Gaussian of sigma_mm of the 3-D distance, or (disc_mm) uniformly over the
    surface within disc_mm in 3-D (the benchmark's reference)."""
    arc = R_MM * math.radians(WALL_DEG)
    s = np.arange(-FLAT_MM, arc + WALL_MM, 0.1)
    y = np.arange(0.5 * LENGTH_MM - 20.0, 0.5 * LENGTH_MM + 20.0, 0.25)
    S, Y = np.meshgrid(s, y, indexing="ij")
    Q, N = _surface_points(S, Y)
    Q, N = Q.reshape(-1, 3), N.reshape(-1, 3)                      # equal areas: the parametrisation is by length
    out = np.empty((len(points), 3))
    for k, p in enumerate(points):
        d2 = ((Q - p) ** 2).sum(axis=1)
        w = (d2 <= disc_mm ** 2).astype(float) if disc_mm else np.exp(-0.5 * d2 / sigma_mm ** 2)
        v = (w[:, None] * N).sum(axis=0)
        out[k] = v / np.linalg.norm(v)
    return out


def _angle_deg(a, b):
    """Unsigned angles (deg) between normal lines (the face is worked from the bilge's outside)."""
    return np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", a, b)), 0.0, 1.0)))


def test_a_bilges_normals_are_its_own_averaged_over_the_tools_footprint():
    """A 5 mm bilge between a bottom and a wall leaning 85 deg: the face's normals across it (mid-length, from 15
    mm before the bilge to 8 mm short of the wall's end) against the exact surface's normal averaged over the
    footprint, the disc within FOOTPRINT_RADIUS_MM in 3-D (the benchmark's reference): within 1.6 deg, 0.3 in the
    median (the chart's window: 8.3 off; a 3-D Gaussian of the same second moment, sigma NORMAL_SMOOTHING_MM, was
    within 0.6 deg of its own closed form and 4.5 off the disc's: the Gaussian's tail across the bend). The worst
    is the lattice's interpolation on the wall, 60 deg from the chart (a 2-node step there is 4 mm of wall)."""
    m = _bilge_mesh()
    wp = Workpiece(np.asarray(m.vertices), np.asarray(m.vertex_normals), np.asarray(m.faces), "bilge.stl", "mm",
                   (), np.asarray(m.vertices))
    surf = freeform_surface(wp, FIT)
    s = np.linspace(-15.0, R_MM * math.radians(WALL_DEG) + WALL_MM - 8.0, 31)
    P, _ = _surface_points(s, np.full_like(s, 0.5 * LENGTH_MM))
    uv = surf.uv_from_points(P)
    got = surf.normal_at(uv[:, 0], uv[:, 1])
    on = surf.point_mm(uv[:, 0], uv[:, 1])
    assert np.max(np.linalg.norm(on - P, axis=1)) < 0.05
    disc = _exact_mean(on, 0.0, disc_mm=FOOTPRINT_RADIUS_MM)
    assert np.max(_angle_deg(got, disc)) < 1.8, _angle_deg(got, disc)
    assert np.median(_angle_deg(got, disc)) < 0.3, _angle_deg(got, disc)
    assert np.max(_angle_deg(_exact_mean(on, NORMAL_SMOOTHING_MM), disc)) > 4.0   # the Gaussian's miss: a real one


def test_a_closed_slabs_far_skin_is_left_out_and_its_rim_kept():
    """A closed 100 x 60 x 4 mm slab seen from above: its top's pieces are taken, its bottom's (under the top by 4
    mm: another layer of the part) are not, its side walls' (steeper than STEEP_KEPT_DEG) are; the pieces' area is
    the top's and the walls' exactly, and no piece's edge is longer than asked (PIECE_RADII of the footprint)."""
    from camtool.part.freeform_exact import ChartMesh
    from camtool.part.mesh_normals import PIECE_RADII, mesh_pieces

    box = trimesh.creation.box(extents=(100.0, 60.0, 4.0))
    edge = PIECE_RADII * FOOTPRINT_RADIUS_MM
    cen, nrm, area = mesh_pieces(ChartMesh(np.asarray(box.vertices), np.asarray(box.faces)), edge)
    top, bottom = nrm[:, 2] > 0.99, nrm[:, 2] < -0.99
    walls = np.abs(nrm[:, 2]) < 0.01
    assert not bottom.any()
    assert math.isclose(area[top].sum(), 100.0 * 60.0, rel_tol=1e-9)
    assert math.isclose(area[walls].sum(), 2 * (100.0 + 60.0) * 4.0, rel_tol=1e-9)
    assert (top | walls).all()
    assert np.all(np.sqrt(2.0 * area) <= edge * 1.0001)      # a right triangle's legs bound its area


def test_a_coarse_cad_mesh_said_to_be_cad_takes_its_triangles_normals():
    """A steep egg-crate sheet (z = 30 sin(x / 15) cos(y / 22.5), slopes to 63 deg) tessellated at 5 mm: its
    vertices are rough (its facets' creases: the roughness verdict takes it for a scan, as the coarse BladeX blade).
    Said to be CAD (``workpiece.scan = "no"``), its normals are its triangles' over the footprint: within 1.2 deg
    (p95) of the exact surface's normal averaged over the FOOTPRINT_RADIUS_MM disc (its closed form sampled every
    0.2 mm), across the face to 3 mm from its edges; judged a scan, the height field's chart window: 3.4 deg."""
    from dataclasses import replace

    from camtool.part.roughness import mesh_is_scan

    amp, wave, h = 30.0, 15.0, 5.0
    f = lambda x, y: amp * np.sin(x / wave) * np.cos(y / (1.5 * wave))          # noqa: E731
    x, y = np.arange(0.0, 120.0 + 1e-9, h), np.arange(0.0, 90.0 + 1e-9, h)
    m = _grid(np.meshgrid(x, y, indexing="ij"), f)
    assert mesh_is_scan(m.vertices, "auto", m.faces)
    wp = Workpiece(np.asarray(m.vertices), np.asarray(m.vertex_normals), np.asarray(m.faces), "crate.stl", "mm",
                   (), np.asarray(m.vertices))
    X, Y = (a.ravel() for a in np.meshgrid(np.arange(0.0, 120.0, 0.2), np.arange(0.0, 90.0, 0.2), indexing="ij"))
    fx = amp / wave * np.cos(X / wave) * np.cos(Y / (1.5 * wave))
    fy = -amp / (1.5 * wave) * np.sin(X / wave) * np.sin(Y / (1.5 * wave))
    N = np.stack([-fx, -fy, np.ones_like(fx)], 1)       # the unit normal x its area per chart cell
    Q = np.stack([X, Y, f(X, Y)], 1)
    rng = np.random.default_rng(0)
    px, py = rng.uniform(3.0, 117.0, 80), rng.uniform(3.0, 87.0, 80)
    pts = np.stack([px, py, f(px, py)], 1)
    disc = np.array([N[((Q - p) ** 2).sum(axis=1) <= FOOTPRINT_RADIUS_MM ** 2].sum(axis=0) for p in pts])
    disc /= np.linalg.norm(disc, axis=1, keepdims=True)
    err = {}
    for scan in ("no", "auto"):
        surf = freeform_surface(replace(wp, scan=scan), FIT)
        uv = surf.uv_from_points(pts)
        err[scan] = np.percentile(_angle_deg(surf.normal_at(uv[:, 0], uv[:, 1]), disc), 95)
    assert err["no"] < 1.2, err
    assert err["auto"] > 2.5, err       # judged a scan: the chart's window (the test shows a real difference)


def _grid(XY, f) -> trimesh.Trimesh:
    """The triangulated grid (X, Y) of the height z = f(x, y)."""
    X, Y = XY
    P = np.stack([X, Y, f(X, Y)], -1).reshape(-1, 3)
    nx, ny = X.shape
    i = (np.arange(nx - 1)[:, None] * ny + np.arange(ny - 1)[None, :]).ravel()
    F = np.vstack([np.stack([i, i + ny, i + 1], 1), np.stack([i + 1, i + ny, i + ny + 1], 1)])
    return trimesh.Trimesh(P, F, process=True)
