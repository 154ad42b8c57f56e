"""``camtool check``: validate a controller program against a robot, and optionally run it."""
from pathlib import Path

import click

from ..console import echo_json


def _simulation(program: Path, robot, profile, fmt: str, against: Path | None, job, path_tol: float | None):
    """(report, None) of simulating PROGRAM, or (None, reason) when its plugin cannot."""
    from ..errors import BadInput
    from ..program.registry import get_plugin
    from ..simulate import reference_from_samples, reference_from_trajectory, simulate

    plugin = get_plugin(fmt)
    if not plugin.simulated:
        return None, f"post-processor {fmt!r} cannot be simulated (it has no read_program)"
    prog = plugin.read_program(program, robot, profile)
    feed = None if job is None else job.process.feed_mm_s
    reference = None
    if against is not None:
        if not Path(against).is_file():
            raise BadInput(f"{against}: planned path file not found")
        if Path(against).suffix.lower() == ".npz":
            from ..run.stage_files import load_stage

            box = load_stage(against, expect=("Trajectory", "TimedTrajectory"))
            reference = reference_from_trajectory(box, robot, feed)
        else:
            t_s, q = get_plugin("csv").read_trajectory(Path(against), robot)
            reference = reference_from_samples(t_s, q, robot, feed)
    world = None if job is None else job.world()   # --job: the program against the job's cell too
    return simulate(prog, robot, reference, path_tol_mm=path_tol, profile=profile, world=world), None


class _JobPost:
    """What ``check --job`` takes from a job: its post settings, process facts (feed,
    tolerance), its cell and the profile of the checked format."""

    def __init__(self, raw_job, robot):
        from ..run.post_inputs import process_for_job
        from ..settings import PostSettings

        self._job, self._robot = raw_job, robot
        self.settings = PostSettings.from_section(raw_job.post)
        self.process = process_for_job(raw_job, self.settings)

    def world(self):
        """The job's collision world (obstacles, floor, the robot's own links)."""
        from ..collision.stage import collision_world
        from ..run.job_settings import JobSettings

        return collision_world(JobSettings.from_job(self._job, self._robot), self._robot)

    def profile(self, fmt: str):
        from ..run.post_inputs import profile_for_job
        from ..program.registry import get_plugin

        return profile_for_job(fmt, get_plugin(fmt), self._robot, self._job, self.settings)


@click.command("check")
@click.argument("program", type=click.Path(path_type=Path))
@click.option("--robot", "robot_name", default=None,
              help="Robot the program is for: a built-in name or a .toml/.urdf file (default: the --job's).")
@click.option("--profile", "profile_file", type=click.Path(path_type=Path), default=None,
              help="Controller profile (default: the shipped profile for the robot and format).")
@click.option("--format", "fmt", default=None,
              help="Post-processor format (default: from the file extension, see `camtool posts`).")
@click.option("--simulate", "run_sim", is_flag=True,
              help="Also re-execute the program as the controller interpolates it (at 4 ms) and report "
                   "deviation, feed, exact stops and module/job switches on the surface, and limit violations.")
@click.option("--against", type=click.Path(path_type=Path), default=None, metavar="PLAN",
              help="With --simulate: the planned path to measure against, a trajectory.npz (`camtool time`) "
                   "or the run's CSV program.")
@click.option("--job", "job_file", type=click.Path(path_type=Path), default=None,
              help="The job the program was written for: its robot placement and tool, post.path_tol_mm, "
                   "feed and cell (for --simulate: the simulated motion against its obstacles, floor and "
                   "the robot's own links).")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object: file, format, robot, profile, ok, findings, moves, duration_s "
                   "(and simulation).")
def command(program: Path, robot_name: str | None, profile_file: Path | None, fmt: str | None, run_sim: bool,
            against: Path | None, job_file: Path | None, as_json: bool) -> None:
    """Check PROGRAM (.pgf/.mod RAPID, .JBI INFORM, .csv, or any installed
    post-processor's files): its structure and completeness (a truncated file
    fails), every value a finite number, every joint value against the robot's
    limits, and every step against the robot's speed limits using the program's
    own timing.

    With --simulate, the program is also re-executed the way the controller
    interpolates it; with --against PLAN the simulated TCP is measured against
    the planned path (the job's post.path_tol_mm, or 0.1 mm, is the tolerance);
    with --job, every robot and tool body is measured against the job's cell on
    the simulated motion (no pair may touch).

    Exit 0 when clean, 2 with one line per finding otherwise (with --json: the
    JSON object, and the same exit code).
    """
    from ..robots import get_robot
    from ..errors import BadInput
    from ..program.check_program import check_program, check_summary, format_of, profile_for_check
    from ..program.registry import get_plugin

    job = None  # what the post stage takes from the job (settings, process facts, profiles)
    if job_file is not None:
        from ..job import load_job
        from ..run.stages import robot_for_job

        raw_job = load_job(job_file, [])
        robot = robot_for_job(raw_job)
        if robot_name is not None and get_robot(robot_name).name != robot.name:
            raise BadInput(f"--robot {robot_name} is not the job's robot {robot.name}")
        job = _JobPost(raw_job, robot)
    elif robot_name is None:
        raise BadInput("give the robot: --robot NAME, or --job JOB")
    else:
        robot = get_robot(robot_name)
    fmt = fmt or format_of(program)
    profile = profile_for_check(fmt, get_plugin(fmt), robot, profile_file)
    if job is not None and profile_file is None:
        profile = job.profile(fmt)
    summary = check_summary(program, robot, profile, fmt) if as_json else None
    findings = summary["findings"] if as_json else check_program(program, robot, profile, fmt)
    sim_out, lines = None, []
    if run_sim and not findings:
        from ..program.process import DEFAULT_PATH_TOL_MM
        from ..simulate import summary_lines

        tol = job.process.path_tol_mm if job is not None else DEFAULT_PATH_TOL_MM
        rep, why = _simulation(program, robot, profile, fmt, against, job, tol)
        if rep is None:
            findings = findings + [f"{program}: {why}"]
        else:
            findings = findings + rep.findings
            sim_out = rep.as_dict()
            sim_out.pop("findings")
            sim_out["path_tol_mm"] = tol if against is not None else None
            lines = summary_lines(rep)
    if as_json:
        summary["findings"] = findings
        summary["ok"] = not findings
        if run_sim:
            summary["simulation"] = sim_out
        echo_json(summary)
        if findings:
            click.get_current_context().exit(2)
        return
    for f in findings:
        click.echo(f)
    for ln in lines:
        click.echo(ln, err=True)
    if findings:
        click.get_current_context().exit(2)
    click.echo(f"{program}: ok", err=True)
