"""``camtool check``: validate a controller program against a robot."""
from pathlib import Path

import click

from ..console import echo_json
from ..robots import get_robot


@click.command("check")
@click.argument("program", type=click.Path(path_type=Path))
@click.option("--robot", "robot_name", required=True,
              help="Robot the program is for: a built-in name or a .toml/.urdf file.")
@click.option("--profile", "profile_file", type=click.Path(path_type=Path), default=None,
              help="Controller profile (default: the shipped profile for the robot and format).")
@click.option("--format", "fmt", default=None,
              help="Post-processor format (default: from the file extension, see `camtool posts`).")
@click.option("--json", "as_json", is_flag=True,
              help="Print one JSON object: file, format, robot, profile, ok, findings, moves, duration_s.")
def command(program: Path, robot_name: str, profile_file: Path | None, fmt: str | None, as_json: bool) -> None:
    """Check PROGRAM (.pgf/.mod RAPID, .JBI INFORM, .csv, or any installed
    post-processor's files): its structure and completeness (a truncated file
    fails), every value a finite number, every joint value against the robot's
    limits, and every step against the robot's speed limits using the program's
    own timing.

    Exit 0 when clean, 2 with one line per finding otherwise (with --json: the
    JSON object, and the same exit code).
    """
    from postprocessors.base import get_plugin
    from postprocessors.check import check_program, check_summary, format_of, profile_for_check

    robot = get_robot(robot_name)
    fmt = fmt or format_of(program)
    profile = profile_for_check(fmt, get_plugin(fmt), robot, profile_file)
    if as_json:
        summary = check_summary(program, robot, profile, fmt)
        echo_json(summary)
        if not summary["ok"]:
            click.get_current_context().exit(2)
        return
    findings = check_program(program, robot, profile, fmt)
    for f in findings:
        click.echo(f)
    if findings:
        click.get_current_context().exit(2)
    click.echo(f"{program}: ok", err=True)
