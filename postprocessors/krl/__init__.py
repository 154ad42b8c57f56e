"""KUKA KRL post-processor: a ``.src`` module and its ``.dat`` data list (KR C2 / KR C4).

The moves come from ``camtool.program.plan.plan_moves`` (waypoints merged within the
path tolerance, corners approximated, exact stops only at the first move, the top of a
retract, the end of a module another follows, and the end):

- **Off the surface** (free motion, the first move): ``PTP XPn`` to an **E6AXIS** target
  (A1..A6 in degrees as the controller shows them, E1..E6): no Status and Turn, so the
  contested S bits never matter. Its speed is ``$VEL_AXIS[1..6]`` (an integer %, the axis
  that needs longest at its % of the profile's ``max_speed``, as INFORM's VJ), rounded so
  that the program's clock tracks the plan's and never faster than the robot's limits.
  Approximation ``C_PTP`` with ``$APO.CPTP`` (% of half the motion; ``C_PTP C_DIS`` into a
  CP move).
- **On the surface** (work, leads): ``LIN XPn`` and ``CIRC XAn, XPn`` to **E6POS** targets
  (X, Y, Z, A, B, C of the TCP in ``$BASE``; no S and T: CP moves keep the configuration),
  at ``$VEL.CP`` (m/s) giving the planned duration, ``$VEL.ORI1/2`` raised where a move
  turns the tool faster; approximation ``C_DIS`` with ``$APO.CDIS`` (mm), the largest of
  ``cdis_mm`` within the path tolerance.
- ``$BASE`` is the job's work object (the workpiece frame in $ROBROOT), ``$TOOL`` the job's
  tool in $FLANGE; ``$ORI_TYPE = #VAR``, ``$CIRC_TYPE = #BASE``.
- Process I/O: ``$OUT[n]=TRUE`` before the move to each row's first work point, ``FALSE``
  after its last (option ``process_output``). Rows start with ``; Row n of N`` and end
  with ``; End of row n``.
- Names: letters, digits and ``_``, a leading letter, at most 24 characters, no keyword.
  Comments (``;``) go through ``dialect.comment_text``.

Programs longer than ``lines_per_file`` moves are split, only after a target in free
motion, into modules ``NAME_001`` ... that the main module ``NAME`` calls in turn.

The package: ``dialect`` (tables, names, frames, options, profile check), ``writer``,
``parser`` (reader) and ``checker``; ``KrlPost`` composes them.
"""
from __future__ import annotations

from camtool.program.plugin import PackagedPost

from . import checker, dialect, parser, writer
from .dialect import OPTIONS


class KrlPost(PackagedPost):
    """KUKA KRL writer, reader and checker (see module doc)."""

    name = "krl"
    extension = ".src"
    extensions = (".src", ".dat")   # every file type it writes; `camtool check` finds the format by these
    requires_profile = True
    check_covers_calls = True   # checking the entry .src checks its .dat and every module it calls
    options_schema = OPTIONS
    dialect, writer, parser, checker = dialect, writer, parser, checker
