"""Quintic timing of surface runs: TCP time law, through-derivatives, piece limits, slow-down.

All joint quantities are in native units (rad or mm, per s^k); times in s.
A *run* is a block of consecutive waypoints that starts and ends at rest.
Several runs are handled at once in one set of arrays: ``first``/``last``
mark the run ends, and piece k (waypoint k to k+1) exists iff ``not last[k]``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import CamtoolError
from ..trajectory import quintic_coefficients

MARGIN = 0.98            # share of each speed/acc/jerk limit the timing may use
STRETCH_PAD = 1.02       # extra stretch on top of the computed ratio, to converge fast
SMOOTH_RADIUS = 2        # pieces each side over which a slow-down is spread
MAX_ITERATIONS = 200
MIN_PIECE_S = 1e-3       # shortest piece (e.g. a repeated pose)
_SIGMA_ACC = 1.875       # max of d/dx of smootherstep 10x^3-15x^4+6x^5
_SIGMA_JERK = 5.7735     # max |d2/dx2| of the same


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


def through_derivative(x: np.ndarray, h_s: np.ndarray, first: np.ndarray, last: np.ndarray) -> np.ndarray:
    """Central finite difference dx/dt on non-uniform steps; zero at run ends.

    ``v_k = (h_r d_l + h_l d_r) / (h_l + h_r)`` with d the slopes of the pieces
    left and right of waypoint k (second-order accurate).
    """
    out = np.zeros_like(x)
    if len(x) < 3:
        return out
    d = np.diff(x, axis=0) / h_s[:, None]
    k = np.nonzero(~first & ~last)[0]
    hl = h_s[k - 1][:, None]
    hr = h_s[k][:, None]
    out[k] = (hr * d[k - 1] + hl * d[k]) / (hl + hr)
    return out


def _smooth_max(f: np.ndarray, piece_run: np.ndarray, radius: int) -> np.ndarray:
    """Spread stretch factors to neighbouring pieces of the same run (never below f)."""
    n = len(f)

    def shifted(x, s, fill):
        out = np.full(n, fill)
        same = np.zeros(n, bool)
        if s >= 0:
            out[: n - s] = x[s:]
            same[: n - s] = piece_run[s:] == piece_run[: n - s]
        else:
            out[-s:] = x[: n + s]
            same[-s:] = piece_run[: n + s] == piece_run[-s:]
        return np.where(same, out, fill), same

    wide = f.copy()
    for s in range(-2 * radius, 2 * radius + 1):
        x, _ = shifted(f, s, 1.0)
        np.maximum(wide, x, out=wide)
    total = np.zeros(n)
    count = np.zeros(n)
    for s in range(-radius, radius + 1):
        x, same = shifted(wide, s, 0.0)
        total += x
        count += same
    return total / count


def tcp_time_law(step_mm: np.ndarray, speed_mm_s: float, ramp_s: float) -> np.ndarray:
    """Time stamps (s) of one run's waypoints for TCP arc steps ``step_mm``.

    The TCP speed rises from rest along a smootherstep in time over ``ramp_s``,
    cruises at ``speed_mm_s`` and falls back to rest symmetrically; a run too
    short to reach the speed gets a lower peak.
    """
    s = np.concatenate([[0.0], np.cumsum(step_mm)])
    total = s[-1]
    v_peak = min(speed_mm_s, total / ramp_s)
    s_ramp = v_peak * ramp_s / 2
    t_total = ramp_s + total / v_peak

    def ramp_time(dist):  # invert S(x) = 2.5x^4 - 3x^5 + x^6 (S(1) = 1/2) by bisection
        y = dist / (v_peak * ramp_s)
        lo = np.zeros_like(y)
        hi = np.ones_like(y)
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            big = mid**4 * (2.5 - 3 * mid + mid * mid) > y
            hi = np.where(big, mid, hi)
            lo = np.where(big, lo, mid)
        return ramp_s * 0.5 * (lo + hi)

    t = ramp_s + (s - s_ramp) / v_peak
    up = s < s_ramp
    down = s > total - s_ramp
    t[up] = ramp_time(s[up])
    t[down] = t_total - ramp_time(total - s[down])
    t[0], t[-1] = 0.0, t_total
    return np.maximum.accumulate(t)


@dataclass(frozen=True)
class TimedRuns:
    """Result of timing surface runs: durations, derivatives, and the planned durations."""

    h_s: np.ndarray        # (n-1,) piece durations (undefined across run ends)
    h_plan_s: np.ndarray   # (n-1,) durations of the TCP time law before any slow-down
    qd: np.ndarray
    qdd: np.ndarray
    iterations: int


def time_runs(q, step_mm, first, last, run_id, limits, speed_mm_s: float) -> TimedRuns:
    """Time runs of waypoints at the TCP speed, slowing down locally until within limits.

    ``q`` (n, dof) waypoints; ``step_mm`` (n-1,) TCP distance of each piece;
    ``first``/``last`` run-end flags; ``run_id`` (n,) run number.
    """
    n, dof = q.shape
    vel, acc, jrk = limits.velocity, limits.acceleration, limits.jerk
    piece_ok = ~last[:-1] if n > 1 else np.zeros(0, bool)
    dq = np.abs(np.diff(q, axis=0)) if n > 1 else np.zeros((0, dof))
    h_floor = np.maximum((dq / (MARGIN * vel)).max(axis=1, initial=0.0), MIN_PIECE_S)
    step_eff = np.maximum(step_mm, speed_mm_s * h_floor)
    h_plan = np.ones(max(n - 1, 0))
    rate_per_s = np.ones(int(run_id.max()) + 1 if n else 0)
    starts = np.nonzero(first)[0]
    ends = np.nonzero(last)[0]
    for a, b in zip(starts, ends):
        if b == a:
            continue
        w = (dq[a:b] / (step_eff[a:b, None] / speed_mm_s)).max(axis=0)  # nominal joint speeds
        ramp_s = max(0.05, float(np.max(_SIGMA_ACC * w / (0.5 * MARGIN * acc))),
                     float(np.max(np.sqrt(_SIGMA_JERK * w / (0.5 * MARGIN * jrk)))))
        rate_per_s[run_id[a]] = 0.5 / ramp_s  # speed-ratio change per s allowed for slow-downs
        h_plan[a:b] = np.maximum(np.diff(tcp_time_law(step_eff[a:b], speed_mm_s, ramp_s)), MIN_PIECE_S)
    pinned = np.zeros((n, dof), bool)
    idx = np.nonzero(piece_ok)[0]
    piece_run = run_id[:-1][idx]
    rate = rate_per_s[piece_run] if len(idx) else np.zeros(0)
    lam = np.ones(len(idx))   # speed ratio per piece: planned duration / actual duration
    h = h_plan.copy()
    for it in range(MAX_ITERATIONS):
        h[idx] = h_plan[idx] / lam
        qd = through_derivative(q, h, first, last)
        qd[pinned] = 0.0
        qdd = through_derivative(qd, h, first, last)
        qdd[pinned] = 0.0
        if len(idx) == 0:
            return TimedRuns(h, h_plan, qd, qdd, it)
        pk = piece_peaks(q[idx], q[idx + 1], qd[idx], qd[idx + 1], qdd[idx], qdd[idx + 1], h[idx],
                         limits.lower, limits.upper)
        if pk.position_break.any():
            rows, cols = np.nonzero(pk.position_break)
            if pinned[idx[rows], cols].all() and pinned[idx[rows] + 1, cols].all():
                raise CamtoolError("timing: a quintic piece leaves the joint range even at rest")
            pinned[idx[rows], cols] = True
            pinned[idx[rows] + 1, cols] = True
            continue
        ratio = limit_ratio(pk, vel, acc, jrk)
        bad = ratio > 1.0
        if not bad.any():
            return TimedRuns(h, h_plan, qd, qdd, it)
        target = np.where(bad, lam / (ratio * STRETCH_PAD), lam)
        lam = _gentle(target, h[idx], piece_run, rate)
    raise CamtoolError(f"timing did not converge within the limits after {MAX_ITERATIONS} slow-down rounds")


def _gentle(lam: np.ndarray, h_s: np.ndarray, piece_run: np.ndarray, rate_per_s: np.ndarray) -> np.ndarray:
    """Lower speed ratios so they change by at most ``rate_per_s`` per second, then smooth (never raising)."""
    if len(lam) == 0:
        return lam
    t = np.cumsum(h_s) - h_s
    run_first = np.r_[True, piece_run[1:] != piece_run[:-1]]
    t = t - t[run_first][np.cumsum(run_first) - 1]  # piece start time within its run
    rt = rate_per_s * t
    big = (2.0 * (np.max(rt) + 2.0)) * (piece_run - piece_run.min())  # keeps runs apart in the scans
    fwd = rt + np.minimum.accumulate(lam - rt - big) + big
    bwd = -rt + np.minimum.accumulate((lam + rt + big)[::-1])[::-1] - big
    out = np.minimum(lam, np.minimum(fwd, bwd))
    return np.clip(_smooth_min(out, piece_run, SMOOTH_RADIUS), 1e-6, 1.0)


def _smooth_min(f: np.ndarray, piece_run: np.ndarray, radius: int) -> np.ndarray:
    """Moving average of a moving minimum within each run: smooth and never above ``f``."""
    return 1.0 / _smooth_max(1.0 / f, piece_run, radius)
