"""CSV post-processor: one row per waypoint, a time column and one column per joint.

Header: ``t_s`` then ``<joint>_<unit>`` with unit ``mm`` for prismatic joints
and ``deg`` or ``rad`` (option ``angle_unit``) for revolute ones, e.g.
``t_s,track_mm,j2_deg,...``. Numbers are written with Python's shortest
round-trip ``repr``, so a reader gets back exactly the floats that were written.
The last line is the trailer ``# END <rows> rows``: a file cut anywhere, even at
a row boundary, has no complete trailer or the wrong count, and fails the check.
(``#`` starts a comment for numpy's ``loadtxt`` and pandas' ``comment="#"``.)
LF line ends, ASCII.

The package: ``dialect`` (columns, trailer, options), ``writer``, ``parser`` (reader)
and ``checker``; ``CsvPost`` composes them.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from camtool.program.plugin import PostProcessor
from camtool.program.process import ProcessInfo

from . import checker, parser, writer
from .dialect import OPTIONS, validate_profile


class CsvPost(PostProcessor):
    """CSV writer, reader and checker (see module doc)."""

    name = "csv"
    extension = ".csv"
    extensions = (".csv",)
    requires_profile = False
    options_schema = OPTIONS

    def post_options(self, post_settings) -> dict:
        """Options set by job keys: ``post.csv_angle_unit`` is the angle unit."""
        return {"angle_unit": post_settings.csv_angle_unit}

    def validate_profile(self, profile, robot) -> None:
        validate_profile(profile, robot)

    def write(self, trajectory, robot, profile, outdir: Path, process: ProcessInfo | None = None) -> list[Path]:
        return writer.write(trajectory, robot, profile, outdir)

    def read(self, path: Path, robot, profile=None) -> tuple[np.ndarray, np.ndarray]:
        return parser.read(path, robot, profile)

    def read_trajectory(self, path: Path, robot) -> tuple[np.ndarray, np.ndarray]:
        """(t_s, q in rad / mm) from a camtool CSV; BadInput when the columns do not fit the robot."""
        return parser.read_trajectory(path, robot)

    def check(self, path: Path, robot, profile=None) -> list[str]:
        return checker.check(path, robot, profile)
