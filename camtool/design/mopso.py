"""Two-step MOPSO with potential-field repulsion (Sun et al. 2023, section 2.2,
on top of Coello, Pulido & Lechuga 2004).

The optimiser is generic: ``evaluate(X)`` takes an (n x d) array of designs
and returns ``(F, violation)``: objectives (n x m, minimised) and a
constraint violation per design (0 = valid; for the arm, the number of
unreachable path points). Invalid designs never enter the Pareto archive;
they are recorded in the *invalid set* and act as obstacles.

Velocity update (per particle, all in real units, r1, r2 ~ U(0, 1) per
component)::

    v <- w v + r1 (pbest - x) + r2 (leader - x) + span * repulsion(u)

with ``u = (x - lower) / span`` the position normalised by the *original*
ranges and ``repulsion`` the gradient of Khatib's potential around every
invalid design o within ``radius`` of u::

    repulsion(u) = sum_o gain (1/d - 1/radius) / d^2 * (u - o) / d,   d = |u - o|

clipped to ``max_repulsion`` per iteration. A position that leaves the box is
put on the bound and its velocity component reversed (Coello). Coello's
mutation then perturbs one variable of a particle with probability
``pm = (1 - t/T)^(1/mutation_rate)`` within +-pm * range.

Step 1 (explore) runs ``explore_iters`` iterations over the full ranges and
then narrows them (``narrow_ranges``). Step 2 (optimise) runs
``optimise_iters`` iterations inside the narrowed ranges: at its first
iteration the particles outside the box are re-drawn inside it, the others
move as usual, so every iteration evaluates exactly ``particles`` designs.
The invalid set of both steps keeps repelling.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .pareto import ParetoArchive, dominates


@dataclass(frozen=True)
class MopsoSettings:
    """Swarm size, iterations and the constants of the update rules."""

    particles: int = 12
    explore_iters: int = 3
    optimise_iters: int = 5
    inertia: float = 0.4            # Coello's W
    archive_capacity: int = 50
    grid_divisions: int = 30
    mutation_rate: float = 0.5      # Coello's mutation rate
    repulsion_gain: float = 0.002   # Khatib eta, in normalised units
    repulsion_radius: float = 0.15  # influence radius, share of each original range
    max_repulsion: float = 0.25     # per-iteration cap, share of each original range
    max_speed: float = 0.5          # velocity cap, share of each range
    narrow_bins: int = 10
    narrow_invalid_share: float = 0.5

    def __post_init__(self):
        if self.particles < 2:
            raise ValueError("particles must be >= 2")
        if self.explore_iters < 0 or self.optimise_iters < 0:
            raise ValueError("iterations must be >= 0")

    @property
    def budget(self) -> int:
        """Designs evaluated by a full run: the initial swarm plus one swarm per iteration."""
        return self.particles * (1 + self.explore_iters + self.optimise_iters)


@dataclass
class MopsoResult:
    """The archive (Pareto set X, front F), every evaluation and the narrowed ranges."""

    front_X: np.ndarray
    front_F: np.ndarray
    X: np.ndarray                 # every evaluated design, in order
    F: np.ndarray
    violation: np.ndarray
    step: np.ndarray              # 1 or 2 per evaluation
    iteration: np.ndarray         # 0 = initial swarm
    lower: np.ndarray
    upper: np.ndarray
    narrowed_lower: np.ndarray
    narrowed_upper: np.ndarray
    evaluations: int = 0
    history: list = field(default_factory=list)

    @property
    def invalid_X(self) -> np.ndarray:
        """Distinct invalid designs found (the obstacles)."""
        bad = self.X[self.violation > 0]
        return np.unique(bad, axis=0) if len(bad) else bad


def repulsion_velocity(u, obstacles, gain: float, radius: float, cap: float) -> np.ndarray:
    """Khatib repulsion (normalised units) on positions ``u`` (n x d) from ``obstacles`` (k x d).

    Obstacles farther than ``radius`` or at the position itself are ignored;
    each row's magnitude is clipped to ``cap``.
    """
    u = np.atleast_2d(np.asarray(u, float))
    out = np.zeros_like(u)
    obstacles = np.asarray(obstacles, float).reshape(-1, u.shape[1])
    if len(obstacles) == 0:
        return out
    diff = u[:, None, :] - obstacles[None, :, :]
    d = np.linalg.norm(diff, axis=2)
    near = (d < radius) & (d > 1e-12)
    with np.errstate(divide="ignore", invalid="ignore"):
        mag = np.where(near, gain * (1.0 / d - 1.0 / radius) / d ** 2, 0.0)
        unit = np.where(near[..., None], diff / np.where(near, d, 1.0)[..., None], 0.0)
    out = np.sum(mag[..., None] * unit, axis=1)
    norm = np.linalg.norm(out, axis=1, keepdims=True)
    return np.where(norm > cap, out * cap / np.maximum(norm, 1e-300), out)


def narrow_ranges(X, valid, lower, upper, keep_X=None, bins: int = 10, invalid_share: float = 0.5):
    """Narrowed (lower, upper) from step 1's evaluations, by peeling invalid slabs.

    Each variable's original range is cut into ``bins`` equal bins; the box
    starts as the whole range. Repeatedly, among the end bins of the box
    (lowest and highest bin of every variable, counting only the designs
    inside the box), the one with the largest share of invalid designs is
    peeled off, as long as that share is at least ``invalid_share`` (an empty
    end bin is no evidence and stays; every variable keeps at least one bin).
    Counting inside the box keeps an invalid region of one variable from
    masking the other. The box is then grown to contain every design of
    ``keep_X`` (the Pareto archive), so no known optimum is cut away. With no
    valid design at all the ranges stay as they are.
    """
    X = np.asarray(X, float).reshape(-1, len(lower))
    valid = np.asarray(valid, bool)
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    if not valid.any():
        return lower.copy(), upper.copy()
    d = len(lower)
    edges = [np.linspace(lower[j], upper[j], bins + 1) for j in range(d)]
    b = np.column_stack([np.clip(np.searchsorted(edges[j], X[:, j], side="right") - 1, 0, bins - 1)
                         for j in range(d)])
    first, last = np.zeros(d, int), np.full(d, bins - 1)
    while True:
        inside = np.all((b >= first) & (b <= last), axis=1)
        best = None
        for j in range(d):
            if first[j] == last[j]:
                continue
            for end, k in ((0, first[j]), (1, last[j])):
                in_bin = inside & (b[:, j] == k)
                total = int(in_bin.sum())
                if total == 0:
                    continue
                share = float(np.sum(in_bin & ~valid)) / total
                if share >= invalid_share and (best is None or (share, total) > best[:2]):
                    best = (share, total, j, end)
        if best is None:
            break
        _, _, j, end = best
        if end == 0:
            first[j] += 1
        else:
            last[j] -= 1
    new_lo = np.array([edges[j][first[j]] for j in range(d)])
    new_hi = np.array([edges[j][last[j] + 1] for j in range(d)])
    if keep_X is not None and len(keep_X):
        keep_X = np.asarray(keep_X, float)
        new_lo = np.minimum(new_lo, keep_X.min(axis=0))
        new_hi = np.maximum(new_hi, keep_X.max(axis=0))
    return new_lo, new_hi


def mutation_probability(t: int, total: int, rate: float) -> float:
    """Coello's mutation probability at iteration t of ``total``: (1 - t/total)^(1/rate)."""
    if total <= 0:
        return 0.0
    return float(max(0.0, 1.0 - t / total) ** (1.0 / rate))


def mutate(X, lower, upper, pm: float, rng: np.random.Generator) -> np.ndarray:
    """Coello's mutation: with probability pm, redraw one variable within +-pm * range."""
    X = X.copy()
    if pm <= 0:
        return X
    for i in range(len(X)):
        if rng.random() < pm:
            j = rng.integers(X.shape[1])
            dx = pm * (upper[j] - lower[j])
            lo, hi = max(X[i, j] - dx, lower[j]), min(X[i, j] + dx, upper[j])
            X[i, j] = lo + (hi - lo) * rng.random()
    return X


def _better(f_new, v_new, f_old, v_old, rng) -> bool:
    """pbest rule: constraint domination, then Pareto; a tie is a coin toss."""
    if v_new == 0 and v_old > 0:
        return True
    if v_new > 0 and v_old == 0:
        return False
    if v_new > 0:  # both invalid: fewer violations wins
        return v_new < v_old or (v_new == v_old and rng.random() < 0.5)
    if dominates(f_new, f_old):
        return True
    if dominates(f_old, f_new):
        return False
    return rng.random() < 0.5


def run_mopso(evaluate: Callable, lower, upper, settings: MopsoSettings = MopsoSettings(),
              rng: np.random.Generator | None = None, resolution=None,
              on_iteration: Callable | None = None) -> MopsoResult:
    """Two-step MOPSO over the box [lower, upper] (see module doc).

    ``resolution`` (per variable, optional) rounds every design to that grid
    before evaluation, so caching works and the archive holds exactly the
    evaluated designs. ``on_iteration(step, t, n_archive)`` is called after
    each swarm evaluation.
    """
    rng = rng if rng is not None else np.random.default_rng(0)
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    if np.any(upper <= lower):
        raise ValueError("every range needs lower < upper")
    d, n, s = len(lower), settings.particles, settings
    res = None if resolution is None else np.broadcast_to(np.asarray(resolution, float), (d,))
    evals = _Evaluations(evaluate, ParetoArchive(s.archive_capacity, s.grid_divisions, rng), on_iteration)
    lo, hi = lower.copy(), upper.copy()
    X = _snap(lo + (hi - lo) * rng.random((n, d)), lo, hi, res)
    swarm = _Swarm(X, *evals(X, 1, 0), lower, upper - lower)
    total = s.explore_iters + s.optimise_iters
    narrowed = (lower.copy(), upper.copy())
    t_global = 0
    for step, iters in ((1, s.explore_iters), (2, s.optimise_iters)):
        if step == 2:
            archive = evals.archive
            narrowed = narrow_ranges(np.array(evals.log["X"]), np.array(evals.log["v"]) == 0, lower, upper,
                                     archive.X if len(archive) else None, s.narrow_bins, s.narrow_invalid_share)
            lo, hi = narrowed
        for t in range(1, iters + 1):
            t_global += 1
            swarm.steer(evals.archive, evals.invalid(), lo, hi, s, rng)
            # at the first iteration of step 2, the particles left outside the narrowed box are re-drawn inside
            outside = swarm.fly(lo, hi, mutation_probability(t_global - 1, total, s.mutation_rate), rng,
                                step == 2 and t == 1, res)
            F, viol = evals(swarm.X, step, t)
            swarm.update_bests(F, viol, outside, rng)
    return evals.result(d, lower, upper, narrowed)


def _snap(X, lo, hi, res):
    """Designs rounded to the grid ``res`` (None: as they are), kept in the box [lo, hi]."""
    if res is not None:
        X = np.round(X / res) * res
        X = np.where(X < lo, X + res, X)
        X = np.where(X > hi, X - res, X)
    return np.clip(X, lo, hi)


class _Evaluations:
    """Every design evaluated, in order (``log``), the valid ones added to the Pareto ``archive``, and the
    count of each swarm evaluation (``history``)."""

    def __init__(self, evaluate: Callable, archive: ParetoArchive, on_iteration: Callable | None):
        self.evaluate, self.archive, self.on_iteration = evaluate, archive, on_iteration
        self.log = {"X": [], "F": [], "v": [], "step": [], "it": []}
        self.history = []

    def __call__(self, X, step: int, t: int):
        """(objectives, violations) of the designs ``X``, evaluated at iteration ``t`` of ``step``."""
        log, archive = self.log, self.archive
        F, viol = self.evaluate(X)
        F, viol = np.asarray(F, float), np.asarray(viol, float)
        for k in range(len(X)):
            log["X"].append(X[k]); log["F"].append(F[k]); log["v"].append(viol[k])
            log["step"].append(step); log["it"].append(t)
            if viol[k] == 0:
                archive.add(X[k], F[k])
        self.history.append({"step": step, "iteration": t, "archive": len(archive),
                             "invalid": int(np.sum(viol > 0))})
        if self.on_iteration is not None:
            self.on_iteration(step, t, len(archive))
        return F, viol

    def invalid(self) -> np.ndarray:
        """The invalid designs evaluated so far (the obstacles)."""
        return np.array(self.log["X"])[np.array(self.log["v"]) > 0]

    def result(self, d: int, lower, upper, narrowed) -> MopsoResult:
        """The run's result: the front, every evaluation, the ranges."""
        log = self.log
        fx, ff = self.archive.sorted()
        m = len(log["F"][0]) if log["F"] else 0
        return MopsoResult(
            front_X=fx.reshape(-1, d), front_F=ff.reshape(-1, m), X=np.array(log["X"]).reshape(-1, d), F=np.array(log["F"]).reshape(-1, m),
            violation=np.array(log["v"]), step=np.array(log["step"]), iteration=np.array(log["it"]),
            lower=lower, upper=upper, narrowed_lower=narrowed[0], narrowed_upper=narrowed[1],
            evaluations=len(log["F"]), history=self.history)


class _Swarm:
    """The particles: positions ``X``, velocities ``V``, personal bests ``P`` with their objectives ``PF`` and
    violations ``Pv``; ``lower`` and ``span0`` the original ranges (the repulsion's normalisation)."""

    def __init__(self, X, F, viol, lower, span0):
        n, d = X.shape
        self.X, self.V = X, np.zeros((n, d))
        self.P, self.PF, self.Pv = X.copy(), F.copy(), viol.copy()
        self.lower, self.span0 = lower, span0

    def steer(self, archive: ParetoArchive, bad: np.ndarray, lo, hi, s: MopsoSettings, rng) -> None:
        """The velocity update (module doc): towards the personal best and a leader of the archive, repelled by
        the invalid designs ``bad``, clipped to ``max_speed`` of the box [lo, hi]."""
        n, d = self.X.shape
        X, P, lower, span0 = self.X, self.P, self.lower, self.span0
        leaders = np.array([archive.leader() if len(archive) else P[i] for i in range(n)])
        r1, r2 = rng.random((n, d)), rng.random((n, d))
        V = s.inertia * self.V + r1 * (P - X) + r2 * (leaders - X)
        if len(bad):
            U = (X - lower) / span0
            V += span0 * repulsion_velocity(U, (bad - lower) / span0, s.repulsion_gain,
                                            s.repulsion_radius, s.max_repulsion)
        vmax = s.max_speed * (hi - lo)
        self.V = np.clip(V, -vmax, vmax)

    def fly(self, lo, hi, pm: float, rng, redraw: bool, res) -> np.ndarray:
        """Move the particles: a position out of the box on its bound with the velocity reversed, Coello's
        mutation with probability ``pm``, with ``redraw`` the particles outside the box re-drawn inside it,
        then snapped to the grid ``res``; which were re-drawn."""
        n, d = self.X.shape
        X, V = self.X, self.V
        Xn = X + V
        out_lo, out_hi = Xn < lo, Xn > hi
        Xn = np.where(out_lo, lo, np.where(out_hi, hi, Xn))
        V = np.where(out_lo | out_hi, -V, V)
        Xn = mutate(Xn, lo, hi, pm, rng)
        outside = np.zeros(n, bool)
        if redraw:
            outside = np.any((X < lo) | (X > hi), axis=1)
            Xn[outside] = lo + (hi - lo) * rng.random((int(outside.sum()), d))
            V[outside] = 0.0
        self.X, self.V = _snap(Xn, lo, hi, res), V
        return outside

    def update_bests(self, F, viol, outside: np.ndarray, rng) -> None:
        """Each particle's best: its new design when re-drawn or better (``_better``)."""
        for i in range(len(self.X)):
            if outside[i] or _better(F[i], viol[i], self.PF[i], self.Pv[i], rng):
                self.P[i], self.PF[i], self.Pv[i] = self.X[i], F[i], viol[i]
