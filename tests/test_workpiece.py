"""Workpiece loading: formats, units, warnings, sampling, normals, transforms, and the
checks that keep damaged files (cut short, NaN, garbage numbers) from becoming a workpiece."""
from pathlib import Path

import numpy as np
import open3d as o3d
import pytest
import trimesh

from camtool.errors import BadInput
from camtool.part.workpiece import LOADERS, Workpiece, load_workpiece


def _box_mesh():
    return trimesh.creation.box(extents=(200.0, 100.0, 50.0))


@pytest.mark.parametrize("name,kw", [("a.stl", {"file_type": "stl"}), ("a_ascii.stl", {"file_type": "stl_ascii"}),
                                     ("a.obj", {}), ("a.off", {}), ("a.glb", {}), ("a.ply", {})])
def test_mesh_formats_sample_area_weighted(tmp_path, name, kw):
    path = tmp_path / name
    data = _box_mesh().export(file_type=kw.get("file_type", path.suffix[1:]))
    path.write_bytes(data if isinstance(data, bytes) else data.encode())
    wp = load_workpiece(path, sample_points=6000, seed=3)
    assert wp.points_mm.shape == (6000, 3) and wp.faces is not None
    assert np.allclose(np.abs(wp.points_mm).max(axis=0), [100, 50, 25], atol=1e-6)
    assert np.allclose(np.linalg.norm(wp.normals, axis=1), 1.0)
    # area weighting: the two 200 x 100 faces hold 20000/35000 of the area
    share = np.mean(np.abs(wp.points_mm[:, 2]) > 25 - 1e-6)
    assert abs(share - 20000 / 35000) < 0.03
    # outward face normals of a closed box
    assert np.all(np.einsum("ij,ij->i", wp.points_mm, wp.normals) > 0)


def test_mesh_sampling_is_deterministic(tmp_path):
    path = tmp_path / "b.stl"
    _box_mesh().export(path)
    a, b = load_workpiece(path, seed=5, sample_points=1000), load_workpiece(path, seed=5, sample_points=1000)
    c = load_workpiece(path, seed=6, sample_points=1000)
    assert np.array_equal(a.points_mm, b.points_mm) and not np.array_equal(a.points_mm, c.points_mm)


def _plane_cloud(n=2000, seed=0):
    rng = np.random.default_rng(seed)
    return np.stack([rng.uniform(-300, 300, n), np.full(n, 600.0), rng.uniform(100, 700, n)], 1)


@pytest.mark.parametrize("ext", [".ply", ".pcd", ".xyz", ".csv", ".txt"])
def test_cloud_formats_get_normals_towards_origin(tmp_path, ext):
    pts = _plane_cloud()
    path = tmp_path / f"c{ext}"
    if ext in (".ply", ".pcd"):
        o3d.io.write_point_cloud(str(path), o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts)))
    else:
        sep = "," if ext == ".csv" else " "
        path.write_text("x,y,z\n" * (ext == ".csv") + "\n".join(sep.join(f"{v:.6f}" for v in p) for p in pts))
    wp = load_workpiece(path, normal_neighbours=10)
    assert wp.faces is None and wp.points_mm.shape == (2000, 3)
    assert np.allclose(wp.points_mm, pts, atol=1e-5)
    assert np.allclose(wp.normals, [0, -1, 0], atol=1e-6)  # the plane faces the origin (sensor)


def test_text_cloud_keeps_file_normals(tmp_path):
    path = tmp_path / "n.xyz"
    pts = _plane_cloud(50)
    path.write_text("\n".join(f"{p[0]} {p[1]} {p[2]} 0 2 0" for p in pts))
    assert np.allclose(load_workpiece(path).normals, [0, 1, 0])


def test_units_m_become_mm_and_transform(tmp_path):
    path = tmp_path / "m.xyz"
    pts_m = _plane_cloud() / 1000.0
    np.savetxt(path, pts_m)
    wp = load_workpiece(path, units="m")
    assert np.allclose(wp.points_mm, pts_m * 1000.0) and wp.units == "m" and wp.warnings == ()
    T = np.eye(4)
    T[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    T[:3, 3] = [10, 20, 30]
    moved = wp.transformed(T)
    assert np.allclose(moved.points_mm, wp.points_mm @ T[:3, :3].T + [10, 20, 30])
    assert np.allclose(moved.normals, [1, 0, 0], atol=1e-6)  # -y rotated by +90 deg about z


def test_implausible_size_warns_with_likely_unit(tmp_path):
    path = tmp_path / "m.xyz"
    np.savetxt(path, _plane_cloud() / 1000.0)  # metres, declared as mm
    wp = load_workpiece(path, units="mm")
    assert len(wp.warnings) == 1 and 'units = "m"' in wp.warnings[0] and str(path) in wp.warnings[0]
    np.savetxt(path, _plane_cloud())  # mm, declared as m -> 849 m across
    assert 'units = "mm"' in load_workpiece(path, units="m").warnings[0]


def test_registry_and_errors(tmp_path):
    assert {".stl", ".obj", ".off", ".glb", ".ply", ".pcd", ".xyz", ".csv", ".txt", ".step"} <= set(LOADERS)
    with pytest.raises(BadInput, match="unsupported file type"):
        load_workpiece(tmp_path / "x.docx")
    with pytest.raises(BadInput, match="not found"):
        load_workpiece(tmp_path / "missing.stl")
    with pytest.raises(BadInput, match="units"):
        load_workpiece(tmp_path / "x.stl", units="ft")


def test_workpiece_is_frozen():
    wp = Workpiece(np.zeros((1, 3)), np.zeros((1, 3)))
    with pytest.raises(Exception):
        wp.units = "m"


# --------------------------------------------------------------------------- damaged input (loader checks)

BAD = Path(__file__).resolve().parent / "bad_input"


def _far_cloud(n=50, seed=1):
    """A patch far from the origin, so that a zero-filled point could not hide."""
    rng = np.random.default_rng(seed)
    return np.round(np.c_[rng.uniform(-300, 300, n), np.full(n, 600.0), rng.uniform(100, 700, n)], 4)


def _ascii_ply(pts, rows=None):
    head = (f"ply\nformat ascii 1.0\nelement vertex {len(pts)}\nproperty double x\nproperty double y\n"
            "property double z\nend_header\n")  # 7 header lines: vertex i is on line 8 + i
    rows = rows if rows is not None else [f"{p[0]} {p[1]} {p[2]}" for p in pts]
    return head + "\n".join(rows) + "\n"


def _pcd(pts, n_points=None, width=None, rows=None):
    n = len(pts)
    head = (f"# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {width or n}\n"
            f"HEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n_points or n}\nDATA ascii\n")
    rows = rows if rows is not None else [f"{p[0]} {p[1]} {p[2]}" for p in pts]
    return head + "\n".join(rows) + "\n"


def test_ascii_ply_cut_short_is_bad_input_not_zero_filled(tmp_path):
    path = tmp_path / "part.ply"
    text = _ascii_ply(_far_cloud(2000))
    path.write_text(text[:len(text) // 2].rsplit("\n", 1)[0] + "\n")
    with pytest.raises(BadInput, match=r"part\.ply: ASCII PLY is truncated: the header says 2000 vertices, "
                                        r"the file holds \d+;"):
        load_workpiece(path)


@pytest.mark.parametrize("token", ["nan", "-inf", "inf", "NaN"])
def test_nonfinite_names_the_file_and_the_first_vertex(tmp_path, token):
    pts = _far_cloud()
    rows = [f"{p[0]} {p[1]} {p[2]}" for p in pts]
    rows[17] = f"{pts[17][0]} {token} {pts[17][2]}"
    rows[30] = f"nan {pts[30][1]} {pts[30][2]}"
    path = tmp_path / "part.ply"
    path.write_text(_ascii_ply(pts, rows))
    with pytest.raises(BadInput) as exc:
        load_workpiece(path)
    msg = str(exc.value)
    assert msg.startswith(f"{path}: vertex 17 (line 25) has a non-finite coordinate ({token.lower()})")
    assert "2 of 50 vertices have NaN or infinite coordinates" in msg
    assert "set workpiece.drop_nonfinite = true" in msg and "\n" not in msg


def test_open3d_style_zero_fill_cannot_happen(tmp_path):
    """The reported case: one -inf in an ASCII PLY made open3d zero-fill the rest of the cloud."""
    pts = _far_cloud(2000)
    rows = [f"{p[0]} {p[1]} {p[2]}" for p in pts]
    rows[12] = f"{pts[12][0]} -inf {pts[12][2]}"
    path = tmp_path / "scan.ply"
    path.write_text(_ascii_ply(pts, rows))
    with pytest.raises(BadInput, match="vertex 12"):
        load_workpiece(path)
    wp = load_workpiece(path, drop_nonfinite=True)
    assert wp.n_points == 1999 and not (wp.points_mm == 0).all(axis=1).any()
    assert np.allclose(wp.points_mm, np.delete(pts, 12, axis=0))


def test_denormal_garbage_is_damage_but_zero_is_fine(tmp_path):
    pts = _far_cloud()
    rows = [f"{p[0]} {p[1]} {p[2]}" for p in pts]
    rows[5] = f"{pts[5][0]} 1e-300 {pts[5][2]}"
    path = tmp_path / "part.xyz"
    path.write_text("\n".join(rows))
    with pytest.raises(BadInput, match=r"point 5 \(line 6\) has a damaged coordinate \(1e-300"):
        load_workpiece(path)
    rows[5] = f"{pts[5][0]} 0 {pts[5][2]}"
    rows[6] = f"{pts[6][0]} 1e-20 {pts[6][2]}"  # small but a plausible float residue
    path.write_text("\n".join(rows))
    assert load_workpiece(path).n_points == 50


def test_drop_nonfinite_drops_points_with_a_warning(tmp_path):
    pts = _far_cloud()
    rows = [f"{p[0]} {p[1]} {p[2]}" for p in pts]
    rows[3], rows[9] = "nan nan nan", f"{pts[9][0]} 1e-300 {pts[9][2]}"
    path = tmp_path / "scan.xyz"
    path.write_text("\n".join(rows))
    wp = load_workpiece(path, drop_nonfinite=True)
    assert wp.n_points == 48 and np.allclose(wp.points_mm, np.delete(pts, [3, 9], axis=0))
    assert len(wp.warnings) == 1
    assert wp.warnings[0] == (f"{path}: dropped 2 of 50 points with NaN, infinite or damaged coordinates "
                              "(workpiece.drop_nonfinite)")


def test_stl_nan_triangle_is_an_error_or_dropped(tmp_path):
    path = BAD / "nan_triangle.stl"
    with pytest.raises(BadInput, match=r"nan_triangle\.stl: triangle 2 has a non-finite coordinate \(nan\); "
                                        r"1 of 4 triangles"):
        load_workpiece(path)
    wp = load_workpiece(path, drop_nonfinite=True, sample_points=500)
    assert len(wp.faces) == 3 and np.isfinite(wp.points_mm).all() and np.isfinite(wp.vertices_mm).all()
    assert "dropped 1 vertex with NaN or infinite" in wp.warnings[0] and "the 1 of 4 triangles using them" in wp.warnings[0]
    path = tmp_path / "all_nan.xyz"
    path.write_text("nan 1 2\n3 inf 4\n")
    with pytest.raises(BadInput, match="all 2 points have NaN or infinite coordinates; nothing is left"):
        load_workpiece(path, drop_nonfinite=True)


def test_mesh_nonfinite_vertex_drops_its_triangles(tmp_path):
    mesh = _box_mesh()
    mesh.apply_translation([500, 600, 700])
    v = mesh.vertices.copy()
    v[0, 1] = np.inf
    path = tmp_path / "box.ply"
    path.write_bytes(trimesh.Trimesh(v, mesh.faces, process=False).export(file_type="ply", encoding="ascii"))
    with pytest.raises(BadInput, match=r"box\.ply: vertex 0 \(line \d+\) has a non-finite coordinate \(inf\)"):
        load_workpiece(path)
    wp = load_workpiece(path, drop_nonfinite=True, sample_points=500)
    used = int((mesh.faces == 0).any(axis=1).sum())
    assert len(wp.faces) == 12 - used and len(wp.vertices_mm) == 7
    assert f"the {used} of 12 triangles using them" in wp.warnings[0]


def test_pcd_counts_are_checked(tmp_path):
    pts = _far_cloud(20)
    path = tmp_path / "scan.pcd"
    path.write_text(_pcd(pts, n_points=30))
    with pytest.raises(BadInput, match=r"says POINTS 30 but WIDTH x HEIGHT = 20 x 1"):
        load_workpiece(path)
    path.write_text(_pcd(pts, rows=[f"{p[0]} {p[1]} {p[2]}" for p in pts[:11]]))
    with pytest.raises(BadInput, match="header says 20 points, the file holds 11 data lines"):
        load_workpiece(path)
    rows = [f"{p[0]} {p[1]} {p[2]}" for p in pts]
    rows[4] = f"{pts[4][0]} {pts[4][1]}"  # open3d skips the short line and makes the last point up
    path.write_text(_pcd(pts, rows=rows))
    with pytest.raises(BadInput, match=r"line 16: expected 3 numbers for a point, found 2"):
        load_workpiece(path)
    rows[4] = "nan nan nan"  # an organised scan's missing return
    path.write_text(_pcd(pts, rows=rows))
    with pytest.raises(BadInput, match=r"point 4 \(line 16\) has a non-finite coordinate"):
        load_workpiece(path)
    wp = load_workpiece(path, drop_nonfinite=True)
    assert wp.n_points == 19 and "dropped 1 of 20 points" in wp.warnings[0]


def test_binary_cut_short_and_corrupt_counts(tmp_path):
    pts = _far_cloud(30)
    path = tmp_path / "scan.pcd"
    o3d.io.write_point_cloud(str(path), o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts)))
    assert load_workpiece(path).n_points == 30
    path.write_bytes(path.read_bytes()[:-7])
    with pytest.raises(BadInput, match=r"binary PCD is truncated or corrupt \(the header says 30 points, 360 bytes"):
        load_workpiece(path)
    path = tmp_path / "scan.ply"
    path.write_bytes(trimesh.PointCloud(pts).export(file_type="ply")[:-5])
    with pytest.raises(BadInput, match=r"binary PLY is truncated or corrupt \(the header says 30 vertices"):
        load_workpiece(path)
    mesh = _box_mesh()
    data = bytearray(mesh.export(file_type="ply"))
    data[data.index(b"end_header\n") + 11 + 8 * 12 + 5 * 13] = 7  # the count byte of face 5
    path = tmp_path / "box.ply"
    path.write_bytes(bytes(data))
    with pytest.raises(BadInput, match=r"binary PLY face 5 has 7 vertex_indices where the first has 3"):
        load_workpiece(path)


def test_text_meshes_cut_short(tmp_path):
    mesh = _box_mesh()
    text = mesh.export(file_type="stl_ascii")
    path = tmp_path / "box.stl"
    path.write_text(text[:len(text) // 2])
    with pytest.raises(BadInput, match="does not end with 'endsolid'"):
        load_workpiece(path)
    path.write_text(text.replace("vertex", "vertex 1", 1))
    with pytest.raises(BadInput, match=r"vertex 0 \(triangle 0\) is not 3 numbers"):
        load_workpiece(path)
    text = mesh.export(file_type="ply", encoding="ascii").decode()
    path = tmp_path / "box.ply"
    path.write_text(text[:text.rindex("\n3 ")])
    with pytest.raises(BadInput, match="ASCII PLY is truncated: the header says 12 faces, the file holds 11"):
        load_workpiece(path)
    text = mesh.export(file_type="off")
    path = tmp_path / "box.off"
    path.write_text(text[:text.rindex("\n3 ")])
    with pytest.raises(BadInput, match="OFF header says 8 vertices and 12 faces, the file holds 19 data lines"):
        load_workpiece(path)
    text = mesh.export(file_type="obj")
    lines = text.splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.startswith("v "))
    lines[k] = " ".join(lines[k].split()[:3])  # a vertex line cut after y
    path = tmp_path / "box.obj"
    path.write_text("\n".join(lines))
    with pytest.raises(BadInput, match=rf"line {k + 1}: a vertex needs x y z numbers"):
        load_workpiece(path)


def test_text_cloud_count_line_and_damaged_first_row(tmp_path):
    pts = _far_cloud(10)
    rows = [f"{p[0]} {p[1]} {p[2]}" for p in pts]
    path = tmp_path / "scan.pts"
    path.write_text("10\n" + "\n".join(rows))
    assert load_workpiece(path).n_points == 10
    path.write_text("12\n" + "\n".join(rows))
    with pytest.raises(BadInput, match="the first line says 12 points, the file holds 10"):
        load_workpiece(path)
    path = tmp_path / "scan.xyz"
    path.write_text(f"{pts[0][0]} 6\x0e0.5 {pts[0][2]}\n" + "\n".join(rows[1:]))  # not a header: a damaged row
    with pytest.raises(BadInput, match="line 1: not a row of 3 numbers"):
        load_workpiece(path)


def test_nothing_printed_by_the_libraries(tmp_path, capfd):
    """open3d prints on stdout (which --json needs clean); RPly and trimesh log on stderr."""
    for name in ("cut_short.ply", "minus_inf.ply", "cut_short.pcd", "nan_triangle.stl"):
        with pytest.raises(BadInput):
            load_workpiece(BAD / name)
    path = tmp_path / "scan.pcd"
    path.write_text(_pcd(_far_cloud(20), rows=["1 2"] * 20))
    with pytest.raises(BadInput):
        load_workpiece(path)
    assert capfd.readouterr() == ("", "")
    import logging

    assert logging.getLogger("trimesh").propagate and not logging.getLogger("trimesh").handlers


@pytest.mark.parametrize("name,words", [
    ("cut_short.ply", "the header says 20 vertices, the file holds 12"),
    ("minus_inf.ply", "vertex 17 (line 26) has a non-finite coordinate (-inf)"),
    ("denormal.xyz", "point 5 (line 6) has a damaged coordinate"),
    ("cut_short.pcd", "the PCD header says 20 points, the file holds 9"),
    ("nan_triangle.stl", "triangle 2 has a non-finite coordinate (nan)"),
])
def test_cli_fit_damaged_file_exit_2(name, words):
    from conftest import run_camtool

    r = run_camtool("fit", BAD / name, "--json")
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("camtool: error: ")
    assert words in r.stderr and name in r.stderr
