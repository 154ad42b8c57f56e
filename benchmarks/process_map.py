"""Process map anchors: the closed form of a straight pass, mr-sim on the same path, and the map's cost.

1. **Closed form, straight pass** (a 300 x 200 mm plate, one 400 mm pass at 100 mm/s sampled at 4 ms):
   a pass of a footprint with unit-volume density f leaves ``A * integral f(x, y) dx`` at lateral offset y,
   A = k_p F per mm of sliding; flat: ``2 sqrt(a^2 - y^2) / (pi a^2)``, parabolic:
   ``8 (a^2 - y^2)^(3/2) / (3 pi a^4)``. Printed: the map's mean over the pass width against the closed
   form's, and the RMS of the cross-section's difference (share of the closed form's peak), for both the
   convolution and the direct sums.
2. **mr-sim** (PyPI ``mr-sim``, BSD, the ``bench`` extra), Preston-law removal for a round tool on a flat
   part, on the same path and footprint: ``Flat + Round + Belt + Preston`` for the flat footprint and
   ``ConstantCurvature + Round + Belt + Preston`` (a paraboloid pressure, its contact radius set to the
   footprint's) for the parabolic one; it is stepped through every 4 ms sample (``set_location``,
   ``set_speed``, ``step``) on its own grid, and camtool's map is computed on the same cell centres.
   Printed: RMS of the difference over the worked area, as a share of the mean.
3. **Real runs**: the sample (the seed sphere, ``samples/sphere.toml``) and a plate
   (``samples/irb2400_plate.toml``), each run with ``process.kind = "polish"`` (parabolic and flat):
   the interior mean (cells farther than the footprint radius from the material's edge) against the
   closed form ``A / step_over_mm`` (rows step_over apart on the surface); on the plate, mr-sim stepped
   through the run's contact samples in the plate's (u, v) mm; on the sphere, mr-sim's ``mrr`` (its pressure
   and Preston models) evaluated in each contact's tangent plane (mr-sim models flat parts only); and the
   map's seconds as a share of the run's.

4. **Planning from the map** (``--case auto``, ``--case target``): the sample run with
   ``raster.step_over_mm = "auto"`` (flat footprint): the chosen step-over, what limits it and the run's
   share within +-5 %; the plate run with a target removal map (150 um + 30 um sin(2 pi u / 200 mm)
   cos(2 pi v / 300 mm), written next to the run) met by feed modulation (``relative_speed_m_s = 5``):
   the residual RMS over the clear aperture before, as planned and as run, and the cycle time.

    .venv/bin/python benchmarks/process_map.py [--quick] [--case straight|plate|sample|auto|target ...]

``--quick`` runs only the straight passes (seconds); the real runs take a few minutes each.
"""
from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from camtool.job import load_job
from camtool.run.pipeline import run_job
from camtool.process.figures import edge_distance_mm, map_figures
from camtool.process.footprint import Footprint
from camtool.process.grid import MapGrid
from camtool.process.integrate import contacts_from_tcp, process_map, tcp_track
from camtool.settings import ProcessSettings
from camtool.part.surface import Boundary, PlaneSurface

ROOT = Path(__file__).resolve().parents[1]
DT_S = 0.004


def per_mm_um_mm2(s: ProcessSettings) -> float:
    """What a mm of sliding puts on the part (um * mm^2): k_p F * 1 mm, in um * mm^2."""
    return s.preston_coefficient_per_pa * s.force_n * 1e-3 * 1e12


def mrsim_class(profile: str):
    import mr_sim

    pressure = mr_sim.Flat if profile == "flat" else mr_sim.ConstantCurvature
    return mr_sim.create_simulation(pressure, mr_sim.Round, mr_sim.Belt, mr_sim.Preston)


def mrsim_make(profile: str, s: ProcessSettings, size_m, cell_m, dt_s=DT_S):
    """An mr-sim simulation of the footprint of ``s`` (SI units)."""
    a = 0.5 * s.diameter_mm / 1000.0
    Sim = mrsim_class(profile)
    if profile == "flat":
        sim = Sim(size_m[0], size_m[1], dx=cell_m, dy=cell_m, dt=dt_s, radius=a, kp=s.preston_coefficient_per_pa)
    else:
        stiffness = 1e6  # any: the curvature is chosen so that the contact radius is a at force F
        k = 4.0 * s.force_n / (a ** 4 * stiffness * math.pi)
        sim = Sim(size_m[0], size_m[1], dx=cell_m, dy=cell_m, dt=dt_s, radius=a, kp=s.preston_coefficient_per_pa,
                  kx=k, ky=k, stiffness=stiffness)
    sim.set_force(s.force_n)
    return sim


def grid_on(surface, x_mm, y_mm, material=None) -> MapGrid:
    """camtool's map grid with the given cell centres (a plane)."""
    shape = (len(y_mm), len(x_mm))
    if material is None:
        X, Y = np.meshgrid(x_mm, y_mm)
        material = surface.boundary.contains(np.column_stack([X.ravel(), Y.ravel()])).reshape(shape)
    cell = float(x_mm[1] - x_mm[0])
    return MapGrid(surface, np.asarray(x_mm, float), np.asarray(y_mm, float), cell, material, np.full(shape, cell * cell))


def rms_share(a, b, mask) -> float:
    return float(np.sqrt(np.mean((a[mask] - b[mask]) ** 2)) / np.mean(b[mask]))


def plate_surface(w=300.0, h=200.0):
    b = Boundary(np.array([[-w / 2, -h / 2], [w / 2, -h / 2], [w / 2, h / 2], [-w / 2, h / 2]]))
    return PlaneSurface(np.zeros(3), np.array([0, 0, 1.0]), np.array([1, 0, 0.0]), np.array([0, 1, 0.0]), b)


def mrsim_track(sim, x_m, y_m, speed_m_s):
    """Step mr-sim through a track (one step per sample); its removal (um)."""
    for x, y, v in zip(x_m, y_m, speed_m_s):
        sim.set_location(x, y)
        sim.set_speed(v)
        sim.step()
    return sim.profile * 1e6


def straight(profile: str) -> dict:
    s = ProcessSettings.make(kind="polish", profile=profile, diameter_mm=50, grid_mm=1.0)
    surface = plate_surface()
    feed, y0 = 100.0, 0.3
    t = np.arange(0, 400 / feed, DT_S)
    tcp = np.column_stack([-200 + feed * t, np.full_like(t, y0), np.zeros_like(t)])
    out = {"profile": profile}
    fp = Footprint.from_settings(s)
    for method in ("convolution", "direct"):
        pm = process_map(s, surface, t, tcp, method=method)
        iu = np.abs(pm.grid.u) < 100  # away from the pass's ends
        closed = per_mm_um_mm2(s) * fp.pass_profile(pm.grid.v - y0)
        band = np.abs(pm.grid.v - y0) < fp.radius_mm
        cross = pm.values[:, iu].mean(axis=1)
        out[f"{method}_mean_ratio"] = float(cross[band].mean() / closed[band].mean())
        out[f"{method}_rms_of_peak"] = float(np.sqrt(np.mean((cross - closed) ** 2)) / closed.max())
    # mr-sim on the same path: its grid (m), camtool's map on the same cell centres
    size = (0.3, 0.2)
    sim = mrsim_make(profile, s, size, 1e-3)
    x_mm, y_mm = sim.X[0] * 1e3, sim.Y[:, 0] * 1e3
    on = np.abs(tcp[:, 0]) <= 150 + fp.radius_mm + 2
    mid = 0.5 * (tcp[1:] + tcp[:-1])
    sel = on[1:] & on[:-1]
    speed = np.linalg.norm(np.diff(tcp, axis=0), axis=1) / np.diff(t) / 1000.0
    t0 = time.perf_counter()
    ref = mrsim_track(sim, mid[sel, 0] / 1e3, mid[sel, 1] / 1e3, speed[sel])
    out["mrsim_seconds"] = time.perf_counter() - t0
    grid = grid_on(surface, x_mm, y_mm)
    t0 = time.perf_counter()
    pm = process_map(s, surface, t, tcp, grid=grid)
    out["camtool_seconds"] = time.perf_counter() - t0
    mask = grid.material & (np.abs(grid.u)[None, :] < 100) & (ref > 0.05 * ref.max())
    out["mrsim_rms_share"] = rms_share(pm.values, ref, mask)
    out["mrsim_mean_ratio"] = float(pm.values[mask].mean() / ref[mask].mean())
    return out


def real_run(case: str, profile: str) -> dict:
    job_file = {"plate": ROOT / "samples" / "irb2400_plate.toml", "sample": ROOT / "samples" / "sphere.toml"}[case]
    job = load_job(job_file, [f"process.kind=polish", f"process.profile={profile}"])
    with tempfile.TemporaryDirectory() as out:
        t0, c0 = time.perf_counter(), time.process_time()
        result = run_job(job, Path(out))
        run_s, run_cpu = time.perf_counter() - t0, time.process_time() - c0
    report = result.outputs["report"]
    figures = report["process_map"]
    surface, trajectory = result.outputs["fit"], result.outputs["time"]
    from camtool.run.stages import robot_for_job
    from camtool.run.job_settings import JobSettings

    robot = robot_for_job(job)
    s = JobSettings.from_job(job, robot).process
    step = float(result.outputs["raster"].step_over_mm)
    t_s, tcp = tcp_track(trajectory, robot, DT_S)
    pm = process_map(s, surface, t_s, tcp)
    fp = Footprint.from_settings(s)
    interior = pm.grid.material & (edge_distance_mm(pm) > fp.radius_mm + 2 * pm.grid.cell_mm)
    w = pm.grid.area_mm2
    interior_mean = float(np.sum(pm.values[interior] * w[interior]) / np.sum(w[interior]))
    closed = per_mm_um_mm2(s) / step
    out = {"case": case, "profile": profile, "run_s": run_s, "run_cpu_s": run_cpu, "map_s": figures["seconds"],
           "map_cpu_s": figures["cpu_seconds"], "map_share": figures["cpu_seconds"] / run_cpu, "interior_mean_um": interior_mean, "closed_form_um": closed,
           "mean_ratio": interior_mean / closed, "figures": figures}
    c = contacts_from_tcp(s, surface, t_s, tcp)
    t0 = time.perf_counter()
    if surface.model == "plane":
        lo, hi = surface.boundary.bounds()
        pad = fp.radius_mm + 4
        size_m = ((hi[0] - lo[0] + 2 * pad) / 1e3, (hi[1] - lo[1] + 2 * pad) / 1e3)
        centre = 0.5 * (lo + hi)
        sim = mrsim_make(profile, s, size_m, pm.grid.cell_mm / 1e3)
        x_mm, y_mm = sim.X[0] * 1e3 + centre[0], sim.Y[:, 0] * 1e3 + centre[1]
        speed = c.travel_mm / c.dt_s / 1000.0
        ref = mrsim_track(sim, (c.uv[:, 0] - centre[0]) / 1e3, (c.uv[:, 1] - centre[1]) / 1e3, speed)
        grid = grid_on(surface, x_mm, y_mm)
        mine = process_map(s, surface, t_s, tcp, grid=grid).values
        mask = grid.material
        out["mrsim"] = "mr-sim stepped through the run's contact samples in the plate's (u, v)"
    else:
        sim = mrsim_make(profile, s, (0.01, 0.01), 1e-3)
        g = pm.grid
        P = g.points_mm()
        ref = np.zeros(g.shape)
        a, R = fp.radius_mm, float(surface.radius_mm)
        centre = np.rint(g.index_of(c.uv)).astype(int)
        hv = int(math.ceil(a / (R * g.dv))) + 1
        # mr-sim's removal rate (its pressure and Preston models) in each contact's tangent plane, every 4 ms
        for k in range(len(c.dt_s)):
            cos_v = max(math.cos(min(abs(c.uv[k, 1]) + (a + g.cell_mm) / R, 1.5)), 0.05)
            hu = int(math.ceil(a / (R * cos_v * g.du))) + 1
            iu0, iv0 = centre[k]
            su = slice(max(iu0 - hu, 0), max(iu0 + hu + 1, 0))
            sv = slice(max(iv0 - hv, 0), max(iv0 + hv + 1, 0))
            d = P[sv, su] - c.point_mm[k]
            n = c.normal[k]
            d = d - (d @ n)[..., None] * n
            ex = np.cross(n, [0.0, 0.0, 1.0])
            ex = ex / np.linalg.norm(ex) if np.linalg.norm(ex) > 1e-9 else np.array([1.0, 0, 0])
            ey = np.cross(n, ex)
            sim.set_speed(c.travel_mm[k] / c.dt_s[k] / 1000.0)
            ref[sv, su] += sim.mrr((d @ ex) / 1e3, (d @ ey) / 1e3) * c.dt_s[k] * 1e6
        mine, mask = pm.values, g.material
        out["mrsim"] = "mr-sim's mrr (pressure and Preston) in each contact's tangent plane"
    out["mrsim_seconds"] = time.perf_counter() - t0
    out["mrsim_rms_share"] = rms_share(mine, ref, mask)
    out["mrsim_mean_ratio"] = float(mine[mask].mean() / ref[mask].mean())
    return out


def auto_run() -> dict:
    job = load_job(ROOT / "samples" / "sphere.toml", ["process.kind=polish", "raster.step_over_mm=auto"])
    with tempfile.TemporaryDirectory() as out:
        report = run_job(job, Path(out)).outputs["report"]
    return report


def target_run() -> dict:
    from camtool.run.stages import surface_for_job, workpiece_for_job

    job_file = ROOT / "samples" / "irb2400_plate.toml"
    surface = surface_for_job(load_job(job_file), workpiece_for_job(load_job(job_file)))
    lo, hi = surface.boundary.bounds()
    with tempfile.TemporaryDirectory() as out:
        u = np.arange(lo[0] - 40, hi[0] + 40, 4.0)
        v = np.arange(lo[1] - 40, hi[1] + 40, 4.0)
        U, V = np.meshgrid(u, v)
        target = 150 + 30 * np.sin(2 * np.pi * (U - lo[0]) / 200) * np.cos(2 * np.pi * (V - lo[1]) / 300)
        np.savez(Path(out) / "target.npz", u=u, v=v, values_um=target)
        job = load_job(job_file, ["process.kind=polish", "process.relative_speed_m_s=5", "process.dwell_iterations=30",
                                  f"process.target_removal_file={Path(out) / 'target.npz'}"])
        report = run_job(job, Path(out) / "run").outputs["report"]
    return report


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="only the straight passes")
    ap.add_argument("--case", action="append", choices=("straight", "plate", "sample", "auto", "target"))
    args = ap.parse_args(argv)
    cases = args.case or (["straight"] if args.quick else ["straight", "plate", "sample", "auto", "target"])
    ok = True
    if "straight" in cases:
        print("straight pass, 50 mm footprint, 400 mm at 100 mm/s, 4 ms samples, 1 mm grid")
        print(f"{'profile':10s} {'conv mean/closed':>17s} {'direct mean/closed':>19s} {'conv RMS/peak':>14s} "
              f"{'mr-sim RMS/mean':>16s} {'mr-sim s':>9s} {'camtool s':>10s}")
        for profile in ("flat", "parabolic"):
            r = straight(profile)
            print(f"{profile:10s} {r['convolution_mean_ratio']:17.4f} {r['direct_mean_ratio']:19.4f} "
                  f"{100 * r['convolution_rms_of_peak']:13.2f}% {100 * r['mrsim_rms_share']:15.2f}% "
                  f"{r['mrsim_seconds']:9.2f} {r['camtool_seconds']:10.3f}")
            ok &= abs(r["convolution_mean_ratio"] - 1) <= 0.01 and abs(r["direct_mean_ratio"] - 1) <= 0.01
            ok &= r["mrsim_rms_share"] <= 0.02
    for case in ("plate", "sample"):
        if case not in cases:
            continue
        profile = "flat" if case == "plate" else "parabolic"
        r = real_run(case, profile)
        f = r["figures"]
        print(f"\n{case} ({profile} footprint, {f['method']}): run {r['run_s']:.1f} s wall / {r['run_cpu_s']:.1f} s CPU, "
              f"map {r['map_s']:.2f} s wall / {r['map_cpu_s']:.2f} s CPU = {100 * r['map_share']:.1f} % of the run's CPU")
        print(f"  interior mean {r['interior_mean_um']:.5g} um, closed form A/step_over {r['closed_form_um']:.5g} um, "
              f"ratio {r['mean_ratio']:.4f}")
        print(f"  mr-sim ({r['mrsim']}, {r['mrsim_seconds']:.1f} s): RMS difference {100 * r['mrsim_rms_share']:.2f} % "
              f"of the mean, mean ratio {r['mrsim_mean_ratio']:.4f}")
        print(f"  map: mean {f['mean']:.4g} {f['units']}, RMS {f['rms_pct']:.2f} %, within 5 % "
              f"{100 * f['uniformity_within_5pct']:.1f} %, within 10 % {100 * f['uniformity_within_10pct']:.1f} %, "
              f"edge roll-off {f['edge_rolloff_width_mm']} mm, uncovered {f['uncovered_area_mm2']} mm2")
        ok &= abs(r["mean_ratio"] - 1) <= 0.01 and r["mrsim_rms_share"] <= 0.02 and r["map_share"] <= 0.10
    if "auto" in cases:
        report = auto_run()
        pm = report["process_map"]
        a = pm["step_over_auto"]
        print(f"\nsample, step_over_mm = auto ({pm['footprint']['profile']} footprint, {pm['footprint']['diameter_mm']:g} mm): chose {a['step_over_mm']} mm, "
              f"limited by {a['limited_by']} (ripple bound {a['ripple_bound_mm']} mm), predicted "
              f"{100 * a['predicted_share_within_band']:.2f} %; the run: {100 * pm['uniformity_within_5pct']:.2f} % of "
              f"the worked area within +-5 %, cycle {report['cycle_time_s']:.1f} s")
        ok &= pm["uniformity_within_5pct"] >= 0.95
    if "target" in cases:
        report = target_run()
        t = report["process_map"]["target"]
        print(f"\nplate, target removal map by feed modulation: residual RMS over the clear aperture "
              f"{t['residual_rms_before_pct']:.2f} % of the target's mean at constant feed, "
              f"{t['residual_rms_after_pct']:.2f} % as planned ({t['iterations']} iterations: "
              f"{', '.join(f'{x:.3g}' for x in t['convergence_rms_um'][:6])} ... {t['convergence_rms_um'][-1]:.3g} um), "
              f"{t['residual_rms_run_pct']:.2f} % as run; feed factors {t['feed_factor_min']}..{t['feed_factor_max']}, "
              f"cycle {report['cycle_time_s']:.1f} s")
        ok &= t["residual_rms_run_pct"] <= 10.0
    print("\nall anchors hold" if ok else "\nSOME ANCHOR DOES NOT HOLD")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
