"""The poses a partial plan leaves out where the motion check fails (``task.allow_partial``, issue #46).

The independent motion check names each failing sample against the part (a link, the tool or the TCP in the
part, too near it off work, off the surface on work) by the program's waypoints round it
(``MotionReport.failing_intervals``). ``failing_path_poses`` takes those waypoints to the programmed path's
poses; ``CheckLeftOut.grown`` takes those to the raster's surface poses (a connector's to the ends of the runs
it joins) and leaves them out as the unreachable ones are: the rest is planned again. A place that fails again
is left out deeper, 1, 2, 4, ... poses along its run, ``CHECK_LEFT_OUT_ROUNDS`` rounds at most: counted work.
The check itself is never loosened; a program is written only once it passes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..path.toolpath import SURFACE_CODES, WORK

CHECK_LEFT_OUT_ROUNDS = 4   # plans again at most this many times, each with more poses left out
KIND_WORDS = {"penetration": "in the part", "clearance": "too near the part", "deviation": "off the surface on work"}


def failing_path_poses(program_path_index, intervals) -> list[tuple[str, str, int, int]]:
    """(kind, body, path pose before, path pose after) of each failing interval (``failing_intervals``: kind,
    body, waypoint before, waypoint after) of a program whose waypoints carry ``program_path_index`` (-1: a
    waypoint the planner inserted, taken to the path pose before it, or after it)."""
    pidx = np.asarray(program_path_index, np.int64)
    M = len(pidx)
    pos = np.arange(M)
    prev = np.maximum.accumulate(np.where(pidx >= 0, pos, -1))
    nxt = np.minimum.accumulate(np.where(pidx >= 0, pos, M)[::-1])[::-1]
    if not (pidx >= 0).any():
        return []

    def before(w: int) -> int:
        return int(pidx[prev[w]] if prev[w] >= 0 else pidx[nxt[w]])

    def after(w: int) -> int:
        return int(pidx[nxt[w]] if nxt[w] < M else pidx[prev[w]])

    return sorted({(kind, body, before(w0), after(w1)) for kind, body, w0, w1 in intervals})


def _surface_end(zone: np.ndarray, k: int, step: int) -> int | None:
    """The first surface pose from ``k`` on in direction ``step`` (``k`` itself when it is one), or None."""
    while 0 <= k < len(zone):
        if zone[k] in SURFACE_CODES:
            return k
        k += step
    return None


def _along_run(path, k: int, depth: int) -> range:
    """Raster path indices ``depth`` - 1 poses either side of ``k``, within its run (one segment, on the surface)."""
    lo = k
    while lo > 0 and k - lo < depth - 1 and path.zone[lo - 1] in SURFACE_CODES and path.segment[lo - 1] == path.segment[k]:
        lo -= 1
    hi = k
    while (hi + 1 < len(path) and hi - k < depth - 1 and path.zone[hi + 1] in SURFACE_CODES
           and path.segment[hi + 1] == path.segment[k]):
        hi += 1
    return range(lo, hi + 1)


@dataclass(frozen=True)
class CheckLeftOut:
    """The raster's poses left out for the motion check's findings so far: path index -> the (kind, body) pairs
    found there, the rounds planned again, and the first finding of each round."""

    found: tuple[tuple[int, str, str], ...] = ()   # (raster path index, kind, body), sorted
    rounds: int = 0
    firsts: tuple[str, ...] = ()

    @property
    def indices(self) -> list[int]:
        return sorted({i for i, _k, _b in self.found})

    def grown(self, path, programmed, index, failing, first: str) -> "CheckLeftOut | None":
        """These poses and those of the ``failing`` path poses (``failing_path_poses`` of the ``programmed``
        path, whose pose k is raster pose ``index[k]``; ``index`` None: the raster itself), each 2 ** rounds
        poses deep along its run; None when out of rounds or no new raster pose would be left out."""
        if self.rounds >= CHECK_LEFT_OUT_ROUNDS or not failing:
            return None
        index = np.arange(len(programmed)) if index is None else np.asarray(index)
        depth = 2 ** self.rounds
        found = set(self.found)
        for kind, body, a, b in failing:
            for k, step in ((a, -1), (b, 1)):
                end = _surface_end(programmed.zone, int(k), step)   # a connector: the run it leaves or enters
                if end is None:
                    continue
                raster = int(index[end])
                found |= {(i, kind, body) for i in _along_run(path, raster, depth)}
        if {i for i, _k, _b in found} <= set(self.indices):
            return None
        return CheckLeftOut(tuple(sorted(found)), self.rounds + 1, self.firsts + (first,))

    def figures(self, path) -> dict:
        """report.json's ``partial.check_left_out``: the poses, work poses, rows (raster segments) and bodies, per
        kind of finding, the rounds and each round's first finding."""
        kinds: dict[str, dict] = {}
        for kind in KIND_WORDS:
            at = sorted({i for i, k, _b in self.found if k == kind})
            if not at:
                continue
            kinds[kind] = {"poses": len(at),
                           "work_poses": int(np.count_nonzero(np.asarray(path.zone)[at] == WORK)),
                           "rows": sorted({int(path.segment[i]) for i in at}),
                           "bodies": sorted({b for _i, k, b in self.found if k == kind})}
        at = self.indices
        return {"path_indices": at, "work_poses": int(np.count_nonzero(np.asarray(path.zone)[at] == WORK)),
                "rows": sorted({int(path.segment[i]) for i in at}), "by_kind": kinds, "rounds": self.rounds,
                "first_findings": list(self.firsts)}

    def line(self, path) -> str:
        """One line: how many work poses were left out where the motion check failed, on which rows, which bodies
        and why."""
        f = self.figures(path)
        why = "; ".join(f"{', '.join(dict.fromkeys(b.split(' (')[0] for b in k['bodies']))} {KIND_WORDS[kind]}"
                        for kind, k in f["by_kind"].items())
        plans = "1 re-plan" if f["rounds"] == 1 else f"{f['rounds']} re-plans"
        return (f"{f['work_poses']} work poses on rows {_spans(f['rows'])} left out where the motion check "
                f"failed: {why} ({plans})")


def _spans(rows: list[int]) -> str:
    """``[37, 38, 39, 41]`` -> ``"37-39, 41"``."""
    out, start = [], None
    for n, r in enumerate(rows):
        if start is None:
            start = r
        if n + 1 == len(rows) or rows[n + 1] != r + 1:
            out.append(f"{start}" if start == r else f"{start}-{r}")
            start = None
    return ", ".join(out)
