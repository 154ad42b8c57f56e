"""``camtool time``: the timing stage of a job (a timed trajectory within every joint limit)."""
from pathlib import Path

import click

from ..console import echo_json
from ..job import load_job
from .resume import TRAJECTORY_FILE, joint_path_of


@click.command("time")
@click.argument("job_file", metavar="JOB", type=click.Path(path_type=Path))
@click.option("--from", "from_file", type=click.Path(path_type=Path), default=None, metavar="JOINT_PATH.npz",
              help="Resume from a saved JointPath (`camtool plan JOB -o DIR` wrote DIR/joint_path.npz).")
@click.option("--path", "path_file", type=click.Path(path_type=Path), default=None, metavar="PATH.npz",
              help="The Path the joint path belongs to (default: path.npz beside --from).")
@click.option("-o", "--outdir", type=click.Path(path_type=Path), required=True,
              help=f"Folder for {TRAJECTORY_FILE}.")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="Override a job-file key, e.g. --set timing.method=ruckig (repeatable).")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
def command(job_file: Path, from_file: Path | None, path_file: Path | None, outdir: Path,
            overrides: tuple[str, ...], as_json: bool) -> None:
    """Time JOB's joint path with the job's [timing] and save the trajectory.

    Writes OUTDIR/trajectory.npz for `camtool post JOB --from OUTDIR/trajectory.npz`.
    """
    from ..run.job_settings import JobSettings
    from ..run.stage_files import save_stage
    from ..run.stages import robot_for_job, time_for_job
    from ..timing.pathlaw import remembered_runs

    from .. import safe_io

    job = load_job(job_file, list(overrides))
    click.get_current_context().with_resource(safe_io.writing_into(outdir))  # checked, held and locked as run's
    robot = robot_for_job(job)
    settings = JobSettings.from_job(job, robot)
    with remembered_runs():   # planned now: lead sizing's run time laws are the timing's
        path, joint_path = joint_path_of(job, settings, robot, from_file, path_file)
        trajectory = time_for_job(settings, joint_path, path, robot)
    saved = save_stage(trajectory, outdir / TRAJECTORY_FILE)
    summary = {"job": str(job_file), "robot": robot.name, "timing_method": settings.timing.method,
               "cycle_time_s": trajectory.duration_s, "waypoints": int(len(trajectory.t_s)), "saved": str(saved)}
    if as_json:
        echo_json(summary)
        return
    click.echo(f"cycle time  {trajectory.duration_s:.3f} s ({len(trajectory.t_s)} waypoints, "
               f"{settings.timing.method})")
    click.echo(f"wrote {saved}")
