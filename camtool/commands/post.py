"""``camtool post``: the post stage of a job (controller programs from a timed trajectory)."""
from pathlib import Path

import click

from ..console import echo_json
from ..job import load_job


@click.command("post")
@click.argument("job_file", metavar="JOB", type=click.Path(path_type=Path))
@click.option("--from", "from_file", type=click.Path(path_type=Path), default=None, metavar="TRAJECTORY.npz",
              help="Resume from a saved trajectory (`camtool time JOB -o DIR` wrote DIR/trajectory.npz).")
@click.option("--path", "path_file", type=click.Path(path_type=Path), default=None, metavar="PATH.npz",
              help="The Path the trajectory belongs to (default: path.npz beside --from); it names the rows.")
@click.option("-o", "--outdir", type=click.Path(path_type=Path), required=True, help="Folder for the programs.")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="Override a job-file key, e.g. --set post.formats=[\"rapid\"] (repeatable).")
@click.option("--json", "as_json", is_flag=True, help="Print the written files as JSON.")
def command(job_file: Path, from_file: Path | None, path_file: Path | None, outdir: Path, overrides: tuple[str, ...],
            as_json: bool) -> None:
    """Write JOB's controller programs ([post] formats) from its timed trajectory.

    The trajectory passes the independent limit check first and every program
    is read back and checked before it is placed, as in `camtool run`.
    """
    from .. import safe_io
    from ..run.post_inputs import preflight
    from ..run.job_settings import JobSettings
    from ..run.stages import post_checked, robot_for_job
    from .resume import trajectory_of

    job = load_job(job_file, list(overrides))
    robot = robot_for_job(job)
    # held by its descriptor, checked through it: not / or home, no link or special file below, no foreign files
    click.get_current_context().with_resource(safe_io.held_outdir(outdir, check=True))
    preflight(robot, job, outdir)
    settings = JobSettings.from_job(job, robot)
    path, trajectory = trajectory_of(job, settings, robot, from_file, path_file)
    with safe_io.locked(outdir):
        safe_io.check_outdir(outdir)  # again under the lock: nothing planted since
        files = post_checked(trajectory, robot, job, outdir, path=path)
    if as_json:
        echo_json({"job": str(job_file), "programs": [str(f) for f in files]})
        return
    for f in files:
        click.echo(f"wrote {f}")
