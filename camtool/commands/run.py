"""``camtool run``: the whole pipeline for one job."""
from contextlib import nullcontext
from pathlib import Path

import click

from ..console import StageProgress, echo_json
from ..job import load_job


@click.command("run")
@click.argument("job_file", metavar="JOB", type=click.Path(path_type=Path))
@click.option("-o", "--outdir", type=click.Path(path_type=Path), default=None,
              help="Output folder (default: out/<job file name>).")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="Override a job-file key, e.g. --set raster.step_over_mm=5 (repeatable).")
@click.option("--compare", is_flag=True, help="Also plan with the other method (seed/general) and plot both.")
@click.option("--json", "as_json", is_flag=True, help="Print the run summary (report.json) as JSON.")
@click.option("--allow-partial", is_flag=True, help="When some poses are out of reach, program the reachable "
              "stretches of the rows and report the coverage (task.allow_partial = true).")
@click.option("--progress", "log_stages", is_flag=True,
              help="Off a terminal too: one line on stderr per finished stage (batch jobs log it).")
@click.option("-q", "--quiet", is_flag=True, help="No progress on stderr (a status line on a terminal, one line "
                                                  "per finished stage with --progress; --json implies it).")
def command(job_file: Path, outdir: Path | None, overrides: tuple[str, ...], compare: bool, as_json: bool,
            allow_partial: bool, log_stages: bool, quiet: bool) -> None:
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
    from ..run.part_stages import PartAhead

    job = load_job(job_file, list(overrides) + (["task.allow_partial=true"] if allow_partial else []))
    # the workpiece is read and fitted in a process of its own while this one imports the pipeline
    part = PartAhead(job) if job.task.kind in ("raster", "sequential_reach") else None
    outdir = outdir or Path("out") / job_file.stem
    # scripts read --json: no progress with it unless asked for (--progress, as batch jobs do for their log)
    progress = StageProgress(quiet=quiet or (as_json and not log_stages), log=log_stages)

    shown: set[str] = set()   # a re-plan passes the workpiece and its fit again: each warning is one line

    def on_stage(name, value):
        for warning in getattr(value, "warnings", ()) if name in ("workpiece", "fit") else ():
            if warning not in shown:
                shown.add(warning)
                click.echo(f"camtool: warning: {warning}", err=True)
        progress.done(name)

    with part if part is not None else nullcontext():
        from ..run.pipeline import run_job

        try:
            result = run_job(job, outdir, compare=compare, on_stage=on_stage, part=part)
        finally:
            progress.close()
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
    if "arm_angle_sqp" in report:  # read once, no link followed, never a FIFO swapped in after the run
        from .. import safe_io
        from ..errors import BadInput

        try:
            text = safe_io.read_input_bytes(outdir / "arm_angle_families.txt", "text", follow=False)
            click.echo(text.decode(errors="replace").rstrip())
        except BadInput:
            pass
    if "cartesian" in report:
        c = report["cartesian"]
        click.echo("cartesian: " + ", ".join(f"{k} {v}" for k, v in c.items() if not isinstance(v, (list, dict))))
    feed = report.get("work_feed")
    if feed and feed.get("work_length_mm"):
        leads = report.get("leads", {})
        sized = (f"; leads lengthened from {leads['lead_mm_set']:g} to {leads['lead_mm_used']:g} mm for the ramps"
                 if leads.get("lead_mm_used", 0) > leads.get("lead_mm_set", 0) else "")
        click.echo(f"feed on work: {100 * feed['work_share_within_1pct']:.1f}% of {feed['work_length_mm'] / 1000:.1f} m "
                   f"within 1% of {feed['commanded_feed_mm_s']:g} mm/s, min {feed['min_work_feed_mm_s']:.1f} mm/s{sized}")
    part = report.get("partial")
    if part:   # --allow-partial: how much was programmed, and what was left out where the motion check failed
        left = part.get("check_left_out")
        click.echo(f"partial: {part['work_poses_kept']} of {part['work_poses_total']} work poses programmed "
                   f"({part['work_kept_pct']:.1f}%) in {part['stretches']} stretches"
                   + (f"; {left['summary']}" if left else ""))
    for w in report.get("faces", {}).get("worked", []):  # a job of several faces: each one, in working order
        wf = w.get("work_feed") or {}
        mc = w.get("motion_check") or {}
        checked = (f", deviation {mc['work_deviation_mm']:.3f} mm" if mc.get("work_deviation_mm") is not None else "") + (
            f", clearance {mc['min_clearance_mm']:.1f} mm" if mc.get("min_clearance_mm") is not None else "")
        contour = f" + {w['contour_runs']} contour runs" if w.get("contour_runs") else ""
        click.echo(f"face {w['index']} ({w['model']}): {w['rows']} rows{contour}, {w['work_points']} work points, coverage "
                   f"{100 * (w['coverage'] or 0.0):.2f}%, feed {100 * wf.get('work_share_within_1pct', 0.0):.1f}% "
                   f"within 1%{checked}")
    slow = report.get("slowdowns", [])
    if slow:
        worst = min(s["speed_ratio"] for s in slow)
        ends = sum(1 for s in slow if s.get("at_run_end"))
        click.echo(f"limits slowed the TCP in {len(slow)} stretches ({ends} at run ends), down to "
                   f"{100 * worst:.0f}% of {report['tcp_speed_mm_s']:.0f} mm/s; see slowdowns in report.json")
    short = report.get("short_leads", [])
    if short:
        click.echo(f"{len(short)} speed ramps do not fit their leads (need up to "
                   f"{max(s['needed_mm'] for s in short):.1f} mm; raster.lead_mm, raster.lead_max_mm); "
                   f"see short_leads in report.json")
    for f in result.files:
        click.echo(f"wrote {f}")
