"""Leads lifted clear of the part: a path modifier, run after the raster, for leads that would enter the part.

A free-form face's leads run straight on along the row's tangent at the work's end
(``raster._straight_leads``), lifted by ``clearance_mm * away**3`` (``away``: the share of the
lead from the work, 0..1). Where the part goes on beyond the work's end and turns up towards
the tool (the rim of a door's handle recess, the foot of its window pillar, a flange) the
tangent runs into it: the Vito door's skin had 22 lead poses up to 4.6 mm inside the part.
The raster knows only its face; the part is the workpiece, so the lift is sized here, against
the part's own geometry (``signed_distance``: the distance of points in front of the part, as
the motion check measures it).

Each lead with a pose inside the part (deeper than ``inside_mm``: 0 on a mesh, a scan's noise
band) rises further, along its work end's tool axis, by ``c * away**3`` with the smallest ``c``
(found in ``ROUNDS`` rounds, each adding the largest deficit over ``away**3``) that puts every
pose of it ``clear_mm`` in front: the cube keeps the lead leaving the work without a kink or a
jump in curvature. Where the part rises so close to the work's end that no ``c`` up to
``MAX_RISE_LEADS`` lead lengths does, the square (no kink) and then a straight climb (a kink the
timing slows for; better than the tool in the part) are tried. The self-motion poses between
two leads take their ends' added lifts, blended along the transition (and rise by a sine bump
where they are still inside); the approach and the depart move with the first and last pose.
Orientations do not change. A lead none of them clears is left at the steepest (the motion
check then refuses it). Deterministic; a path with every lead clear comes back as it was (the same object).
"""
from __future__ import annotations

from dataclasses import replace
from typing import Callable

import numpy as np

from .toolpath import ZONE_CODE, Path

LEAD_CLEAR_MM = 1.0   # a lead or self-motion pose closer than this to the part is lifted
ROUNDS = 8            # rounds of lifting a lead and measuring it again
CHORD_STEP_MM = 0.25  # a lead or self-motion is measured along its chords at most this far apart (at 2 mm a chord of
                      # the Vito door's lead-ins ran 0.097 mm into a bent edge between its samples, at 0.02 mm on them)
CHORD_SLACK_MM = 0.02  # a lead's chords may come this close to the part's inside (the joint motion bows off them by 0.06 mm more on the door)
CLEARED_SHARE = 0.5   # a ramp whose poses end this share of clear_mm in front of the part clears it
MAX_RISE_LEADS = 3.0  # a lead rises by at most this many of its own lengths at its far end
RAMP_POWERS = (3, 2, 1)  # the lift's power of the lead's share: the cube first (no kink, no jump in curvature)

_LEAD_IN, _LEAD_OUT = ZONE_CODE["lead_in"], ZONE_CODE["lead_out"]
_SELF, _APPROACH, _DEPART = ZONE_CODE["self_motion"], ZONE_CODE["approach"], ZONE_CODE["depart"]


def _runs(mask: np.ndarray) -> list[np.ndarray]:
    """Index runs of consecutive True entries of ``mask``."""
    k = np.flatnonzero(mask)
    return [r for r in np.split(k, np.flatnonzero(np.diff(k) > 1) + 1) if len(r)]


def _leads(path: Path) -> list[tuple[np.ndarray, int, np.ndarray]]:
    """(pose indices, work-end pose index, away share of each pose) of every lead of the path, in path order."""
    out = []
    zone = np.asarray(path.zone)
    for code in (_LEAD_IN, _LEAD_OUT):
        same = (zone == code)
        for run in _runs(same):
            for k in np.split(run, np.flatnonzero(np.diff(path.segment[run]) != 0) + 1):
                n = len(k)
                away = (n - np.arange(n)) / n if code == _LEAD_IN else (np.arange(n) + 1.0) / n
                anchor = k[-1] + 1 if code == _LEAD_IN else k[0] - 1
                if 0 <= anchor < len(zone):
                    out.append((k, int(anchor), away))
    return sorted(out, key=lambda t: int(t[0][0]))


def _lead_chords(P: np.ndarray, k: np.ndarray, anchor: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(the lead's poses with its work end, in path order; chord index and share of points strictly inside its
    chords, ``CHORD_STEP_MM`` apart at most): a lead's pose can be in front of the part while the chord to the
    next one, or to the work's end, cuts a bent edge (the Vito door's lead-ins: 0.16 mm deep)."""
    chain = np.r_[k, anchor] if anchor > k[-1] else np.r_[anchor, k]
    q, w = _along_chords(P[chain])
    inner = w > 0
    return chain, q[inner], w[inner]


def _rise(sd_of: Callable, p: np.ndarray, up: np.ndarray, shape: np.ndarray, clear_mm,
          cap_mm: float) -> tuple[float, bool]:
    """(the smallest ``c`` (mm, at most ``cap_mm``) with every ``p + c * shape * up`` ``clear_mm`` in front, whether
    they are at least ``CLEARED_SHARE`` of that in front with it) (``up``: one direction, or one per point)."""
    c = 0.0
    for _ in range(ROUNDS + 1):
        sd = np.nan_to_num(sd_of(p + (c * shape)[:, None] * up), nan=np.inf, posinf=np.inf, neginf=-cap_mm)
        deficit = clear_mm - sd
        if deficit.max() <= 0 or c >= cap_mm:
            break
        c = min(c + float(np.max(deficit / np.maximum(shape, 1e-3))), cap_mm)
    return c, bool(np.all(sd >= np.minimum(CLEARED_SHARE * np.asarray(clear_mm), clear_mm)))


def cleared_leads(path: Path, signed_distance: Callable[[np.ndarray], np.ndarray], lead_mm: float,
                  only: np.ndarray | None = None, clear_mm: float = LEAD_CLEAR_MM, inside_mm: float = 0.0) -> Path:
    """``path`` with its leads (and the self-motions between them) that enter the part deeper than ``inside_mm``
    (0 on a mesh; a scan's noise band) lifted ``clear_mm`` clear of it (module docstring).
    ``signed_distance(points_mm)``: mm in front of the part (+) or inside it (-). ``lead_mm``: the raster's lead.
    ``only``: the poses whose leads may move (a free-form face's), None: all."""
    P = np.asarray(path.poses_mm[:, :3, 3], float)
    up = -np.asarray(path.poses_mm[:, :3, 2], float)      # off the part: against the tool's axis
    extra = np.zeros_like(P)
    cap = MAX_RISE_LEADS * max(lead_mm, 1.0)
    for k, anchor, away in _leads(path):
        if only is not None and not only[anchor]:
            continue
        chain, q, w = _lead_chords(P, k, anchor)
        C = (1 - w)[:, None] * P[chain][q] + w[:, None] * P[chain][q + 1]
        if (np.nan_to_num(signed_distance(P[k]), nan=np.inf).min() >= -inside_mm
                and np.nan_to_num(signed_distance(C), nan=np.inf).min() >= -inside_mm - CHORD_SLACK_MM):
            continue
        # the poses clear_mm in front, the points on the chords between them (and the work's end) out of the part
        pts = np.vstack([P[k], C])
        target = np.r_[np.full(len(k), clear_mm), np.full(len(C), -inside_mm - CHORD_SLACK_MM)]
        for power in RAMP_POWERS:   # the gentlest ramp that clears the part within the cap
            shape = away ** power
            s_chain = np.r_[shape, 0.0] if anchor > k[-1] else np.r_[0.0, shape]
            shape_pts = np.r_[shape, (1 - w) * s_chain[q] + w * s_chain[q + 1]]
            c, out = _rise(signed_distance, pts, up[anchor], shape_pts, target, cap)
            if out and c < cap:
                break
        extra[k] = (c * shape)[:, None] * up[anchor]
    extra = _transitions_follow(path, P, extra, signed_distance, (clear_mm, inside_mm), cap, only)
    if not extra.any():
        return path
    poses = np.array(path.poses_mm, float)
    poses[:, :3, 3] = P + extra
    return replace(path, poses_mm=poses)


def _transitions_follow(path: Path, P: np.ndarray, extra: np.ndarray, signed_distance: Callable, clear: tuple,
                        cap: float, only: np.ndarray | None) -> np.ndarray:
    """``extra`` with each self-motion run taking its two ends' added lifts (blended linearly, then a sine bump
    where still too close), the approach the first pose's and the depart the last pose's."""
    zone = np.asarray(path.zone)
    extra = extra.copy()
    for k in _runs(zone == _SELF):
        a, b = k[0] - 1, k[-1] + 1
        if a < 0 or b >= len(zone) or (only is not None and not (only[a] or only[b])):
            continue
        f = (np.arange(len(k)) + 1.0) / (len(k) + 1)
        extra[k] = (1 - f)[:, None] * extra[a] + f[:, None] * extra[b]
        bump = np.sin(np.pi * f)
        up = -np.asarray(path.poses_mm[k, :3, 2], float)
        # measured along the chords between the poses too (a transition's poses may lie 90 mm apart)
        chain = np.concatenate([[a], k, [b]])
        q, w = _along_chords(P[chain] + extra[chain])
        bump_q = (1 - w) * np.concatenate([[0.0], bump])[q] + w * np.concatenate([bump, [0.0]])[q]
        up_c = np.vstack([up[:1], up, up[-1:]])
        up_q = (1 - w)[:, None] * up_c[q] + w[:, None] * up_c[q + 1]
        at = (1 - w)[:, None] * (P[chain] + extra[chain])[q] + w[:, None] * (P[chain] + extra[chain])[q + 1]
        clear_mm, inside_mm = clear
        if np.nan_to_num(signed_distance(at), nan=np.inf).min() < -inside_mm:
            h, _ = _rise(signed_distance, at, up_q, bump_q, clear_mm, cap)
            extra[k] += (h * bump)[:, None] * up
    for code in (_APPROACH, _DEPART):
        k = np.flatnonzero(zone == code)
        if len(k):
            src = k[-1] + 1 if code == _APPROACH else k[0] - 1
            if 0 <= src < len(zone):
                extra[k] = extra[src]
    return extra


def _along_chords(chain: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(chord index, share along it) of points at most ``CHORD_STEP_MM`` apart on the polyline ``chain`` (its
    vertices included, the last one not)."""
    q, w = [], []
    for i, length in enumerate(np.linalg.norm(np.diff(chain, axis=0), axis=1)):
        n = max(1, int(np.ceil(length / CHORD_STEP_MM)))
        q.append(np.full(n, i))
        w.append(np.arange(n) / n)
    return np.concatenate(q), np.concatenate(w)
