"""``camtool fit``: load a workpiece and fit a plane, sphere patch or cylinder with its boundary."""
from pathlib import Path

import click
import numpy as np

from ..console import echo_json
from ..job import load_job

SURFACE_FILE = "surface.json"


def surface_summary(surface) -> dict:
    """The JSON summary of a fitted surface (parameters, statistics, boundary); of a job's several faces
    (``surface.FaceSet``), ``{"model": "faces", "faces": [{"index": ..., summary}, ...]}``."""
    from ..part.surface import FaceSet, PlaneSurface

    if isinstance(surface, FaceSet):
        return {"model": "faces", "faces": [{"index": i, **surface_summary(f)}
                                            for i, f in zip(surface.indices, surface.surfaces)]}
    d = {"model": surface.model}
    if surface.model == "freeform":
        d.update(surface.summary())
    elif isinstance(surface, PlaneSurface):
        d.update(normal=surface.normal, offset_mm=surface.offset_mm)
    else:
        d.update(center_mm=surface.center_mm, radius_mm=float(surface.radius_mm))
        if surface.model == "cylinder":
            d.update(axis=surface.axis, concave=bool(surface.concave))
    s = surface.stats
    d.update(inlier_ratio=s.inlier_ratio, rms_mm=s.rms_mm, max_residual_mm=s.max_residual_mm,
             n_points=s.n_points, n_inliers=s.n_inliers)
    d["boundary"] = {"uv_unit": surface.uv_unit, **surface.boundary.to_dict()}
    return d


@click.command("fit")
@click.argument("input_file", metavar="JOB|INPUT", type=click.Path(path_type=Path))
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="With a JOB: override a job-file key, e.g. --set fit.threshold_mm=1 (repeatable).")
@click.option("-o", "--outdir", type=click.Path(path_type=Path), default=None,
              help=f"Save the surface as OUTDIR/{SURFACE_FILE}, for `camtool raster JOB --from`.")
@click.option("--model", type=click.Choice(["auto", "plane", "sphere", "cylinder"]), default="auto", show_default=True,
              help="Surface model; auto takes the one with most inliers (a plane when a plane explains the data).")
@click.option("--threshold", "threshold_mm", type=click.FloatRange(min=0, min_open=True), default=0.5,
              show_default=True, help="RANSAC inlier distance in mm.")
@click.option("--units", type=click.Choice(["mm", "m", "in"]), default="mm", show_default=True,
              help="Length unit of INPUT; everything becomes mm.")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed (same seed, same fit).")
@click.option("--drop-nonfinite", is_flag=True,
              help="Drop points with NaN, infinite or damaged coordinates (with a warning) instead of refusing INPUT.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON for scripts.")
@click.option("--save", type=click.Path(path_type=Path), default=None,
              help="Write the surface as JSON (camtool surface file).")
def command(input_file: Path, overrides: tuple[str, ...], outdir: Path | None, model: str, threshold_mm: float,
            units: str, seed: int, drop_nonfinite: bool, as_json: bool, save: Path | None) -> None:
    """Fit a plane, sphere or cylinder to a JOB's workpiece (placed in the cell, the job's [fit]
    settings; with [faces] select, the selected face of its segmentation), or to an INPUT mesh
    or point cloud in its own frame (the options below).

    Meshes: STL, OBJ, PLY, OFF, GLB, STEP. Point clouds: PLY without faces, PCD,
    XYZ, CSV, TXT. Prints the parameters in mm, the inlier ratio, RMS and largest
    residual of the inliers, and the boundary.
    """
    from ..part.fit import fit_surface
    from ..settings import FitSettings
    from ..run.stages import surface_for_job, workpiece_for_job
    from ..part.surface import PlaneSurface, save_surface
    from ..part.workpiece import load_workpiece

    from .. import safe_io

    if input_file.suffix.lower() == ".toml":
        job = load_job(input_file, list(overrides))
        wp = workpiece_for_job(job)
        for w in wp.warnings:
            click.echo(f"camtool: warning: {w}", err=True)
        surface = surface_for_job(job, wp)
    else:
        wp = load_workpiece(input_file, units=units, seed=seed, drop_nonfinite=drop_nonfinite)
        for w in wp.warnings:
            click.echo(f"camtool: warning: {w}", err=True)
        surface = fit_surface(wp, FitSettings.make(model=model, threshold_mm=threshold_mm, seed=seed))
    click.get_current_context().with_resource(safe_io.writing_into(outdir))  # checked, held and locked as run's
    if outdir is not None:
        save = save or outdir / SURFACE_FILE
    if save is not None:
        save_surface(surface, save)
    if as_json:
        echo_json(surface_summary(surface))
        return
    from ..part.surface import FaceSet

    if isinstance(surface, FaceSet):  # one line per face, in the job's selection
        for f in surface_summary(surface)["faces"]:
            click.echo(f"face {f['index']:<3} {f['model']:<9} inliers {f['n_inliers']:>7}  rms_mm {f['rms_mm']:.4f}  "
                       f"boundary {len(f['boundary']['outer_uv'])} vertices, {len(f['boundary']['holes_uv'])} holes")
        if save is not None:
            click.echo(f"{'saved':<16} {save}")
        return
    s, b = surface.stats, surface.boundary
    rows = [("model", surface.model)]
    for w in getattr(surface, "warnings", ()):
        click.echo(f"camtool: warning: {w}", err=True)
    if surface.model == "freeform":
        f = surface.summary()
        rows += [("area_mm2", f"{f['area_mm2']:.1f}"), ("mean_normal", " ".join(f"{x:.6f}" for x in f["normal"])),
                 ("curvature_1_mm", f"{f['curvature_range'][0]:.6f}..{f['curvature_range'][1]:.6f} (mean, p1..p99)"),
                 ("grid", f"{f['grid_mm']:g} mm, {f['source']}, smoothing {f['smoothing_mm']:g} mm")]
    elif isinstance(surface, PlaneSurface):
        n = surface.normal
        rows += [("normal", f"{n[0]:.6f} {n[1]:.6f} {n[2]:.6f}"), ("offset_mm", f"{surface.offset_mm:.4f}")]
    else:
        c = surface.center_mm
        rows += [("center_mm", f"{c[0]:.4f} {c[1]:.4f} {c[2]:.4f}"), ("radius_mm", f"{surface.radius_mm:.4f}")]
        if surface.model == "cylinder":
            a = surface.axis
            rows += [("axis", f"{a[0]:.6f} {a[1]:.6f} {a[2]:.6f}"),
                     ("side", "inside (concave)" if surface.concave else "outside")]
    lo, hi = b.bounds()
    unit = surface.uv_unit
    if unit == "rad":
        lo, hi, unit = np.degrees(lo), np.degrees(hi), "deg"
    elif unit == "rad,mm":  # cylinder: angle, axial mm
        lo, hi, unit = np.array([np.degrees(lo[0]), lo[1]]), np.array([np.degrees(hi[0]), hi[1]]), "deg, mm"
    rows += [("inliers", f"{s.n_inliers} of {s.n_points} ({100 * s.inlier_ratio:.1f} %)"),
             ("rms_mm", f"{s.rms_mm:.4f}"), ("max_residual_mm", f"{s.max_residual_mm:.4f}"),
             ("boundary", f"{len(b.outer_uv)} vertices, {len(b.holes_uv)} holes, "
                          f"u {lo[0]:.2f}..{hi[0]:.2f} v {lo[1]:.2f}..{hi[1]:.2f} {unit}")]
    for key, value in rows:
        click.echo(f"{key:<16} {value}")
    if save is not None:
        click.echo(f"{'saved':<16} {save}")
