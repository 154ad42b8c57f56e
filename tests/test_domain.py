"""camtool.part.domain: a boundary's point-in-polygon test, row by row on grids, is matplotlib's answer."""
import numpy as np
import pytest
from matplotlib.path import Path as MplPath

from camtool.part.domain import Boundary, inside_polygon


def star(k: int, seed: int) -> np.ndarray:
    """A star-shaped polygon of k vertices with random radii (concave, many crossings a row)."""
    rng = np.random.default_rng(seed)
    a = np.sort(rng.uniform(0.0, 2 * np.pi, k))
    r = rng.uniform(20.0, 100.0, k)
    return np.c_[r * np.cos(a), r * np.sin(a)] + [300.0, -40.0]


@pytest.mark.parametrize("seed", range(6))
def test_grid_points_inside_a_polygon_are_matplotlibs(seed):
    """On a coverage grid (cell centres, rows shared by many points), and on a grid through the polygon's own
    vertices and edges (ties: asked of matplotlib), the mask is matplotlib's, point for point."""
    P = star(400, seed)
    lo, hi = P.min(axis=0) - 5.0, P.max(axis=0) + 5.0
    U, V = np.meshgrid(np.linspace(lo[0], hi[0], 301), np.linspace(lo[1], hi[1], 203))
    uv = np.c_[U.ravel(), V.ravel()]
    want = MplPath(P).contains_points(uv)
    assert 0 < want.sum() < len(uv) and np.array_equal(inside_polygon(P, uv), want)
    on = np.r_[P, 0.5 * (P + np.roll(P, -1, axis=0))]              # every vertex and edge midpoint
    rows = np.unique(on[:, 1])[::7]
    ties = np.c_[np.tile(on[:, 0], len(rows)), np.repeat(rows, len(on))]
    assert np.array_equal(inside_polygon(P, ties), MplPath(P).contains_points(ties))


def test_scattered_points_and_holes_are_matplotlibs():
    """Points on rows of their own go to matplotlib; a boundary's holes are cut out of its outer polygon."""
    rng = np.random.default_rng(3)
    outer, hole = star(300, 1), 0.3 * (star(50, 2) - [300.0, -40.0]) + [300.0, -40.0]
    uv = rng.uniform([180.0, -160.0], [420.0, 80.0], (5000, 2))
    b = Boundary(outer, (hole,))
    want = MplPath(outer).contains_points(uv) & ~MplPath(hole).contains_points(uv)
    assert np.array_equal(b.contains(uv), want)
    U, V = np.meshgrid(np.linspace(180.0, 420.0, 200), np.linspace(-160.0, 80.0, 150))
    grid = np.c_[U.ravel(), V.ravel()]
    assert np.array_equal(b.contains(grid), MplPath(outer).contains_points(grid) & ~MplPath(hole).contains_points(grid))
