"""A CAD mesh face's exact heights (camtool/part/freeform_exact.py): against closed-form planes and the mesh itself."""
import json
import pickle
from dataclasses import replace

import numpy as np
import pytest
import trimesh

from camtool.part.fit import fit_surface
from camtool.part.freeform_exact import ChartMesh
from camtool.part.surface import surface_from_dict
from camtool.part.workpiece import Workpiece
from camtool.settings import FitSettings

R_MM = 10.0          # the fillet's radius (a door's window frame bends at 8-25 mm)
BEND_DEG = 60.0      # the sheet turns down by this much round it


def test_heights_are_the_triangles_planes_and_the_top_one_wins():
    """Two stacked triangles over the unit square's corner: the upper one's plane, by its closed form; none: NaN."""
    V = np.array([[0, 0, 1.0], [10, 0, 3.0], [0, 10, 2.0], [0, 0, -5.0], [10, 0, -5.0], [0, 10, -5.0]])
    m = ChartMesh(V, np.array([[0, 1, 2], [3, 4, 5]]))
    x, y = np.array([1.0, 2.5, 4.0, 9.0]), np.array([1.0, 3.0, 0.5, 9.0])
    h = m.heights(x, y)
    assert np.allclose(h[:3], 1.0 + 0.2 * x[:3] + 0.1 * y[:3], atol=1e-12)   # z = 1 + x/5 + y/10
    assert np.isnan(h[3])                                                   # outside both


def bent_sheet(step_deg=3.0, width_mm=60.0):
    """A sheet flat for x in [-60, 0], bent down round a R_MM fillet by BEND_DEG, then straight on for 40 mm."""
    t = np.radians(np.arange(0.0, BEND_DEG + 1e-9, step_deg))
    arc = np.c_[R_MM * np.sin(t), R_MM * (np.cos(t) - 1.0)]
    end = arc[-1] + 40.0 * np.array([np.cos(t[-1]), -np.sin(t[-1])])
    xz = np.r_[[[-60.0, 0.0], [-30.0, 0.0]], arc, [0.5 * (arc[-1] + end)], [end]]
    ys = np.linspace(-width_mm / 2, width_mm / 2, 13)
    V = np.array([[x, y, z] for y in ys for x, z in xz])
    n = len(xz)
    F = []
    for j in range(len(ys) - 1):
        for i in range(n - 1):
            a, b, c, d = j * n + i, j * n + i + 1, (j + 1) * n + i, (j + 1) * n + i + 1
            F += [[a, b, d], [a, d, c]]
    return V, np.array(F)


@pytest.fixture(scope="module")
def fillet():
    V, F = bent_sheet()
    mesh = trimesh.Trimesh(V, F, process=False)
    pts, fi = trimesh.sample.sample_surface(mesh, 20000, seed=0)
    wp = Workpiece(np.asarray(pts), np.asarray(mesh.face_normals)[fi], F, "fillet.stl", "mm", (), V)
    return mesh, fit_surface(wp, FitSettings.make(model="freeform"))


def _off_mesh_mm(mesh, P):
    return trimesh.proximity.closest_point(mesh, P)[1]


def test_points_round_the_fillet_lie_on_the_mesh(fillet):
    """The face's points over the bend are on its facets; the height field's bilinear ones are not (the cause of
    the door's 1.7 mm): the test fails without the exact heights (with the mesh dropped, ``mesh=None``)."""
    mesh, s = fillet
    assert s.mesh is not None
    lo, hi = s.boundary.bounds()
    g = np.stack(np.meshgrid(np.linspace(lo[0], hi[0], 90), np.linspace(lo[1], hi[1], 9)), -1).reshape(-1, 2)
    uv = g[s.boundary.contains(g)]
    exact = _off_mesh_mm(mesh, s.point_mm(uv[:, 0], uv[:, 1]))
    grid_only = replace(s, mesh=None)
    bilinear = _off_mesh_mm(mesh, grid_only.point_mm(uv[:, 0], uv[:, 1]))
    assert exact.max() < 1e-6
    assert bilinear.max() > 0.01        # on this 1 mm grid; it grows with the grid squared (the door's: 2.6 mm)


def test_projection_onto_the_fillet_lies_on_the_mesh(fillet):
    """project_mm (the sag's midposes): chord midpoints across the bend come onto the facets."""
    mesh, s = fillet
    P, _, _ = trimesh.proximity.closest_point(mesh, np.c_[np.linspace(-5, 14, 40), np.zeros(40), np.zeros(40)])
    mid = 0.5 * (P[:-1] + P[1:])        # chords between neighbouring surface points, under the convex bend
    assert _off_mesh_mm(mesh, s.project_mm(mid)).max() < 1e-6


def test_the_mesh_survives_the_stage_file_and_pickling(fillet):
    _, s = fillet
    back = surface_from_dict(json.loads(json.dumps(s.to_dict())))
    again = pickle.loads(pickle.dumps(s))
    u, v = np.linspace(-40, 10, 30), np.zeros(30)
    assert np.array_equal(back.point_mm(u, v), s.point_mm(u, v))
    assert np.array_equal(again.point_mm(u, v), s.point_mm(u, v))


def test_turned_rows_keep_the_exact_heights(fillet):
    mesh, s = fillet
    t = s.rows_at(np.radians(30.0))
    lo, hi = t.boundary.bounds()
    g = np.stack(np.meshgrid(np.linspace(lo[0], hi[0], 40), np.linspace(lo[1], hi[1], 9)), -1).reshape(-1, 2)
    uv = g[t.boundary.contains(g)]
    assert _off_mesh_mm(mesh, t.point_mm(uv[:, 0], uv[:, 1])).max() < 1e-6


# --------------------------------------------------------------------------- a face's gaps (another face's slivers)

GAP_R_MM = 20.0     # a tight cylindrical bend: a membrane over a 4 mm gap sags w^2 / (8 R) = 0.1 mm off it


def cylinder_sheet(dx_mm=1.0, dy_mm=2.0, z_mm=0.0):
    """z = sqrt(R^2 - x^2) - R + z_mm for |x| <= 14, |y| <= 30: (vertices, faces, each triangle's (x index, y))."""
    xs, ys = np.arange(-14.0, 14.0 + 1e-9, dx_mm), np.arange(-30.0, 30.0 + 1e-9, dy_mm)
    V = np.array([[x, y, np.sqrt(GAP_R_MM ** 2 - x ** 2) - GAP_R_MM + z_mm] for y in ys for x in xs])
    n = len(xs)
    F, col = [], []
    for j in range(len(ys) - 1):
        for i in range(n - 1):
            a, b, c, d = j * n + i, j * n + i + 1, (j + 1) * n + i, (j + 1) * n + i + 1
            F += [[a, b, d], [a, d, c]]
            col += [(i, ys[j]), (i, ys[j])]
    return V, np.array(F), np.array(col)


@pytest.fixture(scope="module")
def gapped():
    """The sheet's face without two strips 4 mm x 40 mm inside it (their triangles another face's, as round the
    door's bends), and under it a second skin 8 mm down (a closed part's other side): the whole part is both."""
    V, F, col = cylinder_sheet()
    V2, F2, _ = cylinder_sheet(z_mm=-8.0)
    whole_V, whole_F = np.r_[V, V2], np.r_[F, F2 + len(V)]
    i, y = col[:, 0], col[:, 1]
    gap = (((i >= 3) & (i < 7)) | ((i >= 18) & (i < 22))) & (np.abs(y + 1.0) < 20.0)
    own = F[~gap]
    part = trimesh.Trimesh(whole_V, whole_F, process=False)
    top = trimesh.Trimesh(V, F, process=False)
    pts, fi = trimesh.sample.sample_surface(trimesh.Trimesh(V, own, process=False), 20000, seed=0)
    normals = np.asarray(top.face_normals)[np.flatnonzero(~gap)][fi]
    face = Workpiece(np.asarray(pts), normals, own, "face.stl", "mm", (), whole_V)
    whole = Workpiece(np.asarray(part.vertices), np.asarray(part.face_normals), whole_F, "part.stl", "mm", (), whole_V)
    from camtool.part.freeform import freeform_surface
    return top, freeform_surface(face, FitSettings.make(model="freeform"), part=whole)


def _over_the_gaps(s):
    """World points 30 mm above the face over its two gap strips (a 7 x 9 grid on each)."""
    x = np.r_[np.linspace(-10.5, -7.5, 7), np.linspace(4.5, 7.5, 7)]
    XY = np.stack(np.meshgrid(x, np.linspace(-16, 16, 9)), -1).reshape(-1, 2)
    return np.c_[XY, np.full(len(XY), 30.0)]


def test_points_in_a_face_gap_lie_on_the_part(gapped):
    """Over the strips the face lacks, its points are on the part's own (the neighbouring face's) triangles, not on
    the height field's membrane (0.1 mm under the bend) and not on the other skin 8 mm down: the test fails
    without the gap triangles (``gaps=None``)."""
    top, s = gapped
    assert s.gaps is not None and s.mesh is not None
    P = _over_the_gaps(s)
    assert _off_mesh_mm(top, s.project_mm(P)).max() < 1e-6
    no_gaps = replace(s, gaps=None)
    assert np.isnan(no_gaps.project_mm(P)[:, 2]).mean() > 0.8          # no triangle of its own there
    c = (P - s.origin_mm) @ s.frame
    membrane = s.origin_mm + np.c_[c[:, :2], no_gaps.height_at(c[:, 0], c[:, 1])] @ s.frame.T
    assert _off_mesh_mm(top, membrane).max() > 0.03


def test_the_gap_triangles_survive_the_stage_file_and_turned_rows(gapped):
    top, s = gapped
    back = surface_from_dict(json.loads(json.dumps(s.to_dict())))
    assert back.gaps is not None and np.array_equal(back.gaps.faces, s.gaps.faces)
    P = _over_the_gaps(s)
    assert np.array_equal(back.project_mm(P), s.project_mm(P))
    assert _off_mesh_mm(top, s.rows_at(np.radians(30.0)).project_mm(P)).max() < 1e-6


def test_projection_past_the_face_edge_is_nan_and_the_points_keep_the_continued_surface(gapped):
    """The sag's projector (``project_mm``) finds no face past its edge (NaN), where ``point_mm`` (the leads) runs on
    the height field continued; over the face and its gaps it is the part's triangles."""
    top, s = gapped
    P = np.array([[18.0, 0.0, 30.0], [-18.0, 5.0, 30.0], [0.0, 0.0, 30.0]])
    on = s.project_mm(P)
    assert np.isnan(on[:2]).all() and np.isfinite(on[2]).all()
    assert _off_mesh_mm(top, on[2:]).max() < 1e-6
    c = (P - s.origin_mm) @ s.frame
    assert np.isfinite(s.height_at(c[:, 0], c[:, 1])).all()


def test_a_point_is_taken_onto_the_triangles_along_its_own_line_either_way():
    """``ChartMesh.along``: a plane tilted 74 deg from the chart plane (the hull's bottom against its face's chart),
    points on either side of it taken along their lines onto it, in float64 (closed form: the line-plane
    intersection); a line that meets no triangle gives NaN."""
    from camtool.part.freeform_exact import ChartMesh

    t = np.radians(74.0)
    n = np.array([np.sin(t), 0.0, np.cos(t)])                    # the plane's normal, 74 deg from the chart's z
    e1, e2 = np.array([np.cos(t), 0.0, -np.sin(t)]), np.array([0.0, 1.0, 0.0])
    s = np.linspace(-20.0, 20.0, 11)
    S, T = np.meshgrid(s, s)
    V = (S.ravel()[:, None] * e1 + T.ravel()[:, None] * e2)
    idx = np.arange(121).reshape(11, 11)
    F = np.concatenate([np.stack([idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel()], 1),
                        np.stack([idx[:-1, :-1].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()], 1)])
    mesh = ChartMesh.of(V, F)
    rng = np.random.default_rng(3)
    P = rng.uniform(-8, 8, (50, 3))
    D = n + rng.normal(0, 0.3, (50, 3))
    D /= np.linalg.norm(D, axis=1)[:, None]
    on = mesh.along(P, D)
    lam = -(P @ n) / (D @ n)
    np.testing.assert_allclose(on, P + lam[:, None] * D, atol=1e-9)
    assert np.isnan(mesh.along(np.array([[0.0, 0.0, 0.0]]) + 100 * e2, e2[None])).all()   # along the plane, off it


def test_points_past_the_triangles_outline_go_onto_the_face(fillet):
    """``onto_face_mm``: a point of the height field continued just past the face's outline (the raster's grid
    boundary passes a fraction of a mm past it where the face turns steep: the IEA 15 MW blade's leading edge) is
    taken to the nearest point of the face's own triangles; points over them stay where they are, to the bit."""
    mesh, surface = fillet
    over = surface.origin_mm + np.array([[5.0, 3.0, 0.0], [-20.0, -4.0, 0.0]]) @ surface.frame.T
    on = surface.project_mm(over)
    assert np.array_equal(surface.onto_face_mm(on), on)
    c = (on - surface.origin_mm) @ surface.frame
    past = c.copy()
    half_width = np.abs((mesh.vertices - surface.origin_mm) @ surface.frame[:, 1]).max()
    past[:, 1] = np.where(c[:, 1] > 0, 1, -1) * (half_width + 0.3)
    past[:, 2] = surface.grid.interp(surface.height, past[:, 0], past[:, 1])
    P = surface.origin_mm + past @ surface.frame.T
    assert np.isnan(surface.triangle_heights(past[:, 0], past[:, 1])).all()
    moved = surface.onto_face_mm(P)
    assert _off_mesh_mm(mesh, moved).max() < 1e-6
    assert np.allclose(np.linalg.norm(moved - P, axis=1), _off_mesh_mm(mesh, P), atol=1e-6)   # the nearest point
