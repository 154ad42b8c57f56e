"""Text a program carries: controller-safe identifiers and small helpers the writers share.

Each dialect has its own sanitiser for free text (comments, headers) in its ``dialect``
module; ``sanitise_name`` makes identifiers (program, module, job, tool names).
"""
from __future__ import annotations

import logging
import re

import numpy as np

log = logging.getLogger("camtool.post")


def sanitise_name(raw: str, *, max_len: int, reserved: frozenset[str] = frozenset(),
                  upper: bool = False, what: str = "name") -> tuple[str, str]:
    """A controller-safe identifier: letters, digits and ``_``, leading letter, at most
    ``max_len`` characters, not in ``reserved`` (compared case-insensitively).

    Returns ``(name, note)``; ``note`` is empty when ``raw`` was already valid.
    """
    s = raw.upper() if upper else raw
    s = re.sub(r"[^A-Za-z0-9_]", "_", s.encode("ascii", "replace").decode("ascii"))
    if not s or not s[0].isalpha():
        s = ("P" if upper else "p") + s
    s = s[:max_len]
    if s.upper() in {r.upper() for r in reserved}:
        s = (s[:max_len - 2] + "_1")
    note = "" if s == raw else f"{what} {raw!r} is not valid for the controller; written as {s!r}"
    if note:   # on stderr as camtool's own line (the logger's last resort prints the message alone)
        log.warning("camtool: warning: %s", note)
    return s, note


def joint_values_edge(trajectory_q: np.ndarray, prismatic: np.ndarray) -> np.ndarray:
    """Joint values in edge units: degrees for revolute joints, mm for prismatic."""
    return np.where(prismatic[None, :], trajectory_q, np.degrees(trajectory_q))


def chunks(n: int, size: int) -> list[range]:
    """Split range(n) into consecutive ranges of at most ``size``."""
    return [range(i, min(i + size, n)) for i in range(0, n, size)] or [range(0)]


def column_names(joint_names) -> list[str]:
    """Joint names as CSV column stems a spreadsheet reads as text: identifiers (letters, digits, ``_``,
    a letter first), never a cell starting with ``=``, ``+``, ``-`` or ``@`` (a formula), made unique."""
    out: list[str] = []
    for raw in joint_names:
        s = re.sub(r"[^A-Za-z0-9_]", "_", str(raw).encode("ascii", "replace").decode("ascii"))[:64]
        if not s[:1].isalpha():
            s = "j" + s
        base, k = s, 2
        while s in out:
            s, k = f"{base}_{k}", k + 1
        out.append(s)
    return out
