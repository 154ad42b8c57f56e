"""motion/geometry.py: needles (triangles narrower than a closest point is exact) cannot tell a point's side.

The IEA 15 MW blade's STEP tessellation has a trailing-edge strip a few um wide near the tip: a ribbon of needles,
one of them a cap (a corner 3 um off its long edge) whose normal points into the blade. Points 5-100 mm beyond the
trailing edge read as inside the part, and the tilt refused the job ("the tool is 132.5 mm inside the part").
Here the same shape, generated: a wedge whose two sides meet through a 5 um ribbon, with such a cap.
"""
from __future__ import annotations

import numpy as np

H_MM = 0.005      # the ribbon's width (the trailing edge's thickness)
EPS_MM = 0.002    # the cap's corner off its long edge
SLOPE = 0.2       # each side's slope towards the trailing edge (x = 0)


def _wedge():
    """Side A (z > 0) and side B (z < 0) from x = -20 to the trailing edge at x = 0, y from 0 to 20, joined by a
    ribbon at x = 0; side A's trailing edge is one edge T0-T2, the ribbon's top edge T0-T1-T2, and the cap
    (T0, T1, T2) fills the sliver between them, T1 EPS_MM in and up off T0-T2: folded back over side A, its
    normal points into the wedge and against the chord, as the blade's did."""
    za = lambda x: H_MM / 2 + SLOPE * -x   # noqa: E731
    d = EPS_MM / np.sqrt(2.0)
    V = np.array([
        [-20, 0, za(-20)], [-20, 20, za(-20)],            # 0, 1: side A inside
        [0, 0, H_MM / 2], [-d, 10, H_MM / 2 + d], [0, 20, H_MM / 2],   # 2, 3, 4: T0, T1 (the cap's corner), T2
        [0, 0, -H_MM / 2], [0, 20, -H_MM / 2],            # 5, 6: B0, B2
        [-20, 0, -za(-20)], [-20, 20, -za(-20)],          # 7, 8: side B inside
    ], float)
    F = np.array([
        [0, 2, 4], [0, 4, 1],                 # side A, its trailing edge the one edge 2-4
        [2, 3, 4],                            # the cap
        [2, 5, 3], [3, 5, 6], [3, 6, 4],      # the ribbon
        [7, 8, 6], [7, 6, 5],                 # side B
    ])
    return V, F


def _part(V, F):
    from camtool.motion.geometry import PartGeometry
    from camtool.part.workpiece import Workpiece

    wp = Workpiece(V.copy(), np.zeros_like(V), F, "wedge", "mm", (), V)
    hint_p = np.array([[-10.0, 10.0, 2.0], [-10.0, 10.0, -2.0]])
    return PartGeometry.from_workpiece(wp, hint_p, np.array([[SLOPE, 0, 1.0], [SLOPE, 0, -1.0]]))


def test_the_cap_and_the_ribbon_are_needles_and_the_sides_are_not():
    from camtool.motion.geometry import needle_triangles

    V, F = _wedge()
    assert needle_triangles(V[F], 0.2).tolist() == [False, False, True, True, True, True, False, False]
    assert not needle_triangles(V[F], 1e-4).any()      # wider than that: no needle


def test_a_point_beyond_the_trailing_edge_is_in_front_of_it_not_behind_the_cap():
    """Its closest feature is the long edge side A and the cap share, whose pseudo-normal took the cap's normal
    (wound with side A's, folded 135 deg back over it), which points into the wedge: 5 mm beyond the edge read -5 mm
    before. A needle takes no part in its edges' pseudo-normals now. Points inside the wedge stay inside."""
    V, F = _wedge()
    part = _part(V, F)
    assert (part.face_normals[2] @ np.array([1.0, 0, 0])) < -0.5   # the cap's own normal faces into the wedge
    beyond = np.array([[5.0, 10.0, 0.0], [50.0, 10.0, 0.0], [100.0, 10.0, 1.0]])
    np.testing.assert_allclose(part.signed_distance(beyond), [5.0, 50.0, np.hypot(100.0, 1.0)], atol=0.01)
    inside = np.array([[-5.0, 10.0, 0.0], [-15.0, 5.0, 0.5]])
    expect = [-(SLOPE * 5.0 + H_MM / 2) / np.hypot(1, SLOPE), -(SLOPE * 15.0 + H_MM / 2 - 0.5) / np.hypot(1, SLOPE)]
    np.testing.assert_allclose(part.signed_distance(inside), expect, atol=0.01)


def test_a_needle_is_read_as_the_edge_where_the_two_sides_meet():
    """The cap's corners lie on side A's edge; through the ribbon it reaches side B's: its pseudo-normal is the two
    sides' normals summed with equal weights, the edge's bisector +x (closed form), as are the ribbon's; a point
    19 mm off towards side B and 7 mm beyond the edge (the blade's second refusal) is in front."""
    V, F = _wedge()
    part = _part(V, F)
    np.testing.assert_allclose(part.needle_normals[2:6], np.tile([1.0, 0.0, 0.0], (4, 1)), atol=1e-9)
    nA = np.array([SLOPE, 0, 1.0]) / np.hypot(1, SLOPE)
    np.testing.assert_allclose(part.needle_normals[[0, 1]], np.tile(nA, (2, 1)), atol=1e-9)   # not needles
    off = np.array([[7.0, 10.0, -3.0]])
    assert part.signed_distance(off)[0] > 0
