"""benchmarks/freeform_metrics.py (issue #46's acceptance figures and the noether baseline) against
closed forms: a flat raster of known spacing, a cylinder where the step on the surface is an arc
and not a chord, a plane tilted 60 deg from noether's slicing planes (the step doubles), a sphere
whose normal is radial."""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import freeform_metrics as fm  # noqa: E402


def _plane(size=200.0, n=41, jitter=0.0, seed=0):
    m = fm.grid_mesh(lambda x, y: np.stack([x, y, np.zeros_like(x)], -1),
                     np.linspace(0, size, n), np.linspace(0, size, n))
    if jitter:   # an irregular triangulation of the same plane
        rng = np.random.default_rng(seed)
        v = m.vertices.copy()
        inner = (v[:, 0] > 0) & (v[:, 0] < size) & (v[:, 1] > 0) & (v[:, 1] < size)
        v[inner, :2] += rng.uniform(-jitter, jitter, (inner.sum(), 2))
        m = fm.trimesh.Trimesh(v, m.faces, process=False)
    return m


def _rows_y(ys, x0=0.0, x1=200.0, pitch=2.0):
    x = np.arange(x0, x1 + 1e-9, pitch)
    return [np.stack([x, np.full_like(x, y), np.zeros_like(x)], 1) for y in ys]


@pytest.mark.parametrize("jitter", [0.0, 1.0])
def test_row_steps_on_a_plane_are_the_spacing(jitter):
    mesh = _plane(jitter=jitter)
    rows = _rows_y([20.0, 30.0, 40.0, 50.0], 20.0, 180.0)
    s = fm.row_steps(fm.SurfaceGeodesic(mesh), rows, 10.0)
    assert len(s) == sum(len(r) for r in rows) - 2 * len(rows)   # every pose but the rows' ends
    # paths on the surface: never shorter than the geodesic, at most 1 % longer
    assert np.percentile(s, 5) > 9.99 and np.percentile(s, 95) < 10.1


def test_row_steps_on_a_cylinder_are_arcs_not_chords():
    R = 30.0
    cyl = fm.grid_mesh(lambda a, z: np.stack([R * np.cos(a), R * np.sin(a), z], -1),
                       np.linspace(0, 4.5, 136), np.linspace(0, 100, 51))
    rows = [np.stack([R * np.cos(np.full(21, a)), R * np.sin(np.full(21, a)), np.linspace(10, 90, 21)], 1)
            for a in (0.5, 2.0, 3.5)]          # 1.5 rad apart: arc 45 mm, chord 40.9 mm
    s = fm.row_steps(fm.SurfaceGeodesic(cyl), rows, 45.0)
    assert abs(np.median(s) - 45.0) < 0.45
    assert np.all(s > 2 * R * math.sin(0.75) + 2.0)


def test_a_row_end_is_no_neighbour():
    # two pieces of one row split at a hole, and a row beside them: the pieces do not measure each other
    mesh = _plane()
    x = np.arange(20.0, 81.0, 2.0)
    rows = [np.stack([x, np.full_like(x, 50.0), 0 * x], 1), np.stack([x + 70, np.full_like(x, 50.0), 0 * x], 1),
            np.stack([np.arange(20.0, 151.0, 2.0), np.full(66, 60.0), np.zeros(66)], 1)]
    s = fm.row_steps(fm.SurfaceGeodesic(mesh), rows, 10.0)
    assert np.all((s > 9.99) & (s < 10.1))


def test_coverage_of_a_flat_raster():
    mesh = _plane()
    samples = fm.surface_samples(mesh, spacing_mm=1.0)
    full = np.vstack(_rows_y(np.arange(5.0, 200.0, 10.0), pitch=1.0))
    assert fm.coverage(samples, full, 6.0) > 0.99
    # rows 20 mm apart, radius 6 mm: strips 12 mm wide of each 20 mm (the outer edges aside)
    sparse_rows = np.vstack(_rows_y(np.arange(10.0, 200.0, 20.0), pitch=0.5))
    assert abs(fm.coverage(samples, sparse_rows, 6.0) - 0.6) < 0.02


def test_distance_axis_error_and_turns_on_a_sphere():
    R = 300.0
    sph = fm.trimesh.creation.icosphere(subdivisions=5, radius=R)
    a = np.linspace(0.2, 1.2, 30)
    n = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], 1)
    pts = (R + 1.0) * n                          # 1 mm off the surface
    d = fm.distance_to_mesh(sph, pts)
    sag = sph.edges_unique_length.max() ** 2 / (6 * R)   # the flat facets lie up to ~e^2 / 6R inside the sphere
    assert np.all(d > 1.0 - 1e-9) and np.all(d < 1.0 + 1.2 * sag)
    nn = fm.averaged_normals(sph, pts)
    # the axis along -n counts as on the normal; the facets (11.6 mm) tilt the 12.5 mm mean by < 0.6 deg
    assert np.all(fm.axis_error_deg(-n, nn) < 0.6)
    tilt = math.radians(5.0)
    tilted = np.cos(tilt) * n + np.sin(tilt) * np.array([0.0, 0.0, 1.0])
    assert np.allclose(fm.axis_error_deg(tilted, nn), 5.0, atol=0.6)
    turns = fm.turns_deg([(pts, n)])
    assert abs(turns.max() - math.degrees(a[1] - a[0])) < 1e-6
    flipped = n.copy()
    flipped[10:] *= -1
    assert fm.turns_deg([(pts, flipped)]).max() > 170.0


def test_noether_baseline_step_doubles_on_a_plane_tilted_60_deg():
    t = math.radians(60.0)
    plane = fm.grid_mesh(lambda x, y: np.stack([x, y * math.cos(t), y * math.sin(t)], -1),
                         np.linspace(0, 200, 41), np.linspace(0, 200, 41))
    rows = fm.plane_slicer(plane, 10.0, 5.0, cut_normal=[0.0, 1.0, 0.0])
    assert len(rows) == 10                       # planes every 10 mm over the 100 mm the plane spans in y
    s = fm.row_steps(fm.SurfaceGeodesic(plane), [p for p, _ in rows], 10.0)
    assert abs(np.median(s) - 20.0) < 0.2
    for p, n in rows:                            # the normals come from the mesh's vertex normals
        assert np.allclose(np.abs(n @ np.array([0.0, -math.sin(t), math.cos(t)])), 1.0, atol=1e-6)
        assert np.allclose(np.diff(p, axis=0) @ np.array([1.0, 0, 0]), 200.0 / (len(p) - 1), atol=1e-6)


def test_noether_baseline_cuts_along_the_principal_axes():
    # a 300 x 100 mm plate: the planes advance along its long side, the rows run across it
    mesh = fm.grid_mesh(lambda x, y: np.stack([x, y, np.zeros_like(x)], -1),
                        np.linspace(0, 300, 61), np.linspace(0, 100, 21))
    rows = fm.plane_slicer(mesh, 10.0, 5.0)
    assert 29 <= len(rows) <= 31
    for p, _ in rows:
        assert np.ptp(p[:, 0]) < 1e-6 and abs(np.ptp(p[:, 1]) - 100.0) < 1e-6


def test_face_region_drops_the_side_walls():
    box = fm.trimesh.creation.box(extents=[200.0, 100.0, 50.0]).subdivide().subdivide()
    mask = fm.face_region(box, up=[0, 0, 1], max_tilt_deg=30.0, radius_mm=1.0)
    assert abs(box.area_faces[mask].sum() - 200.0 * 100.0) < 1e-6   # one of the two big faces, whole


def test_row_steps_go_round_a_fold_not_through_the_air():
    # rows on a cylinder 3 rad apart: the straight segment between them crosses the inside (chord
    # 59.8 mm); the distance on the surface is the arc, 90 mm
    R = 30.0
    cyl = fm.grid_mesh(lambda a, z: np.stack([R * np.cos(a), R * np.sin(a), z], -1),
                       np.linspace(0, 4.0, 121), np.linspace(0, 60, 31))
    rows = [np.stack([R * np.cos(np.full(11, a)), R * np.sin(np.full(11, a)), np.linspace(10, 50, 11)], 1)
            for a in (0.5, 3.5)]
    s = fm.row_steps(fm.SurfaceGeodesic(cyl), rows, 90.0)
    assert abs(np.median(s) - 90.0) < 1.5


def test_axis_normal_on_a_coarse_mesh_is_the_discs_own_mean():
    """A wavy sheet meshed coarsely (25 mm grid, triangles as large as the 12.5 mm disc): the fine quadrature's
    mean normal agrees with the disc's mean taken over dense area-uniform samples (the exact integral's Monte
    Carlo, 16 per mm^2); the file's own centroids alone miss it by degrees."""
    wavy = fm.grid_mesh(lambda x, y: np.stack([x, y, 20.0 * np.sin(x / 40.0) * np.cos(y / 55.0)], -1),
                        np.linspace(0, 300, 13), np.linspace(0, 300, 13))
    rng = np.random.default_rng(3)
    pts = np.column_stack([rng.uniform(60, 240, (40, 2)), np.zeros(40)])
    pts[:, 2] = 20.0 * np.sin(pts[:, 0] / 40.0) * np.cos(pts[:, 1] / 55.0)
    samples, tri = fm.trimesh.sample.sample_surface(wavy, int(16 * wavy.area), seed=1)
    c, _, f = fm.closest(wavy, pts)
    ref = np.empty_like(c)
    for i, ids in enumerate(fm.cKDTree(samples).query_ball_point(c, fm.AXIS_RADIUS_MM)):
        n = wavy.face_normals[tri[np.asarray(ids, int)]]
        ref[i] = (n * np.sign(n @ wavy.face_normals[f[i]])[:, None]).sum(axis=0)
    ref /= np.linalg.norm(ref, axis=1, keepdims=True)
    fine = fm.axis_error_deg(fm.averaged_normals(wavy, pts), ref)
    coarse = fm.axis_error_deg(fm.averaged_normals(wavy, pts, fine=False), ref)
    assert np.percentile(fine, 95) < 0.5
    assert np.percentile(coarse, 95) > 2.0


def _step(height_mm=40.0):
    """A step: the floor z = 0 (x < 0), a wall x = 0 up to height_mm facing the floor (-x), a top z = height_mm (x >
    0); 100 mm along y. Quads split into triangles; the floor in two CAD faces (x < -30, and the rest)."""
    xs, ys = np.linspace(-60.0, 0.0, 25), np.linspace(0.0, 100.0, 41)
    floor = fm.grid_mesh(lambda x, y: np.stack([x, y, np.zeros_like(x)], -1), xs, ys)
    wall = fm.grid_mesh(lambda z, y: np.stack([np.zeros_like(z), y, z], -1), np.linspace(0.0, height_mm, 17), ys)
    top = fm.grid_mesh(lambda x, y: np.stack([x, y, np.full_like(x, height_mm)], -1), -xs[::-1], ys)
    m = fm.trimesh.util.concatenate([floor, wall, top])
    m.merge_vertices()
    owner = np.concatenate([np.where(floor.triangles_center[:, 0] < -30.0, 0, 1), np.full(len(wall.faces), 2),
                            np.full(len(top.faces), 3)])
    return m, owner


@pytest.mark.parametrize("with_owner", [False, True])
def test_own_face_normal_leaves_out_a_wall_across_a_sharp_edge(with_owner):
    """A floor point d mm from a 90 deg step's wall: the 12.5 mm disc's mean takes in the wall, the closed form
    atan(A_wall / A_floor) (the ball's area on the wall: half a disc of radius sqrt(R^2 - d^2); on the floor: the
    disc less its segment past the wall); on the worked face's own triangles (the floor: its two tangent CAD faces
    joined, or the mesh split at its sharp edges) the floor's own normal, exactly."""
    m, owner = _step()
    faces = fm.worked_faces(m, owner if with_owner else None)
    floor = m.triangles_center[:, 2] < 1e-9
    assert len(np.unique(faces[floor])) == 1 and not np.isin(faces[~floor], faces[floor]).any()
    R = fm.AXIS_RADIUS_MM
    d = np.array([2.0, 5.0, 8.0, 11.0])
    pts = np.stack([-d, np.full_like(d, 50.0), np.zeros_like(d)], 1)
    a_wall = 0.5 * np.pi * (R * R - d * d)
    a_floor = np.pi * R * R - (R * R * np.arccos(d / R) - d * np.sqrt(R * R - d * d))
    want = np.degrees(np.arctan2(a_wall, a_floor))
    up = np.tile([0.0, 0.0, 1.0], (len(d), 1))
    whole = fm.axis_error_deg(up, fm.averaged_normals(m, pts))
    own = fm.axis_error_deg(up, fm.own_face_normals(m, pts, faces))
    assert np.all(np.abs(whole - want) < 1.0), (whole, want)
    assert np.all(own < 1e-6), own


def test_worked_coverage_leaves_out_a_neighbouring_face_the_region_takes_in():
    """The step's floor worked by rows 10 mm apart (x from -55 to -5 mm), its region taken with a 10 mm strip of
    the wall: the whole coverage misses the wall's samples, the worked faces' coverage (the floor: the faces holding
    the TCPs) is the floor's alone, which the rows cover."""
    m, owner = _step()
    faces = fm.worked_faces(m, owner)
    floor = m.triangles_center[:, 2] < 1e-9
    wall_low = (np.abs(m.triangles_center[:, 0]) < 1e-9) & (m.triangles_center[:, 2] < 10.0)
    samples = fm.surface_samples(m, floor | wall_low, spacing_mm=1.0)
    tcps = np.vstack([np.stack([np.full(101, x), np.linspace(0.0, 100.0, 101), np.zeros(101)], 1)
                      for x in np.arange(-55.0, -4.0, 10.0)])
    on_wall = np.abs(samples[:, 0]) < 1e-6
    whole = fm.coverage(samples, tcps, 6.0)
    own = fm.worked_coverage(m, samples, tcps, faces, 10.0)
    assert own == pytest.approx(fm.coverage(samples[~on_wall], tcps, 6.0), abs=1e-12)
    assert own > 0.99 and whole < own - 0.05
