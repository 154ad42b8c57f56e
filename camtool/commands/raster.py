"""``camtool raster``: the raster stage of a job (workpiece, fit, raster)."""
from pathlib import Path

import click
import numpy as np

from ..console import echo_json
from ..errors import BadInput
from ..job import load_job
from .. import safe_io

PATH_FILE = "path.npz"

ZONE_COLOURS = {"work": "tab:blue", "self_motion": "tab:orange", "lead_in": "tab:green",
                "lead_out": "tab:red", "approach": "tab:purple", "depart": "tab:brown", "retract": "black"}


@click.command("raster")
@click.argument("job_file", metavar="JOB", type=click.Path(path_type=Path))
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="Override a job-file key, e.g. --set raster.step_over_mm=5 (repeatable).")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@click.option("--plot", "plot_file", type=click.Path(path_type=Path), default=None, metavar="FILE.png",
              help="Write a PNG: the path in 3D on the surface, zones coloured, and the (u, v) map.")
@click.option("--save", "save_file", type=click.Path(path_type=Path), default=None, metavar="PATH.npz",
              help="Save the Path (.npz) for later stages.")
@click.option("--from", "from_file", type=click.Path(path_type=Path), default=None, metavar="SURFACE.json",
              help="Resume from a saved surface (`camtool fit JOB -o DIR` wrote DIR/surface.json) instead of "
                   "fitting again.")
@click.option("-o", "--outdir", type=click.Path(path_type=Path), default=None,
              help=f"Save the Path as OUTDIR/{PATH_FILE}, for `camtool plan JOB --from`.")
def command(job_file: Path, overrides: tuple[str, ...], as_json: bool, plot_file: Path | None,
            save_file: Path | None, from_file: Path | None, outdir: Path | None) -> None:
    """Raster the surface of JOB into an S-path with segments and self-motion zones.

    Loads and fits the workpiece as the job says, then prints rows, segments,
    work points, zone points, path length (mm) and coverage (the share of the
    surface within half the diagonal of a pitch x step-over cell, plus 2 % of
    the step-over, of a work point).
    """
    from ..report.faces import path_figures
    from ..run.stage_files import save_stage
    from ..run.stages import path_for_job, surface_for_job, workpiece_for_job
    from ..part.surface import load_surface

    for f, ext in ((plot_file, ".png"), (save_file, ".npz")):
        if f is not None and f.suffix.lower() != ext:
            raise BadInput(f"{f}: expected a {ext} file name")
    job = load_job(job_file, list(overrides))
    from .. import safe_io

    workpiece = None
    if from_file is not None:
        surface = load_surface(from_file)
    else:
        workpiece = workpiece_for_job(job)
        for w in workpiece.warnings:
            click.echo(f"camtool: warning: {w}", err=True)
        surface = surface_for_job(job, workpiece)
    path = path_for_job(job, surface, workpiece)
    summary = {"job": str(job_file), "surface": surface.model, **path_figures(path, surface)}
    click.get_current_context().with_resource(safe_io.writing_into(outdir))  # checked, held and locked as run's
    if outdir is not None:
        save_file = save_file or outdir / PATH_FILE
    if save_file is not None:
        save_stage(path, save_file)
        summary["saved"] = str(save_file)
    if plot_file is not None:
        plot_raster(surface, path, plot_file, title=f"{job_file.name}: {summary['work_points']} work points")
        summary["plot"] = str(plot_file)
    if as_json:
        echo_json(summary)
        return
    click.echo(f"surface          {surface.model}")
    click.echo(f"rows             {summary['rows']}")
    if summary.get("contour_runs"):
        click.echo(f"contour runs     {summary['contour_runs']}  (raster.contour: along the edges, after the rows)")
    click.echo(f"segments         {summary['segments']}")
    click.echo(f"work points      {summary['work_points']}")
    zones = ", ".join(f"{k} {v}" for k, v in summary["zone_counts"].items())
    click.echo(f"zone points      {summary['zone_points']}  ({zones})")
    click.echo(f"path length mm   {summary['path_length_mm']:.1f}  (work {summary['work_length_mm']:.1f})")
    click.echo(f"coverage         {100 * summary['coverage']:.2f} %")
    for key in ("saved", "plot"):
        if key in summary:
            click.echo(f"wrote {summary[key]}")


def plot_raster(surface, path, file: Path, title: str = "") -> None:
    """PNG of the path in 3D over the surface (zones coloured) beside the (u, v) map."""
    from ..files import output_file
    from ..path.toolpath import ZONES

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sphere = surface.model == "sphere"
    to_plot = np.degrees if sphere else (lambda a: a)
    unit = "deg" if sphere else "mm"
    lo, hi = surface.boundary.bounds()
    fig = plt.figure(figsize=(13, 6))
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    U, V = np.meshgrid(np.linspace(lo[0], hi[0], 30), np.linspace(lo[1], hi[1], 30))
    S = surface.point_mm(U, V)
    ax3.plot_surface(S[..., 0], S[..., 1], S[..., 2], color="0.85", alpha=0.35, linewidth=0)
    p = path.poses_mm[:, :3, 3]
    ax3.plot(p[:, 0], p[:, 1], p[:, 2], color="0.4", linewidth=0.3)
    ax2 = fig.add_subplot(1, 2, 2)
    uv = to_plot(surface.uv_from_points(p))
    for code, name in enumerate(ZONES):
        sel = path.zone == code
        if sel.any():
            size = 0.6 if name == "work" else 3
            ax3.scatter(p[sel, 0], p[sel, 1], p[sel, 2], s=size, color=ZONE_COLOURS[name], label=name)
            ax2.scatter(uv[sel, 0], uv[sel, 1], s=size, color=ZONE_COLOURS[name], label=name)
    ax3.set_xlabel("x mm")
    ax3.set_ylabel("y mm")
    ax3.set_zlabel("z mm")
    ax3.set_aspect("equal")
    n = -path.poses_mm[path.is_work, :3, 2].mean(axis=0)  # look at the surface from its outside
    ax3.view_init(elev=float(np.degrees(np.arcsin(np.clip(n[2], -1, 1)))) + 20,
                  azim=float(np.degrees(np.arctan2(n[1], n[0]))) - 35)
    ax3.legend(loc="upper left", fontsize=7, markerscale=4)
    for k, poly in enumerate((surface.boundary.outer_uv, *surface.boundary.holes_uv)):
        closed = to_plot(np.vstack([poly, poly[:1]]))
        ax2.plot(closed[:, 0], closed[:, 1], color="black", linewidth=1.2, label="boundary" if k == 0 else None)
    ax2.plot(uv[:, 0], uv[:, 1], color="0.4", linewidth=0.3)
    ax2.set_xlabel(f"u ({'azimuth, ' if sphere else ''}{unit})")
    ax2.set_ylabel(f"v ({'elevation, ' if sphere else ''}{unit})")
    ax2.set_aspect("equal" if not sphere else "auto")
    ax2.set_title("(u, v) domain")
    fig.suptitle(title)
    fig.tight_layout()
    safe_io.save_figure(fig, output_file(file), dpi=110)
    plt.close(fig)
