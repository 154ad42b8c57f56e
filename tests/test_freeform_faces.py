"""Free-form faces in the segmentation (camtool.part.freeform_faces): a mould block's trough, a noisy dome scan,
a panel with a bent flange; the selection by model, index, nearest and largest; several faces (free-form and
analytic) in one path; analytic parts untouched. Small generated parts."""
import numpy as np
import pytest
import trimesh

from camtool.part import segment as segment_module
from camtool.part.faces import select_faces
from camtool.part.segment import SegmentSettings, segment
from camtool.part.surface import FaceSet
from camtool.part.workpiece import Workpiece
from camtool.path.raster import raster_path
from camtool.settings import RasterSettings

from test_freeform import grid_mesh, mesh_workpiece


def mould_mesh():
    """A block 300 x 200 x 60 mm whose top holds a trough 240 x 120 mm, 45 mm deep (its rim a crease)."""
    x, y = np.arange(-150, 150.01, 2.5), np.arange(-100, 100.01, 2.5)
    inside = lambda X, Y: (np.abs(X) < 120) & (np.abs(Y) < 60)  # noqa: E731
    V, F = grid_mesh(x, y, lambda X, Y: np.where(inside(X, Y), -45 * (1 - (X / 120) ** 2) * (1 - (Y / 60) ** 2)
                                                 * (1 + 0.15 * np.sin(X / 40)), 0.0))
    top = trimesh.Trimesh(V, F, process=False)
    box = trimesh.creation.box([300, 200, 60])
    box.apply_translation([0, 0, -30])
    box.update_faces(box.triangles_center[:, 2] < -1e-6)
    box.remove_unreferenced_vertices()
    m = trimesh.util.concatenate([top, box])
    m.merge_vertices()
    return np.asarray(m.vertices), np.asarray(m.faces)


@pytest.fixture(scope="module")
def mould():
    V, F = mould_mesh()
    wp, _ = mesh_workpiece(V, F, n=40000)
    return wp, segment(wp, SegmentSettings())


def test_a_moulds_trough_is_one_freeform_face_and_its_planes_stay(mould):
    wp, seg = mould
    models = [f.model for f in seg.faces]
    assert models.count("freeform") == 1
    assert models.count("plane") >= 5          # the top round the trough, four sides (the bottom is not sampled)
    ff = next(f for f in seg.faces if f.model == "freeform")
    P = wp.points_mm[ff.inliers]
    assert (np.abs(P[:, 0]) < 125).all() and (np.abs(P[:, 1]) < 65).all()   # the trough's points only
    Q = wp.points_mm
    trough = (np.abs(Q[:, 0]) < 119) & (np.abs(Q[:, 1]) < 59) & (Q[:, 2] > -50)
    assert np.isin(np.flatnonzero(trough), ff.inliers).mean() > 0.97
    s = ff.summary()
    assert s["model"] == "freeform" and s["radius_mm"] is None and s["normal"][2] > 0.9
    lo, hi = s["curvature_range"]
    assert lo < hi and s["holes"] == 0 and 0.8 * 40000 < s["area_mm2"] < 1.6 * 40000
    assert seg.unassigned < 0.02 * seg.n_points


def test_select_freeform_faces_like_the_others(mould):
    wp, seg = mould
    ff = next(f for f in seg.faces if f.model == "freeform")
    assert [f.index for f in select_faces(seg, "freeform", wp)] == [ff.index]
    assert [f.index for f in select_faces(seg, [ff.index], wp)] == [ff.index]
    assert select_faces(seg, {"nearest_mm": [0.0, 0.0, -40.0]}, wp)[0].index == ff.index
    assert len(select_faces(seg, {"largest": 3}, wp)) == 3
    assert seg.faces[0].area_mm2 >= seg.faces[1].area_mm2 >= seg.faces[-1].area_mm2


def test_freeform_and_plane_faces_in_one_path(mould):
    wp, seg = mould
    ff = next(f for f in seg.faces if f.model == "freeform")
    top = max((f for f in seg.faces if f.model == "plane" and f.surface.normal[2] > 0.99), key=lambda f: f.area_mm2)
    fs = FaceSet((ff.surface, top.surface), (ff.index, top.index), ({}, {"step_over_mm": 15.0}))
    path = raster_path(fs, RasterSettings.make(step_over_mm=10.0, pitch_mm=5.0))
    assert set(np.unique(path.face)) == {ff.index, top.index}
    assert np.isfinite(path.poses_mm).all()
    for f in (ff, top):
        on = path.is_work & (path.face == f.index)
        assert on.sum() > 100
        P = path.poses_mm[on, :3, 3]
        _, d, _ = trimesh.proximity.closest_point(trimesh.Trimesh(wp.vertices_mm, wp.faces), P)
        # every work TCP on the block's own mesh (the plane's hole reaches into the trough's corners, where the
        # trough leaves z = 0 tangentially, as far as fit.threshold_mm lets the plane hold its points)
        assert np.percentile(d, 99 if f is ff else 95) < 0.1
        z = path.poses_mm[on, :3, 2]           # the tool axis into the part along its normal
        uv = f.surface.uv_from_points(P)
        n = f.surface.normal_at(uv[:, 0], uv[:, 1])
        assert np.percentile(np.degrees(np.arccos(np.clip(-np.sum(z * n, 1), -1, 1))), 95) < 3.0


def test_a_noisy_dome_scan_is_one_face():
    rng = np.random.default_rng(4)
    n, R = 40000, 200.0
    u, ph = rng.uniform(np.cos(np.radians(50)), 1, n), rng.uniform(0, 2 * np.pi, n)
    s = np.sqrt(1 - u ** 2)
    P = np.stack([R * s * np.cos(ph), R * s * np.sin(ph), R * u], 1)
    N = P / R
    P = P + rng.normal(0, 1.2, P.shape)
    N = N + rng.normal(0, 0.15, N.shape)     # a scanner's noisy normals, signs mixed
    N *= np.where(rng.random(n) < 0.5, -1, 1)[:, None]
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    seg = segment(Workpiece(P, N, None, "dome.ply"), SegmentSettings())
    assert [f.model for f in seg.faces] == ["freeform"]
    assert len(seg.faces[0].inliers) > 0.97 * n


def test_a_panels_flange_is_a_face_of_its_own():
    """A panel bent down 65 deg along one edge: two free-form faces, split at the sharp edge; with sharp_edge_deg
    above the bend they are one."""
    x, y = np.linspace(-150, 150, 121), np.linspace(-100, 100, 81)
    z_of = lambda X, Y: -(X ** 2) / 1200 - (Y ** 2) / 2000 + X * Y / 6000  # noqa: E731
    V1, F1 = grid_mesh(x, y, z_of)
    t = np.linspace(0, 30, 7)
    ze = z_of(x, 100.0)
    XF = np.repeat(x[None], len(t), 0)
    V2 = np.stack([XF, 100 + np.cos(np.radians(65)) * t[:, None] + 0 * XF,
                   ze[None] - np.sin(np.radians(65)) * t[:, None]], -1).reshape(-1, 3)
    _, F2 = grid_mesh(x, t, lambda X, Y: 0 * X)
    m = trimesh.Trimesh(np.vstack([V1, V2]), np.vstack([F1, F2 + len(V1)]))
    m.merge_vertices()
    wp, _ = mesh_workpiece(np.asarray(m.vertices), np.asarray(m.faces), n=40000)
    on_flange = wp.points_mm[:, 1] > 100.5
    seg = segment(wp, SegmentSettings())
    panel = seg.faces[0]
    assert panel.model == "freeform" and on_flange[panel.inliers].mean() < 0.005
    assert (~on_flange).sum() * 0.97 < len(panel.inliers)
    others = np.concatenate([f.inliers for f in seg.faces[1:]])
    assert np.isin(np.flatnonzero(on_flange), others).mean() > 0.9     # the flange: faces of its own (planes here)
    one = segment(wp, SegmentSettings(sharp_edge_deg=80.0))
    assert one.faces[0].model == "freeform" and np.isin(np.flatnonzero(on_flange), one.faces[0].inliers).mean() > 0.9


def test_an_analytic_part_keeps_its_faces(monkeypatch):
    """A box's planes: the free-form pass finds no free-form region and returns the segmentation itself."""
    box = trimesh.creation.box([200, 150, 80])
    wp, _ = mesh_workpiece(np.asarray(box.vertices), np.asarray(box.faces), n=30000)
    seen = []
    real = segment_module.with_freeform_faces

    def spy(seg, *a):
        out = real(seg, *a)
        seen.append(out is seg)
        return out

    monkeypatch.setattr(segment_module, "with_freeform_faces", spy)
    seg = segment(wp, SegmentSettings())
    assert seen == [True]
    assert [f.model for f in seg.faces] == ["plane"] * 6


def wall_trough_mesh():
    """A trough (sheet, mm) whose right wall is a cylinder (R 150 mm, axis along y) tangent to its free-form floor
    and creased 40 deg into the rim at x = 80; its ends are planes rising at 60 deg, creased into the trough. As the
    TOOLING4G mould's trough (benchmarks/parts/freeform/tooling4g_polishing_mold.stl): a curved wall the trough
    runs into."""
    R, xc = 150.0, 80.0 - 150.0 * np.sin(np.radians(40.0))
    zc = np.sqrt(R ** 2 - (80.0 - xc) ** 2)

    def z_of(X, Y):
        cyl = zc - np.sqrt(R ** 2 - (np.minimum(X, 80.0) - xc) ** 2)
        floor = cyl + np.where(X < 20.0, ((20.0 - X) / 60.0) ** 2 * (10.0 + 6.0 * np.sin(Y / 35.0)), 0.0)
        ends = -np.tan(np.radians(60.0)) * (150.0 - np.abs(Y))
        return np.minimum(np.where(X < 80.0, np.maximum(floor, ends), 0.0), 0.0)

    return grid_mesh(np.arange(-80.0, 110.01, 2.5), np.arange(-170.0, 170.01, 2.5), z_of)


def test_a_curved_wall_the_trough_runs_into_is_part_of_its_face():
    """The cylinder wall meets the floor tangentially along as long a line as it creases into the rim and the ends:
    judged on its border inside the trough's smooth region (all smooth), it is a fragment of the trough, not a face
    of its own (judged on its whole border, 0.4 smooth, it stayed a cylinder face and the trough came in two)."""
    V, F = wall_trough_mesh()
    wp, mesh = mesh_workpiece(V, F, n=40000)
    seg = segment(wp, SegmentSettings())
    models = [f.model for f in seg.faces]
    assert models.count("freeform") == 1 and "cylinder" not in models
    ff = next(f for f in seg.faces if f.model == "freeform")
    Q = wp.points_mm
    trough = (Q[:, 0] < 78.0) & (np.abs(Q[:, 1]) < 118.0) & (Q[:, 2] < -1.0)
    wall = trough & (Q[:, 0] > 22.0)
    assert np.isin(np.flatnonzero(wall), ff.inliers).mean() > 0.97
    assert np.isin(np.flatnonzero(trough), ff.inliers).mean() > 0.97
    # the face is the trough's own triangles (not the end planes' nor the rim's): its area against the mesh's
    c, n = mesh.triangles_center, mesh.face_normals
    inner = (c[:, 0] < 80.0) & (c[:, 2] < -0.5) & (np.abs(n[:, 1]) < 0.7)
    assert abs(ff.area_mm2 - mesh.area_faces[inner].sum()) < 0.05 * mesh.area_faces[inner].sum()
