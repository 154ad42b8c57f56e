"""Chord sag poses (camtool.plan.sag): the arc midpoint lies on spheres and cylinders, convex and concave."""
import numpy as np
import pytest

from camtool.plan.sag import arc_midpose


def pose_on_sphere(center, R, direction, outward=True):
    """A tool pose on a sphere: TCP on the surface, tool z into the material (against the outward normal)."""
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    T = np.eye(4)
    T[:3, 3] = center + R * d
    z = -d if outward else d
    x = np.cross([0.0, 0.0, 1.0], z)
    x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-9 else np.array([1.0, 0, 0])
    T[:3, 0], T[:3, 1], T[:3, 2] = x, np.cross(z, x), z
    return T


@pytest.mark.parametrize("outward", [True, False])
def test_arc_midpoint_is_on_the_sphere(outward):
    c, R = np.array([1000.0, 0.0, 100.0]), 600.0
    a = pose_on_sphere(c, R, [-1.0, 0.0, 0.0], outward)
    b = pose_on_sphere(c, R, [-np.cos(20 / R), np.sin(20 / R), 0.0], outward)   # ~20 mm apart
    T, sag = arc_midpose(a, b)
    chord = np.linalg.norm(a[:3, 3] - b[:3, 3])
    assert sag == pytest.approx(chord ** 2 / (8 * R), rel=1e-3)           # 0.083 mm at 20 mm pitch
    assert np.linalg.norm(T[:3, 3] - c) == pytest.approx(R, abs=1e-6)     # on the surface, not on the chord
    mid_chord = 0.5 * (a[:3, 3] + b[:3, 3])
    assert np.linalg.norm(mid_chord - c) < R - 0.08                        # the chord runs behind it


def test_flat_steps_have_no_sag():
    a = np.eye(4)
    b = np.eye(4)
    b[:3, 3] = [20.0, 0, 0]
    T, sag = arc_midpose(a, b)
    assert sag == 0.0 and np.allclose(T[:3, 3], [10.0, 0, 0])
