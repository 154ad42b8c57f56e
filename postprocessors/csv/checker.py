"""CSV checker: trailer, header, numbers, then joint values and speeds against the robot."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from camtool.errors import BadInput
from camtool.program.check import MAX_PER_KIND, check_motion

from .dialect import TRAILER_RE, trailer
from .parser import _parse, _read_text, columns


def check(path: Path, robot, profile=None) -> list[str]:
    """Findings for a CSV: a complete trailer whose row count matches (so a file cut
    anywhere fails), the header against the robot, one number per column, every value
    a finite number; then every value against the robot's limits and every step's
    speed (from ``t_s``) against its speed limits (tolerance 1e-9)."""
    path = Path(path)
    try:
        text = _read_text(path)
        t_s, q = columns(path, *_parse(path, text), robot)
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
