"""Time laws along a geometric joint path: plateaus of constant path speed joined by jerk-limited S-curves.

A *section* (a surface run, or a soft group of a free chain) is a cubic spline
``q(s)`` through its poses (``PathSpline``; not-a-knot, C2, two poses: a straight
line), ``s`` a path parameter (TCP chord length in mm on runs, normalised joint
chord on free chains). It starts and ends at rest. Its time law ``s(t)`` is

    rest -> S-curve -> plateau v_0 -> S-curve -> plateau v_1 -> ... -> S-curve -> rest

- **Plateaus.** Each piece of the spline has a target speed (``target``); consecutive
  pieces with the same target form a plateau, run at exactly that constant speed.
  At constant speed the joint motion on a spline piece is a cubic in time, so the
  quintic Hermite between two poses reproduces it exactly: speed, acceleration and
  jerk there are ``q' v``, ``q'' v^2`` and ``q''' v^3`` (``speed_bounds`` gives the
  highest constant speed within the limits, per piece, exactly).
- **S-curves.** A change of speed is a jerk-limited S-curve in time (path jerk +J,
  optional constant acceleration A, -J). It lies in the *faster* plateau: a slower
  plateau keeps its speed over its whole length (a slow stretch is entered at its
  speed and left at its speed). Its path bounds A and J are the largest (on a grid,
  refined by bisection) that keep every joint within 98 % of its limits at the
  S-curve's own instants, positions and path speeds, by the triangle inequality on
  ``qdd = q'' v^2 + q' a``, ``qddd = q''' v^3 + 3 q'' v a + q' j`` with the piece maxima
  of |q'|, |q''|, |q'''| (``_Budget.fits``). ``transition_limits`` is the closed form
  for one set of maxima at one top speed (``runs.lead_bound_mm``).
- **Fitting.** A plateau too short for the S-curves it must hold is lowered (bisection
  on its speed) until they fit; equal neighbours merge. Speeds only go down, so this
  ends. A section that cannot reach its target therefore still starts and ends at rest.
- **Samples.** Every pose at its time, every phase boundary of the S-curves, and
  samples every ``FILL_S`` inside S-curves; q, q', q'' of the composition at each.
  ``check_section`` bounds the quintic Hermite between them exactly
  (``quintic.piece_peaks``); a section above ``CHECK_SHARE`` of a limit is re-planned
  with lower S-curve bounds (``DERATE``).

All quantities: path parameter s, joint values in native units, times in s.
"""
from __future__ import annotations

import hashlib
from collections import OrderedDict
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline

from .quintic import MARGIN, limit_ratio, piece_peaks
from .scurve_fit import fits_compiled, search_compiled

FILL_S = 0.010          # longest sample interval inside an S-curve
MIN_GAP_S = 1e-3        # samples closer than this to a kept one are dropped (poses are always kept)
CHECK_SHARE = 0.995     # a section's Hermite pieces must stay within this share of every limit
CHECK_GRID = 6          # speed grid per Hermite piece in that check (a bound: grid maximum + max|a| h / 12)
DERATE = 0.8            # S-curve bounds are scaled by this when a section breaks CHECK_SHARE
MAX_DERATE_ROUNDS = 8
A_SHARES = (1.0, 0.7, 0.5, 0.3)  # transition_limits: shares of the acceleration budget tried
SCURVE_SAMPLES = 16     # instants of an S-curve at which its joint use is bounded
J_GRID = 2.0 ** np.arange(4.0, -9.0, -1.0)     # path jerks tried, relative to the section's reference
A_GRID = 4.0 ** np.arange(2.0, -3.0, -1.0)     # path accelerations tried, relative likewise
REFINE_STEPS = 4        # bisection steps refining the best grid J, then A
SPEED_TOL = 1e-3        # a plateau lowered to fit its S-curves: relative precision of its speed
_FRACTIONS: dict = {}   # instants of an S-curve as shares of its duration, per sample count


# ----------------------------------------------------------------------------- the geometric path


class PathSpline:
    """Cubic spline q(s) through the poses ``q`` (n, dof) at strictly increasing ``s`` (n,).

    Not-a-knot for n >= 3 (a parabola for n = 3), a straight line for n = 2.
    ``c`` (4, n-1, dof): per piece ``q = c0 x^3 + c1 x^2 + c2 x + c3`` with
    ``x = s - s_k`` (scipy's layout); ``c3`` is the pose itself.
    """

    def __init__(self, s: np.ndarray, q: np.ndarray):
        s = np.asarray(s, float)
        q = np.asarray(q, float)
        self.s, self.q = s, q
        n, dof = q.shape
        if n == 2:
            c = np.zeros((4, 1, dof))
            c[2, 0] = (q[1] - q[0]) / (s[1] - s[0])
            c[3, 0] = q[0]
        else:
            c = np.array(CubicSpline(s, q, bc_type="not-a-knot").c)
            c[3] = q[:-1]
        self.c = c
        self.h = np.diff(s)

    @property
    def length(self) -> float:
        return float(self.s[-1] - self.s[0])

    def piece_of(self, x: np.ndarray) -> np.ndarray:
        return np.clip(np.searchsorted(self.s, x, side="right") - 1, 0, len(self.h) - 1)

    def derivatives(self, x: np.ndarray, k: np.ndarray | None = None):
        """(q, q', q'', q''') at path positions ``x`` (m,), each (m, dof); ``k``: their pieces."""
        x = np.asarray(x, float)
        if k is None:
            k = self.piece_of(x)
        u = (x - self.s[k])[:, None]
        c0, c1, c2, c3 = (self.c[i][k] for i in range(4))
        q = ((c0 * u + c1) * u + c2) * u + c3
        d1 = (3 * c0 * u + 2 * c1) * u + c2
        d2 = 6 * c0 * u + 2 * c1
        d3 = 6 * c0
        return q, d1, d2, d3

    def piece_bounds(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per piece and joint (n-1, dof): exact maxima of |q'|, |q''| and |q'''| over the piece."""
        c0, c1, c2, _ = self.c
        h = self.h[:, None]
        d1_0, d1_h = np.abs(c2), np.abs((3 * c0 * h + 2 * c1) * h + c2)
        with np.errstate(divide="ignore", invalid="ignore"):
            xv = np.where(c0 != 0, -c1 / (3 * c0), -1.0)
        inside = (xv > 0) & (xv < h)
        xv = np.where(inside, xv, 0.0)
        d1_v = np.where(inside, np.abs((3 * c0 * xv + 2 * c1) * xv + c2), 0.0)
        p1 = np.maximum(np.maximum(d1_0, d1_h), d1_v)
        p2 = np.maximum(np.abs(2 * c1), np.abs(6 * c0 * h + 2 * c1))
        p3 = np.abs(6 * c0)
        return p1, p2, p3


def speed_bounds(p1, p2, p3, limits, share: float = MARGIN):
    """Highest constant path speed per piece within ``share`` of every limit: (speed (n-1,), joint, kind).

    ``kind`` is 0 (speed), 1 (acceleration) or 2 (jerk): the limit that binds.
    """
    with np.errstate(divide="ignore"):
        r = np.stack([share * limits.velocity / p1, np.sqrt(share * limits.acceleration / p2),
                      np.cbrt(share * limits.jerk / p3)])  # (3, n-1, dof)
    flat = r.transpose(1, 0, 2).reshape(len(p1), -1)
    arg = np.argmin(flat, axis=1)
    v = flat[np.arange(len(p1)), arg]
    return v, arg % p1.shape[1], arg // p1.shape[1]


# ----------------------------------------------------------------------------- S-curves


def scurve(v0: float, v1: float, A: float, J: float) -> tuple[list[tuple[float, float]], float, float]:
    """Jerk-limited change of speed v0 -> v1 (zero acceleration at both ends) with |a| <= A, |j| <= J.

    Returns (phases [(jerk, duration)], duration, distance). Distance = mean speed x duration.
    """
    dv = v1 - v0
    if dv == 0.0:
        return [], 0.0, 0.0
    sign = 1.0 if dv > 0 else -1.0
    dv = abs(dv)
    if dv * J <= A * A:
        tj = float(np.sqrt(dv / J))
        phases = [(sign * J, tj), (-sign * J, tj)]
        T = 2 * tj
    else:
        tj = A / J
        ta = dv / A - tj
        phases = [(sign * J, tj), (0.0, ta), (-sign * J, tj)]
        T = 2 * tj + ta
    return phases, T, 0.5 * (v0 + v1) * T


def scurve_time(dv: float, A: float, J: float) -> float:
    dv = abs(dv)
    return 2 * float(np.sqrt(dv / J)) if dv * J <= A * A else dv / A + A / J


def transition_limits(p1, p2, p3, vm: float, limits, share: float = MARGIN, dv: float = 1.0):
    """Path bounds (A, J) of an S-curve over a stretch with joint-derivative maxima p1, p2, p3 (dof,).

    ``vm``: the highest path speed in it. Of the acceleration shares ``A_SHARES`` the one
    with the shortest S-curve for a speed change ``dv`` is taken. (0, 0) if none fits.
    """
    ok = p1 > 0
    if not ok.any():
        return np.inf, np.inf
    a_room = share * limits.acceleration[ok] - p2[ok] * vm * vm
    if np.any(a_room <= 0):
        return 0.0, 0.0
    a_full = float(np.min(a_room / p1[ok]))
    best = (0.0, 0.0, np.inf)
    for f in A_SHARES:
        A = f * a_full
        j_room = share * limits.jerk[ok] - p3[ok] * vm ** 3 - 3 * p2[ok] * vm * A
        if np.any(j_room <= 0):
            continue
        J = float(np.min(j_room / p1[ok]))
        T = scurve_time(dv, A, J)
        if T < best[2]:
            best = (A, J, T)
    return best[0], best[1]


# ----------------------------------------------------------------------------- planning a section


@dataclass
class Plateau:
    """Pieces a..b-1 (spline pieces) at constant speed v; s0, s1 their path span."""

    a: int
    b: int
    v: float
    s0: float
    s1: float

    @property
    def length(self) -> float:
        return self.s1 - self.s0


@dataclass
class SectionPlan:
    """A planned time law: plateaus, the S-curve before each (and after the last), phases."""

    plateaus: list
    transitions: list          # len(plateaus) + 1 dicts: v0, v1, A, J, D, T, phases, into (plateau index or -1)
    phase_t0: np.ndarray = field(default_factory=lambda: np.zeros(0))
    phase_s0: np.ndarray = field(default_factory=lambda: np.zeros(0))
    phase_v0: np.ndarray = field(default_factory=lambda: np.zeros(0))
    phase_a0: np.ndarray = field(default_factory=lambda: np.zeros(0))
    phase_j: np.ndarray = field(default_factory=lambda: np.zeros(0))
    phase_tau: np.ndarray = field(default_factory=lambda: np.zeros(0))
    phase_cruise: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))

    @property
    def duration(self) -> float:
        return float(self.phase_t0[-1] + self.phase_tau[-1]) if len(self.phase_tau) else 0.0


class _Budget:
    """Joint-derivative maxima per spline piece, and the S-curves that fit them."""

    def __init__(self, spline: PathSpline, limits, share: float = MARGIN):
        self.s = spline.s
        self.p1, self.p2, self.p3 = spline.piece_bounds()
        self.a_lim = share * limits.acceleration
        self.j_lim = share * limits.jerk
        self.v_lim = share * limits.velocity
        p1max = self.p1.max(axis=0)
        ok = p1max > 0
        self.a_ref = float(np.min(self.a_lim[ok] / p1max[ok])) if ok.any() else 1.0
        self.j_ref = float(np.min(self.j_lim[ok] / p1max[ok])) if ok.any() else 1.0
        self._c = None  # contiguous copies for the compiled test, made on first use

    def fits(self, v0: float, v1: float, A: np.ndarray, J: np.ndarray, s_start: np.ndarray,
             samples: int = SCURVE_SAMPLES) -> np.ndarray:
        """Per candidate (A[c], J[c], start position s_start[c]): True if the S-curve v0 -> v1 keeps
        every joint within the shares of its limits, by the triangle inequality on the piece maxima
        at the actual path speed and acceleration of ``samples`` instants (phase ends included).

        Compiled (``scurve_fit.py``); ``fits_numpy`` is the same test in numpy, the reference."""
        A, J, s_start = (np.ascontiguousarray(np.atleast_1d(np.asarray(x, float))) for x in (A, J, s_start))
        self._compiled()
        return fits_compiled(v0, v1, A, J, s_start, self._fractions(samples), *self._c)

    def search(self, v0: float, v1: float, s_edge: float, before: bool, a_grid: np.ndarray, j_grid: np.ndarray,
               refine_steps: int, samples: int = SCURVE_SAMPLES) -> tuple[bool, float, float]:
        """(found, A, J) of ``_scurve_at``'s search, compiled (``scurve_fit.search_compiled``)."""
        self._compiled()
        return search_compiled(v0, v1, s_edge, before, np.ascontiguousarray(a_grid, float),
                               np.ascontiguousarray(j_grid, float), refine_steps, self._fractions(samples), *self._c)

    @staticmethod
    def _fractions(samples: int) -> np.ndarray:
        frac = _FRACTIONS.get(samples)
        if frac is None:
            frac = _FRACTIONS.setdefault(samples, np.linspace(1e-9, 1.0 - 1e-9, samples))
        return frac

    def _compiled(self) -> None:
        if self._c is None:
            self._c = tuple(np.ascontiguousarray(x, float) for x in (
                self.s, self.p1, self.p2, self.p3, self.a_lim, self.j_lim, self.v_lim * (1 + 1e-9)))

    def fits_numpy(self, v0: float, v1: float, A: np.ndarray, J: np.ndarray, s_start: np.ndarray,
                   samples: int = SCURVE_SAMPLES) -> np.ndarray:
        """``fits`` in numpy (the reference the compiled test is checked against)."""
        A, J, s_start = (np.atleast_1d(np.asarray(x, float)) for x in (A, J, s_start))
        dv = abs(v1 - v0)
        sign = 1.0 if v1 > v0 else -1.0
        short = dv * J <= A * A
        tj = np.where(short, np.sqrt(dv / J), A / J)
        ta = np.where(short, 0.0, dv / np.where(short, 1.0, A) - tj)
        T = 2 * tj + ta
        # instants strictly inside: an S-curve ending at a slower plateau's first pose does not run on it
        u = np.linspace(1e-9, 1.0 - 1e-9, samples)[None, :] * T[:, None]           # (C, M)
        u = np.sort(np.concatenate([u, tj[:, None], (tj + ta)[:, None]], axis=1), axis=1)
        t1 = np.minimum(u, tj[:, None])
        t2 = np.clip(u - tj[:, None], 0.0, ta[:, None])
        t3 = np.clip(u - (tj + ta)[:, None], 0.0, tj[:, None])
        Jc, tjc, tac = J[:, None], tj[:, None], ta[:, None]
        a1 = Jc * tjc                                   # acceleration after the first phase
        acc = Jc * t1 - Jc * t3
        vel = v0 + sign * (Jc * t1 * t1 / 2 + a1 * t2 + a1 * t3 - Jc * t3 * t3 / 2)
        pos = v0 * u + sign * (Jc * t1 ** 3 / 6 + (Jc * tjc * tjc / 2) * t2 + a1 * t2 * t2 / 2
                               + (Jc * tjc * tjc / 2 + a1 * tac) * t3 + a1 * t3 * t3 / 2 - Jc * t3 ** 3 / 6)
        x = s_start[:, None] + pos
        k = np.clip(np.searchsorted(self.s, x, side="right") - 1, 0, len(self.p1) - 1)
        p1, p2, p3 = self.p1[k], self.p2[k], self.p3[k]                                # (C, M, dof)
        v = np.maximum(vel, 0.0)[..., None]
        a = np.abs(acc)[..., None]
        jj = J[:, None, None]
        ok_a = p2 * v * v + p1 * a <= self.a_lim
        ok_j = p3 * v ** 3 + 3 * p2 * v * a + p1 * jj <= self.j_lim
        ok_v = p1 * v <= self.v_lim * (1 + 1e-9)
        return (ok_a & ok_j & ok_v).all(axis=(1, 2))


def _scurve_at(budget: _Budget, v0: float, v1: float, s_edge: float, before: bool, derate: float,
                s_lo: float, s_hi: float) -> dict:
    """The shortest S-curve v0 -> v1 ending at ``s_edge`` (``before``: decelerating into it) or starting there.

    Path accelerations and jerks on a grid (relative to the section's reference
    values) are bounded at the S-curve's own instants and positions
    (``_Budget.fits``); the fastest that fits is refined by bisection on J, then A
    (compiled, ``_Budget.search``). ``derate`` scales the result. D = inf when none fits.
    """
    out = {"v0": v0, "v1": v1, "A": 0.0, "J": 0.0, "D": 0.0, "T": 0.0, "phases": []}
    if v0 == v1:
        return out
    found, A, J = budget.search(v0, v1, s_edge, before, budget.a_ref * A_GRID, budget.j_ref * J_GRID, REFINE_STEPS)
    if not found:
        out.update(D=np.inf, T=np.inf)
        return out
    A, J = derate * A, derate * J
    phases, T, D = scurve(v0, v1, A, J)
    out.update(A=A, J=J, D=D, T=T, phases=phases)
    return out


def _merge(plateaus: list) -> list:
    out = []
    for p in plateaus:
        if out and out[-1].v == p.v:
            out[-1].b, out[-1].s1 = p.b, p.s1
        else:
            out.append(Plateau(p.a, p.b, p.v, p.s0, p.s1))
    return out


def plateaus_of(spline: PathSpline, target: np.ndarray) -> list:
    """Consecutive pieces with the same target speed, as plateaus."""
    edges = np.r_[0, np.flatnonzero(np.diff(target) != 0) + 1, len(target)]
    return [Plateau(int(a), int(b), float(target[a]), float(spline.s[a]), float(spline.s[b]))
            for a, b in zip(edges[:-1], edges[1:])]


def plan_section(spline: PathSpline, target: np.ndarray, limits, derate: float = 1.0,
                 max_rounds: int = 400) -> SectionPlan:
    """Plan the time law of a rest-to-rest section for per-piece target speeds (see the module doc)."""
    budget = _Budget(spline, limits)
    s_lo, s_hi = float(spline.s[0]), float(spline.s[-1])
    memo: dict = {}

    def _transition(budget, v0, v1, edge, before, derate, s_lo, s_hi):  # noqa: F811 - memoised per section
        key = (v0, v1, edge, before)
        if key not in memo:
            memo[key] = _scurve_at(budget, v0, v1, edge, before, derate, s_lo, s_hi)
        return dict(memo[key])

    plats = _merge(plateaus_of(spline, np.asarray(target, float)))

    def trans_list(pl):
        speeds = [0.0] + [p.v for p in pl] + [0.0]
        out = []
        for i in range(len(pl) + 1):
            v0, v1 = speeds[i], speeds[i + 1]
            edge = pl[i].s0 if i < len(pl) else pl[-1].s1
            before = v0 > v1  # decelerating: it lies in the plateau before the edge
            t = _transition(budget, v0, v1, edge, before, derate, s_lo, s_hi)
            t["into"] = (i - 1) if before else i
            out.append(t)
        return out

    def need(pl, i, trans):
        return sum(t["D"] for t in trans if t["into"] == i)

    trans = trans_list(plats)
    for _ in range(max_rounds):
        bad = [i for i, p in enumerate(plats) if need(plats, i, trans) > p.length * (1 + 1e-12) + 1e-12]
        if not bad:
            break
        i = bad[0]
        p = plats[i]
        vl = plats[i - 1].v if i > 0 else 0.0
        vr = plats[i + 1].v if i + 1 < len(plats) else 0.0

        def need_at(v):
            d = 0.0
            if v > vl:
                d += _transition(budget, vl, v, p.s0, False, derate, s_lo, s_hi)["D"]
            if v > vr:
                d += _transition(budget, v, vr, p.s1, True, derate, s_lo, s_hi)["D"]
            return d

        floor = max([x for x in (vl, vr) if x < p.v], default=0.0)
        if floor > 0 and need_at(floor) > p.length:
            plats[i].v = floor  # merges with that neighbour, whose S-curve then has its length too
        else:
            lo, hi = floor, p.v
            while hi - lo > SPEED_TOL * p.v:
                mid = 0.5 * (lo + hi)
                if need_at(mid) <= p.length:
                    lo = mid
                else:
                    hi = mid
            plats[i].v = lo if lo > 0 else 0.5 * hi
        plats = _merge(plats)
        trans = trans_list(plats)
    else:
        raise RuntimeError("time law: plateaus did not settle")
    plan = SectionPlan(plats, trans)
    _phases(plan)
    return plan


def _phases(plan: SectionPlan) -> None:
    """Fill the phase arrays: S-curve phases and cruises, in order, with their start states.

    Each S-curve ends exactly at its target speed with zero acceleration, and each
    cruise starts exactly there (no drift of round-off from one phase to the next).
    """
    rows = []  # (jerk, tau, cruise, v_start, a_start)
    pl, tr = plan.plateaus, plan.transitions
    v = 0.0
    for i in range(len(pl) + 1):
        a = 0.0
        v = tr[i]["v0"]
        for j, tau in tr[i]["phases"]:
            if tau > 0:
                rows.append((j, tau, False, v, a))
                v = v + a * tau + j * tau * tau / 2
                a = a + j * tau
        if i < len(pl):
            used = sum(t["D"] for t in tr if t["into"] == i)
            rest = pl[i].length - used
            if rest > 1e-12 * max(1.0, pl[i].length):
                rows.append((0.0, rest / pl[i].v, True, pl[i].v, 0.0))
    n = len(rows)
    j = np.array([r[0] for r in rows])
    tau = np.array([r[1] for r in rows])
    v0 = np.array([r[3] for r in rows])
    a0 = np.array([r[4] for r in rows])
    t0 = np.concatenate([[0.0], np.cumsum(tau)[:-1]]) if n else np.zeros(0)
    ds = v0 * tau + a0 * tau * tau / 2 + j * tau ** 3 / 6
    s0 = float(pl[0].s0) + (np.concatenate([[0.0], np.cumsum(ds)[:-1]]) if n else np.zeros(0))
    plan.phase_t0, plan.phase_s0, plan.phase_v0, plan.phase_a0 = t0, s0, v0, a0
    plan.phase_j, plan.phase_tau = j, tau
    plan.phase_cruise = np.array([r[2] for r in rows], bool)


def law_at(plan: SectionPlan, t: np.ndarray, s_end: float):
    """(s, v, a) of the time law at times ``t`` (clipped to the section); s within [s0, s_end]."""
    t = np.asarray(t, float)
    k = np.clip(np.searchsorted(plan.phase_t0, t, side="right") - 1, 0, len(plan.phase_t0) - 1)
    dt = np.clip(t - plan.phase_t0[k], 0.0, plan.phase_tau[k])
    j = plan.phase_j[k]
    a0, v0 = plan.phase_a0[k], plan.phase_v0[k]
    s = plan.phase_s0[k] + v0 * dt + a0 * dt * dt / 2 + j * dt ** 3 / 6
    v = np.maximum(v0 + a0 * dt + j * dt * dt / 2, 0.0)
    a = a0 + j * dt
    return np.minimum(s, s_end), v, a


def times_at(plan: SectionPlan, x: np.ndarray) -> np.ndarray:
    """Times at which the law reaches path positions ``x`` (monotone; bisection within each phase)."""
    x = np.asarray(x, float)
    k = np.clip(np.searchsorted(plan.phase_s0, x, side="right") - 1, 0, len(plan.phase_s0) - 1)
    # a position inside a zero-length (in s) phase run: take the last phase that starts at or before it
    lo = np.zeros(len(x))
    hi = plan.phase_tau[k].copy()
    j, a0, v0, s0 = plan.phase_j[k], plan.phase_a0[k], plan.phase_v0[k], plan.phase_s0[k]
    for _ in range(52):  # 2^-52 of a phase: below the round-off of t
        mid = 0.5 * (lo + hi)
        s = s0 + v0 * mid + a0 * mid * mid / 2 + j * mid ** 3 / 6
        big = s > x
        hi = np.where(big, mid, hi)
        lo = np.where(big, lo, mid)
    return plan.phase_t0[k] + 0.5 * (lo + hi)


@dataclass(frozen=True)
class SectionSamples:
    """Samples of a timed section: times from its start, states, and which are poses (knot index or -1)."""

    t_s: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    knot: np.ndarray


def sample_section(spline: PathSpline, plan: SectionPlan, fill_s: float = FILL_S) -> SectionSamples:
    """Poses at their times, S-curve phase boundaries, and samples every ``fill_s`` inside S-curves."""
    n = len(spline.s)
    t_knot = times_at(plan, spline.s)
    t_knot[0] = 0.0
    T = plan.duration
    t_knot[-1] = T
    t_knot = np.maximum.accumulate(t_knot)
    extra = [plan.phase_t0[1:]] if len(plan.phase_t0) > 1 else []
    for k in np.flatnonzero(~plan.phase_cruise):
        tau = plan.phase_tau[k]
        m = int(np.ceil(tau / fill_s))
        if m > 1:
            extra.append(plan.phase_t0[k] + tau * np.arange(1, m) / m)
    extra = np.unique(np.concatenate(extra)) if extra else np.zeros(0)
    extra = extra[(extra > 0) & (extra < T)]
    if len(extra):  # drop samples too close to a pose, then to each other
        near = np.abs(extra[:, None] - t_knot[None, :]).min(axis=1) if n * len(extra) < 4e6 else \
            _nearest_gap(extra, t_knot)
        extra = extra[near >= MIN_GAP_S]
        keep = np.ones(len(extra), bool)
        last = -np.inf
        for i, x in enumerate(extra):
            if x - last < MIN_GAP_S:
                keep[i] = False
            else:
                last = x
        extra = extra[keep]
    t_all = np.concatenate([t_knot, extra])
    knot = np.concatenate([np.arange(n), np.full(len(extra), -1)])
    order = np.argsort(t_all, kind="stable")
    t_all, knot = t_all[order], knot[order]
    s, v, a = law_at(plan, t_all, float(spline.s[-1]))
    on = knot >= 0
    s[on] = spline.s[knot[on]]
    piece = spline.piece_of(s)
    piece[on] = np.minimum(knot[on], len(spline.h) - 1)
    q, d1, d2, _ = spline.derivatives(s, piece)
    q[on] = spline.q[knot[on]]
    qd = d1 * v[:, None]
    qdd = d2 * (v * v)[:, None] + d1 * a[:, None]
    qd[0] = qdd[0] = qd[-1] = qdd[-1] = 0.0
    return SectionSamples(t_all, q, qd, qdd, knot)


def _nearest_gap(x, grid):
    i = np.clip(np.searchsorted(grid, x), 1, len(grid) - 1)
    return np.minimum(np.abs(x - grid[i - 1]), np.abs(grid[i] - x))


def check_section(samples: SectionSamples, limits, share: float = CHECK_SHARE) -> np.ndarray:
    """Per sample interval: the time stretch needed to bring its Hermite piece within ``share`` (<= 1: fine)."""
    t, q, qd, qdd = samples.t_s, samples.q, samples.qd, samples.qdd
    if len(t) < 2:
        return np.zeros(0)
    h = np.diff(t)
    pk = piece_peaks(q[:-1], q[1:], qd[:-1], qd[1:], qdd[:-1], qdd[1:], h, limits.lower, limits.upper,
                     n_grid=CHECK_GRID)
    r = limit_ratio(pk, limits.velocity, limits.acceleration, limits.jerk, share)
    return np.where(pk.position_break.any(axis=1), np.inf, r)


RUN_MEMO_SIZE = 2048    # run time laws kept for a second, identical request (lead sizing, then timing)
_RUN_MEMO: OrderedDict | None = None   # while ``remembered_runs`` is open


@contextmanager
def remembered_runs():
    """Within it each run's time law is planned once (``time_run_section``); on leaving (the outermost),
    the laws kept are let go: a job's plan and time stages, not the process, hold them."""
    global _RUN_MEMO
    outer = _RUN_MEMO
    _RUN_MEMO = OrderedDict() if outer is None else outer
    try:
        yield
    finally:
        _RUN_MEMO = outer


def time_run_section(spline: PathSpline, target: np.ndarray, limits, fill_s: float = FILL_S):
    """``time_section`` of a surface run, each run planned once within ``remembered_runs``: lead sizing
    (``runs.run_leads``) and the timing of the same joint path (``runs.time_runs``) ask for the very same
    sections, so the second request gets the first's (plan, samples, derate), arrays read-only. Keyed on
    the exact bytes of the knots, poses, targets, limits and ``fill_s``; at most ``RUN_MEMO_SIZE`` kept.
    Outside ``remembered_runs``, every request is planned."""
    if _RUN_MEMO is None:
        return _read_only(*time_section(spline, target, limits, fill_s))
    h = hashlib.blake2b(digest_size=20)
    for a in (spline.s, spline.q, target, limits.lower, limits.upper, limits.velocity, limits.acceleration,
              limits.jerk, np.array([fill_s], float)):
        a = np.ascontiguousarray(a, float)
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    key = h.digest()
    hit = _RUN_MEMO.get(key)
    if hit is not None:
        _RUN_MEMO.move_to_end(key)
        return hit
    _RUN_MEMO[key] = hit = _read_only(*time_section(spline, target, limits, fill_s))
    while len(_RUN_MEMO) > RUN_MEMO_SIZE:
        _RUN_MEMO.popitem(last=False)
    return hit


def _read_only(plan, smp, derate) -> tuple:
    for arr in (smp.t_s, smp.q, smp.qd, smp.qdd, smp.knot):
        arr.setflags(write=False)
    return plan, smp, derate


class LeavesJointRange(RuntimeError):
    """The spline through a run's poses leaves a joint's range between them: no slower time law mends it."""


def time_section(spline: PathSpline, target: np.ndarray, limits, fill_s: float = FILL_S):
    """Plan, sample and check a section; S-curve bounds are lowered until every Hermite piece is within
    ``CHECK_SHARE``. Returns (plan, samples, derate); raises RuntimeError if it never fits."""
    derate = 1.0
    for _ in range(MAX_DERATE_ROUNDS):
        plan = plan_section(spline, target, limits, derate)
        smp = sample_section(spline, plan, fill_s)
        r = check_section(smp, limits)
        if not len(r) or r.max() <= 1.0:
            return plan, smp, derate
        if np.isinf(r).any():
            raise LeavesJointRange("time law: the spline leaves the joint range")
        derate *= DERATE
        target = np.minimum(target, _plateau_caps(plan, smp, r, target))
    raise RuntimeError("time law: no S-curve bounds keep the section within the limits")


def _plateau_caps(plan: SectionPlan, smp: SectionSamples, r: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Lower the target of pieces whose constant-speed samples break a limit (round-off safety)."""
    cap = np.full(len(target), np.inf)
    bad = np.flatnonzero(r > 1.0)
    if not len(bad):
        return cap
    k_of = np.maximum.accumulate(np.where(smp.knot >= 0, smp.knot, 0))
    for i in bad:
        k = min(int(k_of[i]), len(target) - 1)
        t_mid = 0.5 * (smp.t_s[i] + smp.t_s[i + 1])
        ph = int(np.clip(np.searchsorted(plan.phase_t0, t_mid, side="right") - 1, 0, len(plan.phase_t0) - 1))
        if plan.phase_cruise[ph]:
            cap[k] = min(cap[k], target[k] / (1.01 * r[i]))
    return cap
