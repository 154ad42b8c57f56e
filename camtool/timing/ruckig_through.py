"""Surface pieces as exact ruckig state-to-state moves between through-states.

Each piece (waypoint k to k+1, states (q, q', q'') at both ends) is timed per
joint by the free ruckig package: one 1-DOF ruckig calculation per joint with
``minimum_duration`` = the piece duration the TCP schedule asks for, so all
joints share that duration (ruckig's time synchronisation, done per DOF). If a
joint needs longer, every joint is recalculated with the longest duration.

A ruckig profile is piecewise cubic in time (constant jerk per phase). The
piece is written out at every jerk switch of every joint, so the quintic
Hermite between consecutive samples (``Trajectory.sample``) reproduces each
joint's cubic exactly. Three numeric details make that hold in float64:

- **Time grid.** Piece durations and sample times are multiples of
  ``TIME_GRID_S`` (2^-30 s), and runs start on that grid, so sample intervals
  are exact even at t ~ 1000 s (otherwise a 1e-13 s error in a 50 µs interval
  gives a jerk error of several % on the track).
- **No near-coincident samples.** Switches of different joints closer than
  ``MIN_GAP_S`` would make intervals so short that position round-off (1 ulp
  of ~1000 mm) shows in the jerk. A joint whose switches fall that close to
  the samples already taken is recalculated by ruckig with a slightly lower
  jerk limit (``JERK_FACTORS``), which moves its switches; a piece where no
  factor helps keeps its quintic piece.
- **Residual.** ruckig meets the target position to ~1e-8 (its tolerance),
  which over a 1 ms interval would be a large jerk error. The residual at the
  piece end is removed by adding the quintic from zero to the residual (jerk
  < 1e-3 of a limit, position < 1e-8); cubic + quintic is still reproduced
  exactly by the Hermite pieces.

Every piece's samples are then checked with the exact Hermite bounds
(``quintic.piece_peaks``) at ``CHECK_SHARE`` of each limit; a piece that fails
keeps its quintic piece. Reasons for every fallback are returned.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, Result, Ruckig, RuckigError
from ruckig import Trajectory as RuckigTrajectory

from ..trajectory import quintic_coefficients
from .quintic import limit_ratio, piece_peaks

TIME_GRID_S = 2.0 ** -30      # exact binary time grid (~0.93 ns; exact up to 2^23 s)
MIN_GAP_S = 6e-5              # shortest interval between two samples of a piece
JERK_FACTORS = (1.0, 0.97, 0.94, 0.91, 0.87, 0.83, 0.78, 0.72, 0.65, 0.55, 0.45, 0.35, 0.25)  # retried jerk-limit scales
CHECK_SHARE = 0.995           # a ruckig piece is kept if its samples stay within this share of each limit
MAX_RESIDUAL = 1e-5           # largest ruckig end-state residual accepted (rad or mm)
SAME_DURATION_S = 1e-12       # a joint's ruckig duration counts as the piece duration within this
KEEP_SHORTER_S = 2 * TIME_GRID_S  # a joint this much shorter (grid rounding) keeps its own profile
CHUNK_PIECES = 1000            # pieces handled at once
CHECK_GRID = 4                # speed grid per sample interval in the check (intervals are ~1 ms)
PHASES = 7

REASONS = ("ruckig_error", "no_common_duration", "switch_times", "residual", "limits", "longer")  # "longer": assemble


def on_grid(t, up: bool = False):
    """Times rounded (or rounded up) to the exact time grid."""
    x = np.asarray(t, float) / TIME_GRID_S
    return (np.ceil(x) if up else np.round(x)) * TIME_GRID_S


@dataclass(frozen=True)
class ThroughPieces:
    """Result of ``through_pieces``: per piece duration, ruckig flag and fallback reason; interior samples.

    ``reason`` is "" for a ruckig piece, else one of ``REASONS``. Samples:
    ``piece`` (index into the pieces given), ``t_s`` from the piece start,
    and q, qd, qdd (native units).
    """

    duration_s: np.ndarray
    used: np.ndarray
    reason: np.ndarray
    piece: np.ndarray
    t_s: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray


class _DofSolver:
    """One 1-DOF ruckig instance per joint, with that joint's limits times ``share``."""

    def __init__(self, limits, share: float):
        self.dof = len(limits.velocity)
        self.jerk = [float(share * x) for x in limits.jerk]
        self.units = []
        for i in range(self.dof):
            inp = InputParameter(1)
            inp.max_velocity = [float(share * limits.velocity[i])]
            inp.max_acceleration = [float(share * limits.acceleration[i])]
            inp.max_jerk = [self.jerk[i]]
            self.units.append((Ruckig(1), inp, RuckigTrajectory(1)))

    def solve(self, i: int, x0, x1, duration_s: float, factor: float = 1.0):
        """(duration, t, j, p, v, a) of joint i's move from x0 to x1 (each (q, qd, qdd)); None on failure."""
        otg, inp, traj = self.units[i]
        inp.current_position = [x0[0]]
        inp.current_velocity = [x0[1]]
        inp.current_acceleration = [x0[2]]
        inp.target_position = [x1[0]]
        inp.target_velocity = [x1[1]]
        inp.target_acceleration = [x1[2]]
        inp.minimum_duration = duration_s
        if factor != 1.0:
            inp.max_jerk = [self.jerk[i] * factor]
        try:
            result = otg.calculate(inp, traj)
        except (RuckigError, RuntimeError):
            result = None
        finally:
            if factor != 1.0:
                inp.max_jerk = [self.jerk[i]]
        if result not in (Result.Working, Result.Finished):
            return None
        prof = traj.profiles[0][0]
        if prof.brake.duration > 0 or prof.accel.duration > 0:
            return None
        return traj.duration, prof.t, prof.j, prof.p, prof.v, prof.a


class _Profiles:
    """Per piece and joint: ruckig phase durations, jerks and phase-start states."""

    def __init__(self, n: int, dof: int):
        self.dur = np.full((n, dof), np.nan)
        self.t = np.zeros((n, dof, PHASES))
        self.j = np.zeros((n, dof, PHASES))
        self.p = np.zeros((n, dof, PHASES + 1))
        self.v = np.zeros((n, dof, PHASES + 1))
        self.a = np.zeros((n, dof, PHASES + 1))

    def store(self, rows, joints, results) -> None:
        """Store solver results for the (row, joint) pairs given (one bulk conversion per field)."""
        if not results:
            return
        rows, joints = np.asarray(rows, int), np.asarray(joints, int)
        self.dur[rows, joints] = [r[0] for r in results]
        for k, arr in enumerate((self.t, self.j, self.p, self.v, self.a), start=1):
            arr[rows, joints] = [r[k] for r in results]

    def starts(self):
        """Start time of every phase (n, dof, 7), as the exclusive cumulative sum of the durations."""
        c = np.cumsum(self.t, axis=-1)
        return np.concatenate([np.zeros(c.shape[:-1] + (1,)), c[..., :-1]], axis=-1)


def _switch_times(t: np.ndarray, j: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Jerk-switch times on the grid, strictly inside (0, T); NaN where none. Shapes (..., 7) -> (..., 7)."""
    c = np.cumsum(t, axis=-1)
    starts = np.concatenate([np.zeros(c.shape[:-1] + (1,)), c[..., :-1]], axis=-1)
    prev = np.full(t.shape[:-1], np.nan)
    out = np.full(t.shape, np.nan)
    for k in range(PHASES):
        live = t[..., k] > 0
        switch = live & ~np.isnan(prev) & (j[..., k] != prev)
        out[..., k] = np.where(switch, starts[..., k], np.nan)
        prev = np.where(live, j[..., k], prev)
    out = on_grid(out)
    with np.errstate(invalid="ignore"):
        inside = (out > 0) & (out < T[..., None])
    return np.where(inside, out, np.nan)


def _too_close(s: np.ndarray, taken: np.ndarray, gap: float) -> np.ndarray:
    """Per row: True if a time in ``s`` lies within (0, gap) of a time in ``taken`` or of another in ``s``."""
    with np.errstate(invalid="ignore"):
        d = np.abs(s[:, :, None] - taken[:, None, :])
        bad = ((d > 0) & (d < gap)).any(axis=(1, 2))
        d = np.abs(s[:, :, None] - s[:, None, :])
        bad |= ((d > 0) & (d < gap)).any(axis=(1, 2))
    return bad


def _evaluate(pr: _Profiles, rows: np.ndarray, times: np.ndarray):
    """q, qd, qdd (len(rows), dof) of the profiles of pieces ``rows`` at ``times`` (from the piece start)."""
    starts = pr.starts()[rows]                         # (m, dof, 7)
    k = (starts <= times[:, None, None]).sum(axis=-1) - 1
    k = np.clip(k, 0, PHASES - 1)[..., None]           # (m, dof, 1)
    dt = times[:, None] - np.take_along_axis(starts, k, -1)[..., 0]
    j = np.take_along_axis(pr.j[rows], k, -1)[..., 0]
    p = np.take_along_axis(pr.p[rows], k, -1)[..., 0]
    v = np.take_along_axis(pr.v[rows], k, -1)[..., 0]
    a = np.take_along_axis(pr.a[rows], k, -1)[..., 0]
    return (p + dt * (v + dt * (a / 2 + dt * j / 6)), v + dt * (a + dt * j / 2), a + dt * j)


def through_pieces(limits, q, qd, qdd, h_s, pieces, share: float) -> ThroughPieces:
    """Time surface pieces as exact ruckig moves; see the module doc.

    ``q``, ``qd``, ``qdd`` (n, dof) through-states; piece k runs from row k to
    k+1 and should last ``h_s[k]``; ``pieces`` lists the k to do; ``share`` of
    each limit is given to ruckig. Done in chunks of ``CHUNK_PIECES`` (bounded memory).
    """
    pieces = np.asarray(pieces, int)
    parts = [_through_chunk(limits, q, qd, qdd, h_s, pieces[a:a + CHUNK_PIECES], share)
             for a in range(0, max(len(pieces), 1), CHUNK_PIECES)]
    if len(parts) == 1:
        return parts[0]
    offset = np.cumsum([0] + [len(p.used) for p in parts[:-1]])
    return ThroughPieces(*(np.concatenate([getattr(p, f) for p in parts]) for f in ("duration_s", "used", "reason")),
                         np.concatenate([p.piece + o for p, o in zip(parts, offset)]),
                         *(np.concatenate([getattr(p, f) for p in parts]) for f in ("t_s", "q", "qd", "qdd")))


def _through_chunk(limits, q, qd, qdd, h_s, pieces, share: float) -> ThroughPieces:
    """``through_pieces`` for one chunk of pieces."""
    P = len(pieces)
    dof = q.shape[1]
    if P == 0:
        z = np.zeros((0, dof))
        return ThroughPieces(np.zeros(0), np.zeros(0, bool), np.zeros(0, str), np.zeros(0, int), np.zeros(0),
                             z, z.copy(), z.copy())
    ch = _Chunk(limits, q, qd, qdd, h_s, pieces, share)
    _common_durations(ch)
    taken = _spaced_switches(ch)
    # 3. samples: the union of switch times and both ends, evaluated from ruckig's phase states
    live = ch.reason == ""
    rows, times = _sample_times(taken, live)
    sq, sv, sa, first, last = _sampled(ch, rows, times, live)
    _check_limits(ch, rows, times, (sq, sv, sa))
    used = ch.reason == ""
    duration = np.where(used, ch.T, on_grid(np.asarray(h_s, float)[pieces], up=True))
    inner = used[rows] & ~first & ~last
    return ThroughPieces(duration, used, ch.reason.astype(str), rows[inner], times[inner], sq[inner], sv[inner],
                         sa[inner])


class _Chunk:
    """One chunk's pieces being timed: the through-states ``q``, ``qd``, ``qdd`` and the ``pieces`` (piece k runs
    from row k to k+1), each piece's duration ``T`` (on the grid), the ruckig profiles found (``pr``), and why a
    piece is not used (``reason``; "" while it is)."""

    def __init__(self, limits, q, qd, qdd, h_s, pieces, share: float):
        self.limits, self.q, self.qd, self.qdd, self.pieces = limits, q, qd, qdd, pieces
        self.P, self.dof = len(pieces), q.shape[1]
        self.solver = _DofSolver(limits, share)
        self.X0 = np.stack([q[pieces], qd[pieces], qdd[pieces]], axis=-1).tolist()     # [n][i] -> (q, qd, qdd)
        self.X1 = np.stack([q[pieces + 1], qd[pieces + 1], qdd[pieces + 1]], axis=-1).tolist()
        self.T = on_grid(np.asarray(h_s, float)[pieces], up=True)
        self.reason = np.full(self.P, "", dtype=object)
        self.pr = _Profiles(self.P, self.dof)

    def solve_pairs(self, rows, joints, factor=1.0):
        """Solve joint ``joints[m]`` of piece ``rows[m]`` at the piece's T; the rows that failed."""
        failed, done_n, done_i, results = set(), [], [], []
        for n, i in zip(rows.tolist(), joints.tolist()):
            res = self.solver.solve(i, self.X0[n][i], self.X1[n][i], float(self.T[n]), factor)
            if res is None:
                failed.add(n)
            else:
                done_n.append(n)
                done_i.append(i)
                results.append(res)
        self.pr.store(done_n, done_i, results)
        return failed


def _common_durations(ch: _Chunk) -> None:
    """1. every joint at the scheduled duration; if a joint needs longer, the others are redone at its
    duration rounded up to the grid (it keeps its own profile, its last phase running < 2 ns longer)."""
    pr, T, reason = ch.pr, ch.T, ch.reason
    rows, joints = np.divmod(np.arange(ch.P * ch.dof), ch.dof)
    reason[list(ch.solve_pairs(rows, joints))] = "ruckig_error"
    for _round in range(3):
        live = reason == ""
        longest = np.nanmax(np.where(live[:, None], pr.dur, -np.inf), axis=1)
        longer = live & (longest > T + SAME_DURATION_S)
        if not longer.any():
            break
        T[longer] = on_grid(longest[longer], up=True)
        rows, joints = np.nonzero(longer[:, None] & (pr.dur < T[:, None] - KEEP_SHORTER_S))
        reason[list(ch.solve_pairs(rows, joints))] = "ruckig_error"
    off = (pr.dur > T[:, None] + SAME_DURATION_S) | (pr.dur < T[:, None] - KEEP_SHORTER_S)
    reason[(reason == "") & off.any(axis=1)] = "no_common_duration"


def _spaced_switches(ch: _Chunk) -> np.ndarray:
    """2. joint by joint: keep switches MIN_GAP_S apart from the samples taken so far (lower jerk if needed);
    the samples taken (P, 2 + dof * PHASES): both ends, then each joint's switch times."""
    taken = np.full((ch.P, 2 + ch.dof * PHASES), np.nan)
    taken[:, 0], taken[:, 1] = 0.0, ch.T
    for i in range(ch.dof):
        s = _switch_times(ch.pr.t[:, i], ch.pr.j[:, i], ch.T)
        bad = (ch.reason == "") & _too_close(s, taken, MIN_GAP_S)
        _lower_jerk(ch, i, s, bad, taken)
        ch.reason[bad] = "switch_times"
        taken[:, 2 + i * PHASES: 2 + (i + 1) * PHASES] = s
    return taken


def _lower_jerk(ch: _Chunk, i: int, s: np.ndarray, bad: np.ndarray, taken: np.ndarray) -> None:
    """Joint ``i`` of the ``bad`` pieces recalculated with lower jerk limits (``JERK_FACTORS``) until its switches
    ``s`` keep clear of the samples ``taken``; ``s`` and ``bad`` updated in place, the factor-1 profile kept
    where no factor helps."""
    pr, T = ch.pr, ch.T
    for f in JERK_FACTORS[1:]:
        rows = np.flatnonzero(bad)
        if not len(rows):
            break
        keep = (pr.dur[rows, i].copy(), pr.t[rows, i].copy(), pr.j[rows, i].copy(), pr.p[rows, i].copy(),
                pr.v[rows, i].copy(), pr.a[rows, i].copy())
        failed = ch.solve_pairs(rows, np.full(len(rows), i), f)
        ok = np.array([n not in failed for n in rows]) & (np.abs(pr.dur[rows, i] - T[rows]) <= SAME_DURATION_S)
        s_new = _switch_times(pr.t[rows, i], pr.j[rows, i], T[rows])
        ok &= ~_too_close(s_new, taken[rows], MIN_GAP_S)
        s[rows[ok]] = s_new[ok]
        bad[rows[ok]] = False
        back = rows[~ok]  # restore the factor-1 profile where the retry did not help
        pr.dur[back, i], pr.t[back, i], pr.j[back, i] = keep[0][~ok], keep[1][~ok], keep[2][~ok]
        pr.p[back, i], pr.v[back, i], pr.a[back, i] = keep[3][~ok], keep[4][~ok], keep[5][~ok]


def _sample_times(taken: np.ndarray, live: np.ndarray):
    """(piece, time) of every sample of the ``live`` pieces: the samples ``taken`` without repeats, in order."""
    taken = np.sort(taken, axis=1)
    dup = np.zeros_like(taken, bool)
    dup[:, 1:] = taken[:, 1:] == taken[:, :-1]
    taken[dup] = np.nan
    rows, cols = np.nonzero(~np.isnan(taken) & live[:, None])
    times = taken[rows, cols]
    order = np.lexsort((times, rows))
    return rows[order], times[order]


def _sampled(ch: _Chunk, rows: np.ndarray, times: np.ndarray, live: np.ndarray):
    """(q, qd, qdd, first, last) of the samples: evaluated from ruckig's phase states, the residual at each
    ``live`` piece's end removed by a quintic from zero to it (a piece with too large a residual is not used),
    both ends the waypoints themselves; ``first`` / ``last`` mark each piece's first and last sample."""
    q, qd, qdd, pieces, T = ch.q, ch.qd, ch.qdd, ch.pieces, ch.T
    sq, sv, sa = _evaluate(ch.pr, rows, times)
    # residual at the piece end, removed by a quintic from zero to it
    ends = np.flatnonzero(live)
    eq, ev, ea = _evaluate(ch.pr, ends, T[ends])
    Tn = T[ends][:, None]
    rq, rv, ra = q[pieces[ends] + 1] - eq, qd[pieces[ends] + 1] - ev, qdd[pieces[ends] + 1] - ea
    big = np.abs(rq).max(axis=1) > MAX_RESIDUAL
    ch.reason[ends[big]] = "residual"
    c = quintic_coefficients(np.zeros_like(rq), np.zeros_like(rq), np.zeros_like(rq), rq, rv * Tn, ra * Tn**2)
    slot = np.full(ch.P, -1)
    slot[ends] = np.arange(len(ends))
    cc = [x[slot[rows]] for x in c]
    u = (times / T[rows])[:, None]
    Tr = T[rows][:, None]
    sq = sq + cc[0] + u * (cc[1] + u * (cc[2] + u * (cc[3] + u * (cc[4] + u * cc[5]))))
    sv = sv + (cc[1] + u * (2 * cc[2] + u * (3 * cc[3] + u * (4 * cc[4] + u * 5 * cc[5])))) / Tr
    sa = sa + (2 * cc[2] + u * (6 * cc[3] + u * (12 * cc[4] + u * 20 * cc[5]))) / Tr**2
    first = np.r_[True, rows[1:] != rows[:-1]][: len(rows)]
    last = np.r_[rows[1:] != rows[:-1], True][: len(rows)]
    for arr, src in ((sq, q), (sv, qd), (sa, qdd)):  # both ends are the waypoints themselves
        arr[first] = src[pieces[rows[first]]]
        arr[last] = src[pieces[rows[last]] + 1]
    return sq, sv, sa, first, last


def _check_limits(ch: _Chunk, rows: np.ndarray, times: np.ndarray, samples) -> None:
    """4. check every sample interval with the exact Hermite bounds: a piece over ``CHECK_SHARE`` of a limit,
    or past a position limit, is not used."""
    sq, sv, sa = samples
    limits = ch.limits
    same = rows[1:] == rows[:-1]
    a, b = np.flatnonzero(same), np.flatnonzero(same) + 1
    pk = piece_peaks(sq[a], sq[b], sv[a], sv[b], sa[a], sa[b], times[b] - times[a], limits.lower, limits.upper,
                     n_grid=CHECK_GRID)
    over = (limit_ratio(pk, limits.velocity, limits.acceleration, limits.jerk, CHECK_SHARE) > 1.0) \
        | pk.position_break.any(axis=1)
    failed = np.unique(rows[a][over])
    ch.reason[failed[ch.reason[failed] == ""]] = "limits"
