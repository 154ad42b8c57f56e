"""The post-processor plugin base: what every controller format provides, with defaults.

A post-processor turns a timed ``camtool.trajectory.Trajectory`` into controller
program files and reads them back. Every plugin, built-in or third-party, derives
from ``PostProcessor`` (docs/plugins.md); camtool asks only what this class
declares, never probes an object for optional methods.

Required: ``name``, ``extension``, ``write`` and ``read``. Everything else has a
default:

- ``extensions``: every file type the plugin writes (``camtool check`` finds a
  file's format by them); default ``(extension,)``.
- ``options_schema``: option -> (type, default, doc); the options live in the
  ``[options]`` table of the controller profile. Default: none.
- ``requires_profile``: True when a profile with an axis map is needed (default);
  False lets the plugin run on its option defaults for any robot.
- ``check_covers_calls``: True when ``check`` of the entry file follows every file
  it loads or calls (then only the entry file is checked); default False.
- ``validate_profile(profile, robot)``: BadInput for a profile the format cannot
  use; default accepts every profile.
- ``post_options(post_settings)``: options the plugin takes from the job's
  ``[post]`` settings (e.g. the CSV angle unit); default none.
- ``check(path, robot, profile)``: findings for one written file; default: the file
  read back with ``read`` and its joint values and durations checked against the
  robot's limits (``camtool.program.check.read_back_check``).
- ``read_program(path, robot, profile)``: the program move by move
  (``ProgramMoves``) for the simulator; default None (the format is not simulated).
- ``simulated``: True when ``read_program`` gives moves; derived from whether the
  class overrides it.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from .moves import ProgramMoves
from .process import ProcessInfo


class PostProcessor(ABC):
    """Base of every post-processor (see module doc)."""

    name: ClassVar[str] = ""
    extension: ClassVar[str] = ""
    extensions: ClassVar[tuple[str, ...]] = ()
    options_schema: ClassVar[dict[str, tuple[type, Any, str]]] = {}
    requires_profile: ClassVar[bool] = True
    check_covers_calls: ClassVar[bool] = False

    @abstractmethod
    def write(self, trajectory, robot, profile, outdir: Path, process: ProcessInfo) -> list[Path]:
        """Write the program files into ``outdir``; their paths, the entry file first."""

    @abstractmethod
    def read(self, path: Path, robot, profile) -> tuple[np.ndarray, np.ndarray]:
        """``(durations_s, q)``: each move's duration (s, NaN where the program gives none)
        and joint values (M x dof, rad / mm) of each move's target."""

    def file_types(self) -> tuple[str, ...]:
        """Every file extension the plugin writes (lower case, with the dot)."""
        return tuple(e.lower() for e in (self.extensions or (self.extension,)))

    def validate_profile(self, profile, robot) -> None:
        """BadInput for a profile this format cannot use; the default accepts every one."""

    def post_options(self, post_settings) -> dict:
        """Options the plugin takes from the job's post settings; the default takes none."""
        return {}

    def check(self, path: Path, robot, profile) -> list[str]:
        """Findings for one written file (empty when clean); the default reads it back."""
        from .check import read_back_check

        return read_back_check(self, path, robot, profile)

    def read_program(self, path: Path, robot, profile) -> ProgramMoves | None:
        """The program move by move, for the simulator; None: this format is not simulated."""
        return None

    def forget(self) -> None:
        """Drop what the plugin keeps of the files it has read (a check and a simulation read a file once);
        the post stage calls it when a format is done. The default keeps nothing."""

    @property
    def simulated(self) -> bool:
        """True when the plugin reads its programs back move by move (``read_program``)."""
        return type(self).read_program is not PostProcessor.read_program

    @property
    def own_check(self) -> bool:
        """True when the plugin checks its files itself (else they are read back)."""
        return type(self).check is not PostProcessor.check


class PackagedPost(PostProcessor):
    """A post-processor laid out as a package of modules, as the built-ins are: ``dialect``
    (``validate_profile``), ``writer`` (``write``), ``parser`` (``read``, ``read_program``) and
    ``checker`` (``check``). The class names its modules; the methods delegate to them, so each
    plugin writes none of this glue again (docs/plugins.md)."""

    dialect = None
    writer = None
    parser = None
    checker = None

    def validate_profile(self, profile, robot) -> None:
        self.dialect.validate_profile(profile, robot)

    def write(self, trajectory, robot, profile, outdir: Path, process: ProcessInfo | None = None) -> list[Path]:
        return self.writer.write(trajectory, robot, profile, outdir, process)

    def read_program(self, path: Path, robot, profile) -> ProgramMoves:
        return self.parser.read_program(path, robot, profile)

    def read(self, path: Path, robot, profile) -> tuple[np.ndarray, np.ndarray]:
        return self.parser.read(path, robot, profile)

    def check(self, path: Path, robot, profile) -> list[str]:
        return self.checker.check(path, robot, profile)

    def forget(self) -> None:
        self.parser.forget()
