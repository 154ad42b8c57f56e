"""Blend the corners of the merged targets: the zone (mm) of every target, and where even the
smallest zone cuts a corner of the surface too much, shorter moves beside it.

``BlendCorners`` takes merged ``Candidates`` (``camtool.program.candidates``) and returns the
``MovePlan``: every target but the first and the last gets the largest blend level whose
corner rounding stays within ``BLEND_SHARE`` of the tolerance (a chord deviates most in the
middle of its move, a corner at its target, and between them both fall off about
quadratically, so the two do not add up). The model is the simulator's: a parabolic blend
over equal times before and after the target, cutting at most r and at most half of either
move, so it deviates by a quarter of the difference of the two cut vectors.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .candidates import WORK, Candidates, runs, segment_max
from .moveplan import KIND_JOINT, KIND_LINEAR, MovePlan
from .moves import joint_travel  # the controller's zone convention for joint moves

BLEND_SHARE = 0.9       # share of the tolerance a corner may cut: a chord deviates most mid-move, a corner
                        # at its target, and between them both fall off about quadratically
ROUNDS = 8               # rounds of shorter moves beside corners that no level fits
MAX_GROWTH = 4.0         # ... while the targets stay within this many times the merged ones: a level no
                         # corner can get would double them every round (the simulator then finds the cut)


def corner_deviation(m: np.ndarray, d_in: np.ndarray, d_out: np.ndarray) -> np.ndarray:
    """Distance of corner-curve points ``p_k + m`` (C, 3) from the polyline through the
    corner: the rays from ``p_k`` back along the incoming move (``-d_in``) and on along
    the outgoing one (``d_out``); unit directions, or zero for a move that does not move
    the TCP."""
    def ray(v):
        along = np.maximum(np.einsum("ki,ki->k", m, v), 0.0)
        return np.linalg.norm(m - along[:, None] * v, axis=1)
    return np.minimum(ray(-d_in), ray(d_out))


def blend_fractions(r: float, L_in: np.ndarray, L_out: np.ndarray, T_in: np.ndarray,
                    T_out: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Share of the incoming and outgoing move a corner of radius r cuts.

    The corner starts ``tau`` before the target and ends ``tau`` after it, where
    ``tau = min(f_in T_in, f_out T_out)`` with ``f = min(1/2, r / L)`` (a move of length 0
    is cut by half): equal times on both sides, so the speed along the corner goes linearly
    from the incoming move's to the outgoing one's (a parabolic blend). Returns the cut
    shares ``tau / T_in`` and ``tau / T_out``.
    """
    f_in = np.where(L_in > 1e-9, np.minimum(0.5, r / np.maximum(L_in, 1e-9)), 0.5)
    f_out = np.where(L_out > 1e-9, np.minimum(0.5, r / np.maximum(L_out, 1e-9)), 0.5)
    tau = np.minimum(f_in * T_in, f_out * T_out)
    return (np.where(T_in > 0, tau / np.where(T_in > 0, T_in, 1.0), 0.0),
            np.where(T_out > 0, tau / np.where(T_out > 0, T_out, 1.0), 0.0))


def blend_levels(dev_at, C: int, budget, levels_mm) -> np.ndarray:
    """Index of the largest blend level (radius, mm, ascending) whose corner deviation
    ``dev_at(r, sel)`` (mm, for the corners ``sel``) stays within ``budget`` at each of C
    corners, every smaller level fitting too; -1 where even the smallest does not.

    The corner model (``blend_fractions``): from ``g_in`` of the incoming move before the
    target to ``g_out`` of the outgoing one after it the path is a quadratic curve with the
    target as control point; its middle, the point farthest from the corner, lies a
    quarter of ``g_out dq_out - g_in dq_in`` from the target (``corner_deviation``).
    """
    out = np.full(C, -1, int)
    ok = np.ones(C, bool)
    for i, r in enumerate(levels_mm):
        sel = np.flatnonzero(ok)
        if not len(sel):
            break
        good = dev_at(r, sel) <= budget[sel]
        ok[sel[~good]] = False
        out[sel[good]] = i
    return out


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=1, keepdims=True)
    return np.where(n > 1e-9, v / np.maximum(n, 1e-12), 0.0)


def _corner_levels(kin, idx, kind_moves, dev, P, q, J, t, zone, free, tol, levels):
    """Blend level of every corner (targets 1 .. m-2) within what the chords left of the
    tolerance (``blend_levels``, the linearised choice checked exactly); -1 where even the
    smallest level cuts the corner too much. Levels beyond what the moves' halves allow are
    written as the smallest such."""
    m = len(idx)
    c = np.arange(1, m - 1)
    a, k, b = idx[c - 1], idx[c], idx[c + 1]
    L_in = np.linalg.norm(P[k] - P[a], axis=1)
    L_out = np.linalg.norm(P[b] - P[k], axis=1)
    T_in, T_out = t[k] - t[a], t[b] - t[k]
    L_in = np.where(kind_moves[c] == KIND_JOINT, np.maximum(L_in, joint_travel(q[k] - q[a], kin.prismatic)), L_in)
    L_out = np.where(kind_moves[c + 1] == KIND_JOINT, np.maximum(L_out, joint_travel(q[b] - q[k], kin.prismatic)),
                     L_out)
    # a corner next to free motion (the end of a lead-out, ...) is cut off the surface
    corner_tol = np.where((free[a] | free[b]) & (zone[k] != WORK), np.maximum(tol[a], tol[b]), tol[k])
    budget = BLEND_SHARE * corner_tol  # chord and corner deviations peak at different places (see doc)
    lin_corner = (kind_moves[c] == KIND_LINEAR) & (kind_moves[c + 1] == KIND_LINEAR)
    d_in = _unit(P[k] - P[a])
    d_out = _unit(P[b] - P[k])
    dq_in, dq_out = q[k] - q[a], q[b] - q[k]

    def dev_at(r, sel, exact=False):
        f_in, f_out = blend_fractions(r, L_in[sel], L_out[sel], T_in[sel], T_out[sel])
        lc = lin_corner[sel]
        mid = np.empty((len(sel), 3))
        if lc.any():
            s_ = sel[lc]
            mid[lc] = (f_out[lc, None] * (P[b[s_]] - P[k[s_]]) - f_in[lc, None] * (P[k[s_]] - P[a[s_]])) / 4
        if (~lc).any():
            s_ = sel[~lc]
            cut = (f_out[~lc, None] * dq_out[s_] - f_in[~lc, None] * dq_in[s_]) / 4
            if exact:
                mid[~lc] = kin.pose(q[k[s_]] + cut)[0] - P[k[s_]]
            else:
                mid[~lc] = np.einsum("kij,kj->ki", J[k[s_]], cut)
        return corner_deviation(mid, d_in[sel], d_out[sel])

    lv = blend_levels(dev_at, len(c), budget, levels)
    for _ in range(4):  # the linearised choice, checked exactly; one level down where it fails
        sel = np.flatnonzero((lv >= 0) & ~lin_corner)
        if not len(sel):
            break
        radii = levels[lv[sel]]
        devs = np.empty(len(sel))
        for r in np.unique(radii):
            w = radii == r
            devs[w] = dev_at(r, sel[w], exact=True)
        over = sel[devs > budget[sel]]
        if not len(over):
            break
        lv[over] -= 1
    # levels beyond what the moves' halves allow cut the same corner: write the smallest such
    reach = np.maximum(L_in, L_out) / 2
    smallest = np.searchsorted(levels, reach - 1e-9)  # first level at least half the longer move
    return np.where(lv >= 0, np.minimum(lv, smallest), lv)


@dataclass(frozen=True)
class BlendCorners:
    """The move plan of merged candidates: kinds, blend levels and rows (module doc).

    ``levels_mm``: the format's blend radii (ascending, all > 0); a corner on the surface never
    gets less than ``min_level_on_surface`` (never an exact stop there): where even that level
    cuts it too much, a skipped waypoint in the middle of each move beside it becomes a target,
    or, where none is skipped, a point of the planned motion near the corner.
    """

    levels_mm: tuple
    min_level_on_surface: int = 0

    def plan(self, cand: Candidates) -> MovePlan:
        levels = np.asarray(self.levels_mm, float)
        min_level_on_surface = self.min_level_on_surface
        kin, st, ratio_exact, keep, origin = cand.kin, cand.st, cand.ratio_exact, cand.keep.copy(), cand.origin
        most = MAX_GROWTH * max(int(keep.sum()), 2)
        for round_ in range(ROUNDS + 1):
            t, q, zone, P, J = st["t"], st["q"], st["zone"], st["P"], st["J"]
            first, last = runs(zone == WORK)
            idx = np.flatnonzero(keep)
            # a move is linear when it starts and ends on process waypoints (and is not the first)
            in_proc = st["in_proc"]
            kind_moves = np.where(in_proc[idx] & np.r_[False, in_proc[idx[:-1]]], KIND_LINEAR, KIND_JOINT)
            kind_moves[0] = KIND_JOINT
            m = len(idx)
            dev = np.concatenate([[0.0], segment_max(keep, ratio_exact) * st["merge_tol"][idx[1:]]]) if m > 1 \
                else np.zeros(m)
            level = np.full(m, -1, int)
            if m <= 2:
                break
            lv = _corner_levels(kin, idx, kind_moves, dev, P, q, J, t, zone, st["free"], st["tol"], levels)
            # where even the smallest level a corner must have (on the surface: no stop) cuts it too
            # much, shorter moves flatten it: a skipped waypoint in the middle of each move beside it
            # becomes a target, or, where none is skipped, a point of the planned motion near the corner
            c = np.arange(1, m - 1)
            on_row = np.zeros(m, bool)
            for i0, i1 in zip(np.searchsorted(idx, first), np.searchsorted(idx, last)):
                on_row[i0:i1 + 1] = True
            bad = c[lv < np.where(on_row[c], max(min_level_on_surface, 0), 0)]
            level[c] = lv
            if not len(bad) or round_ == ROUNDS or m > most:
                break
            added = False
            steps, times = [], []
            for j in bad:
                for a_, b_, near in ((idx[j - 1], idx[j], idx[j]), (idx[j], idx[j + 1], idx[j])):
                    if b_ - a_ > 1:
                        keep[(a_ + b_) // 2] = True
                        added = True
                    elif t[b_] > t[a_] and on_row[j]:
                        # a quarter of the move from the corner, on the planned motion
                        steps.append(a_)
                        times.append(t[near] + (0.25 if near == a_ else -0.25) * (t[b_] - t[a_]))
            if steps:
                steps, times = np.array(steps), np.array(times)
                u, i_u = np.unique(times, return_index=True)
                cand = replace(cand, keep=keep, origin=origin).with_points(steps[i_u], u, picked=True)
                st, keep, origin, ratio_exact = cand.st, cand.keep.copy(), cand.origin, cand.ratio_exact
                added = True
            if not added:
                break
        t, q, zone, P, R = st["t"], st["q"], st["zone"], st["P"], st["R"]
        first, last = runs(zone == WORK)
        # rows: from a row's first to its last work point the tool is on the surface
        row = np.full(m, -1, int)
        row_start = np.zeros(m, bool)
        row_end = np.zeros(m, bool)
        pos_first = np.searchsorted(idx, first)
        pos_last = np.searchsorted(idx, last)
        for r_, (i0, i1) in enumerate(zip(pos_first, pos_last)):
            row[i0:i1 + 1] = r_
            row_start[i0] = True
            row_end[i1] = True
        on_surface = row >= 0
        return MovePlan(wp=origin[idx], kind=kind_moves, t=t[idx], level=level, row=row, row_start=row_start,
                        row_end=row_end, free=~on_surface, deviation_mm=dev, P=P[idx], R=R[idx],
                        q=q[idx], rows=len(first), zone=zone[idx])
