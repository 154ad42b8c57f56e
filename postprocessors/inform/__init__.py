"""Yaskawa INFORM post-processor: ``.JBI`` job files (ASCII, CRLF).

The moves come from ``camtool.program.plan.plan_moves`` (waypoints merged
within the path tolerance, corners blended by position levels, exact stops
``PL=0`` only at the first move, the top of a retract, the end of a job that
is followed by another, and the end). Each move has its own position:

- **Joint moves** ``MOVJ C… [BC…] VJ=xx.xx PL=n`` to positions in pulses
  (``///POSTYPE PULSE``; ``C`` line for the robot RB1, ``BC`` for a base axis
  BS1, ``EC`` for a station ST1, axis order from the profile). INFORM has no
  per-move duration, so the timing is approximated by VJ, a percentage of each
  axis's maximum speed ``max_speed`` from the profile::

      VJ = 100 * max_i |dv_i| / (dt * vmax_i)

  with dt the planned duration of the move; VJ is rounded to 0.01 so that the
  job's clock tracks the plan's, never above what the robot's speed limits
  allow, and clipped to 0.01..100.00. The first move (from wherever the robot
  is) uses ``approach_vj``.
- **Linear moves** (profile option ``motion = "cartesian"``, robots whose
  kinematics the controller knows, robot group RB1 only) ``MOVL C… V=v PL=n`` to
  Cartesian positions in the robot base frame (``///POSTYPE BASE``,
  ``///RECTAN``, ``///RCONF`` from the planned joints; ``C=X,Y,Z,Rx,Ry,Rz[,Re]``
  in mm and degrees, the rotation fixed-axis x, y, z, and Re the 7th axis value
  of a 7-axis arm) with the TCP speed V (mm/s, 0.1) that gives the planned
  duration. Free motion stays joint moves.
- **Process I/O**: ``DOUT OT#(n) ON`` before the move to each row's first work
  point and ``DOUT OT#(n) OFF`` after the move to its last (option
  ``process_output``; 0 = none, the job says so in a comment). Every row starts
  with a comment ``'ROW n/N`` and ends with ``'END ROW n``.
- ``///DATE`` from the ``date`` option (default ``job``: the job file's time, so
  reruns give byte-identical files), ``///COMM`` names the job.

Jobs longer than ``lines_per_job`` positions are split, only after a target in
free motion, into ``NAME_1``, ``NAME_2`` ... (each name <= ``job_name_length``
characters) and a main job ``NAME`` runs them with ``CALL JOB:...``.

The package: ``dialect`` (tables, names, pulses, options, profile check), ``writer``,
``parser`` (reader) and ``checker``; ``InformPost`` composes them.
"""
from __future__ import annotations

from camtool.program.plugin import PackagedPost

from . import checker, dialect, parser, writer
from .dialect import OPTIONS, from_pulses, to_pulses


class InformPost(PackagedPost):
    """Yaskawa INFORM writer, reader and checker (see module doc)."""

    name = "inform"
    extension = ".JBI"
    extensions = (".JBI",)
    requires_profile = True
    check_covers_calls = True  # checking the entry job checks every job it calls
    options_schema = OPTIONS
    to_pulses = staticmethod(to_pulses)
    from_pulses = staticmethod(from_pulses)
    dialect, writer, parser, checker = dialect, writer, parser, checker
