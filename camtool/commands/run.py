"""``camtool run``: the whole pipeline for one job."""
import time
from pathlib import Path

import click

from ..console import echo_json, progress_enabled
from ..job import load_job
from ..pipeline import run_job

STAGE_NAMES = {"workpiece": "loaded workpiece", "fit": "fitted surface", "raster": "rastered path",
               "plan": "planned joints", "time": "timed trajectory", "post": "wrote programs"}


@click.command("run")
@click.argument("job_file", metavar="JOB", type=click.Path(path_type=Path))
@click.option("-o", "--outdir", type=click.Path(path_type=Path), default=None,
              help="Output folder (default: out/<job file name>).")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="Override a job-file key, e.g. --set raster.step_over_mm=5 (repeatable).")
@click.option("--compare", is_flag=True, help="Also plan with the other method (seed/general) and plot both.")
@click.option("--json", "as_json", is_flag=True, help="Print the run summary (report.json) as JSON.")
def command(job_file: Path, outdir: Path | None, overrides: tuple[str, ...], compare: bool, as_json: bool) -> None:
    """Run JOB end to end: workpiece, fit, raster, plan, time, check, post.

    [task] kind = "raster" (default) rasters the fitted surface; "sequential_reach"
    plans seed 002's target grid by arm-angle SQP; "cartesian" follows seed
    001's line and arc.

    Writes the controller programs of [post] formats, OUTDIR/report.json,
    OUTDIR/points.csv and OUTDIR/plots/. Programs are written only when every
    stage succeeded, the timed trajectory passed the independent limit check
    and every program passed `camtool check`. Exit 3 when the plan cannot be
    done (report.json and plots/unreachable.png say where and why).
    """
    job = load_job(job_file, list(overrides))
    outdir = outdir or Path("out") / job_file.stem
    t0 = time.perf_counter()
    live = progress_enabled() and not as_json

    def on_stage(name, value):
        for warning in getattr(value, "warnings", ()) if name == "workpiece" else ():
            click.echo(f"camtool: warning: {warning}", err=True)
        if live:
            click.echo(f"  {STAGE_NAMES.get(name, name):<18} {time.perf_counter() - t0:6.1f} s", err=True)

    result = run_job(job, outdir, compare=compare, on_stage=on_stage)
    report = result.outputs["report"]
    if as_json:
        echo_json(report)
        return
    click.echo(f"{report['robot']} / {report['method']}: {report['points_work']} work points, "
               f"{report['on_surface_jumps']} on-surface jumps, max work step {report['max_joint_step_work_deg']:.3f} deg, "
               f"{report['reverse_plans']} reverse plans, {report['retracts']} retracts")
    click.echo(f"accuracy: {report['max_position_error_mm']:.2e} mm, {report['max_orientation_error_deg']:.2e} deg;"
               f" cycle time {report['cycle_time_s']:.1f} s; peak speed {100 * report['peak_joint_speed_ratio']:.0f}%"
               f", acc {100 * report['peak_joint_acc_ratio']:.0f}% of limits")
    table = outdir / "arm_angle_families.txt"
    if "arm_angle_sqp" in report and table.exists():
        click.echo(table.read_text().rstrip())
    if "cartesian" in report:
        c = report["cartesian"]
        click.echo("cartesian: " + ", ".join(f"{k} {v}" for k, v in c.items() if not isinstance(v, (list, dict))))
    slow = report.get("slowdowns", [])
    if slow:
        worst = min(s["speed_ratio"] for s in slow)
        ends = sum(1 for s in slow if s.get("at_run_end"))
        click.echo(f"limits slowed the TCP in {len(slow)} stretches ({ends} at run ends), down to "
                   f"{100 * worst:.0f}% of {report['tcp_speed_mm_s']:.0f} mm/s; see slowdowns in report.json")
    for f in result.files:
        click.echo(f"wrote {f}")
