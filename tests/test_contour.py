"""Tests of camtool.path.contour and the contour pass of camtool.path.raster: runs along the edges, split at corners,
the material on their left, none on a full turn's seam, and the slivers of oblique edges covered."""
import math

import numpy as np
import pytest
import shapely
from matplotlib.path import Path as MplPath

from camtool.path.contour import CORNER_DEG, SIMPLIFY_MM, contour_runs, spans_full_turn
from camtool.path.face_set import joined
from camtool.path.raster import (
    CONTOUR_BELOW,
    contour_offset_mm,
    count_contour_runs,
    count_rows,
    raster_path,
    raster_summary,
)
from camtool.settings import RasterSettings
from camtool.run.stage_files import load_stage, save_stage
from camtool.part.surface import Boundary, Cylinder, PlaneSurface
from camtool.path.toolpath import ZONE_CODE

WORK = ZONE_CODE["work"]


def rect(u0, u1, v0, v1):
    return np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]], float)


def plane(outer, holes=()):
    return PlaneSurface(np.zeros(3), np.array([0, 0, 1.0]), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]),
                        Boundary(np.asarray(outer, float), tuple(np.asarray(h, float) for h in holes)))


def half_ring(r_in=100.0, r_out=120.0, n=180):
    """A half annulus (the end face of a half pipe) in the plane z = 0, mm."""
    a = np.linspace(0, math.pi, n)
    outer = np.c_[r_out * np.cos(a), r_out * np.sin(a)]
    inner = np.c_[r_in * np.cos(a[::-1]), r_in * np.sin(a[::-1])]
    return plane(np.vstack([outer, inner]))


def distance_to_polygon(points, poly):
    """Distance (mm) of 2-D points to a closed polygon's edges."""
    a, b = poly, np.roll(poly, -1, axis=0)
    ab = b - a
    t = np.clip(np.einsum("nij,ij->ni", points[:, None, :] - a[None], ab) / np.sum(ab * ab, axis=1), 0, 1)
    near = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(points[:, None, :] - near, axis=2).min(axis=1)


SETTINGS = dict(step_over_mm=10.0, pitch_mm=5.0)


def test_a_ring_rastered_across_gets_a_contour_and_full_coverage():
    ring = half_ring()
    rows_only = raster_path(ring, RasterSettings.make(**SETTINGS, contour="off"))
    assert rows_only.contour is None and raster_summary(rows_only, ring)["coverage"] < CONTOUR_BELOW
    auto = raster_path(ring, RasterSettings.make(**SETTINGS))
    s = raster_summary(auto, ring)
    assert s["coverage"] >= CONTOUR_BELOW and s["contour_runs"] >= 4     # two arcs and the two end lines
    assert s["rows"] == raster_summary(rows_only, ring)["rows"]             # the rows are the same rows
    n_rows = len(np.unique(rows_only.segment))
    assert np.array_equal(auto.poses_mm[:len(rows_only) - 3], rows_only.poses_mm[:len(rows_only) - 3])
    assert np.all(auto.segment[auto.contour] >= n_rows - 1) and not auto.contour[:len(rows_only) - 3].any()


def test_contour_work_points_lie_the_offset_inside_every_edge():
    surf = plane(rect(0, 200, 0, 100), (rect(80, 120, 40, 60),))
    path = raster_path(surf, RasterSettings.make(**SETTINGS, contour="on"))
    d = contour_offset_mm(10.0, 5.0)
    assert d == pytest.approx(5.0)
    w = path.poses_mm[path.is_work & path.contour, :3, 3][:, :2]
    near = np.minimum(distance_to_polygon(w, surf.boundary.outer_uv), distance_to_polygon(w, surf.boundary.holes_uv[0]))
    # on the straight edges exactly the offset in; round a hole's corners the offset ring is an arc of that
    # radius, drawn by chords within contour.SIMPLIFY_MM
    assert np.allclose(near, d, atol=SIMPLIFY_MM) and np.median(np.abs(near - d)) < 1e-9
    assert count_contour_runs(path) == 5    # 4 sides outside, split at the corners; round the hole one closed run
    assert count_rows(path) == raster_summary(raster_path(surf, RasterSettings.make(**SETTINGS, contour="off")))["rows"]


def test_runs_split_at_corners_keep_the_material_on_their_left():
    box = Boundary(rect(0, 100, 0, 60), (rect(40, 60, 20, 40),))
    runs = contour_runs(box, 1.0, 1.0, 5.0)
    outer, hole = MplPath(box.outer_uv), MplPath(box.holes_uv[0])
    assert len(runs) == 5 and sum(r.closed for r in runs) == 1
    for r in runs:
        xy = np.vstack([r.xy_mm, r.xy_mm[:1]]) if r.closed else r.xy_mm
        d = np.diff(xy, axis=0)
        assert np.all(np.degrees(np.arccos(np.clip(np.sum(d[1:] * d[:-1], 1) / np.maximum(
            np.linalg.norm(d[1:], axis=1) * np.linalg.norm(d[:-1], axis=1), 1e-12), -1, 1))) <= CORNER_DEG)
        mid = 0.5 * (xy[0] + xy[1])
        left = mid + 2.0 * np.array([-d[0, 1], d[0, 0]]) / np.linalg.norm(d[0])
        right = mid - 2.0 * np.array([-d[0, 1], d[0, 0]]) / np.linalg.norm(d[0])
        inside = lambda p: outer.contains_point(p) and not hole.contains_point(p)  # noqa: E731
        # the left is material farther from the edge; the right, the 5 mm band to the edge, then none
        assert inside(left)
        assert not inside(right + 3.5 * (right - mid) / np.linalg.norm(right - mid))
    # each next run starts where the one before ended (a corner), or at the nearest start
    ends = [r.xy_mm[-1] for r in runs[:-1]]
    starts = [r.xy_mm[0] for r in runs[1:]]
    assert sum(np.allclose(a, b) for a, b in zip(ends, starts)) >= 3


def test_a_circle_is_one_closed_run_spread_evenly():
    a = np.linspace(0, 2 * math.pi, 360, endpoint=False)
    surf = plane(np.c_[50 * np.cos(a), 50 * np.sin(a)])
    runs = contour_runs(surf.boundary, 1.0, 1.0, 5.0)
    assert len(runs) == 1 and runs[0].closed
    path = raster_path(surf, RasterSettings.make(**SETTINGS, contour="on"))
    w = path.poses_mm[path.is_work & path.contour, :3, 3]
    gaps = np.linalg.norm(np.diff(np.vstack([w, w[:1]]), axis=0), axis=1)
    assert gaps.max() <= 5.0 + 1e-9 and gaps.max() - gaps.min() < 0.05
    assert np.allclose(np.hypot(w[:, 0], w[:, 1]), 45.0, atol=SIMPLIFY_MM)


def test_a_strip_about_a_step_wide_gets_two_runs_beside_its_middle():
    runs = contour_runs(Boundary(rect(0, 300, 0, 10)), 1.0, 1.0, 5.0)
    long_runs = [r for r in runs if r.length_mm > 100]
    assert len(long_runs) == 2
    assert sorted(round(float(r.xy_mm[:, 1].mean()), 3) for r in long_runs) == [2.5, 7.5]


def test_a_cylinder_all_round_gets_no_contour_on_its_seam():
    frame = np.eye(3)
    cyl = Cylinder(np.zeros(3), 50.0, frame, Boundary(rect(-math.pi, math.pi, 0, 100)))
    assert spans_full_turn(cyl) and not spans_full_turn(plane(rect(0, 10, 0, 10)))
    runs = contour_runs(cyl.boundary, 50.0, 1.0, 5.0, periodic=True)
    assert len(runs) == 2
    for r in runs:  # the two rims, each once round: v = 5 and v = 95, u over the full turn
        assert np.ptp(r.xy_mm[:, 1]) < 1e-9 and r.xy_mm[0, 1] in (5.0, 95.0)
        assert np.ptp(r.xy_mm[:, 0]) == pytest.approx(2 * math.pi * 50.0, abs=1e-6)
    path = raster_path(cyl, RasterSettings.make(**SETTINGS, contour="on"))
    v = path.poses_mm[path.is_work & path.contour, 2, 3]
    assert np.allclose(np.minimum(np.abs(v - 5.0), np.abs(v - 95.0)), 0.0, atol=1e-9)


def test_contour_flags_survive_stage_files_and_joined_faces(tmp_path):
    ring = half_ring()
    path = raster_path(ring, RasterSettings.make(**SETTINGS))
    save_stage(path, tmp_path / "path.npz")
    back = load_stage(tmp_path / "path.npz")
    assert np.array_equal(back.contour, path.contour)
    plain = raster_path(plane(rect(0, 100, 0, 50)), RasterSettings.make(**SETTINGS))
    assert plain.contour is None
    both = joined([plain, path], [0, 1], (3, 5), RasterSettings.make(**SETTINGS))
    assert both.contour is not None and not both.contour[:len(plain)].any()
    assert np.array_equal(both.contour[len(plain):], path.contour)
    k = int(np.flatnonzero(both.contour & both.is_work)[0])
    assert both.segment_text(k).startswith("face 5, segment ") and both.segment_text(k).endswith("(contour)")


def test_contour_key_is_checked(tmp_path):
    from camtool.errors import BadInput
    from camtool.job import load_job
    job = tmp_path / "job.toml"
    job.write_text('[workpiece]\nfile = "x.stl"\n[raster]\ncontour = "sometimes"\n')
    with pytest.raises(BadInput, match="contour"):
        load_job(job)


def weaving_ellipse(a_mm=200.0, b_mm=140.0, cell_mm=1.0, seed=3):
    """An ellipse's outline traced on a scan's boundary cells: jittered by a cell and snapped to ``cell_mm``,
    so it weaves in 1 mm steps (as a scanned face's outline does), counter-clockwise."""
    t = np.linspace(0, 2 * math.pi, 1400, endpoint=False)
    xy = np.c_[a_mm * np.cos(t), b_mm * np.sin(t)]
    xy += np.random.default_rng(seed).integers(-1, 2, xy.shape) * cell_mm
    xy = np.round(xy / cell_mm) * cell_mm
    keep = np.r_[True, np.any(np.diff(xy, axis=0) != 0, axis=1)]
    return xy[keep]


def test_a_scans_weaving_outline_is_one_run_when_its_corners_are_rounded():
    outline = weaving_ellipse()
    hole = np.c_[30 * np.cos(np.linspace(0, -2 * math.pi, 200, endpoint=False)),
                 30 * np.sin(np.linspace(0, -2 * math.pi, 200, endpoint=False))]
    b = Boundary(outline, (np.round(hole),))
    sharp = contour_runs(b, 1.0, 1.0, 7.5)
    assert len(sharp) > 5   # the weave reads as corners: a smooth rim cut into runs a few mm long
    rounded = contour_runs(b, 1.0, 1.0, 7.5, round_corners_mm=2.0)
    assert len(rounded) == 2 and all(r.closed for r in rounded)
    # still the offset ring: every point 7.5 mm inside the material's edge (as GEOS reads the weaving outline),
    # farther only by the rounding
    edge = shapely.make_valid(shapely.Polygon(outline, [b.holes_uv[0]])).buffer(0).boundary
    outer = max(rounded, key=lambda r: r.length_mm)
    d = shapely.distance(shapely.points(outer.xy_mm), edge)
    assert 7.5 - SIMPLIFY_MM - 1e-6 < d.min() and d.max() < 7.5 + 2.0


def test_rounding_keeps_a_real_corner_a_rounded_turn_not_a_split():
    b = Boundary(rect(0, 100, 0, 60), ())
    sharp = contour_runs(b, 1.0, 1.0, 5.0)
    assert len(sharp) == 4   # split at the rectangle's four corners
    rounded = contour_runs(b, 1.0, 1.0, 5.0, round_corners_mm=2.0)
    assert len(rounded) == 1 and rounded[0].closed
    corner = np.array([5.0, 5.0])  # the offset rectangle's corner: the run passes within 2 (sqrt 2 - 1) of it
    d = np.linalg.norm(rounded[0].xy_mm - corner, axis=1).min()
    assert abs(d - 2.0 * (math.sqrt(2) - 1)) < 0.05
