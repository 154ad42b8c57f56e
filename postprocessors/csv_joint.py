"""CSV post-processor: one row per waypoint, a time column and one column per joint.

Header: ``t_s`` then ``<joint>_<unit>`` with unit ``mm`` for prismatic joints
and ``deg`` or ``rad`` (option ``angle_unit``) for revolute ones, e.g.
``t_s,track_mm,j2_deg,...``. Numbers are written with Python's shortest
round-trip ``repr``, so a reader gets back exactly the floats that were written.
The last line is the trailer ``# END <rows> rows``: a file cut anywhere, even at
a row boundary, has no complete trailer or the wrong count, and fails the check.
(``#`` starts a comment for numpy's ``loadtxt`` and pandas' ``comment="#"``.)
LF line ends, ASCII.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from camtool.errors import BadInput

from .base import sanitise_name
from .check import MAX_PER_KIND, check_motion

COLUMN_RE = re.compile(r"^(?P<joint>.+)_(?P<unit>mm|deg|rad)$")
TRAILER_RE = re.compile(r"^# END (?P<rows>[0-9]+) rows$")


def trailer(n_rows: int) -> str:
    """The last line of a camtool CSV: the number of data rows above it."""
    return f"# END {n_rows} rows"


def _read_text(path: Path) -> str:
    try:
        return path.read_text(encoding="ascii")
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
        try:  # every cell at once; a bad cell is found line by line below
            cells = ",".join(body).split(",")
            return header, np.array(cells, dtype=float).reshape(-1, len(header))
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


def columns_for(robot, angle_unit: str) -> list[str]:
    """The header for a robot: t_s then <joint>_<unit>."""
    return ["t_s"] + [f"{n}_{'mm' if p else angle_unit}" for n, p in zip(robot.joint_names, robot.prismatic)]


class CsvPost:
    """CSV writer and reader (see module doc)."""

    name = "csv"
    extension = ".csv"
    extensions = (".csv",)
    requires_profile = False
    options_schema = {
        "angle_unit": (str, "deg", "Unit of revolute joints: deg or rad (the job's post.csv_angle_unit sets it)."),
    }

    @staticmethod
    def job_options(job) -> dict:
        """Options set by job keys: ``post.csv_angle_unit`` is the angle unit."""
        return {"angle_unit": job.post.csv_angle_unit}

    def validate_profile(self, profile, robot) -> None:
        """BadInput on an angle unit other than deg or rad."""
        if profile.options.get("angle_unit", "deg") not in ("deg", "rad"):
            raise BadInput(f"{profile.source}: options.angle_unit: expected 'deg' or 'rad', "
                           f"found {profile.options['angle_unit']!r}")

    def write(self, trajectory, robot, profile, outdir: Path) -> list[Path]:
        """Write ``<NAME>.csv``: t_s and every joint per waypoint."""
        self.validate_profile(profile, robot)
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

    def read(self, path: Path, robot, profile=None) -> tuple[np.ndarray, np.ndarray]:
        """(durations_s, q): the step before each row (NaN for the first) and joint values in
        rad / mm; the unit of each column is taken from its header."""
        t_s, q = self.read_trajectory(path, robot)
        return np.concatenate([[np.nan], np.diff(t_s)]), q

    def read_trajectory(self, path: Path, robot) -> tuple[np.ndarray, np.ndarray]:
        """(t_s, q in rad / mm) from a camtool CSV; BadInput when the columns do not fit the robot."""
        return self._columns(path, *read_table(path), robot)

    def _columns(self, path, header, data, robot) -> tuple[np.ndarray, np.ndarray]:
        if not header or header[0] != "t_s":
            raise BadInput(f"{path}:1: the first column must be t_s, found {header[0] if header else ''!r}")
        if len(header) != robot.dof + 1:
            raise BadInput(f"{path}:1: {len(header) - 1} joint columns, robot {robot.name} has {robot.dof}")
        q = np.empty((len(data), robot.dof))
        for i, (col, jn, pr) in enumerate(zip(header[1:], robot.joint_names, robot.prismatic)):
            m = COLUMN_RE.match(col)
            if not m or m.group("joint") != jn:
                raise BadInput(f"{path}:1: column {i + 2} is {col!r}, expected {jn}_<unit>")
            unit = m.group("unit")
            if (unit == "mm") != bool(pr):
                raise BadInput(f"{path}:1: column {col!r}: joint {jn} is "
                               f"{'prismatic (mm)' if pr else 'revolute (deg or rad)'}")
            q[:, i] = np.radians(data[:, i + 1]) if unit == "deg" else data[:, i + 1]
        return data[:, 0], q

    def check(self, path: Path, robot, profile=None) -> list[str]:
        """Findings for a CSV: a complete trailer whose row count matches (so a file cut
        anywhere fails), the header against the robot, one number per column, every value
        a finite number; then every value against the robot's limits and every step's
        speed (from ``t_s``) against its speed limits (tolerance 1e-9)."""
        path = Path(path)
        try:
            text = _read_text(path)
            t_s, q = self._columns(path, *_parse(path, text), robot)
        except BadInput as exc:
            return [str(exc)]
        out = []
        lines = text.splitlines()
        m = TRAILER_RE.match(lines[-1])
        if not text.endswith("\n"):
            out.append(f"{path}:{len(lines)}: no newline at the end of the file (truncated?)")
        if m is None:
            out.append(f"{path}:{len(lines)}: no trailer '{trailer(len(t_s))}': the file is truncated or "
                       "not a complete camtool CSV")
        elif int(m.group("rows")) != len(t_s):
            out.append(f"{path}:{len(lines)}: the trailer says {m.group('rows')} rows, the file has {len(t_s)}")
        if len(t_s) == 0:
            return out + [f"{path}: no rows"]
        where = [f"{path}:{k + 2}" for k in range(len(t_s))]
        bad_t = np.flatnonzero(~np.isfinite(t_s))
        out += [f"{where[k]}: t_s is not a finite number" for k in bad_t[:MAX_PER_KIND]]
        # with a broken time column the speeds are unknown: the finding above fails the check
        dur = np.full(len(t_s), np.nan) if len(bad_t) else np.concatenate([[np.nan], np.diff(t_s)])
        return out + check_motion(q, dur, robot, where, np.full(robot.dof, 1e-9))
