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


def test_batched_sags_are_the_midpose_sags():
    """The batched screen (chord_sags_mm) gives each step's own arc_midpose sag: convex, concave,
    flat and opposite tool axes."""
    from camtool.plan.sag import arc_midpose, chord_sags_mm
    from camtool.transforms import matrix_from_xyz_rpy

    rng = np.random.default_rng(4)
    Ta = np.array([matrix_from_xyz_rpy(rng.normal(0, 300, 3), rng.uniform(-180, 180, 3)) for _ in range(40)])
    Tb = np.array([a @ matrix_from_xyz_rpy(rng.normal(0, 20, 3), rng.normal(0, 5, 3)) for a in Ta])
    Tb[0] = Ta[0]                                   # no step
    Tb[1] = Ta[1].copy()
    Tb[1][:3, 3] += [5.0, 0.0, 0.0]                 # flat: parallel tool axes
    sags = chord_sags_mm(Ta, Tb)
    assert np.allclose(sags, [arc_midpose(a, b)[1] for a, b in zip(Ta, Tb)], rtol=1e-9, atol=1e-7)   # arccos of near-parallel axes: ~1e-8 mm
    assert sags[0] == 0.0 and sags[1] < 1e-7 and (sags[2:] > 1e-3).all()
