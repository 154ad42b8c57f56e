"""``camtool check``: validate a controller program against a robot."""
from pathlib import Path

import click

from ..robots import get_robot


@click.command("check")
@click.argument("program", type=click.Path(path_type=Path))
@click.option("--robot", "robot_name", required=True,
              help="Robot the program is for: a built-in name or a .toml/.urdf file.")
@click.option("--profile", "profile_file", type=click.Path(path_type=Path), default=None,
              help="Controller profile (default: the shipped profile for the robot and format).")
def command(program: Path, robot_name: str, profile_file: Path | None) -> None:
    """Check PROGRAM (.pgf/.mod RAPID, .JBI INFORM, or .csv): its structure,
    every joint value against the robot's limits, and every step against the
    speed limits using the program's own timing.

    Exit 0 when clean, 2 with one line per finding otherwise.
    """
    from postprocessors.check import check_program, format_of
    from ..profiles import load_profile

    robot = get_robot(robot_name)
    fmt = format_of(program)
    profile = None
    if profile_file is not None or fmt != "csv":
        profile = load_profile(profile_file, robot.name, fmt, robot)
    findings = check_program(program, robot, profile)
    for f in findings:
        click.echo(f)
    if findings:
        click.get_current_context().exit(2)
    click.echo(f"{program}: ok", err=True)
