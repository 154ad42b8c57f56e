"""``camtool batch``: many jobs, each in its own process, on a local pool or Dask."""
import os
import time
from pathlib import Path

import click

from ..console import echo_json, progress_enabled
from .options import TIMEOUT, WORKERS, sigterm_as_interrupt


@click.command("batch")
@click.argument("paths", metavar="JOB_OR_DIR...", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("-o", "--outdir", type=click.Path(path_type=Path), default=Path("out/batch"), show_default=True,
              help="Batch output folder: one sub-folder per job, plus summary.json.")
@click.option("-j", "--jobs", "workers", type=WORKERS, default=None,
              help="Jobs run at once (default: the number of CPUs).")
@click.option("--executor", type=click.Choice(["local", "dask"]), default="local", show_default=True,
              help="local: a process per job on this machine; dask: Dask distributed (pip install 'camtool[dask]').")
@click.option("--scheduler", metavar="ADDRESS", default=None,
              help="Dask scheduler to join, e.g. tcp://10.0.0.5:8786 (default: start a LocalCluster of -j workers).")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="Override a job-file key in every job, e.g. --set raster.step_over_mm=5 (repeatable).")
@click.option("--timeout", type=TIMEOUT, default=None, metavar="S",
              help="Kill a job still running after S seconds and mark it timeout.")
@click.option("--force", is_flag=True, help="Rerun jobs whose inputs are unchanged since their last successful run.")
@click.option("--json", "as_json", is_flag=True, help="Print summary.json to stdout instead of the table.")
def command(paths, outdir: Path, workers, executor: str, scheduler, overrides, timeout, force: bool,
            as_json: bool) -> None:
    """Run every JOB (a job file, or each *.toml in a folder), each in its own process.

    Each job writes into OUTDIR/<job file stem>/ (with camtool.log); a failed
    job never stops the others. OUTDIR/summary.json lists per job its status
    (ok, cached, failed, infeasible, bad_input, unavailable, timeout), exit
    code, reason, wall time, planned points, cycle time and files. A job
    whose inputs, overrides and camtool version are unchanged since its last
    successful run is skipped as cached (--force reruns it).

    Exit codes: 0 every job ok or cached, 3 any job failed, 2 bad input to the
    batch itself (no job found, missing path, bad --set).
    """
    from .. import safe_io
    from ..batch.runner import check_overrides, discover_jobs

    check_overrides(overrides)  # bad input to the batch itself: one line, nothing written
    discover_jobs(paths)
    if scheduler and executor != "dask":
        raise click.UsageError("--scheduler works only with --executor dask")
    if executor == "dask":
        from ..batch.executors import get_executor

        get_executor("dask", workers or os.cpu_count() or 1, scheduler)  # BadInput before anything runs
    # held by its descriptor, checked through it (not / or home, no link or special file below, no foreign files)
    with safe_io.writing_into(outdir), sigterm_as_interrupt():  # one batch per folder; SIGTERM kills the jobs too
        _batch(paths, outdir, workers, executor, scheduler, overrides, timeout, force, as_json)


def _batch(paths, outdir: Path, workers, executor: str, scheduler, overrides, timeout, force: bool,
           as_json: bool) -> None:
    from ..batch import prepare_batch, run_batch, summary_dict, write_summary
    from ..batch.summary import live_progress, summary_table

    t0 = time.perf_counter()
    workers = workers or os.cpu_count() or 1
    specs, decided = prepare_batch(paths, outdir, overrides, timeout, force)
    with live_progress(len(specs) + len(decided), progress_enabled()) as (on_start, on_done):
        for r in decided:
            on_done(r)
        results = run_batch(specs, executor, workers, scheduler, on_start, on_done)
    results = sorted(decided + results, key=lambda r: r.job)
    meta = {"executor": executor, "workers": workers, "scheduler": scheduler, "overrides": list(overrides),
            "timeout_s": timeout, "force": force, "wall_time_s": round(time.perf_counter() - t0, 3)}
    summary = summary_dict(results, outdir, meta)
    file = write_summary(summary, outdir)
    if as_json:
        echo_json(summary)
    else:
        from rich.console import Console

        console = Console(soft_wrap=False)
        console.print(summary_table(summary))
        c = summary["counts"]
        parts = [f"{n} {s}" for s, n in c.items() if n]
        click.echo(f"{', '.join(parts)} in {meta['wall_time_s']:.1f} s; summary: {file}")
    if summary["exit_code"]:
        click.get_current_context().exit(summary["exit_code"])
