"""ABB RAPID post-processor: ``.mod`` modules plus a ``.pgf`` program file.

The moves come from ``camtool.program.plan.plan_moves``: waypoints merged while
the controller's interpolation stays within the path tolerance, corners blended
by zones, exact stops (``fine``) only at the first move, at the top of a
retract, at the end of a module that is followed by another, and at the end.

- Joint moves: ``MoveAbsJ jointtarget, speed \\T:=dt, zone, tool \\WObj:=wobj;``
  with the planned duration (0.1 ms grid, rounded so that the program's clock
  tracks the plan's and no move is faster than the robot's speed limits allow).
  Joint values: 1e-4 deg, 1e-3 mm; 9E9 for axes the profile leaves unconnected.
- Linear moves (profile option ``motion = "cartesian"``, for robots whose
  kinematics the controller knows): ``MoveL robtarget, [v_tcp,v_ori,5000,1000],
  zone, tool \\WObj:=wobj;`` with the robtarget (position 1e-3 mm, quaternion,
  confdata cf1, cf4, cf6, cfx from the planned joints, external axes) in the work
  object at the workpiece frame, and the TCP speed that gives the planned
  duration. Free motion stays joint moves.
- The first move goes from wherever the robot is to the start at
  ``approach_speed`` and stops (``fine``).
- Process I/O: ``SetDO signal, 1;`` before the move to each row's first work
  point and ``SetDO signal, 0;`` after the move to its last (option
  ``process_signal``; without one the header says the program switches nothing).
  Every row starts with a comment ``! Row n of N ...`` and ends with ``! End of
  row n``.
- Programs longer than ``lines_per_module`` moves are split into modules
  ``<NAME>_001 ...`` only after a target in free motion; each module holds one
  routine ``<NAME>_001_run`` and the main module ``<NAME>`` loads, runs (late
  binding ``%"<NAME>_001_run"%;``) and unloads them in turn.

The package: ``dialect`` (tables, formats, options, profile check), ``writer``,
``parser`` (reader) and ``checker``; ``RapidPost`` composes them.
"""
from __future__ import annotations

from camtool.program.plugin import PackagedPost

from . import checker, dialect, parser, writer
from .dialect import OPTIONS


class RapidPost(PackagedPost):
    """ABB RAPID writer, reader and checker (see module doc)."""

    name = "rapid"
    extension = ".mod"
    extensions = (".pgf", ".mod")  # every file type it writes; `camtool check` finds the format by these
    requires_profile = True
    check_covers_calls = True  # checking the entry file checks every module it loads
    options_schema = OPTIONS
    dialect, writer, parser, checker = dialect, writer, parser, checker
