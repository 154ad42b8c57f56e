"""Partial jobs: the reachable stretches of a path, for ``camtool run --allow-partial``.

When a few poses are out of reach, the rest of the raster can still be worked:

    stretches = reachable_stretches(path, unreachable, min_work_poses=2)
    sub, index = partial_path(path, stretches)
    joint_path = plan_for_job(settings, sub, robot, workpiece)   # every pose of ``sub`` reachable
    # sub pose k is path pose index[k]; poses not in ``index`` are left out of the program

A *run* is a stretch of surface poses (work, lead-in, lead-out) of one
segment (``toolpath.run_bounds``). Each run is cut at its unreachable poses
into maximal stretches of reachable poses; a stretch with fewer than
``min_work_poses`` work poses is dropped. A stretch's end at a cut (an
unreachable pose of its row next to it) becomes its lead: that work pose is
relabelled lead-in / lead-out, so the work never ends in the corner of the
lift that follows (and the coverage counts it out). Connector poses (self-motion zones,
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

from ..path.toolpath import SURFACE_CODES as SURFACE
from ..path.toolpath import WORK, ZONE_CODE, Path, run_bounds


@dataclass(frozen=True)
class Stretch:
    """Path poses first..last (inclusive) of one segment, every one reachable."""

    first: int
    last: int
    segment: int
    work_poses: int
    cut_in: bool = False    # the stretch starts at a cut (an unreachable pose of its row before it)
    cut_out: bool = False   # it ends at a cut

    def as_dict(self) -> dict:
        return {"first": self.first, "last": self.last, "segment": self.segment, "work_poses": self.work_poses,
                "cut_in": self.cut_in, "cut_out": self.cut_out}


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
            cut_in = s > a and path.zone[s] == WORK
            cut_out = k - 1 < b and path.zone[k - 1] == WORK
            work -= int(cut_in) + int(cut_out)   # a cut end's work pose becomes the stretch's lead (partial_path)
            if work >= max(min_work_poses, 1):
                out.append(Stretch(s, k - 1, int(path.segment[s]), work, bool(cut_in), bool(cut_out)))
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
    zone = path.zone[idx].copy()
    # A stretch cut at an unreachable pose ends in work with no lead: the controller's blend into the lift
    # there would round the last work corner (the program simulator measured 0.5-1.5 mm off the path).
    # The cut end's work pose becomes the stretch's lead-in / lead-out: on the surface, out of the work zone.
    where = {int(i): k for k, i in enumerate(idx)}
    for st in stretches:
        if st.cut_in:
            zone[where[st.first]] = ZONE_CODE["lead_in"]
        if st.cut_out:
            zone[where[st.last]] = ZONE_CODE["lead_out"]
    sub = Path(path.poses_mm[idx], np.array(seg, dtype=path.segment.dtype), path.point[idx], zone,
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
