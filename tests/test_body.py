"""camtool.collision.body: a body's bounding ball holds all of it (the world's broad phase rests on it)."""
import numpy as np
import pytest
import trimesh

from camtool.collision.body import WORLD, Body, hull_points
from camtool.errors import BadInput


def _surface_points(body: Body, rng) -> np.ndarray:
    s = body.size_mm
    if body.shape == "capsule":
        m = trimesh.creation.capsule(height=s[1], radius=s[0], count=[16, 16])
    elif body.shape == "cylinder":
        m = trimesh.creation.cylinder(radius=s[0], height=s[1], sections=32)
    elif body.shape == "box":
        m = trimesh.creation.box(extents=s)
    elif body.shape == "sphere":
        m = trimesh.creation.icosphere(subdivisions=3, radius=s[0])
    else:
        return body.points_mm
    return np.asarray(m.vertices)


@pytest.mark.parametrize("shape,size", [("capsule", (40.0, 300.0)), ("cylinder", (25.0, 150.0)),
                                        ("box", (60.0, 250.0, 300.0)), ("sphere", (70.0,)), ("convex", ())])
def test_ball_holds_the_whole_body(shape, size):
    rng = np.random.default_rng(2)
    pts = hull_points(rng.normal(size=(200, 3)) * [300.0, 40.0, 90.0] + [500.0, -20.0, 10.0]) \
        if shape == "convex" else None
    body = Body("b", "obstacle", WORLD, shape, size, np.eye(4), pts)
    centre, radius = body.ball_mm
    assert np.linalg.norm(_surface_points(body, rng) - centre, axis=1).max() <= radius + 1e-9
    assert np.isfinite(radius) and radius > 0


def test_halfspace_ball_is_infinite_and_flat_hulls_are_refused():
    floor = Body("floor", "obstacle", WORLD, "halfspace", (-400.0,), np.eye(4))
    assert floor.ball_mm[1] == np.inf
    with pytest.raises(BadInput, match="flat or degenerate"):
        hull_points(np.c_[np.random.default_rng(0).random((20, 2)), np.zeros(20)])
