"""camtool.part.box_grid: the (point, box) pairs against a direct test of every point with every box."""
import numpy as np
import pytest

from camtool.part.box_grid import BoxGrid


def _direct(P, lo, hi, reach=0.0):
    inside = np.all((P[:, None, :] + reach >= lo[None]) & (P[:, None, :] - reach <= hi[None]), axis=2)
    return np.nonzero(inside)   # (rows, boxes), ordered by row, then box


def _boxes(rng, n, long_share):
    """Small boxes and a share of long thin ones (a cylinder's strips), and a few large ones."""
    c = rng.uniform(0, 100, (n, 3))
    half = rng.uniform(0.05, 1.0, (n, 3))
    long = rng.random(n) < long_share
    half[long, rng.integers(0, 3, long.sum())] = rng.uniform(20, 60, long.sum())
    half[:3] = 40.0
    return c - half, c + half


@pytest.mark.parametrize("long_share", [0.0, 0.3, 1.0])
def test_pairs_are_every_point_in_every_box(long_share):
    rng = np.random.default_rng(5)
    lo, hi = _boxes(rng, 400, long_share)
    P = rng.uniform(-10, 110, (1500, 3))
    P[:50] = lo[:50]              # on a box's corner: bounds count
    grid = BoxGrid(lo, hi, P)
    row, box = grid.holding(P)
    exp_row, exp_box = _direct(P, lo, hi)
    assert np.array_equal(row, exp_row) and np.array_equal(box, exp_box)


def test_pairs_within_reach():
    rng = np.random.default_rng(6)
    lo, hi = _boxes(rng, 300, 0.2)
    P = rng.uniform(-10, 110, (800, 3))
    grid = BoxGrid(lo, hi, P)
    for reach in (0.01, 0.5, grid.cell):
        row, box = grid.holding(P, reach)
        exp_row, exp_box = _direct(P, lo, hi, reach)
        assert np.array_equal(row, exp_row) and np.array_equal(box, exp_box)


def test_memory_stays_bounded_for_large_boxes():
    """Boxes of all sizes: the grid holds at most MAX_ENTRIES_PER_BOX entries a box."""
    from camtool.part.box_grid import MAX_ENTRIES_PER_BOX

    rng = np.random.default_rng(7)
    lo = rng.uniform(0, 1000, (2000, 3))
    hi = lo + rng.uniform(0, 1000, (2000, 3)) ** rng.uniform(0.2, 1.0, (2000, 1))
    grid = BoxGrid(lo, hi, rng.uniform(0, 1000, (5000, 3)))
    assert len(grid._keys) <= MAX_ENTRIES_PER_BOX * 2000


def test_no_boxes_and_no_points():
    grid = BoxGrid(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((4, 3)))
    row, box = grid.holding(np.zeros((4, 3)))
    assert len(row) == len(box) == 0
    grid = BoxGrid(np.zeros((1, 3)), np.ones((1, 3)), np.zeros((0, 3)))
    assert len(grid.holding(np.zeros((0, 3)))[0]) == 0
