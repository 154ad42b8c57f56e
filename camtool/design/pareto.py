"""Pareto dominance and the bounded Pareto archive of MOPSO (Coello et al. 2004).

All objectives are minimised. The archive keeps non-dominated solutions up to
a capacity; when it is full, a member of a crowded hypercube of the objective
grid is dropped. Leaders are drawn by Coello's hypercube roulette: a cube is
chosen with probability proportional to 10 / (members in the cube), then a
member of that cube at random, so sparse parts of the front lead more often.
"""
from __future__ import annotations

import numpy as np

LEADER_FITNESS = 10.0  # Coello's x in fitness = x / (members in the hypercube)


def dominates(a, b) -> bool:
    """True when objective vector ``a`` Pareto-dominates ``b`` (minimising)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return bool(np.all(a <= b) and np.any(a < b))


def nondominated_mask(F) -> np.ndarray:
    """Boolean mask of the rows of ``F`` (n x m) that no other row dominates."""
    F = np.asarray(F, float)
    n = len(F)
    keep = np.ones(n, bool)
    for i in range(n):
        le = np.all(F <= F[i], axis=1)
        lt = np.any(F < F[i], axis=1)
        if np.any(le & lt):
            keep[i] = False
    return keep


def crowding_distance(F) -> np.ndarray:
    """NSGA-II crowding distance of each row of ``F``; boundary rows get inf."""
    F = np.asarray(F, float)
    n, m = F.shape
    dist = np.zeros(n)
    if n <= 2:
        return np.full(n, np.inf)
    for j in range(m):
        order = np.argsort(F[:, j], kind="stable")
        span = F[order[-1], j] - F[order[0], j]
        dist[order[0]] = dist[order[-1]] = np.inf
        if span > 0:
            dist[order[1:-1]] += (F[order[2:], j] - F[order[:-2], j]) / span
    return dist


def grid_cells(F, divisions: int, inflate: float = 0.1) -> np.ndarray:
    """Hypercube index (one int per row) of each row of ``F`` on a grid of
    ``divisions`` per objective over the rows' bounds, inflated by ``inflate``."""
    F = np.asarray(F, float)
    lo, hi = F.min(axis=0), F.max(axis=0)
    pad = inflate * (hi - lo)
    lo, hi = lo - pad, hi + pad
    span = np.where(hi > lo, hi - lo, 1.0)
    idx = np.clip(((F - lo) / span * divisions).astype(int), 0, divisions - 1)
    return np.ravel_multi_index(idx.T, (divisions,) * F.shape[1]) if len(F) else np.zeros(0, int)


class ParetoArchive:
    """Non-dominated solutions (design X, objectives F) up to ``capacity``.

    Two members may share an objective vector when their designs differ
    (several arms of the same length): they are all Pareto-optimal.
    """

    def __init__(self, capacity: int = 100, divisions: int = 30, rng: np.random.Generator | None = None):
        if capacity < 1 or divisions < 1:
            raise ValueError("archive capacity and grid divisions must be >= 1")
        self.capacity, self.divisions = capacity, divisions
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.X = np.zeros((0, 0))
        self.F = np.zeros((0, 0))

    def __len__(self) -> int:
        return len(self.F)

    def add(self, x, f) -> bool:
        """Offer one solution; True if it joined the archive."""
        x, f = np.asarray(x, float), np.asarray(f, float)
        if len(self.F) == 0:
            self.X, self.F = x[None, :].copy(), f[None, :].copy()
            return True
        if any(dominates(g, f) for g in self.F):
            return False
        if np.any(np.all(self.X == x, axis=1)):
            return False  # this very design is already in
        keep = np.array([not dominates(f, g) for g in self.F])
        self.X = np.vstack([self.X[keep], x])
        self.F = np.vstack([self.F[keep], f])
        if len(self.F) > self.capacity:
            self._drop_one_crowded()
        return bool(np.any(np.all(self.X == x, axis=1)))

    def _drop_one_crowded(self) -> None:
        cells = grid_cells(self.F, self.divisions)
        uniq, inverse, counts = np.unique(cells, return_inverse=True, return_counts=True)
        crowded = np.flatnonzero(counts > 1)
        weights = counts[crowded].astype(float) if len(crowded) else counts.astype(float)
        pool = crowded if len(crowded) else np.arange(len(uniq))
        cube = pool[self.rng.choice(len(pool), p=weights / weights.sum())]
        members = np.flatnonzero(inverse == cube)
        drop = members[self.rng.integers(len(members))]
        self.X = np.delete(self.X, drop, axis=0)
        self.F = np.delete(self.F, drop, axis=0)

    def leader(self) -> np.ndarray:
        """A leader design by hypercube roulette (fitness 10 / members per cube)."""
        if len(self.F) == 0:
            raise ValueError("the archive is empty")
        cells = grid_cells(self.F, self.divisions)
        uniq, inverse, counts = np.unique(cells, return_inverse=True, return_counts=True)
        fitness = LEADER_FITNESS / counts
        cube = self.rng.choice(len(uniq), p=fitness / fitness.sum())
        members = np.flatnonzero(inverse == cube)
        return self.X[members[self.rng.integers(len(members))]].copy()

    def sorted(self) -> tuple[np.ndarray, np.ndarray]:
        """The archive as (X, F) sorted by the objectives (first, then second, ...)."""
        if len(self.F) == 0:
            return self.X, self.F
        order = np.lexsort(tuple(np.column_stack([self.F, self.X]).T[::-1]))
        return self.X[order], self.F[order]
