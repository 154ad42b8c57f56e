"""``camtool robots``: the robot library, with each robot's source and controller conventions."""
import click

from ..console import echo_json


@click.command("robots")
@click.option("--json", "as_json", is_flag=True, help="Print JSON for scripts.")
def command(as_json: bool) -> None:
    """List the built-in robots: degrees of freedom, joint types and limits, source and controller conventions.

    Limits are in degrees (revolute) or mm (prismatic), speeds per second. Source is
    "paper" (a seed paper's table, to reproduce it) or "manufacturer" (the robot as its
    controller sees it, from the ROS-Industrial description); the controller lines give
    each controller axis as a formula of camtool's joints, its limits, and the
    controller's tool0 and robot frames (docs/robots.md).
    """
    from ..robots import BUILTIN_ROBOTS, get_robot

    robots = [get_robot(n).describe() for n in BUILTIN_ROBOTS]
    if as_json:
        echo_json(robots)
        return
    for r in robots:
        c = r["controller"]
        click.echo(f"{r['name']}  ({r['dof']} DOF, {r['convention']} DH, source: {c['source']})")
        for j in r["joints"]:
            click.echo(f"  {j['name']:<6} {j['type']:<9} {j['lower']:>8.1f} .. {j['upper']:>7.1f} {j['unit']:<3}"
                       f"  v {j['velocity_per_s']:>6.0f}  a {j['acceleration_per_s2']:>6.0f}  j {j['jerk_per_s3']:>6.0f}")
        click.echo(f"  controller: {c['reference']}")
        if c["identity"]:
            names = ", ".join(a["name"] for a in c["axes"])
            click.echo(f"    axes {names} = camtool's joints; tool0 = flange; robot frame = base")
        else:
            for a in c["axes"]:
                click.echo(f"    {a['formula']:<16} {a['lower']:>8.1f} .. {a['upper']:>7.1f} {a['unit']}")
            for key, label, parent in (("tool0_in_flange", "tool0", "flange"),
                                       ("robot_frame_in_base", "robot frame", "base")):
                f = c[key]
                click.echo(f"    {label} in the {parent}: xyz {_vec(f['xyz_mm'])} mm, rpy {_vec(f['rpy_deg'])} deg")
        if c["driver"]:
            click.echo(f"    driver: {c['driver']}")
        if c["urdf"]:
            click.echo(f"    description: {c['urdf']['file']} ({c['urdf']['reference']})")


def _vec(v) -> str:
    return "(" + ", ".join(f"{x:g}" for x in v) + ")"
