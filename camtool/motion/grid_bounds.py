"""Compiled grid lookups of the motion check's part bounds (numba).

``PartGeometry.lower_bound`` runs on millions of capsule pieces per check;
in numpy it makes a dozen temporaries a call, and that was a fifth of the
seed job's check. These loops compute the same numbers point by point
(``tests/test_motion_check.py`` compares them with the numpy formula).
They are written here, not taken from a library, because the bound is this
module's own construction (docs/motion-check.md "Speed").
"""
from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, inline="always")
def _node(p, g_lo, cell, shape):
    """(flat index, distance) of the grid node nearest the local point p (clamped to the grid)."""
    flat = 0
    a2 = 0.0
    for k in range(3):
        i = np.rint((p[k] - g_lo[k]) / cell)
        i = min(max(i, 0.0), shape[k] - 1.0)
        flat = flat * shape[k] + int(i)
        d = p[k] - (g_lo[k] + i * cell)
        a2 += d * d
    return flat, np.sqrt(a2)


@nb.njit(cache=True)
def lower_bounds(p, h, g_lo, cell, shape, rho, dist, box_lo, box_hi, slack, horizon):
    """Per local point p[i] and half length h[i]: the grid's lower bound of the value over the ball."""
    n = p.shape[0]
    out = np.empty(n)
    for i in range(n):
        t2 = 0.0
        for k in range(3):
            e = max(box_lo[k] - p[i, k], p[i, k] - box_hi[k], 0.0)
            t2 += e * e
        t = np.sqrt(t2)
        flat, a = _node(p[i], g_lo, cell, shape)
        lb = dist[flat] - a - h[i] - slack if rho[flat] >= a + h[i] else -np.inf
        if t > h[i]:
            lb = max(lb, horizon + t - h[i])
        out[i] = lb
    return out


@nb.njit(cache=True)
def nearest_nodes(p, g_lo, cell, shape):
    """(flat index, distance) of each local point's nearest grid node."""
    n = p.shape[0]
    flat = np.empty(n, np.int64)
    a = np.empty(n)
    for i in range(n):
        flat[i], a[i] = _node(p[i], g_lo, cell, shape)
    return flat, a


def load_compiled() -> None:
    """Load both loops from numba's cache (the first compiled call in a process also sets numba up, about
    0.6 s) on a one-point grid, with the argument types the check passes: a process made ready ahead of the
    check (``geometry.import_part_libraries``) does it while the run still plans."""
    p, v3, shape = np.zeros((1, 3)), np.zeros(3), np.ones(3, np.int64)
    nearest_nodes(p, v3, 1.0, shape)
    fixed = np.zeros(1)
    fixed.setflags(write=False)   # half lengths given per point arrive as a read-only broadcast
    for h in (np.zeros(1), fixed):
        lower_bounds(p, h, v3, 1.0, shape, np.zeros(1), np.zeros(1), v3, v3, 0.0, 1.0)
