"""The batch summary: OUTDIR/summary.json, the exit code, the table and progress."""
from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path

from .. import __version__, safe_io
from ..console import to_json

STATUSES = ("ok", "cached", "failed", "infeasible", "bad_input", "unavailable", "timeout")


def batch_exit_code(results) -> int:
    """0 when every job is ok or cached, else 3 (a plan of the batch failed)."""
    return 0 if all(r.succeeded for r in results) else 3


def summary_dict(results, outdir, meta: dict | None = None) -> dict:
    """summary.json content: counts and one entry per job (sorted by job path);
    file names relative to OUTDIR."""
    outdir = Path(outdir).resolve()
    jobs = []
    for r in sorted(results, key=lambda r: r.job):
        d = r.as_dict()
        folder = Path(d.pop("outdir"))
        rel = folder.relative_to(outdir) if folder.is_relative_to(outdir) else folder
        d["outdir"] = str(rel)
        d["log"] = str(rel / "camtool.log")
        d["files"] = [str(rel / f) for f in r.files]
        jobs.append(d)
    counts = {s: sum(r.status == s for r in results) for s in STATUSES}
    return {"camtool": __version__, **(meta or {}), "exit_code": batch_exit_code(results),
            "jobs_total": len(results), "counts": counts, "jobs": jobs}


def write_summary(summary: dict, outdir) -> Path:
    """Write OUTDIR/summary.json atomically; returns its path."""
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    return safe_io.write_file(outdir, "summary.json", to_json(summary) + "\n")


def summary_table(summary: dict):
    """A rich Table of the jobs of a summary."""
    from rich.table import Table

    style = {"ok": "green", "cached": "cyan", "timeout": "yellow"}
    table = Table(title=f"camtool batch: {summary['jobs_total']} job(s)", title_justify="left")
    for col, just in (("job", "left"), ("status", "left"), ("exit", "right"), ("time s", "right"),
                      ("points", "right"), ("cycle s", "right"), ("reason", "left")):
        table.add_column(col, justify=just, overflow="fold")
    for j in summary["jobs"]:
        table.add_row(j["name"], f"[{style.get(j['status'], 'red')}]{j['status']}[/]", str(j["exit_code"]),
                      f"{j['wall_time_s']:.1f}", "" if j["points"] is None else str(j["points"]),
                      "" if j["cycle_time_s"] is None else f"{j['cycle_time_s']:.1f}", j["reason"])
    return table


@contextmanager
def live_progress(total: int, enabled: bool):
    """A rich progress display on stderr (done / running / failed); yields
    ``(on_start, on_done)`` callbacks, no-ops when not ``enabled``."""
    if not enabled or total == 0:
        yield (lambda spec: None), (lambda result: None)
        return
    import threading

    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    lock = threading.Lock()
    state = {"running": 0, "failed": 0}
    with Progress(TextColumn("batch"), BarColumn(), TextColumn("{task.completed}/{task.total} done"),
                  TextColumn("[blue]{task.fields[running]} running"), TextColumn("[red]{task.fields[failed]} failed"),
                  TimeElapsedColumn(), console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task("batch", total=total, running=0, failed=0)

        def on_start(spec):
            with lock:
                state["running"] += 1
                bar.update(task, running=state["running"])

        def on_done(result):
            with lock:
                state["running"] = max(0, state["running"] - 1)
                state["failed"] += not result.succeeded
                bar.update(task, advance=1, running=state["running"], failed=state["failed"])

        yield on_start, on_done
