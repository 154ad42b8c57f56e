"""No turn above ``MAX_TURN_DEG`` between neighbouring work poses of a free-form face: a path modifier.

A free-form face's rows are sampled at ``raster.pitch_mm`` along the surface, and the tool axis follows the face's
smoothed normal. Where the face bends tighter than the pitch (the noether panel scan's pocket rim turns its own
12.5 mm mean normal 10 deg over one 10 mm step) neighbouring work poses turn by more than issue #46 allows (5 deg).
The planner's sag split (``plan.sag``) halves such steps in the joint path, but only where it sees them as one
step: where the planner lifts the tool off the part between the two poses (a retract at a wrist flip, 9 of the
panel's 3736 steps, up to 10.2 deg) the step is no longer one, and the turn stays. So the path itself is refined
here, before anything is planned: each such step is cut into the fewest equal pieces that turn at most
``MAX_TURN_DEG`` (its orientation slerped, each new point taken onto the face), and the planner then sees the
turn spread over those poses (on the panel the wrist turns about half as much a step, and 8 of its 9 retracts
go).

Only work steps (both poses work, one segment, one free-form face) are cut; leads, connectors and analytic faces
keep their poses. A path with no such step comes back as the same object.

Why by hand: scipy's rotations give the slerp; no library refines a tool path where its axis turns
(noether's tool-path modifiers resample at a uniform spacing, not by the turn).
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Callable, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from .toolpath import WORK, Path

MAX_TURN_DEG = 5.0   # issue #46: "no turn of more than 5 deg between neighbouring work poses"

Projector = Callable[..., np.ndarray]   # points (m, 3) mm onto a face (NaN where it has none under one; keywords
                                        # ``along`` (m, 3) lines, ``continued``: the face continued over its holes)


def turning_steps(path: Path, faces: Sequence[tuple[np.ndarray, Projector]],
                  max_turn_rad: float = math.radians(MAX_TURN_DEG)) -> tuple[np.ndarray, np.ndarray]:
    """(the first pose k of each work step k -> k+1 on one of ``faces`` (mask of its poses, projector) whose tool
    axis turns by more than ``max_turn_rad``, the index into ``faces`` of each)."""
    zone, seg = np.asarray(path.zone), np.asarray(path.segment)
    step = (zone[:-1] == WORK) & (zone[1:] == WORK) & (seg[:-1] == seg[1:])
    z = np.asarray(path.poses_mm[:, :3, 2], float)
    step &= np.einsum("ki,ki->k", z[:-1], z[1:]) < math.cos(max_turn_rad)
    which = np.full(len(step), -1)
    for i, (mask, _) in enumerate(faces):
        mask = np.asarray(mask, bool)
        which[step & mask[:-1] & mask[1:] & (which < 0)] = i
    k = np.flatnonzero(which >= 0)
    return k, which[k]


def split_turns(path: Path, faces: Sequence[tuple[np.ndarray, Projector]],
                max_turn_deg: float = MAX_TURN_DEG) -> tuple[Path, int]:
    """(``path`` with every work step on one of ``faces`` (mask of its poses, projector onto it) that turns its
    tool axis by more than ``max_turn_deg`` cut into n equal pieces (module doc), how many poses were added).

    n is the least that turns the whole frame (the axis and the spin about it) by at most ``max_turn_deg`` a
    piece: the axis then turns at most that. The new poses are work poses of the step's segment (and face,
    contour run), numbered along it; their points are the chord's taken onto the face (kept on the chord
    where the face has none under them)."""
    max_turn_rad = math.radians(max_turn_deg)
    k, which = turning_steps(path, faces, max_turn_rad)
    if not len(k):
        return path, 0
    P = np.asarray(path.poses_mm, float)
    Ra, Rb = Rotation.from_matrix(P[k, :3, :3]), Rotation.from_matrix(P[k + 1, :3, :3])
    rel = (Ra.inv() * Rb).as_rotvec()
    n = np.ceil(np.linalg.norm(rel, axis=1) / max_turn_rad - 1e-12).astype(int)
    src = np.repeat(np.arange(len(k)), n - 1)                                 # the step of each new pose
    f = np.concatenate([np.arange(1, m) / m for m in n])                     # its place along the step
    new = np.broadcast_to(np.eye(4), (len(src), 4, 4)).copy()
    new[:, :3, :3] = (Ra[src] * Rotation.from_rotvec(f[:, None] * rel[src])).as_matrix()
    chord = P[k[src], :3, 3] + f[:, None] * (P[k[src] + 1, :3, 3] - P[k[src], :3, 3])
    new[:, :3, 3] = chord
    half = 0.5 * np.linalg.norm(P[k[src] + 1, :3, 3] - P[k[src], :3, 3], axis=1)
    for i, (_, project) in enumerate(faces):
        on = which[src] == i
        if on.any():
            new[on, :3, 3] = _onto_face(project, chord[on], new[on, :3, 2], half[on])
    return _with_poses(path, k[src], f, new), len(src)


def _onto_face(project, chord: np.ndarray, axis: np.ndarray, half: np.ndarray) -> np.ndarray:
    """The chord's points taken onto the face along their own tool axes (the surface's normal: the ship hull's
    bilge, 74 deg from its chart plane, had no face under a point along the chart's normal and a pose stayed on
    the chord, 0.45 mm inside the hull) where that meets it within half the step; else along the chart's normal
    (``project``'s default); else, over a hole the step crosses, onto the face continued across it
    (``continued=True``) where that lies within half the step; else kept on the chord. On the chord over a
    4.5 mm hole of the noether panel scan a pose rode 0.66 mm above the hole's rim, past the 0.6 mm the motion
    check allows (the rim sags under a 10 mm chord; with its axes low-passed that step was cut in two, not three)."""
    onto = project(chord, along=axis)
    far = ~within_mm(onto, chord, half)
    if far.any():
        onto[far] = project(chord[far])
    miss = ~np.isfinite(onto).all(axis=1)
    if miss.any():
        onto[miss] = project(chord[miss], continued=True)
        onto[miss & ~within_mm(onto, chord, half)] = np.nan
    return np.where(np.isfinite(onto).all(axis=1)[:, None], onto, chord)


def within_mm(p: np.ndarray, ref: np.ndarray, radius_mm: np.ndarray) -> np.ndarray:
    """(m,) whether each point taken onto a face lies within ``radius_mm`` of its reference point (False where it
    has none: NaN). A face that overhangs its chart plane holds another layer farther off (the hull's stern)."""
    with np.errstate(invalid="ignore"):
        return np.linalg.norm(p - ref, axis=1) <= radius_mm


def _with_poses(path: Path, after: np.ndarray, f: np.ndarray, poses: np.ndarray) -> Path:
    """``path`` with ``poses`` inserted, each after pose ``after`` at ``f`` (0..1) along its step, carrying that
    pose's segment, zone, face and contour flag; the work points of each segment numbered 1.. again."""
    key = np.r_[np.arange(len(path), dtype=float), after + f]
    order = np.argsort(key, kind="stable")
    src = np.r_[np.arange(len(path)), after][order]          # the pose each row copies its labels from

    def take(a):
        return None if a is None else np.asarray(a)[src]
    seg, zone = take(path.segment), take(path.zone)
    point = take(path.point)
    for s in np.unique(np.asarray(path.segment)[after]):
        rows = (zone == WORK) & (seg == s)
        point[rows] = np.arange(1, rows.sum() + 1)
    return replace(path, poses_mm=np.concatenate([np.asarray(path.poses_mm, float), poses])[order], segment=seg,
                   point=point, zone=zone, face=take(path.face), contour=take(path.contour))
