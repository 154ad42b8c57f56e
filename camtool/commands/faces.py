"""``camtool faces JOB|PART``: split the job's placed workpiece (or a bare part file, in its own frame) into faces,
number them, picture them."""
from pathlib import Path

import click

from ..console import echo_json
from ..job import job_for_part, load_job

PNG_FILE = "faces.png"


@click.command("faces")
@click.argument("job_file", metavar="JOB|PART", type=click.Path(path_type=Path))
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="Override a job-file key, e.g. --set faces.normal_tol_deg=15 (repeatable).")
@click.option("--units", type=click.Choice(["mm", "m", "in"]), default="mm", show_default=True,
              help="Length unit of a PART file (a job file says its own: workpiece.units).")
@click.option("-o", "--outdir", type=click.Path(path_type=Path), default=None,
              help=f"Write the picture OUTDIR/{PNG_FILE} (the points coloured and numbered by face).")
@click.option("--json", "as_json", is_flag=True, help="Print JSON for scripts.")
def command(job_file: Path, overrides: tuple[str, ...], units: str, outdir: Path | None, as_json: bool) -> None:
    """List the faces of a JOB's workpiece (planes, spheres, cylinders, free-form), numbered largest first;
    or of a PART file (mesh, STEP or point cloud, not .toml) in its own frame, with every key at its default.

    The numbers are what [faces] select = [indices] names. Each face: its
    model, area, normal (plane; a free-form face's mean normal) or axis
    (cylinder), radius, centre, inliers and RMS residual (a free-form face's
    curvature range in --json); `selected` marks the faces the job's
    selection takes. Settings: [faces] and fit.threshold_mm, fit.seed
    (docs/faces.md).
    """
    from ..part.step import read_ahead

    is_job = job_file.suffix.lower() == ".toml"
    job = load_job(job_file, list(overrides)) if is_job else job_for_part(job_file, units, list(overrides))
    step = job.resolve(job.workpiece.file)
    if step.suffix.lower() in (".step", ".stp"):
        read_ahead(step)   # OpenCASCADE reads and tessellates it in a child while the segmentation is imported
    from ..part.faces import faces_png, segment_faces, select_faces   # heavy: only when the command runs
    from ..run.part_stages import faces_settings
    from ..run.part_stages import workpiece_for_job

    wp = workpiece_for_job(job)
    for w in wp.warnings:
        click.echo(f"camtool: warning: {w}", err=True)
    faces = faces_settings(job)
    seg = segment_faces(faces, wp)
    chosen = set()
    if faces.segmented:
        chosen = {f.index for f in select_faces(seg, faces.select, wp, faces.source)}
    rows = [{**f.summary(), "selected": f.index in chosen} for f in seg.faces]
    png = faces_png(seg, wp, outdir / PNG_FILE, title=f"{job_file.name}: {len(seg.faces)} faces") \
        if outdir is not None else None
    if as_json:
        echo_json({"faces": rows, "n_points": seg.n_points, "unassigned": seg.unassigned,
                   "dropped_small_faces": seg.dropped_faces, "image": None if png is None else str(png)})
        return
    click.echo(f"{'face':>4} {'model':<15} {'area_mm2':>11} {'radius_mm':>10} {'normal / axis':<26} "
               f"{'center_mm':<28} {'inliers':>8} {'rms_mm':>7}")
    for r in rows:
        direction = r.get("normal") or r.get("axis") or []
        d = " ".join(f"{x:+.3f}" for x in direction)
        c = " ".join(f"{x:.1f}" for x in r["center_mm"])
        radius = "" if r["radius_mm"] is None else f"{r['radius_mm']:.3f}"
        side = " inside" if r.get("concave") else ""
        mark = " *" if r["selected"] else ""
        click.echo(f"{r['index']:>4} {r['model'] + side:<15} {r['area_mm2']:>11.1f} {radius:>10} {d:<26} {c:<28} "
                   f"{r['inliers']:>8} {r['rms_mm']:>7.4f}{mark}")
    click.echo(f"{seg.unassigned} of {seg.n_points} points on no face; {seg.dropped_faces} small face(s) "
               f"{'merged' if job.faces.small_faces == 'merge' else 'dropped'}"
               + ("; * = selected by faces.select" if chosen else ""))
    if png is not None:
        click.echo(f"wrote {png}")
