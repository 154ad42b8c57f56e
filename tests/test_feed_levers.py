"""benchmarks/feed_levers.py's facet_rows: a row across a faceted cylinder gets a pose at every facet edge, and every step on one facet.

The reference is the part's own mesh (trimesh's closest points on the prism's triangles) and the polygon's corners
in closed form; the projector the module is given is the prism's, by a 2-D line cut written here."""
from __future__ import annotations

import math
import sys
from pathlib import Path as FilePath

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(FilePath(__file__).resolve().parents[1] / "benchmarks"))
from feed_levers import FacetRowSettings, axes_lowpassed, facet_rows, simplified, work_runs  # noqa: E402
from camtool.path.toolpath import ZONE_CODE, Path
from camtool.plan.sag import ON_FACE_MM

R_MM, SIDES, HALF_H_MM = 100.0, 24, 60.0          # a 24-sided prism: 15 deg kinks, facets 26.1 mm wide
PITCH_MM, BAND_MM = 5.0, 0.025


def _corners_xz() -> np.ndarray:
    a = 2 * np.pi * np.arange(SIDES) / SIDES
    return R_MM * np.stack([np.sin(a), np.cos(a)], axis=1)          # (x, z), corner 0 on top


def _prism() -> trimesh.Trimesh:
    c = _corners_xz()
    V = np.concatenate([np.c_[c[:, 0], np.full(SIDES, y), c[:, 1]] for y in (-HALF_H_MM, HALF_H_MM)])
    i = np.arange(SIDES)
    j = (i + 1) % SIDES
    F = np.concatenate([np.c_[i, j, i + SIDES], np.c_[j, j + SIDES, i + SIDES]])
    return trimesh.Trimesh(V, F, process=False)


def _project(points, along=None, continued=False):
    """Points onto the prism's sides along their lines ``along`` (either way, the nearest); NaN off them."""
    P = np.asarray(points, float).reshape(-1, 3)
    D = np.asarray(along, float).reshape(-1, 3)
    c = _corners_xz()
    a, b = c, np.roll(c, -1, axis=0)
    out = np.full(P.shape, np.nan)
    for k in range(len(P)):
        best = np.inf
        for e in range(SIDES):
            M = np.array([[D[k, 0], a[e, 0] - b[e, 0]], [D[k, 2], a[e, 1] - b[e, 1]]])
            if abs(np.linalg.det(M)) < 1e-12:
                continue
            t, u = np.linalg.solve(M, a[e] - P[k, [0, 2]])
            if -1e-12 <= u <= 1 + 1e-12 and abs(t) < best and abs(P[k, 1] + t * D[k, 1]) <= HALF_H_MM:
                best, out[k] = abs(t), P[k] + t * D[k]
    return out


def _on_polygon(s_mm: np.ndarray) -> np.ndarray:
    """Points at arc lengths ``s_mm`` along the polygon's perimeter from corner 0 (clockwise seen from +y)."""
    c = _corners_xz()
    side = 2 * R_MM * math.sin(math.pi / SIDES)
    k = np.floor(s_mm / side).astype(int) % SIDES
    f = (s_mm / side - np.floor(s_mm / side))[:, None]
    return c[k] + f * (c[(k + 1) % SIDES] - c[k])


def _row_path(y_mm: float = 0.0, from_mm: float = -70.0, to_mm: float = 70.0) -> Path:
    """A lead-in, a work row across the prism's axis at an even pitch on its facets (s from ``from_mm`` to
    ``to_mm`` around corner 0), a lead-out; tool axes the cylinder's radial normals (smooth, not the facets')."""
    side = 2 * R_MM * math.sin(math.pi / SIDES)
    s = np.arange(from_mm, to_mm + 1e-9, PITCH_MM) + 1.3          # the corners fall inside steps
    xz = _on_polygon(np.mod(s, SIDES * side))
    P = np.c_[xz[:, 0], np.full(len(s), y_mm), xz[:, 1]]
    n = np.c_[xz[:, 0], np.zeros(len(s)), xz[:, 1]]
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    T = np.broadcast_to(np.eye(4), (len(s) + 2, 4, 4)).copy()
    z = -n
    x = np.broadcast_to([0.0, 1.0, 0.0], z.shape)
    T[1:-1, :3, 0], T[1:-1, :3, 1], T[1:-1, :3, 2], T[1:-1, :3, 3] = x, np.cross(z, x), z, P
    T[0], T[-1] = T[1], T[-2]
    T[0, :3, 3] += 10.0 * n[0]
    T[-1, :3, 3] += 10.0 * n[-1]
    zone = np.r_[ZONE_CODE["lead_in"], np.full(len(s), ZONE_CODE["work"]), ZONE_CODE["lead_out"]]
    point = np.r_[0, np.arange(1, len(s) + 1), 0]
    return Path(T, np.zeros(len(T), int), point, zone, pitch_mm=PITCH_MM)


def _chord_gaps_mm(path: Path, mesh: trimesh.Trimesh) -> np.ndarray:
    """(work steps,) how far each work step's chord (9 points inside it) leaves the prism's triangles."""
    w = np.flatnonzero((path.zone[:-1] == ZONE_CODE["work"]) & (path.zone[1:] == ZONE_CODE["work"]))
    P = path.poses_mm[:, :3, 3]
    f = np.arange(1, 10) / 10.0
    X = P[w, None] + f[None, :, None] * (P[w + 1] - P[w])[:, None]
    d = trimesh.proximity.closest_point(mesh, X.reshape(-1, 3))[1]
    return d.reshape(len(w), -1).max(axis=1)


def test_every_step_on_one_facet_and_a_pose_at_every_edge():
    mesh, path = _prism(), _row_path()
    settings = FacetRowSettings(pitch_mm=PITCH_MM, band_mm=BAND_MM)
    assert _chord_gaps_mm(path, mesh).max() > 4 * BAND_MM      # as rastered: chords cut under the crests
    out, figures = facet_rows(path, [(np.ones(len(path), bool), _project)], settings)
    assert figures.runs == 1 and figures.kept == 0
    assert _chord_gaps_mm(out, mesh).max() <= 1e-4               # every step on one facet: no sag to split
    w = out.zone == ZONE_CODE["work"]
    P = out.poses_mm[w, :3, 3]
    assert trimesh.proximity.closest_point(mesh, P)[1].max() <= ON_FACE_MM
    # every corner the row crosses is a pose; between corners the fewest equal steps of at most the pitch
    c = _corners_xz()
    ang = np.degrees(np.arctan2(P[[0, -1], 0], P[[0, -1], 2]))
    crossed = [k for k in range(-SIDES // 2, SIDES // 2) if ang[0] < 360.0 * k / SIDES < ang[1]]
    corner_xyz = np.array([[c[k % SIDES, 0], 0.0, c[k % SIDES, 1]] for k in crossed])
    assert np.linalg.norm(P[:, None] - corner_xyz[None], axis=2).min(axis=0).max() <= 1e-4
    knots = np.r_[P[:1], corner_xyz, P[-1:]]
    legs = np.linalg.norm(np.diff(knots, axis=0), axis=1)
    assert w.sum() == 1 + int(np.ceil(legs / PITCH_MM - 1e-9).sum())
    steps = np.linalg.norm(np.diff(P, axis=0), axis=1)
    assert steps.max() <= PITCH_MM + 1e-9
    # the row's ends and its leads stay; the tool axes stay the smooth normals (slerped), points renumbered
    assert np.array_equal(out.poses_mm[[0, 1, -2, -1]], path.poses_mm[[0, 1, -2, -1]])
    radial = np.c_[P[:, 0], np.zeros(len(P)), P[:, 2]]
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    assert np.degrees(np.arccos(np.clip(-np.einsum("ij,ij->i", out.poses_mm[w, :3, 2], radial), -1, 1))).max() < 0.6
    assert np.array_equal(out.point[w], np.arange(1, w.sum() + 1))


def test_a_run_off_the_face_keeps_its_poses():
    path = _row_path(y_mm=HALF_H_MM + 5.0)     # past the prism's end: no facet under the row
    out, figures = facet_rows(path, [(np.ones(len(path), bool), _project)], FacetRowSettings(PITCH_MM, BAND_MM))
    assert out is path and figures.kept == 1 and figures.runs == 0


def test_work_runs_split_at_segments_and_masks():
    path = _row_path()
    seg = path.segment.copy()
    seg[10:] = 1
    split = Path(path.poses_mm, seg, path.point, path.zone, pitch_mm=PITCH_MM)
    mask = np.ones(len(path), bool)
    mask[20] = False
    assert work_runs(split, mask) == [(1, 9), (10, 19), (21, len(path) - 2)]


def test_simplified_keeps_the_kinks_of_a_polyline():
    t = np.linspace(0.0, 30.0, 301)
    y = np.where(t < 10, 0.0, np.where(t < 20, 0.2 * (t - 10), 2.0 - 0.1 * (t - 20)))
    keep = simplified(np.c_[t, y, np.zeros_like(t)], 0.01)
    assert list(t[keep]) == [0.0, 10.0, 20.0, 30.0]


def test_axes_lowpassed_smooths_the_axes_and_keeps_the_points():
    rng = np.random.default_rng(3)
    path = _row_path()
    w = np.flatnonzero(path.zone == ZONE_CODE["work"])
    noisy = path.poses_mm.copy()
    wobble = Rotation.from_rotvec(np.c_[rng.normal(0.0, 0.02, len(w)), np.zeros(len(w)), np.zeros(len(w))])
    noisy[w, :3, :3] = (Rotation.from_matrix(noisy[w, :3, :3]) * wobble).as_matrix()
    rough = Path(noisy, path.segment, path.point, path.zone, pitch_mm=PITCH_MM)
    out = axes_lowpassed(rough, 10.0)
    assert np.array_equal(out.poses_mm[:, :3, 3], rough.poses_mm[:, :3, 3])
    assert np.array_equal(out.poses_mm[w[[0, -1]]], rough.poses_mm[w[[0, -1]]])

    def turn_deg(P):   # the largest turn of the tool axis between neighbouring work poses
        z = P[w, :3, 2]
        return np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", z[:-1], z[1:]), -1, 1))).max()
    assert turn_deg(out.poses_mm) < 0.5 * turn_deg(rough.poses_mm)
