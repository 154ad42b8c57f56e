"""Exact limits of quintic Hermite pieces (the interpolation between a Trajectory's waypoints).

``piece_peaks`` bounds speed, acceleration and jerk of every piece (and flags
position-limit breaks); ``limit_ratio`` turns them into the time stretch that
brings a piece within a share of the limits. The time laws (``pathlaw.py``,
``runs.py``, ``flow.py``) and the ruckig pieces check themselves with them.
All joint quantities are in native units (rad or mm, per s^k); times in s.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..trajectory import quintic_coefficients

MARGIN = 0.98            # share of each speed/acc/jerk limit the timing plans with


@dataclass(frozen=True)
class PiecePeaks:
    """Per piece and joint (n, dof): upper bounds of |v|, |a|, |j|, and position-limit breaks."""

    speed: np.ndarray
    acc: np.ndarray
    jerk: np.ndarray
    position_break: np.ndarray  # bool


def _quadratic_roots(a, b, c):
    """Both real roots of a s^2 + b s + c (nan where none); linear case handled."""
    with np.errstate(divide="ignore", invalid="ignore"):
        disc = b * b - 4 * a * c
        sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
        quad = np.abs(a) > 1e-12 * (np.abs(b) + np.abs(c) + 1e-300)
        r1 = np.where(quad, (-b + sq) / (2 * a), np.where(b != 0, -c / b, np.nan))
        r2 = np.where(quad, (-b - sq) / (2 * a), np.nan)
    return r1, r2


def piece_peaks(q0, q1, v0, v1, a0, a1, h_s, lower, upper, n_grid: int = 16) -> PiecePeaks:
    """Bounds of speed, acc and jerk on quintic Hermite pieces, and position-limit breaks.

    Jerk and acceleration maxima are exact (roots of the quadratic jerk); the
    speed maximum is a grid maximum plus the bound max|a|*h/(2*n_grid), so it
    never underestimates. A piece with zero speed and acceleration at both ends
    of a joint is monotone in that joint and is judged by its end values.
    """
    h = np.asarray(h_s, float)[:, None]
    c0, c1, c2, c3, c4, c5 = quintic_coefficients(q0, v0 * h, a0 * h**2, q1, v1 * h, a1 * h**2)

    def jerk(s):
        return 6 * c3 + 24 * c4 * s + 60 * c5 * s * s

    def acc(s):
        return 2 * c2 + s * (6 * c3 + s * (12 * c4 + s * 20 * c5))

    def vel(s):
        return c1 + s * (2 * c2 + s * (3 * c3 + s * (4 * c4 + s * 5 * c5)))

    def pos(s):
        return c0 + s * (c1 + s * (c2 + s * (c3 + s * (c4 + s * c5))))

    with np.errstate(divide="ignore", invalid="ignore"):
        s_j = np.where(c5 != 0, -24 * c4 / (120 * c5), 0.0)
    s_j = np.clip(np.nan_to_num(s_j), 0.0, 1.0)
    jmax = np.maximum.reduce([np.abs(jerk(0.0)), np.abs(jerk(1.0)), np.abs(jerk(s_j))]) / h**3
    r1, r2 = _quadratic_roots(60 * c5, 24 * c4, 6 * c3)
    r1 = np.clip(np.nan_to_num(r1), 0.0, 1.0)
    r2 = np.clip(np.nan_to_num(r2), 0.0, 1.0)
    amax = np.maximum.reduce([np.abs(acc(0.0)), np.abs(acc(1.0)), np.abs(acc(r1)), np.abs(acc(r2))]) / h**2
    vgrid = np.zeros_like(c0)
    pmin = np.minimum(q0, q1)
    pmax = np.maximum(q0, q1)
    for s in np.linspace(0.0, 1.0, n_grid + 1):
        np.maximum(vgrid, np.abs(vel(s)), out=vgrid)
        p = pos(s)
        np.minimum(pmin, p, out=pmin)
        np.maximum(pmax, p, out=pmax)
    vmax = vgrid / h + amax * h / (2 * n_grid)
    pad = vmax * h / (2 * n_grid)
    monotone = (v0 == 0) & (v1 == 0) & (a0 == 0) & (a1 == 0)
    pmin = np.where(monotone, np.minimum(q0, q1), pmin - pad)
    pmax = np.where(monotone, np.maximum(q0, q1), pmax + pad)
    return PiecePeaks(vmax, amax, jmax, (pmin < lower) | (pmax > upper))


def limit_ratio(peaks: PiecePeaks, velocity, acceleration, jerk, share: float = MARGIN) -> np.ndarray:
    """Per piece: the time-stretch factor that brings it within ``share`` of every limit.

    Uniform time scaling by r divides speed by r, acc by r^2 and jerk by r^3.
    """
    r = np.maximum.reduce([
        peaks.speed / (share * velocity),
        np.sqrt(peaks.acc / (share * acceleration)),
        np.cbrt(peaks.jerk / (share * jerk)),
    ])
    return r.max(axis=1)
