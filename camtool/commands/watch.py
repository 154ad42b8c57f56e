"""``camtool watch``: a hot folder; every new job or workpiece file in it is run."""
import os
import threading
from pathlib import Path

import click

from ..console import echo_json
from .options import INTERVAL, TIMEOUT, WORKERS, sigterm_as_interrupt


@click.command("watch")
@click.argument("indir", type=click.Path(path_type=Path))
@click.option("-o", "--outdir", type=click.Path(path_type=Path), default=Path("out/watch"), show_default=True,
              help="Output folder: one sub-folder per file run, plus summary.json.")
@click.option("--template", type=click.Path(path_type=Path), required=True, metavar="JOB",
              help="Job file run for each new workpiece file, with workpiece.file set to it.")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="Override a job-file key in the template and in every job file (repeatable).")
@click.option("-j", "--jobs", "workers", type=WORKERS, default=None,
              help="Jobs run at once (default: the number of CPUs).")
@click.option("--interval", type=INTERVAL, default=2.0, show_default=True,
              metavar="S", help="Seconds between polls; a file is run once unchanged over one interval.")
@click.option("--once", is_flag=True, help="Run what is in INDIR now (once stable) and exit, e.g. from cron.")
@click.option("--max-jobs", type=click.IntRange(min=1), default=None, metavar="N",
              help="Exit after N files were handled.")
@click.option("--timeout", type=TIMEOUT, default=None, metavar="S",
              help="Kill a job still running after S seconds and mark it timeout.")
@click.option("--json", "as_json", is_flag=True, help="Print summary.json to stdout at the end instead of text.")
def command(indir: Path, outdir: Path, template: Path, overrides, workers, interval: float, once: bool,
            max_jobs, timeout, as_json: bool) -> None:
    """Run every new job (*.toml) or workpiece file that appears in INDIR.

    A job file runs as it is (with the --set overrides). A workpiece file (any
    extension the workpiece loader accepts: STL, PLY, OBJ, PCD, XYZ, CSV, ...)
    runs with the --template job, whose workpiece.file is set to the file;
    that job is written to OUTDIR/<file name>/job.toml. A file is taken once
    its size and mtime stayed the same over one --interval. Jobs run as in
    `camtool batch` (own process, camtool.log, caching); OUTDIR/summary.json
    is updated after every round. A failing job never stops the watcher.

    Without --once it polls until Ctrl-C (exit 0) or --max-jobs. Exit codes
    with --once or --max-jobs: 0 every job ok or cached, 3 any job failed;
    2 bad input (INDIR missing, bad template, bad --set) before anything runs.
    """
    from .. import safe_io
    from ..batch.watch import Watcher

    watcher = Watcher.create(indir, outdir, template, overrides, timeout, workers or os.cpu_count() or 1)
    with safe_io.writing_into(watcher.outdir), sigterm_as_interrupt():  # one watcher per folder; SIGTERM kills the jobs
        _watch(watcher, interval, once, max_jobs, as_json)


def _watch(watcher, interval: float, once: bool, max_jobs, as_json: bool) -> None:
    from ..batch.summary import STATUSES, batch_exit_code
    lock = threading.Lock()

    def on_done(r) -> None:
        if as_json:
            return
        reason = f": {r.reason}" if r.reason and not r.succeeded else ""
        with lock:
            click.echo(f"{r.name}: {r.status} ({r.wall_time_s:.1f} s){reason}")

    if not once:
        click.echo(f"camtool watch: watching {watcher.indir} every {interval:g} s; output in {watcher.outdir}"
                   + ("" if max_jobs else "; Ctrl-C to stop"), err=True)
    interrupted = False
    try:
        watcher.watch(interval, once=once, max_jobs=max_jobs, on_done=on_done)
    except KeyboardInterrupt:
        interrupted = True
        watcher.write_summary()
    summary = watcher.summary()
    if as_json:
        echo_json(summary)
    else:
        counts = {s: sum(r.status == s for r in watcher.results) for s in STATUSES}
        done = ", ".join(f"{n} {s}" for s, n in counts.items() if n) or "no job run"
        if watcher.pending:
            done += f"; {len(watcher.pending)} file(s) still changing: " + ", ".join(p.name for p in watcher.pending)
        click.echo(("stopped: " if interrupted else "") + f"{done}; summary: {watcher.outdir / 'summary.json'}")
    code = 0 if interrupted else batch_exit_code(watcher.results)
    if code:
        click.get_current_context().exit(code)
