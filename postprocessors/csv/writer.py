"""CSV writer: one row per waypoint, ``t_s`` and every joint (see ``postprocessors.csv``)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from camtool.program.text import sanitise_name

from .dialect import columns_for, trailer, validate_profile

BLOCK_ROWS = 20_000   # rows turned to text at a time: a dense job's table as text at once is ~0.4 GB


def write(trajectory, robot, profile, outdir: Path) -> list[Path]:
    """Write ``<NAME>.csv``: t_s and every joint per waypoint."""
    validate_profile(profile, robot)
    unit = profile.options.get("angle_unit", "deg")
    name, _ = sanitise_name(profile.program_name, max_len=64, what="CSV file name")
    q = np.asarray(trajectory.q, float)
    edge = np.where(robot.prismatic[None, :], q, np.degrees(q) if unit == "deg" else q)
    table = np.column_stack([np.asarray(trajectory.t_s, float), edge])
    path = Path(outdir) / f"{name}.csv"
    with open(path, "wb") as f:
        f.write((",".join(columns_for(robot, unit)) + "\n").encode("ascii"))
        for a in range(0, len(table), BLOCK_ROWS):
            # Python's shortest round-trip repr of each float (numpy's astype(str) writes the same text,
            # at half the speed)
            rows = table[a:a + BLOCK_ROWS].tolist()
            f.write(("\n".join(",".join(map(repr, row)) for row in rows) + "\n").encode("ascii"))
        f.write((trailer(len(table)) + "\n").encode("ascii"))
    return [path]
