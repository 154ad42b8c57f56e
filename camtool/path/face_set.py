"""Several faces of a part worked in one program: the faces, their order, and the joined tool path.

A job whose ``[faces] select`` names more than one face gets a ``surface.FaceSet`` where
a single-face job gets its surface. ``raster.raster_path`` rasters each face with its
own settings (the job's ``[raster]`` and ``faces.raster``) and joins them:

1. **Order** (``working_order``): nearest neighbour from the largest face, each face's
   path going from its entry (approach) to its exit (depart), then 2-opt on the
   order while the air distance from exits to entries falls. Deterministic.
2. **Join** (``joined``): the faces' paths one after another, segments numbered on,
   each pose carrying its face (``Path.face``). Between two faces the path holds the
   one face's depart and the next one's approach; the planner turns that connector into
   a lift, a free move around the part (RRT-Connect, checked against the part and the
   cell) and a descent (``plan/connectors.py``), as it does for any reconfiguration.

The joined path's ``step_over_mm`` and ``pitch_mm`` are the job's ``[raster]`` ones; each
face's own figures are in report.json's ``faces.worked``.
"""
from __future__ import annotations

from dataclasses import asdict

import numpy as np

from ..settings import RasterSettings
from ..part.surface import FaceSet
from .toolpath import Path

MAX_TWO_OPT_ROUNDS = 50  # improving 2-opt passes over the order (each is O(n^2) for n faces)


def raster_changes(job_raster_keys: dict, face_keys: dict) -> dict:
    """The ``RasterSettings`` fields that ``face_keys`` ([raster] keys of ``faces.raster``) change over the
    job's ``[raster]`` keys."""
    base = asdict(RasterSettings.make(**job_raster_keys))
    own = asdict(RasterSettings.make(**{**job_raster_keys, **face_keys}))
    return {k: v for k, v in own.items() if v != base[k]}


def raster_faces(face_set: FaceSet, settings: RasterSettings, raster_one) -> Path:
    """Every face rastered (``raster_one(surface, settings)``: ``raster.raster_path``) with its settings, in
    working order, joined into one Path."""
    paths = [raster_one(s, face_set.settings_for(k, settings)) for k, s in enumerate(face_set.surfaces)]
    return joined(paths, working_order(paths), face_set.indices, settings)


def _ends_mm(paths: list[Path]) -> tuple[np.ndarray, np.ndarray]:
    """(entries, exits): each path's first and last TCP position (mm)."""
    return (np.array([p.poses_mm[0][:3, 3] for p in paths]), np.array([p.poses_mm[-1][:3, 3] for p in paths]))


def air_mm(order: list[int], entries: np.ndarray, exits: np.ndarray) -> float:
    """The straight distance (mm) from each face's exit to the next one's entry, summed over ``order``."""
    return float(sum(np.linalg.norm(entries[b] - exits[a]) for a, b in zip(order[:-1], order[1:])))


def working_order(paths: list[Path]) -> list[int]:
    """The order the faces are worked in: nearest neighbour from the first (largest) face, then 2-opt.

    Hand-written: a handful of faces, an open tour from a fixed start with directed
    costs (a face's exit to the next one's entry); no kept library solves that small
    case more simply, and ``scipy`` has no TSP solver."""
    entries, exits = _ends_mm(paths)
    n = len(paths)
    order, left = [0], set(range(1, n))
    while left:
        last = order[-1]
        nxt = min(left, key=lambda j: (float(np.linalg.norm(entries[j] - exits[last])), j))
        order.append(nxt)
        left.remove(nxt)
    best = air_mm(order, entries, exits)
    for _ in range(MAX_TWO_OPT_ROUNDS):
        improved = False
        for i in range(1, n - 1):
            for j in range(i + 1, n):
                trial = order[:i] + order[i:j + 1][::-1] + order[j + 1:]
                cost = air_mm(trial, entries, exits)
                if cost < best - 1e-9:
                    order, best, improved = trial, cost, True
        if not improved:
            break
    return order


def joined(paths: list[Path], order: list[int], indices: tuple[int, ...], settings: RasterSettings) -> Path:
    """The paths in ``order`` as one Path: segments numbered on, each pose with its face (``indices``); its
    ``step_over_mm`` and ``pitch_mm`` are ``settings``' (the job's, before any face's own keys)."""
    poses, segment, point, zone, face, contour = [], [], [], [], [], []
    offset = 0
    for k in order:
        p = paths[k]
        poses.append(p.poses_mm)
        segment.append(p.segment + offset)
        point.append(p.point)
        zone.append(p.zone)
        face.append(np.full(len(p), indices[k], np.int32))
        contour.append(np.zeros(len(p), bool) if p.contour is None else p.contour)
        offset += int(p.segment.max()) + 1
    return Path(np.concatenate(poses), np.concatenate(segment).astype(np.int32), np.concatenate(point),
                np.concatenate(zone), paths[order[0]].free_spin, settings.step_over_mm, settings.pitch_mm,
                face=np.concatenate(face),
                contour=np.concatenate(contour) if any(paths[k].contour is not None for k in order) else None)


def face_runs(path: Path) -> list[tuple[int, np.ndarray]]:
    """(face index, the path's pose indices of that face) in working order."""
    if path.face is None:
        return []
    change = np.flatnonzero(np.r_[True, path.face[1:] != path.face[:-1]])
    bounds = np.r_[change, len(path)]
    return [(int(path.face[a]), np.arange(a, b)) for a, b in zip(bounds[:-1], bounds[1:])]


def face_paths(face_set: FaceSet, path: Path) -> list[tuple[int, np.ndarray, Path]]:
    """(face index, its pose indices in the joined ``path``, that face's own part of it, with its step-over
    and pitch) in working order."""
    k_of = {i: k for k, i in enumerate(face_set.indices)}
    out = []
    for index, idx in face_runs(path):
        change = face_set.raster_changes[k_of[index]]
        out.append((index, idx, Path(path.poses_mm[idx], path.segment[idx] - path.segment[idx].min(), path.point[idx],
                                path.zone[idx], path.free_spin, change.get("step_over_mm", path.step_over_mm),
                                change.get("pitch_mm", path.pitch_mm),
                                contour=None if path.contour is None else path.contour[idx])))
    return out
