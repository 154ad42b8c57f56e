"""Strips between creases (camtool.part.crease_strips): a chamfer narrower than the smooth regions' edge band, at the
foot of a wall beside a free-form floor, is a face of its own (on main it was small fragments and points on no face:
the TOOLING4G mould's chamfer). Small generated parts."""
import numpy as np

from camtool.part.crease_strips import on_triangles, triangle_pieces
from camtool.part.segment import SegmentSettings, segment

from test_freeform import mesh_workpiece


WALL_MM = 0.2   # the wall drops 20 mm over this (89.4 deg)


def chamfer_width_mm(y):
    return 5.0 + 1.8 * np.sin(y / 30.0)   # the chamfer turns from 36 to 57 deg along y: no plane holds it


def chamfered_trough_mesh():
    """A sheet (mm): a rim at z = 0 (x < 0), a wall 20 mm down over ``WALL_MM``, a chamfer 5 mm down over
    ``chamfer_width_mm`` (36-57 deg, creased 32-53 deg into the wall and as much into the floor, level at its foot),
    then a free-form floor to x = 200. A grid in (s, y), s mapped onto x per row so that the creases are mesh edges."""
    s = np.concatenate([np.linspace(-40.0, 0.0, 17), [1.0], np.linspace(2.0, 5.0, 4), np.linspace(7.5, 200.0, 78)])
    y = np.linspace(-150.0, 150.0, 121)
    S, Y = np.meshgrid(s, y)
    w = chamfer_width_mm(Y)
    x0 = WALL_MM + w
    X = np.where(S <= 0.0, S, np.where(S <= 1.0, WALL_MM * S, np.where(S <= 5.0, WALL_MM + (S - 1.0) / 4.0 * w,
                                                                        x0 + (S - 5.0) * (200.0 - x0) / 195.0)))
    floor = -25.0 - 8.0 * np.sin(np.pi * (X - x0) / (200.0 - x0)) ** 2 * (1.0 + 0.3 * np.sin(Y / 50.0))
    Z = np.where(S <= 0.0, 0.0, np.where(S <= 1.0, -20.0 * S, np.where(S <= 5.0, -20.0 - 5.0 * (S - 1.0) / 4.0, floor)))
    ny, nx = S.shape
    idx = np.arange(nx * ny).reshape(ny, nx)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    F = np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    return np.stack([X, Y, Z], -1).reshape(-1, 3), F


def on_chamfer(P):
    return (P[:, 0] > WALL_MM + 1e-6) & (P[:, 0] < WALL_MM + chamfer_width_mm(P[:, 1]) - 1e-6)


def test_the_chamfer_is_one_piece_of_the_mesh_and_its_points_lie_on_it():
    V, F = chamfered_trough_mesh()
    piece = triangle_pieces(V, F)
    T = V[F]
    c = T.mean(axis=1)
    chamfer = on_chamfer(c)
    assert len(np.unique(piece[chamfer])) == 1                        # joined along its length ...
    assert not np.isin(piece[~chamfer], piece[chamfer]).any()          # ... and bounded by the creases
    P = np.array([[10.0, 0.0, 0.0], [0.0, 0.0, 5.0]])
    P[0] = T[7].mean(axis=0)
    assert list(on_triangles(P, T)) == [7, -1]                         # on its own triangle; off the mesh: none


def test_a_chamfer_narrower_than_the_edge_band_is_a_face_of_its_own():
    V, F = chamfered_trough_mesh()
    wp, _ = mesh_workpiece(V, F, n=40000)
    seg = segment(wp, SegmentSettings())
    P = wp.points_mm
    chamfer = np.flatnonzero(on_chamfer(P))
    owner = np.full(len(P), -1)
    for f in seg.faces:
        owner[f.inliers] = f.index
    main = np.bincount(owner[chamfer][owner[chamfer] >= 0], minlength=len(seg.faces)).argmax()
    assert np.mean(owner[chamfer] == main) > 0.9                       # one face holds the chamfer ...
    face = seg.faces[main]
    assert on_chamfer(P[face.inliers]).mean() > 0.9                     # ... and little else
    floor = (P[:, 0] > WALL_MM + chamfer_width_mm(P[:, 1]) + 8.0) & (np.abs(P[:, 1]) < 140.0)
    trough = np.bincount(owner[floor][owner[floor] >= 0]).argmax()
    assert seg.faces[trough].model == "freeform" and trough != main    # the floor is a free-form face of its own
