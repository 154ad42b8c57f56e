"""camtool.program.arcs: the cross product written out, and arc points by row or all at once."""
import numpy as np

from camtool.program.arcs import arc_point, circle_through, cross3


def test_cross3_is_numpys_cross_bit_for_bit():
    """The arc fitter's cross product: np.cross's numbers exactly (programs stay byte-identical), broadcast alike."""
    rng = np.random.default_rng(7)
    for sa, sb in (((500, 3), (500, 3)), ((3,), (40, 3)), ((3,), (3,)), ((6, 1, 3), (1, 5, 3))):
        a, b = rng.normal(size=sa) * 1e3, rng.normal(size=sb) * 1e-2
        got, want = cross3(a, b), np.cross(a, b)
        assert got.shape == want.shape and np.array_equal(got, want)


def test_arc_points_all_at_once_are_the_points_one_by_one():
    """The simulator takes every arc point of a program at once (``interpolation._Targets.on_move``): the
    same numbers as one point at a time, and on the circle through the three points."""
    rng = np.random.default_rng(3)
    K = 400
    P0, Pv, P1 = (rng.normal(size=(K, 3)) * 100.0 for _ in range(3))
    c, rad, n, r0, sweep, ok = circle_through(P0, Pv, P1)
    s = rng.uniform(0.0, 1.0, K)
    batch = arc_point(c, n, r0, sweep, s)
    one = np.array([arc_point(c[i][None], n[i][None], r0[i][None], sweep[i:i + 1], s[i:i + 1])[0] for i in range(K)])
    assert np.array_equal(batch, one)
    assert np.allclose(np.linalg.norm(batch - c, axis=1), rad, rtol=1e-9, atol=1e-9)
    assert np.allclose(arc_point(c, n, r0, sweep, np.ones(K)), P1, atol=1e-6)
