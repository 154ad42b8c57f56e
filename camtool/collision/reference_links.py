"""The manufacturer robots' own link shapes: the vendored ROS-Industrial collision meshes.

A robot whose controller data names a vendored ROS-Industrial description
(``[controller.urdf]``: the IRB2400, the SIA20) is a DH model whose joint
frames are not the URDF's link frames. Its bodies are the URDF's
``<collision>`` meshes, each as the convex hull of its vertices (mm), moved
into the model's joint frame that carries the same link:

    local_T = inv(model joint frame k at q) @ URDF mesh placement at urdf_from_model(q)

with the URDF's base_link = the model's base. The link is rigid, so the
product does not depend on ``q``; ``tests/test_reference_links.py`` checks it
over random configurations. Convex hulls enclose the meshes (never thinner
than the robot) and keep coal's GJK queries fast (docs/motion-check.md).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import BadInput
from ..safe_io import read_input_bytes
from ..robots.urdf_meshes import collision_geometry
from ..robots.joint_frames import joint_frames_mm
from .body import BASE, MM_PER_M, Body, hull_points, mesh_points, se3_mm

REFERENCE_Q_FRACTION = 0.37   # the configuration the placements are taken at (any one works: links are rigid)
_MEMO: dict = {}               # (URDF, model chain) -> bodies: the meshes are read once a process


def has_reference_links(robot) -> bool:
    """True if the robot's controller data names a vendored ROS-Industrial description."""
    conv = robot.conventions
    return conv is not None and conv.urdf_path is not None and conv.urdf_matrix is not None


def reference_link_bodies(robot, q_rad: np.ndarray | None = None) -> list[Body]:
    """The URDF's collision meshes as convex bodies on the model's joint frames (module docstring)."""
    conv = robot.conventions
    key = (str(conv.urdf_path), conv.urdf_joint_names, conv.urdf_matrix.tobytes(),
           b"".join(np.asarray(M.homogeneous).tobytes() for M in robot.model.jointPlacements),
           None if q_rad is None else np.asarray(q_rad, float).tobytes())
    if key not in _MEMO:
        _MEMO[key] = tuple(_read_bodies(robot, q_rad))
    return list(_MEMO[key])


def _read_bodies(robot, q_rad) -> list[Body]:
    import pinocchio as pin

    conv = robot.conventions
    path = Path(conv.urdf_path)
    data = read_input_bytes(path, "robot")  # opened once, a regular file under the cap: a FIFO never blocks
    try:
        um = pin.buildModelFromXML(data.decode("utf-8"))  # the checked text, never the file again by name
    except Exception as exc:
        raise BadInput(f"{path}: cannot read the URDF ({type(exc).__name__})") from None
    # package://<pkg>/... resolves against the folders above the URDF (<pkg>/urdf/<robot>.urdf)
    geometry = collision_geometry(um, path, list(path.resolve().parents)[:3], data)
    gm = geometry.model
    if q_rad is None:
        lo, hi = robot.limits.lower, robot.limits.upper
        q_rad = lo + REFERENCE_Q_FRACTION * (hi - lo)
    q_model = np.asarray(q_rad, float)
    frames = joint_frames_mm(robot, q_model)
    q_urdf = np.zeros(um.nq)
    urdf_q = conv.urdf_from_model(q_model)
    joint_of_urdf = {}
    for k, name in enumerate(conv.urdf_joint_names):
        jid = um.getJointId(name)
        if jid >= um.njoints:
            raise BadInput(f"{path}: has no joint {name!r} ([controller.urdf] joints)")
        q_urdf[um.joints[jid].idx_q] = urdf_q[k]
        joint_of_urdf[jid] = k + 1
    ud = um.createData()
    gd = pin.GeometryData(gm)
    pin.forwardKinematics(um, ud, q_urdf)
    pin.updateGeometryPlacements(um, ud, gm, gd)
    out = []
    for k, (go, mesh) in enumerate(zip(gm.geometryObjects, geometry.meshes)):
        if mesh is None:
            continue
        pts = hull_points(_vertices_m(mesh.path) * np.asarray(mesh.scale) * MM_PER_M)
        T_world = se3_mm(gd.oMg[k])
        parent = _moving_parent(um, go.parentJoint, joint_of_urdf)
        name = um.frames[go.parentFrame].name if go.parentFrame < len(um.frames) else go.name
        if parent == BASE:
            out.append(Body(name, "base", BASE, "convex", (), T_world, pts))
        else:
            local = np.linalg.inv(frames[parent - 1]) @ T_world
            out.append(Body(name, "link", parent, "convex", (), local, pts))
    return out


VENDORED = Path(__file__).resolve().parents[1] / "robots" / "data" / "ros-industrial"


def _vertices_m(mesh_path: str) -> np.ndarray:
    """The vertices (m) of a collision mesh. A vendored one is read by trimesh: the ROS-I meshes
    carry denormal coordinates (1e-33 m) that the workpiece loader rightly refuses in a part, and
    that are harmless in a hull. Any other file (a user's description) goes through the workpiece
    loader, with its checks (no links followed, no special files, bounded size)."""
    path = Path(mesh_path)
    if not path.resolve().is_relative_to(VENDORED):
        return mesh_points(path, "m", drop_damaged=True) / MM_PER_M   # the path as given: no link followed
    import trimesh

    mesh = trimesh.load(str(path), force="mesh", process=False)
    return np.asarray(mesh.vertices, float)


def _moving_parent(um, jid: int, joint_of_urdf: dict) -> int:
    """The model joint (1..dof) that moves URDF joint ``jid``'s link, BASE for the fixed base."""
    while jid > 0 and jid not in joint_of_urdf:
        jid = um.parents[jid]
    return joint_of_urdf.get(jid, BASE)
