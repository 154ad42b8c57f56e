"""Circles through three points: the geometry of circular moves (MoveC / MOVC)."""
from __future__ import annotations

import numpy as np


def cross3(a, b):
    """``np.cross(a, b)`` of 3-vectors (..., 3), the same products and differences in the same order (bit for
    bit): written out because np.cross's axis handling costs ~20 us a call, and the arc fitter asks for
    tens of thousands of small ones a program (issue #46's hood: a second of the post stage)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def circle_through(P0, Pv, P1):
    """Circle through P0, Pv, P1 (each (K, 3)): centre, radius, unit axis, start vector, sweep (rad)."""
    a, b = P0 - Pv, P1 - Pv
    axb = cross3(a, b)
    den = 2 * np.einsum("ki,ki->k", axb, axb)
    ok = den > 1e-12
    den = np.where(ok, den, 1.0)
    c = Pv + (cross3(np.einsum("ki,ki->k", a, a)[:, None] * b - np.einsum("ki,ki->k", b, b)[:, None] * a, axb)
              / den[:, None])
    n = axb / np.maximum(np.linalg.norm(axb, axis=1, keepdims=True), 1e-12)
    n = -n  # P0 -> Pv -> P1 turns positively about n
    r0, r1, rv = P0 - c, P1 - c, Pv - c
    rad = np.linalg.norm(r0, axis=1)

    def ang(u, v):
        return np.arctan2(np.einsum("ki,ki->k", cross3(u, v), n), np.einsum("ki,ki->k", u, v)) % (2 * np.pi)
    sweep = ang(r0, r1)
    bad_dir = ang(r0, rv) > sweep  # via not between: go the other way round
    n = np.where(bad_dir[:, None], -n, n)
    sweep = np.where(bad_dir, 2 * np.pi - sweep, sweep)
    return c, rad, n, r0, sweep, ok


def arc_point(c, n, r0, sweep, s):
    th = sweep * s
    ct, st = np.cos(th)[:, None], np.sin(th)[:, None]
    return c + r0 * ct + cross3(n, r0) * st + n * np.einsum("ki,ki->k", n, r0)[:, None] * (1 - ct)
