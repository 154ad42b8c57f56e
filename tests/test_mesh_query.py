"""collision.mesh_query: coal's nearest points on a mesh agree with trimesh's, signed inside closed meshes."""
import numpy as np
import pytest
import trimesh

from camtool.collision.mesh_query import MeshQuery
from camtool.errors import BadInput


def test_closest_points_agree_with_trimesh_on_an_open_patch():
    mesh = trimesh.load(str(__import__("conftest").SAMPLES / "sphere_patch.stl"))
    rng = np.random.default_rng(1)
    P = rng.uniform(mesh.bounds[0] - 50, mesh.bounds[1] + 50, (300, 3))
    near, triangle = MeshQuery(mesh).closest(P)
    ref, dist, _ = trimesh.proximity.closest_point(mesh, P)
    assert np.abs(near - ref).max() < 1e-6
    # the triangle found holds the point found (at a shared edge either neighbour is right)
    on = trimesh.triangles.closest_point(mesh.triangles[triangle], near)
    assert np.abs(on - near).max() < 1e-6
    assert np.allclose(MeshQuery(mesh).distance(P), dist, atol=1e-6)


def test_signed_distance_is_negative_inside_a_closed_box():
    box = trimesh.creation.box(extents=(100, 200, 300))
    q = MeshQuery(box)
    d = q.signed_distance([[0, 0, 0], [0, 0, 140], [80, 0, 0], [50, 100, 150]])
    assert d == pytest.approx([-50.0, -10.0, 30.0, 0.0], abs=1e-9)


def test_an_open_mesh_has_no_signed_distance_and_an_empty_one_is_refused():
    patch = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    with pytest.raises(BadInput, match="watertight"):
        MeshQuery(patch).signed_distance([[0, 0, 1]])
    with pytest.raises(BadInput, match="triangle mesh"):
        MeshQuery(trimesh.Trimesh())
    assert MeshQuery(patch).distance(np.zeros((0, 3))).shape == (0,)
