"""CSV writer: one row per waypoint, ``t_s`` and every joint (see ``postprocessors.csv``)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from camtool.program.text import sanitise_name

from .dialect import columns_for, trailer, validate_profile


def write(trajectory, robot, profile, outdir: Path) -> list[Path]:
    """Write ``<NAME>.csv``: t_s and every joint per waypoint."""
    validate_profile(profile, robot)
    unit = profile.options.get("angle_unit", "deg")
    name, _ = sanitise_name(profile.program_name, max_len=64, what="CSV file name")
    q = np.asarray(trajectory.q, float)
    edge = np.where(robot.prismatic[None, :], q, np.degrees(q) if unit == "deg" else q)
    lines = [",".join(columns_for(robot, unit))]
    # numpy's float to text is Python's shortest round-trip repr, for a whole table at once
    table = np.column_stack([np.asarray(trajectory.t_s, float), edge]).astype(str).tolist()
    lines += [",".join(row) for row in table]
    lines.append(trailer(len(lines) - 1))
    path = Path(outdir) / f"{name}.csv"
    path.write_bytes(("\n".join(lines) + "\n").encode("ascii"))
    return [path]
