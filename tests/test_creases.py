"""A mesh's creases (camtool.part.creases) and the free-form regions' edge test that uses them
(freeform_faces.smooth_regions): a box's twelve edges, a finely tessellated cylinder without any,
and a 1.2 m sheet bent through 90 deg around a 10 mm fillet (one smooth region, as on a car door's
window frame) against the same sheet folded sharply (two)."""
import math

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from camtool.part.creases import crease_points
from camtool.part.freeform_faces import smooth_regions
from camtool.part.sampling import CONNECT_SPACINGS


def test_a_boxs_creases_are_its_twelve_edges():
    box = trimesh.creation.box([200.0, 100.0, 50.0])
    step = 5.0
    C = crease_points(box.vertices, box.faces, 30.0, step)
    half = np.array([100.0, 50.0, 25.0])
    # every crease point lies on a box edge: two of its coordinates at the half extents (closed form)
    on_bound = np.isclose(np.abs(C), half, atol=1e-9).sum(axis=1)
    assert (on_bound >= 2).all()
    # and every edge is covered at most a step apart: the edges' points at 1 mm all lie within step/2 of one
    edges = []
    for axis in range(3):
        others = [a for a in range(3) if a != axis]
        for s1 in (-1, 1):
            for s2 in (-1, 1):
                t = np.linspace(-half[axis], half[axis], int(2 * half[axis]) + 1)
                E = np.zeros((len(t), 3))
                E[:, axis] = t
                E[:, others[0]] = s1 * half[others[0]]
                E[:, others[1]] = s2 * half[others[1]]
                edges.append(E)
    d, _ = cKDTree(C).query(np.vstack(edges))
    assert d.max() <= step / 2 + 1e-9
    # the faces' diagonals (two coplanar triangles) are no crease; a 100 deg angle finds none either
    assert len(crease_points(box.vertices, box.faces, 100.0, step)) == 0


def test_a_fine_cylinder_has_no_crease_at_30_deg_but_every_facet_edge_at_5():
    cyl = trimesh.creation.cylinder(radius=50.0, height=100.0, sections=64)   # 5.625 deg between side facets
    side = cyl.triangles_center[:, 2]
    cyl.update_faces(np.abs(np.abs(side) - 50.0) > 1e-6)   # the side only (the caps' rims are creases)
    cyl.remove_unreferenced_vertices()
    assert len(crease_points(cyl.vertices, cyl.faces, 30.0, 5.0)) == 0
    C = crease_points(cyl.vertices, cyl.faces, 5.0, 5.0)
    assert len(C) > 0 and np.allclose(np.hypot(C[:, 0], C[:, 1]), 50.0)


def bent_sheet(fillet_mm: float):
    """An L-profile sheet 1000 mm wide: 700 mm flat, a quarter turn of radius ``fillet_mm`` (0: a sharp fold), 500 mm up."""
    s_flat = np.linspace(-700.0, 0.0, 36)
    arc = np.linspace(0.0, math.pi / 2, max(2, int(math.ceil(fillet_mm * math.pi / 2 / 2.0)) + 1))[1:]
    up = np.linspace(0.0, 500.0, 26)[1:]
    x = np.concatenate([s_flat, fillet_mm * np.sin(arc), np.full(len(up), fillet_mm)])
    z = np.concatenate([np.zeros(len(s_flat)), fillet_mm * (1 - np.cos(arc)), fillet_mm + up])
    if fillet_mm == 0:
        x, z = np.concatenate([s_flat, np.zeros(len(up))]), np.concatenate([np.zeros(len(s_flat)), up])
    y = np.linspace(0.0, 1000.0, 51)
    n_p, n_y = len(x), len(y)
    V = np.stack([np.tile(x, n_y), np.repeat(y, n_p), np.tile(z, n_y)], axis=1)
    idx = np.arange(n_p * n_y).reshape(n_y, n_p)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    return trimesh.Trimesh(V, np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)]), process=False)


def _regions(m, with_mesh: bool):
    P, fi = trimesh.sample.sample_surface(m, 20000, seed=1)
    N = np.asarray(m.face_normals)[fi]
    mesh = (np.asarray(m.vertices), np.asarray(m.faces)) if with_mesh else None
    region = smooth_regions(np.asarray(P), N, 30.0, CONNECT_SPACINGS, mesh)
    return np.unique(region[region >= 0])


def test_a_large_sheet_bent_round_a_tight_fillet_is_one_region_and_a_sharp_fold_two():
    fillet = bent_sheet(10.0)
    assert len(crease_points(fillet.vertices, fillet.faces, 30.0, 2.0)) == 0   # the mesh's own angles: no crease
    assert len(_regions(fillet, with_mesh=True)) == 1
    # the sample's own test over four spacings (about 15 mm here, a 10 mm fillet turns 86 deg over it) splits it
    assert len(_regions(fillet, with_mesh=False)) == 2
    fold = bent_sheet(0.0)
    assert len(_regions(fold, with_mesh=True)) == 2
