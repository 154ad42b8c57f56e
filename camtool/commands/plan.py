"""``camtool plan``: the plan stage of a job (joint values for every pose of the path)."""
from pathlib import Path

import click
import numpy as np

from ..console import echo_json
from ..job import load_job
from .resume import JOINT_PATH_FILE, joint_path_of


@click.command("plan")
@click.argument("job_file", metavar="JOB", type=click.Path(path_type=Path))
@click.option("--from", "from_file", type=click.Path(path_type=Path), default=None, metavar="PATH.npz",
              help="Resume from a saved Path (`camtool raster JOB -o DIR` wrote DIR/path.npz).")
@click.option("-o", "--outdir", type=click.Path(path_type=Path), required=True,
              help=f"Folder for {JOINT_PATH_FILE} (and a copy of the Path it belongs to).")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="Override a job-file key, e.g. --set planner.seed=3 (repeatable).")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
def command(job_file: Path, from_file: Path | None, outdir: Path, overrides: tuple[str, ...], as_json: bool) -> None:
    """Plan the joint values of JOB's path with the job's [planner] and save them.

    Writes OUTDIR/joint_path.npz and OUTDIR/path.npz (the Path it plans: with
    raster.lead_auto the leads may be longer than the given Path's), for
    `camtool time JOB --from OUTDIR/joint_path.npz`. Exit 3 when poses are out
    of reach.
    """
    from ..run.job_settings import JobSettings
    from ..run.stage_files import save_stage
    from ..run.stages import robot_for_job

    from .. import safe_io

    job = load_job(job_file, list(overrides))
    click.get_current_context().with_resource(safe_io.writing_into(outdir))  # checked, held and locked as run's
    robot = robot_for_job(job)
    settings = JobSettings.from_job(job, robot)
    path, joint_path = joint_path_of(job, settings, robot, None, from_file)
    # the Path it planned: the given one, or rastered again with longer leads (raster.lead_auto)
    files = [save_stage(joint_path, outdir / JOINT_PATH_FILE), save_stage(path, outdir / "path.npz")]
    ev = joint_path.events
    summary = {"job": str(job_file), "robot": robot.name, "method": settings.planner.method,
               "rows": int(len(joint_path.q)), "reverse_plans": len(ev.get("reverse_plans", [])),
               "retracts": len(ev.get("retracts", [])),
               "max_position_error_mm": float(np.max(joint_path.position_error_mm)),
               "lead_mm": ev.get("leads", {}).get("lead_mm_used", settings.raster.lead_mm),
               "smoothed_runs": len(ev.get("smoothed_runs", [])),
               "plan_seconds": float(ev.get("plan_seconds", 0.0)), "saved": [str(f) for f in files]}
    if as_json:
        echo_json(summary)
        return
    for key, value in summary.items():
        if key != "saved":
            click.echo(f"{key:<22} {value}")
    for f in files:
        click.echo(f"wrote {f}")
