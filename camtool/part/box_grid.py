"""Which boxes hold which points: a uniform grid over many axis-aligned boxes (a mesh's triangles' boxes).

``BoxGrid(lo, hi, P).holding(P)`` gives every (point, box) pair with the point inside the box (bounds
included), as rtree's ``intersection_v`` does for query boxes of half-width ``pad`` on boxes grown by ``pad``,
in array passes: each box is entered in the grid cells it overlaps, each point looks in its own cell. The cell
is chosen for the points to be asked (``_best_cell``): the least entries plus pairs to test, with at most
``MAX_ENTRIES_PER_BOX`` entries a box (bounded memory).

Hand-written: rtree answers the same query, but box by box through its C library (about 30 s per million
points on this machine, most of ``camtool faces`` on a STEP part); scipy's trees index points, not boxes.
"""
from __future__ import annotations

import numpy as np

MAX_ENTRIES_PER_BOX = 32  # grid cells entered per box, on average at most (bounds the memory)
PAIR_COST = 1.0         # a (point, box) pair to test costs about as much as an entry
PROBE = 20000           # boxes and points (strided) the cell's cost is estimated on
STEPS = 24              # cells tried: the boxes' extent halved up to this many times


class BoxGrid:
    """Boxes ``lo``, ``hi`` (n, 3) in a uniform grid of cubic cells, the cell chosen for the points ``P`` (m, 3)
    that will be asked: the one of least estimated work, entries plus the (point, box) pairs its cells hold."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray, P: np.ndarray):
        self.lo, self.hi = np.asarray(lo, float).reshape(-1, 3), np.asarray(hi, float).reshape(-1, 3)
        self.origin = self.lo.min(axis=0) if len(self.lo) else np.zeros(3)
        self.cell = self._best_cell(np.asarray(P, float).reshape(-1, 3))
        first, last = self._cells(self.lo), self._cells(self.hi)
        count = np.prod(last - first + 1, axis=1)
        self.dims = (last.max(axis=0) + 2) if len(count) else np.ones(3, np.int64)
        box, ijk = _entries(first, last, count)
        key = _key(ijk, self.dims)
        order = np.argsort(key, kind="stable")
        self._keys, self._boxes = key[order], box[order]

    def _cells(self, X: np.ndarray, cell: float | None = None) -> np.ndarray:
        return np.floor((X - self.origin) / (cell or self.cell)).astype(np.int64)

    def _best_cell(self, P: np.ndarray) -> float:
        """The cell (the boxes' extent halved k times) of least entries + PAIR_COST x pairs a box, estimated on
        PROBE strided boxes and points; finer cells are not tried once the entries pass MAX_ENTRIES_PER_BOX."""
        size = float((self.hi.max(axis=0, initial=-np.inf) - self.origin).max()) if len(self.lo) else 1.0
        size = size if np.isfinite(size) and size > 0 else 1.0
        if not len(self.lo) or not len(P):
            return size
        bi = np.linspace(0, len(self.lo) - 1, min(len(self.lo), PROBE)).astype(int)
        pi = np.linspace(0, len(P) - 1, min(len(P), PROBE)).astype(int)
        lo, hi, Q = self.lo[bi], self.hi[bi], P[pi]
        best, best_cost = size, np.inf
        for k in range(STEPS):
            cell = size / 2.0 ** k
            first, last = self._cells(lo, cell), self._cells(hi, cell)
            count = np.prod(last - first + 1, axis=1)
            if count.sum() > MAX_ENTRIES_PER_BOX * len(bi):
                break
            qc = np.clip(self._cells(Q, cell), 0, None)
            dims = np.maximum(last.max(axis=0), qc.max(axis=0)) + 2
            keys = np.sort(_key(_entries(first, last, count)[1], dims))
            qk = _key(qc, dims)
            pairs = int((np.searchsorted(keys, qk, "right") - np.searchsorted(keys, qk, "left")).sum())
            # per box of all: its entries, and its pairs with all the points (the probes' pairs scaled up)
            cost = count.sum() / len(bi) + PAIR_COST * pairs / (len(Q) * len(bi)) * len(P)
            if cost < best_cost:
                best, best_cost = cell, cost
        return best

    def holding(self, P: np.ndarray, reach: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """(point index, box index) of every point P (m, 3) inside a box (bounds included), or with ``reach``
        within that distance of it along each axis (the point's box of half-width ``reach`` meets the box),
        ordered by point, then by box."""
        P = np.asarray(P, float).reshape(-1, 3)
        first = np.clip(self._cells(P - reach), 0, self.dims - 1)
        last = np.clip(self._cells(P + reach), 0, self.dims - 1)
        out = np.any((self._cells(P + reach) < 0) | (self._cells(P - reach) >= self.dims), axis=1)
        count = np.where(out, 0, np.prod(last - first + 1, axis=1))
        point, ijk = _entries(first, last, count)
        key = _key(ijk, self.dims)
        a, b = np.searchsorted(self._keys, key, "left"), np.searchsorted(self._keys, key, "right")
        n = b - a
        row = np.repeat(point, n)
        box = self._boxes[np.repeat(a, n) + np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)]
        if np.any(count > 1):   # a box met in two of a point's cells once
            pair = np.unique(row * len(self.lo) + box)
            row, box = pair // len(self.lo), pair % len(self.lo)
        ok = np.all((P[row] + reach >= self.lo[box]) & (P[row] - reach <= self.hi[box]), axis=1)
        return row[ok], box[ok]


def _key(ijk: np.ndarray, dims: np.ndarray) -> np.ndarray:
    return (ijk[:, 0] * dims[1] + ijk[:, 1]) * dims[2] + ijk[:, 2]


def _entries(first: np.ndarray, last: np.ndarray, count: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(box, cell ijk) of every cell each box overlaps (cells ``first`` .. ``last`` a side, ``count`` in all)."""
    box = np.repeat(np.arange(len(count)), count)
    at = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)   # the entry within its box
    span = (last - first + 1)[box]
    ijk = first[box] + np.stack([at % span[:, 0], (at // span[:, 0]) % span[:, 1], at // (span[:, 0] * span[:, 1])],
                                axis=1)
    return box, ijk
