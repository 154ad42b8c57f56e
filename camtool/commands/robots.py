"""``camtool robots``: the robot library."""
import click

from ..console import echo_json


@click.command("robots")
@click.option("--json", "as_json", is_flag=True, help="Print JSON for scripts.")
def command(as_json: bool) -> None:
    """List the built-in robots: degrees of freedom, joint types and limits.

    Limits are in degrees (revolute) or mm (prismatic), speeds per second.
    """
    from ..robots import BUILTIN_ROBOTS, get_robot

    robots = [get_robot(n).describe() for n in BUILTIN_ROBOTS]
    if as_json:
        echo_json(robots)
        return
    for r in robots:
        click.echo(f"{r['name']}  ({r['dof']} DOF, {r['convention']} DH)")
        for j in r["joints"]:
            click.echo(f"  {j['name']:<6} {j['type']:<9} {j['lower']:>8.1f} .. {j['upper']:>7.1f} {j['unit']:<3}"
                       f"  v {j['velocity_per_s']:>6.0f}  a {j['acceleration_per_s2']:>6.0f}  j {j['jerk_per_s3']:>6.0f}")
