"""What the post stage knows about the process beyond the joint trajectory (``ProcessInfo``),
and the date a program shows."""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from datetime import datetime, timezone

DATE_FORMAT = "%Y/%m/%d %H:%M"
DEFAULT_PATH_TOL_MM = 0.1   # post.path_tol_mm: the program's TCP within this of the planned path on work
DEFAULT_ORI_TOL_DEG = 0.5   # post.ori_tol_deg: tool orientation of merged Cartesian moves


@dataclass(frozen=True)
class ProcessInfo:
    """What camtool knows about the process, handed to every plugin's ``write``.

    Every field has a default, so a plugin must work with ``ProcessInfo()`` too.

    - ``path_tol_mm``: largest distance of the program's interpolated TCP from the planned
      path (job key ``post.path_tol_mm``); moves are merged and corners blended within it.
    - ``ori_tol_deg``: largest tool-orientation deviation of merged Cartesian moves.
    - ``feed_mm_s``: the commanded TCP speed on work (``timing.tcp_speed_mm_s``), or None.
    - ``job_name``: the job file's name (for program comments), ``""`` when unknown.
    - ``job_time``: ``"yyyy/mm/dd hh:mm"`` (UTC) of the job file's modification, or None.
    - ``row_labels``: a label per work row, in order (e.g. the raster segment), or ().
    - ``joint_moves_s``: (start, end) spans (s from the plan's start) written as joint moves, not
      straight ones: the post stage sets them where the program's simulator found a straight move the
      controller cannot follow (a wrist singularity: no joint solution, or a joint above its speed), or ().
    - ``closer_s``: (start, end, share) spans (s from the plan's start) whose moves are merged and whose
      corners are blended within ``share`` (< 1) of ``path_tol_mm``: the post stage sets them where the
      program's simulator found the program farther from the planned path than it aims for, or ().
    """

    path_tol_mm: float = DEFAULT_PATH_TOL_MM
    ori_tol_deg: float = DEFAULT_ORI_TOL_DEG
    feed_mm_s: float | None = None
    job_name: str = ""
    job_time: str | None = None
    row_labels: tuple = field(default_factory=tuple)
    joint_moves_s: tuple = field(default_factory=tuple)
    closer_s: tuple = field(default_factory=tuple)


def program_date(option: str, process: ProcessInfo | None = None) -> str:
    """The date a program shows, ``yyyy/mm/dd hh:mm`` (UTC):

    - ``"job"`` (the default of the built-ins): the job file's modification time
      (``process.job_time``), so rerunning the same job gives byte-identical programs;
      without a job, as ``"now"``;
    - ``"now"``: the clock, or ``SOURCE_DATE_EPOCH`` when set (reproducible builds);
    - anything else is taken as the date itself (already checked by the plugin).
    """
    if option == "job" and process is not None and process.job_time:
        return process.job_time
    if option in ("job", "now"):
        epoch = os.environ.get("SOURCE_DATE_EPOCH")
        when = datetime.fromtimestamp(int(epoch), timezone.utc) if epoch and epoch.isdigit() \
            else datetime.now(timezone.utc)
        return when.strftime(DATE_FORMAT)
    return option
