"""CSV reader: the table of a camtool CSV, and its time and joint columns for a robot."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from camtool.errors import BadInput

from camtool.program.text import column_names

from .dialect import COLUMN_RE


BLOCK_ROWS = 20_000   # rows parsed at a time (see _parse)


def read_bytes(path: Path) -> bytes:
    """The bytes of one CSV file (the reader's only file access)."""
    from camtool.safe_io import read_program_bytes  # regular files under the cap: a FIFO never blocks

    return read_program_bytes(path)


def _read_text(path: Path) -> str:
    try:
        # as text mode reads it: universal newlines
        return read_bytes(path).decode("ascii").replace("\r\n", "\n").replace("\r", "\n")
    except (OSError, UnicodeDecodeError) as exc:
        raise BadInput(f"{path}: cannot read as ASCII CSV ({exc})") from None


def read_table(path: Path) -> tuple[list[str], np.ndarray]:
    """Header and values (file units) of a camtool CSV; BadInput on a malformed file.

    A last line starting with ``#`` (the trailer) is not data; the check, not the
    reader, insists on a complete trailer."""
    path = Path(path)
    return _parse(path, _read_text(path))


def _parse(path: Path, text: str) -> tuple[list[str], np.ndarray]:
    lines = text.splitlines()
    if not lines:
        raise BadInput(f"{path}: empty file")
    if len(lines) > 1 and lines[-1].startswith("#"):
        lines = lines[:-1]
    header = lines[0].split(",")
    body = lines[1:]
    if body and all(line.count(",") == len(header) - 1 for line in body):
        try:  # a block of rows' cells at once (a dense job's at once: ~0.3 GB); a bad cell is found below
            blocks = [np.array(",".join(body[a:a + BLOCK_ROWS]).split(","), dtype=float)
                      for a in range(0, len(body), BLOCK_ROWS)]
            return header, np.concatenate(blocks).reshape(-1, len(header))
        except ValueError:
            pass
    rows = []
    for n, line in enumerate(lines[1:], 2):
        cells = line.split(",")
        if len(cells) != len(header):
            raise BadInput(f"{path}:{n}: {len(cells)} values, the header has {len(header)} columns")
        try:
            rows.append([float(c) for c in cells])
        except ValueError:
            raise BadInput(f"{path}:{n}: values must be numbers") from None
    return header, np.array(rows, dtype=float).reshape(-1, len(header))




def read(path: Path, robot, profile=None) -> tuple[np.ndarray, np.ndarray]:
    """(durations_s, q): the step before each row (NaN for the first) and joint values in
    rad / mm; the unit of each column is taken from its header."""
    t_s, q = read_trajectory(path, robot)
    return np.concatenate([[np.nan], np.diff(t_s)]), q

def read_trajectory(path: Path, robot) -> tuple[np.ndarray, np.ndarray]:
    """(t_s, q in rad / mm) from a camtool CSV; BadInput when the columns do not fit the robot."""
    return columns(path, *read_table(path), robot)

def columns(path, header, data, robot) -> tuple[np.ndarray, np.ndarray]:
    if not header or header[0] != "t_s":
        raise BadInput(f"{path}:1: the first column must be t_s, found {header[0] if header else ''!r}")
    if len(header) != robot.dof + 1:
        raise BadInput(f"{path}:1: {len(header) - 1} joint columns, robot {robot.name} has {robot.dof}")
    q = np.empty((len(data), robot.dof))
    for i, (col, jn, pr) in enumerate(zip(header[1:], column_names(robot.joint_names), robot.prismatic)):
        m = COLUMN_RE.match(col)
        if not m or m.group("joint") != jn:
            raise BadInput(f"{path}:1: column {i + 2} is {col!r}, expected {jn}_<unit>")
        unit = m.group("unit")
        if (unit == "mm") != bool(pr):
            raise BadInput(f"{path}:1: column {col!r}: joint {jn} is "
                           f"{'prismatic (mm)' if pr else 'revolute (deg or rad)'}")
        q[:, i] = np.radians(data[:, i + 1]) if unit == "deg" else data[:, i + 1]
    return data[:, 0], q
