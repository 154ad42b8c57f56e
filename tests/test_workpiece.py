"""Workpiece loading: formats, units, warnings, sampling, normals, transforms."""
import numpy as np
import open3d as o3d
import pytest
import trimesh

from camtool.errors import BadInput
from camtool.workpiece import LOADERS, Workpiece, load_workpiece


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
