"""The manufacturer robots' link bodies against the ROS-Industrial description itself: every hull
vertex, placed through camtool's joint frames, lands where the URDF (Pinocchio on the vendored file,
driven through the drivers' conventions) puts that mesh, at random configurations."""
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import trimesh
from scipy.spatial import cKDTree

from camtool.collision import CollisionWorld, robot_bodies
from camtool.collision.acm import DATA_DIR, _from_json, geometry_hash
from camtool.collision.reference_links import has_reference_links, reference_link_bodies
from camtool.robots import get_robot

ROSI = Path(__file__).resolve().parents[1] / "camtool" / "robots" / "data" / "ros-industrial"


def _urdf_mesh_points_mm(robot, q_model):
    """Each collision mesh's vertices (mm, base frame) as the URDF places them: link name -> points."""
    conv = robot.conventions
    path = str(conv.urdf_path)
    um = pin.buildModelFromUrdf(path)
    gm = pin.buildGeomFromUrdf(um, path, pin.GeometryType.COLLISION, package_dirs=[str(ROSI)])
    q = np.zeros(um.nq)
    for k, name in enumerate(conv.urdf_joint_names):
        q[um.joints[um.getJointId(name)].idx_q] = conv.urdf_from_model(q_model)[k]
    d, gd = um.createData(), pin.GeometryData(gm)
    pin.forwardKinematics(um, d, q)
    pin.updateGeometryPlacements(um, d, gm, gd)
    out = {}
    for k, go in enumerate(gm.geometryObjects):
        v = np.asarray(trimesh.load(go.meshPath, force="mesh", process=False).vertices) * go.meshScale
        M = gd.oMg[k]
        out[um.frames[go.parentFrame].name] = (v @ M.rotation.T + M.translation) * 1000.0
    return out


@pytest.mark.parametrize("name", ["irb2400", "sia20", "kr16", "m20ia"])
def test_hulls_sit_where_the_urdf_puts_the_meshes(name):
    robot = get_robot(name)
    assert has_reference_links(robot)
    world = CollisionWorld(robot)
    rng = np.random.default_rng(11)
    lo, hi = robot.limits.lower, robot.limits.upper
    for _ in range(4):
        q = lo + rng.random(robot.dof) * (hi - lo)
        truth = _urdf_mesh_points_mm(robot, q)
        poses = world.body_poses_mm(world.joint_frames_mm(q))
        for b, body in enumerate(world.robot_bodies):
            if body.kind == "tool":
                continue
            placed = body.points_mm @ poses[b][:3, :3].T + poses[b][:3, 3]
            # every hull vertex is a mesh vertex: the nearest vertex placed by the URDF is on it
            gap, _ = cKDTree(truth[body.name]).query(placed)
            assert gap.max() < 1e-6, (name, body.name)


def test_placements_do_not_depend_on_the_configuration_they_are_taken_at():
    robot = get_robot("irb2400")
    a = reference_link_bodies(robot)
    b = reference_link_bodies(robot, np.radians([10.0, -20.0, 30.0, 40.0, -50.0, 60.0]))
    assert max(np.abs(x.local_T_mm - y.local_T_mm).max() for x, y in zip(a, b)) < 1e-9


@pytest.mark.parametrize("name", ["irb2400", "sia20", "kr16", "m20ia"])
def test_shipped_matrix_is_made_for_the_mesh_bodies(name):
    robot = get_robot(name)
    shipped = _from_json((DATA_DIR / f"acm_{name}.json").read_text())
    assert shipped.geometry_hash == geometry_hash(robot, robot_bodies(robot, 25.0))


def test_forearm_folded_onto_the_base_collides_and_straight_arm_is_free():
    """A self-collision the matrix does not allow is measured: the irb2400's arm bent back (axis 2 at
    -100 deg, axis 3 at its +65 deg limit) drives the wrist into its own base."""
    robot = get_robot("irb2400")
    world = CollisionWorld(robot)
    free = world.pair_distances_mm(np.zeros(robot.dof))
    assert np.all(free > 0.0)
    folded = world.pair_distances_mm(np.radians([0.0, -100.0, 165.0, 0.0, 0.0, 0.0]))
    names = {world.pair_name(p) for p, d in zip(world.pairs, folded) if d <= 0.0}
    assert ("base_link", "link_4") in names and all("link_4" in (a, b) for a, b in names)


def test_a_users_copy_of_the_description_gives_the_same_hulls(tmp_path):
    """A user robot whose [controller.urdf] names its own copy of the ROS-I package: the meshes are read
    through the workpiece loader (no link followed; ROS-I's denormal coordinates dropped) and give the
    vendored robot's hulls."""
    import shutil
    import tomllib

    from camtool.robots.library import robot_from_toml

    src = ROSI / "abb_irb2400_support"
    shutil.copytree(src, tmp_path / "abb_irb2400_support")
    data = tomllib.loads((ROSI.parent / "irb2400.toml").read_text())
    data["name"] = "my_irb2400"
    data["controller"]["source"] = "user"
    data["controller"]["urdf"]["file"] = "abb_irb2400_support/urdf/irb2400.urdf"
    mine = robot_from_toml(data, str(tmp_path / "my_irb2400.toml"))
    assert has_reference_links(mine) and str(mine.conventions.urdf_path).startswith(str(tmp_path))
    theirs, ours = reference_link_bodies(mine), reference_link_bodies(get_robot("irb2400"))
    assert [b.name for b in theirs] == [b.name for b in ours]
    for a, b in zip(theirs, ours):
        assert np.allclose(a.local_T_mm, b.local_T_mm, atol=1e-9)
        assert cKDTree(b.points_mm).query(a.points_mm)[0].max() < 1e-3   # float32 STL read two ways
