"""CSV: the columns (``t_s``, ``<joint>_<unit>``), the trailer, the plugin's options and the
check of a profile."""
from __future__ import annotations

import re

from camtool.errors import BadInput
from camtool.program.text import column_names

COLUMN_RE = re.compile(r"^(?P<joint>.+)_(?P<unit>mm|deg|rad)$")
TRAILER_RE = re.compile(r"^# END (?P<rows>[0-9]+) rows$")


def trailer(n_rows: int) -> str:
    """The last line of a camtool CSV: the number of data rows above it."""
    return f"# END {n_rows} rows"


def columns_for(robot, angle_unit: str) -> list[str]:
    """The header for a robot: t_s then <joint>_<unit>."""
    names = column_names(robot.joint_names)  # identifiers: a joint name never becomes a spreadsheet formula
    return ["t_s"] + [f"{n}_{'mm' if p else angle_unit}" for n, p in zip(names, robot.prismatic)]


OPTIONS = {
    "angle_unit": (str, "deg", "Unit of revolute joints: deg or rad (the job's post.csv_angle_unit sets it)."),
}


def validate_profile(profile, robot) -> None:
    """BadInput on an angle unit other than deg or rad."""
    if profile.options.get("angle_unit", "deg") not in ("deg", "rad"):
        raise BadInput(f"{profile.source}: options.angle_unit: expected 'deg' or 'rad', "
                       f"found {profile.options['angle_unit']!r}")
