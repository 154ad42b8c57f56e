"""Partial jobs: the reachable stretches of a path, for ``camtool run --allow-partial``.

When a few poses are out of reach, the rest of the raster can still be worked:

    stretches = reachable_stretches(path, unreachable, min_work_poses=2)
    sub, index = partial_path(path, stretches)
    joint_path = plan_for_job(settings, sub, robot, workpiece)   # every pose of ``sub`` reachable
    # sub pose k is path pose index[k]; poses not in ``index`` are left out of the program

A *run* is a stretch of surface poses (work, lead-in, lead-out) of one
segment (``toolpath.run_bounds``). Each run is cut at its unreachable poses
into maximal stretches of reachable poses; a stretch with fewer than
``min_work_poses`` work poses is dropped. Connector poses (self-motion zones,
approach, depart) are never part of a stretch; ``partial_path`` keeps the
original connectors between two consecutive kept stretches of different
segments (when none of their poses is unreachable) and renumbers the segments
so that a stretch cut out of the middle of a row becomes a run of its own:
the planner then treats the gap like a connector between runs (no poses;
a reconfiguration there is lifted off the part by ``plan_for_job``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..toolpath import SURFACE_CODES as SURFACE
from ..toolpath import WORK, Path, run_bounds


@dataclass(frozen=True)
class Stretch:
    """Path poses first..last (inclusive) of one segment, every one reachable."""

    first: int
    last: int
    segment: int
    work_poses: int

    def as_dict(self) -> dict:
        return {"first": self.first, "last": self.last, "segment": self.segment, "work_poses": self.work_poses}


def _runs(path: Path) -> list[tuple[int, int]]:
    """(first, last) of every run (``toolpath.run_bounds``, the one definition of a run)."""
    _surface, start, end = run_bounds(path.zone, path.segment)
    return [(int(a), int(b)) for a, b in zip(np.flatnonzero(start), np.flatnonzero(end))]


def reachable_stretches(path: Path, unreachable, min_work_poses: int = 2) -> list[Stretch]:
    """The maximal stretches of reachable surface poses of every run (module doc), in path order.

    ``unreachable``: path indices, or the ``report['unreachable']`` list of a
    ``PlanInfeasible`` (dicts with an ``index``).
    """
    bad = np.zeros(len(path), bool)
    for u in unreachable:
        i = int(u["index"]) if isinstance(u, dict) else int(u)
        if 0 <= i < len(path):
            bad[i] = True
    out = []
    for a, b in _runs(path):
        k = a
        while k <= b:
            if bad[k]:
                k += 1
                continue
            s = k
            while k <= b and not bad[k]:
                k += 1
            work = int(np.count_nonzero(path.zone[s:k] == WORK))
            if work >= min_work_poses:
                out.append(Stretch(s, k - 1, int(path.segment[s]), work))
    return out


def partial_path(path: Path, stretches: list[Stretch], unreachable=()) -> tuple[Path, np.ndarray]:
    """The sub-path of ``stretches`` (module doc) and, per sub-path pose, its index in ``path``."""
    bad = {int(u["index"]) if isinstance(u, dict) else int(u) for u in unreachable}
    keep, seg = [], []
    for n, st in enumerate(stretches):
        if n:
            prev = stretches[n - 1]
            gap = range(prev.last + 1, st.first)
            if (prev.segment != st.segment and all(path.zone[i] not in SURFACE for i in gap)
                    and not any(i in bad for i in gap)):
                keep += list(gap)
                seg += [n] * len(gap)
        keep += list(range(st.first, st.last + 1))
        seg += [n] * (st.last - st.first + 1)
    idx = np.array(keep, int)
    sub = Path(path.poses_mm[idx], np.array(seg, dtype=path.segment.dtype), path.point[idx], path.zone[idx],
               path.free_spin, path.step_over_mm, path.pitch_mm)
    return sub, idx


def partial_summary(path: Path, stretches: list[Stretch]) -> dict:
    """Figures for report.json: how much of the work the stretches cover."""
    work = int(np.count_nonzero(path.zone == WORK))
    kept = sum(s.work_poses for s in stretches)
    per_segment: dict[int, int] = {}
    for s in stretches:
        per_segment[s.segment] = per_segment.get(s.segment, 0) + 1
    work_segments = {int(x) for x in np.unique(path.segment[path.zone == WORK])}
    return {"stretches": len(stretches), "work_poses_kept": kept, "work_poses_total": work,
            "work_kept_pct": round(100.0 * kept / work, 2) if work else 0.0,
            "segments_split": sum(1 for n in per_segment.values() if n > 1),
            "segments_dropped": len(work_segments - set(per_segment))}
