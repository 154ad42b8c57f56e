"""The process map on a free-form face's own mesh (issue #46): its figures against independent references.

1. **Flat**: a plate 300 x 200 mm (tilted 30 deg) given as a mesh and taken as a free-form face, and the same
   plate as an analytic plane; the plane's raster (step-over 10 mm, parabolic 30 mm footprint, grid 2 mm)
   run at 100 mm/s is mapped on both. Printed: the figures side by side (and the mesh map on its vertices
   alone), the exact share within 5 % (tests/process_reference.py, 200k points) over the plate and over the
   face's worked area (its 1 mm material nodes' cells), and the largest difference between the refined
   samples and the exact direct sums there (share of the peak).
2. **Curved**: a saddle CAD mesh z = (x^2 - y^2) / 400 (240 x 180 mm); three passes along x on the true
   surface. Printed: the largest difference between the mesh map and direct sums of the footprint over a
   0.5 mm sampling of the true surface (each sample with its exact area element, the true normals), as a
   share of the peak; and the vertex areas against the true area element (p99 of the relative error).
2b. **Saddle raster**: passes 10, 13 and 16 mm apart across a saddle CAD mesh 140 x 110 mm, past its edges:
   the share within 5 % of the exact reference (true normals, 200k points uniform in area over the worked
   area), of the mesh map and of the map on its vertices alone.
3. **Auto**: ``raster.step_over_mm = "auto"`` on saddles z = (x^2 - y^2) / 1000 of 300 x 210 and
   200 x 150 mm: the chosen step-over, its predicted share within +-5 %, what limits it, and the seconds.
4. **Cost**: a panel 1.3 x 0.8 m (z = (x^2 - y^2) / 4000, a 50 mm parabolic footprint, grid 2 mm), its raster
   at 20 mm run at 100 mm/s: the map's seconds, vertices, refined samples and their spacing across the rows.

    .venv/bin/python benchmarks/process_mesh_map.py
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from camtool.part.fit import fit_surface  # noqa: E402
from camtool.process.figures import map_figures  # noqa: E402
from camtool.process.footprint import Footprint  # noqa: E402
from camtool.process.maps import track_map  # noqa: E402
from camtool.process.mesh_map import mesh_process_map  # noqa: E402
from camtool.process.stepover import choose_step_over  # noqa: E402
from camtool.settings import RasterSettings  # noqa: E402
from test_freeform import grid_mesh, mesh_workpiece  # noqa: E402
from process_reference import contacts, removal_at, sample_points  # noqa: E402
from test_process_mesh_map import (FIT, POLISH, dense_reference, face_chart_points, plane_track, saddle,  # noqa: E402
                                   saddle_exact_share, share_of, small_saddle_face, three_passes, tilted)
from test_process_mesh_map import saddle_raster as saddle_raster_track  # noqa: E402

KEYS = ("worked_area_mm2", "mean", "rms_pct", "uniformity_within_5pct", "uniformity_within_10pct",
        "edge_rolloff_width_mm", "uncovered_share")


def exact_share(h, weights=None, band=0.05) -> float:
    return share_of(h, np.ones(len(h)) if weights is None else weights, band)


def flat() -> None:
    from camtool.part.surface import Boundary, PlaneSurface

    V, F = grid_mesh(np.linspace(-150, 150, 31), np.linspace(-100, 100, 21), lambda X, Y: 0 * X)
    free = fit_surface(mesh_workpiece(tilted(V), F)[0], FIT)
    ex, ey = tilted(np.eye(3))[0], tilted(np.eye(3))[1]
    plane = PlaneSurface(np.zeros(3), np.cross(ex, ey), ex, ey,
                         Boundary(np.array([[-150, -100], [150, -100], [150, 100], [-150, 100]], float)))
    t, tcp = plane_track(plane)
    t0 = time.perf_counter()
    grid_map = track_map(POLISH, plane, t, tcp, rows_mm=10.0)
    t1 = time.perf_counter()
    mesh_map = track_map(POLISH, free, t, tcp, rows_mm=10.0)
    t2 = time.perf_counter()
    unrefined = mesh_process_map(POLISH, free, t, tcp, mesh_map.grid, 10.0, refine=False)
    a, b, u = map_figures(grid_map), map_figures(mesh_map), map_figures(unrefined)
    k = POLISH.preston_coefficient_per_pa * POLISH.force_n * 1e-3 * 1e12
    segments = contacts(plane, t, tcp, POLISH.contact_tol_mm, k)
    xy = face_chart_points(free, 200_000)
    P = free.origin_mm + xy[:, :1] * free.frame[:, 0] + xy[:, 1:] * free.frame[:, 1]
    P -= np.outer((P - plane.origin_mm) @ plane.normal, plane.normal)
    on_face = exact_share(removal_at(P, segments, "parabolic", 15.0))
    on_plate = exact_share(removal_at(sample_points(plane, 200_000), segments, "parabolic", 15.0))
    print("== 1. flat: the analytic plane's grid map | the same plate as a free-form face, its mesh map | the mesh "
          "map on its vertices alone (unrefined)")
    for key in KEYS:
        print(f"  {key:26s} {a[key]:>12} | {b[key]:>12} | {u[key]:>12}")
    print(f"  seconds                    {t1 - t0:12.2f} | {t2 - t1:12.2f}  ({len(mesh_map.values)} vertices, "
          f"{len(mesh_map.fine.values)} samples {b['samples_across_rows_mm']} mm apart across the rows)")
    print(f"  exact share within 5 % (200k points): over the plate {on_plate:.4f} "
          f"(grid map {a['uniformity_within_5pct']}),"
          f" over the face's worked area {on_face:.4f} (mesh map {b['uniformity_within_5pct']}, unrefined "
          f"{u['uniformity_within_5pct']})")
    fine = mesh_map.fine
    some = np.flatnonzero(fine.grid.material)[::20]
    Q = fine.grid.points_mm()[some]
    Q -= np.outer((Q - plane.origin_mm) @ plane.normal, plane.normal)
    print(f"  refined samples vs the exact direct sums there: max |diff| "
          f"{np.abs(fine.values[some] - removal_at(Q, segments, 'parabolic', 15.0)).max() / fine.values.max():.2e} "
          "of the peak")


def saddle_raster() -> None:
    face = small_saddle_face()
    print("== 2b. a saddle CAD mesh 140 x 110 mm, passes along x past its edges; share within 5 %: the exact reference"
          " over the face's worked area | the mesh map | unrefined")
    for step in (10.0, 13.0, 16.0):
        t, tcp = saddle_raster_track(step)
        t0 = time.perf_counter()
        pm = track_map(POLISH, face, t, tcp, rows_mm=step)
        seconds = time.perf_counter() - t0
        un = mesh_process_map(POLISH, face, t, tcp, pm.grid, step, refine=False)
        exact = saddle_exact_share(face, tcp, 200_000)
        got, alone = map_figures(pm)["uniformity_within_5pct"], map_figures(un)["uniformity_within_5pct"]
        print(f"  step {step:4.1f} mm: {exact:.4f} | {got:.4f} | {alone:.4f}   ({seconds:.1f} s, "
              f"{len(pm.fine.values)} samples)")


def curved() -> None:
    V, F = grid_mesh(np.linspace(-120, 120, 97), np.linspace(-90, 90, 73), saddle)
    face = fit_surface(mesh_workpiece(V, F)[0], FIT)
    rows = three_passes()
    tcp = np.vstack(rows)
    t0 = time.perf_counter()
    pm = track_map(POLISH, face, np.arange(len(tcp)) * 0.005, tcp)
    seconds = time.perf_counter() - t0
    per_mm = POLISH.preston_coefficient_per_pa * POLISH.force_n * 1e-3 * 1e12
    mids = np.vstack([0.5 * (r[1:] + r[:-1]) for r in rows[0::2]])
    w = np.concatenate([per_mm * np.linalg.norm(np.diff(r, axis=0), axis=1) for r in rows[0::2]])
    n = np.column_stack([-mids[:, 0] / 200.0, mids[:, 1] / 200.0, np.ones(len(mids))])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    m = pm.grid
    P = m.points_mm()
    near = m.material & (np.abs(P[:, 1]) < 30) & (np.abs(P[:, 0]) < 60)
    fp = Footprint.from_settings(POLISH)
    ref = dense_reference(P[near], mids, n, w, fp.radius_mm, fp.shape)
    inner = m.material & (m.edge_distance_mm() > 5.0)
    slope = np.hypot(P[inner, 0] / 200.0, P[inner, 1] / 200.0)
    area_err = np.abs(m.area_mm2[inner] / (np.sqrt(1 + slope ** 2) * m.spacing_mm ** 2) - 1.0)
    print("== 2. curved: a saddle CAD mesh z = (x^2 - y^2) / 400, three passes; the map against direct sums over "
          "a 0.5 mm sampling of the true surface")
    fg = pm.fine.grid
    Pf = fg.points_mm()
    some = np.flatnonzero(fg.material & (np.abs(Pf[:, 1]) < 30) & (np.abs(Pf[:, 0]) < 60))[::7]
    fine_ref = dense_reference(Pf[some], mids, n, w, fp.radius_mm, fp.shape)
    print(f"  max |map - reference| {np.abs(pm.values[near] - ref).max() / ref.max():.2e} of the peak "
          f"({int(near.sum())} vertices: their cells' averages against the point values); map {seconds:.2f} s for "
          f"{len(m.vertices_mm)} vertices")
    print(f"  its refined samples: max |sample - reference| "
          f"{np.abs(pm.fine.values[some] - fine_ref).max() / fine_ref.max():.2e} of the peak ({len(some)} samples)")
    print(f"  vertex area vs the true area element: p99 relative error {np.percentile(area_err, 99):.2e} "
          f"(the projection is up to {100 * (np.sqrt(1 + slope.max() ** 2) - 1):.1f} % short)")


def auto() -> None:
    print("== 3. raster.step_over_mm = \"auto\" on a free-form face (parabolic 30 mm, target 95 % within +-5 %)")
    for w, h in ((300, 210), (200, 150)):
        V, F = grid_mesh(np.linspace(-w / 2, w / 2, 61), np.linspace(-h / 2, h / 2, 43),
                         lambda X, Y: (X ** 2 - Y ** 2) / 1000.0)
        face = fit_surface(mesh_workpiece(V, F)[0], FIT)
        t0 = time.perf_counter()
        _, rec = choose_step_over(face, RasterSettings.make(step_over_mm="auto", pitch_mm=10, lead_mm=20),
                                  POLISH, 100.0)
        print(f"  saddle {w} x {h} mm: step-over {rec['step_over_mm']} mm, predicted share "
              f"{rec['predicted_share_within_band']:.3f}, met {rec['met']}, limited by {rec['limited_by']}, "
              f"{len(rec['candidates'])} candidate(s), {time.perf_counter() - t0:.1f} s")


def cost() -> None:
    from camtool.path.raster import raster_path
    from camtool.process.stepover import _track
    from camtool.settings import ProcessSettings

    V, F = grid_mesh(np.linspace(-650, 650, 131), np.linspace(-400, 400, 81), lambda X, Y: (X ** 2 - Y ** 2) / 4000.0)
    face = fit_surface(mesh_workpiece(V, F, n=200000)[0], FIT)
    process = ProcessSettings.make(kind="polish", profile="parabolic", diameter_mm=50)
    path = raster_path(face, RasterSettings.make(step_over_mm=20, pitch_mm=10, lead_mm=20))
    t, tcp = _track(path, 100.0, 0.5 * process.grid_mm, 11.0)
    t0 = time.perf_counter()
    pm = track_map(process, face, t, tcp, rows_mm=20.0)
    f = map_figures(pm)
    samples = len(pm.fine.values) if pm.fine is not None else len(pm.values)
    print(f"== 4. cost: a panel 1.3 x 0.8 m, grid {process.grid_mm:g} mm, rows 20 mm: the map "
          f"{time.perf_counter() - t0:.1f} s for {len(pm.values)} vertices ({samples} samples, "
          f"{f['samples_across_rows_mm']} mm apart "
          f"across the rows) and {len(t)} track samples")


def main() -> int:
    flat()
    curved()
    saddle_raster()
    auto()
    cost()

    return 0


if __name__ == "__main__":
    sys.exit(main())
