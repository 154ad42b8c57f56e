"""``camtool run``: the whole pipeline for one job."""
from pathlib import Path

import click

from ..console import echo_json
from ..job import load_job
from ..pipeline import run_job


@click.command("run")
@click.argument("job_file", metavar="JOB", type=click.Path(path_type=Path))
@click.option("-o", "--outdir", type=click.Path(path_type=Path), default=None,
              help="Output folder (default: out/<job name> beside the current folder).")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="Override a job-file key, e.g. --set raster.step_over_mm=5 (repeatable).")
@click.option("--json", "as_json", is_flag=True, help="Print the run summary as JSON.")
def command(job_file: Path, outdir: Path | None, overrides: tuple[str, ...], as_json: bool) -> None:
    """Run JOB end to end: workpiece, fit, raster, plan, time, check, post.

    Programs are written only when every stage succeeded and every program
    passed the checker. Exit 3 when the plan cannot be done (the report says
    where and why), 4 when a stage is not available yet.
    """
    job = load_job(job_file, list(overrides))
    outdir = outdir or Path("out") / job_file.stem
    result = run_job(job, outdir)
    summary = {"job": str(job_file), "outdir": str(outdir), "stages": result.stages,
               "files": [str(f) for f in result.files]}
    if as_json:
        echo_json(summary)
    else:
        for f in result.files:
            click.echo(f"wrote {f}")
