"""report.json's ``faces.worked`` and the figures of a path over several faces (``camtool.path.face_set``)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..path.face_set import face_paths
from ..path.raster import coverage as face_coverage
from ..path.raster import raster_summary
from ..part.segment import area_mm2
from ..part.surface import FaceSet
from ..timing.feed import feed_profile, feed_statistics
from ..path.toolpath import Path, row_segments


def coverage(face_set: FaceSet, path: Path, grid: int = 400) -> float:
    """Share (0..1) of the faces' area the joined ``path`` covers, each face by its own rows."""
    surface_of = dict(zip(face_set.indices, face_set.surfaces))
    parts = [(area_mm2(surface_of[i]), face_coverage(surface_of[i], own, own.step_over_mm, grid))
             for i, _, own in face_paths(face_set, path)]
    total = sum(a for a, _ in parts)
    return float(sum(a * c for a, c in parts) / total) if total > 0 else 0.0


def faces_worked(face_set: FaceSet, path: Path, trajectory, sampled, motion: dict | None = None) -> list[dict]:
    """report.json's ``faces.worked``: per face in working order, its segments, rows, work points and coverage
    (``raster.raster_summary`` of its own poses on its surface), its TCP feed on work measured on ``sampled``
    (``timing.SampledMotion``, ``timing.feed``) and, given the motion check's figures (``motion``, by segment), its worst figures there."""
    surface_of = dict(zip(face_set.indices, face_set.surfaces))
    feed = float(getattr(trajectory, "tcp_speed_mm_s", 0.0) or 0.0)
    profile = feed_profile(trajectory, sampled) if feed > 0 and len(sampled.t_s) > 1 else None
    if profile is not None:  # the face of each sample interval: its waypoint's segment's
        tw = np.asarray(trajectory.t_s, float)
        mid = 0.5 * (profile.t_s[:-1] + profile.t_s[1:])
        k = np.clip(np.searchsorted(tw, mid, side="right") - 1, 0, max(len(tw) - 2, 0))
        seg = row_segments(trajectory.path_index, trajectory.zone, path.segment)[k]
        face_of_segment = np.full(int(path.segment.max()) + 1, -1)
        face_of_segment[path.segment] = path.face
        interval_face = np.where(seg >= 0, face_of_segment[np.maximum(seg, 0)], -1)
    out = []
    for index, idx, own in face_paths(face_set, path):
        surface = surface_of[index]
        entry = {"index": index, "model": surface.model, **raster_summary(own, surface),
                 "segment_range": [int(path.segment[idx].min()), int(path.segment[idx].max())]}
        if profile is not None:
            entry["work_feed"] = feed_statistics(replace(profile, work=profile.work & (interval_face == index)), feed)
        if motion is not None:
            entry["motion_check"] = face_motion(motion, set(np.unique(path.segment[idx]).tolist()))
        out.append(entry)
    return out


def face_motion(motion: dict, segments: set[int]) -> dict:
    """The motion check's worst figures over the samples of ``segments`` (its ``by_index``, by segment): the
    deepest penetration into the part, the work deviation, the off-work clearance and the failing samples."""
    rows = [r for r in motion.get("by_index", ()) if r["index"] in segments]

    def worst(key, pick):
        values = [r[key] for r in rows if r[key] is not None]
        return pick(values) if values else None
    failing = {}
    for r in rows:
        for kind, n in r["failing_samples"].items():
            failing[kind] = failing.get(kind, 0) + n
    return {"samples": sum(r["samples"] for r in rows), "max_penetration_mm": worst("max_penetration_mm", max),
            "work_deviation_mm": worst("work_deviation_mm", max), "min_clearance_mm": worst("min_clearance_mm", min),
            "failing_samples": failing}


def path_figures(path: Path, surface) -> dict:
    """``raster.raster_summary`` of a path on its surface; on a ``FaceSet``, its coverage face by face."""
    if not isinstance(surface, FaceSet):
        return raster_summary(path, surface)
    return {**raster_summary(path), "coverage": round(coverage(surface, path), 5)}
