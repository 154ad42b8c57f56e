"""FANUC LS post-processor: ``.LS`` programs (R-30iA / R-30iB), the ASCII listing FANUC's
offline tools (ROBOGUIDE, MakeTP) compile into a TP program.

The moves come from ``camtool.program.plan.plan_moves`` (waypoints merged within the path
tolerance, corners rounded, FINE only at the first move, the top of a retract, the end of
a program another follows, and the end):

- **Every position is in joint representation** (``J1``..``J6`` in degrees as the pendant
  shows them, 3 decimals): the controller's J3 is measured from the horizontal, ``J3 = j3
  - j2`` of the serial joints (fanuc_driver's J23 linkage). No target depends on CONFIG,
  whose turn-number axes public sources disagree on.
- **Off the surface**: ``J P[n] v% CNTn`` (v an integer % of the axes' maximum speeds, the
  axis that needs longest governing, as INFORM's VJ), rounded so that the program's clock
  tracks the plan's and never faster than the robot's limits.
- **On the surface**: ``L P[n] vmm/sec CNTn`` and ``C P[via]`` / ``:  P[end] ...`` (the TCP
  of the UTOOL in a straight line or on the circle to the joint position), v the integer
  TCP speed that gives the planned duration; ``CNTn`` the largest of the profile's ``cnt``
  whose modelled corner (``cnt_mm``) stays within the path tolerance.
- Frames: the program selects ``UFRAME_NUM`` / ``UTOOL_NUM`` and every position records
  them; with ``set_frames`` it writes the job's tool into ``UTOOL[n]`` and the work object
  into ``UFRAME[n]`` (``PR[k]=P[i]``, ``UTOOL[n]=PR[k]``: two Cartesian positions in
  /POS, frame data only, never moved to).
- Process I/O: ``DO[n]=ON`` before each row's first work point, ``OFF`` after its last
  (option ``process_output``); rows start with ``!ROW n/N`` and end with ``!END ROW n``.
- Names: upper-case letters, digits and ``_``, a leading letter, at most
  ``program_name_length`` characters; remarks through ``dialect.comment_text``.

Programs longer than ``lines_per_program`` moves are split, only after a target in free
motion, into ``NAME_1``, ``NAME_2``, ... that the main program ``NAME`` calls in turn.

The package: ``dialect``, ``writer``, ``parser`` (reader) and ``checker``; ``FanucPost``
composes them.
"""
from __future__ import annotations

from camtool.program.plugin import PackagedPost

from . import checker, dialect, parser, writer
from .dialect import OPTIONS


class FanucPost(PackagedPost):
    """FANUC LS writer, reader and checker (see module doc)."""

    name = "fanuc"
    extension = ".LS"
    extensions = (".LS",)
    requires_profile = True
    check_covers_calls = True   # checking the entry program checks every program it calls
    options_schema = OPTIONS
    dialect, writer, parser, checker = dialect, writer, parser, checker
