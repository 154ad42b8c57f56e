"""A URDF's collision meshes are checked, and Pinocchio opens none of them: hostile mesh files (a symlink,
a FIFO, a missing file) are refused in one line naming the link and the mesh, and never block."""
import os
import shutil
import tomllib
from pathlib import Path

import pinocchio as pin
import pytest

from camtool.collision.reference_links import reference_link_bodies
from camtool.errors import BadInput
from camtool.robots.library import robot_from_toml
from camtool.robots.urdf_meshes import CollisionMesh, checked_collision_urdf, collision_geometry, resolve_mesh

ROSI = Path(__file__).resolve().parents[1] / "camtool" / "robots" / "data" / "ros-industrial"
URDF = ROSI / "abb_irb2400_support" / "urdf" / "irb2400.urdf"
LINK_3 = Path("abb_irb2400_support/meshes/irb2400/collision/link_3.stl")


def _users_copy(tmp_path):
    """A user robot naming its own copy of the IRB2400 package ([controller.urdf])."""
    shutil.copytree(ROSI / "abb_irb2400_support", tmp_path / "abb_irb2400_support")
    data = tomllib.loads((ROSI.parent / "irb2400.toml").read_text())
    data["name"] = "my_irb2400"
    data["controller"]["source"] = "user"
    data["controller"]["urdf"]["file"] = "abb_irb2400_support/urdf/irb2400.urdf"
    return robot_from_toml(data, str(tmp_path / "my_irb2400.toml"))


def test_vendored_description_gives_pinocchios_own_geometry():
    model = pin.buildModelFromUrdf(str(URDF))
    ours = collision_geometry(model, URDF, [ROSI])
    theirs = pin.buildGeomFromUrdf(model, str(URDF), pin.GeometryType.COLLISION, package_dirs=[str(ROSI)])
    pairs = list(zip(ours.model.geometryObjects, ours.meshes, theirs.geometryObjects, strict=True))
    assert [a.name for a, _, _ in pairs] == [b.name for _, _, b in pairs]
    assert [(a.parentJoint, a.parentFrame) for a, _, _ in pairs] == [(b.parentJoint, b.parentFrame) for _, _, b in pairs]
    for a, mesh, b in pairs:
        assert a.placement.isApprox(b.placement)
        assert mesh.path.is_absolute() and mesh.path.resolve() == Path(b.meshPath).resolve()
        assert mesh.scale == tuple(b.meshScale)


def test_filenames_resolve_like_ros(tmp_path):
    (tmp_path / "pkg" / "meshes").mkdir(parents=True)
    mesh = tmp_path / "pkg" / "meshes" / "a.stl"
    mesh.write_bytes(b"solid a\nendsolid a\n")
    urdf = tmp_path / "pkg" / "robot.urdf"
    assert resolve_mesh("package://pkg/meshes/a.stl", urdf, [tmp_path / "none", tmp_path]) == mesh
    assert resolve_mesh(f"file://{mesh}", urdf, []) == mesh
    assert resolve_mesh("meshes/a.stl", urdf, []) == mesh
    assert resolve_mesh("package://pkg/meshes/b.stl", urdf, [tmp_path]) is None


def test_a_mesh_replaced_by_a_symlink_is_refused_naming_the_link(tmp_path):
    robot = _users_copy(tmp_path)
    target = tmp_path / LINK_3
    target.unlink()
    os.symlink("/etc/passwd", target)
    with pytest.raises(BadInput) as exc:
        reference_link_bodies(robot)
    line = str(exc.value)
    assert "\n" not in line and "'link_3'" in line and "link_3.stl" in line and "symlink" in line


def test_a_mesh_replaced_by_a_fifo_is_refused_without_blocking(tmp_path):
    robot = _users_copy(tmp_path)
    target = tmp_path / LINK_3
    target.unlink()
    os.mkfifo(target)
    with pytest.raises(BadInput, match="link_3.*FIFO"):
        reference_link_bodies(robot)


def test_a_missing_mesh_is_named(tmp_path):
    robot = _users_copy(tmp_path)
    (tmp_path / LINK_3).unlink()
    with pytest.raises(BadInput, match=r"link 'link_3' collision mesh .*link_3\.stl.*not found"):
        reference_link_bodies(robot)


def test_the_text_pinocchio_reads_names_only_checked_files(tmp_path):
    _users_copy(tmp_path)
    urdf = tmp_path / "abb_irb2400_support" / "urdf" / "irb2400.urdf"
    text, meshes = checked_collision_urdf(urdf, [tmp_path])
    import xml.etree.ElementTree as ET

    assert not ET.fromstring(text).findall("link/collision/geometry/mesh")
    assert CollisionMesh(tmp_path / LINK_3, (1.0, 1.0, 1.0)) in meshes["link_3"]


def test_pinocchio_opens_no_mesh_so_a_swap_after_the_check_is_never_read(tmp_path, monkeypatch):
    """The race the issue names: a mesh checked, then swapped for a FIFO before Pinocchio would open it.
    Pinocchio now opens nothing, so the geometry is built at once, without blocking."""
    import camtool.robots.urdf_meshes as um

    _users_copy(tmp_path)
    urdf = tmp_path / "abb_irb2400_support" / "urdf" / "irb2400.urdf"
    checked = um.checked_collision_urdf

    def check_then_swap(*args, **kwargs):
        out = checked(*args, **kwargs)
        (tmp_path / LINK_3).unlink()
        os.mkfifo(tmp_path / LINK_3)
        return out

    monkeypatch.setattr(um, "checked_collision_urdf", check_then_swap)
    geometry = um.collision_geometry(pin.buildModelFromUrdf(str(URDF)), urdf, [tmp_path])
    assert sum(m is not None for m in geometry.meshes) == len(geometry.model.geometryObjects)


def test_a_scale_that_is_no_number_is_one_line(tmp_path):
    _users_copy(tmp_path)
    urdf = tmp_path / "abb_irb2400_support" / "urdf" / "irb2400.urdf"
    urdf.write_text(urdf.read_text().replace('link_3.stl"', 'link_3.stl" scale="1 nan 1"', 1))
    with pytest.raises(BadInput, match=r"link 'link_3' .*scale must be three finite"):
        checked_collision_urdf(urdf, [tmp_path])
