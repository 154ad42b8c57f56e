"""``camtool fk``: forward kinematics of a robot at given joint values."""
import click
import numpy as np

from ..console import echo_json
from ..errors import BadInput


@click.command("fk", context_settings={"ignore_unknown_options": True})
@click.argument("robot")
@click.argument("q", nargs=-1, required=True)
@click.option("--deg", is_flag=True, help="Revolute values are in degrees (default: radians). Prismatic values are always mm.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON for scripts.")
def command(robot: str, q: tuple[str, ...], deg: bool, as_json: bool) -> None:
    """Flange pose of ROBOT at joint values Q... (one per joint).

    Prints the position in mm and the orientation as a unit quaternion w, x, y, z
    in the robot base frame.
    """
    from ..robots import get_robot
    from ..transforms import quaternion_wxyz_from_matrix

    r = get_robot(robot)
    try:
        values = np.array([float(x) for x in q])
    except ValueError:
        raise BadInput(f"joint values must be numbers, got {' '.join(q)}") from None
    if len(values) != r.dof:
        raise BadInput(f"{r.name} has {r.dof} joints ({', '.join(r.joint_names)}); got {len(values)} values")
    if not np.all(np.isfinite(values)) or np.any(np.abs(values) > 1e6):
        raise BadInput(f"joint values must be finite numbers within +-1e6, got {' '.join(q)}")
    if deg:
        values = r.q_from_edge(values)
    T = r.fk(values)
    pos = np.round(T[:3, 3], 6) + 0.0
    quat = np.round(quaternion_wxyz_from_matrix(T[:3, :3]), 9) + 0.0
    if as_json:
        echo_json({"robot": r.name, "position_mm": pos, "quaternion_wxyz": quat,
                   "within_limits": r.within_limits(values)})
        return
    click.echo(f"position_mm      {pos[0]:.3f} {pos[1]:.3f} {pos[2]:.3f}")
    click.echo(f"quaternion_wxyz  {quat[0]:.6f} {quat[1]:.6f} {quat[2]:.6f} {quat[3]:.6f}")
    if not r.within_limits(values):
        click.echo("warning: the configuration is outside the joint limits", err=True)
