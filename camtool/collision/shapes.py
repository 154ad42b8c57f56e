"""Collision shapes: the robot's link bodies, the tool and the cell's obstacles (docs/motion-check.md).

A ``Body`` is one coal shape fixed in one frame: a joint frame of the robot
(``parent`` = 1..dof, Pinocchio's joint index, the frame after the joint's
motion), the robot's base (``parent`` = 0) or the world (``parent`` = -1,
obstacles and the floor). Lengths are mm everywhere, coal included.

Robot bodies (``robot_bodies``), sized from the robot's own geometry:

- a capsule round every constant offset between consecutive joint origins (and
  from the last joint to the flange), its radius ``link_radius_mm(length)`` =
  15 % of the link's length, within 40..100 mm (seed8: column 72, upper arm 60,
  forearm 63, wrist 40 mm);
- a robot whose first joint is prismatic (a track, seed8) also gets its
  carriage: a flat box under the first link's foot, 300 mm along the track,
  250 mm across, 60 mm high (the rail itself lies below it, on the floor: a
  ``cell.floor_z_mm`` at or below the carriage's underside stands for it);
- the tool: the convex hull of ``[tool] mesh`` (flange frame), or a cylinder of
  ``check.tool_radius_mm`` from the flange to the TCP.

Why hand-sized shapes: seed8 and the DH robots have no meshes; these shapes
are documented and enclose the joint axes with the radii above. The
manufacturer robots (IRB2400, SIA20) use their ROS-Industrial collision meshes
instead (``reference_links.py``), URDF robots their own collision elements.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import BadInput
from ..transforms import matrix_from_xyz_rpy
from .body import BASE, MM_PER_M, WORLD, Body, convex_hull, hull_points, mesh_points, se3_mm  # noqa: F401 (re-exported)

LINK_RADIUS_FRACTION = 0.15
LINK_RADIUS_MIN_MM, LINK_RADIUS_MAX_MM = 40.0, 100.0
CARRIAGE_MM = (60.0, 250.0, 300.0)    # along the first link (height), across, along the track
MIN_LINK_MM = 1e-6


def link_radius_mm(length_mm: float) -> float:
    """Capsule radius of a link of this length (mm): 15 %, within 40..100 mm."""
    return float(np.clip(LINK_RADIUS_FRACTION * length_mm, LINK_RADIUS_MIN_MM, LINK_RADIUS_MAX_MM))


def segment_T(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Placement of a z-axis shape centred between a and b, z along b - a."""
    z = np.asarray(b, float) - np.asarray(a, float)
    z = z / max(np.linalg.norm(z), 1e-12)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2] = x, np.cross(z, x), z
    T[:3, 3] = (np.asarray(a, float) + np.asarray(b, float)) / 2.0
    return T


def joint_offsets(robot) -> list[np.ndarray]:
    """(dof) offset (mm) from each joint origin to the next one (the flange after the last), in its frame."""
    m = robot.model
    out = [np.asarray(m.jointPlacements[i + 1].translation) * MM_PER_M for i in range(1, robot.dof)]
    out.append(se3_mm(m.frames[robot.flange_frame_id].placement)[:3, 3])
    return out


def robot_bodies(robot, tool_radius_mm: float, tool_points_mm: np.ndarray | None = None) -> tuple[Body, ...]:
    """The link, carriage and tool bodies of a robot (module docstring); a URDF robot's own
    collision elements when it has any (``urdf_bodies``), a manufacturer robot's vendored
    ROS-Industrial collision meshes (``reference_links``)."""
    from .reference_links import has_reference_links, reference_link_bodies

    if robot.convention == "urdf":
        bodies = urdf_bodies(robot)
    elif has_reference_links(robot):
        bodies = reference_link_bodies(robot)
    else:
        bodies = []
    if bodies:
        return tuple(bodies) + _tool_bodies(robot, tool_radius_mm, tool_points_mm)
    names = list(robot.joint_names)
    offsets = joint_offsets(robot)
    for i, o in enumerate(offsets):
        L = float(np.linalg.norm(o))
        if L <= MIN_LINK_MM:
            continue
        nxt = names[i + 1] if i + 1 < robot.dof else "flange"
        bodies.append(Body(f"{names[i]}-{nxt}", "link", i + 1, "capsule", (link_radius_mm(L), L),
                           segment_T(np.zeros(3), o)))
    if robot.dof and robot.prismatic[0]:
        bodies = _track_bodies(robot, offsets[0]) + bodies
    return tuple(bodies) + _tool_bodies(robot, tool_radius_mm, tool_points_mm)


def _tool_bodies(robot, tool_radius_mm, tool_points_mm) -> tuple[Body, ...]:
    bodies = []
    flange = se3_mm(robot.model.frames[robot.flange_frame_id].placement)
    tool = np.asarray(robot.tool_T_mm, float)
    if tool_points_mm is not None:
        pts = hull_points(tool_points_mm)
        bodies.append(Body("tool", "tool", robot.dof, "convex", (), flange, pts))
    elif np.linalg.norm(tool[:3, 3]) > 1.0:
        L = float(np.linalg.norm(tool[:3, 3]))
        bodies.append(Body("tool", "tool", robot.dof, "cylinder", (float(tool_radius_mm), L),
                           flange @ segment_T(np.zeros(3), tool[:3, 3])))
    return tuple(bodies)


def urdf_bodies(robot) -> list[Body]:
    """A URDF robot's ``<collision>`` elements (Pinocchio's buildGeomFromUrdf): boxes, cylinders and
    spheres as they are, meshes as their convex hulls (mm), on the joint frames they belong to."""
    import coal

    from ..robots.urdf_meshes import collision_geometry

    path = Path(robot.source)
    data_dir = Path(__file__).resolve().parents[1] / "robots" / "data" / "ros-industrial"
    geometry = collision_geometry(robot.model, path, [path.parent, data_dir])
    out = []
    for k, (go, mesh) in enumerate(zip(geometry.model.geometryObjects, geometry.meshes)):
        T = se3_mm(go.placement)
        g = go.geometry
        name = f"{go.name}" if go.name else f"collision{k}"
        if mesh is not None:
            pts = mesh_points(mesh.path, "m", drop_damaged=True) * np.asarray(mesh.scale)
            out.append(Body(name, "link", go.parentJoint, "convex", (), T, hull_points(pts)))
        elif isinstance(g, coal.Box):
            out.append(Body(name, "link", go.parentJoint, "box", tuple(2.0 * MM_PER_M * np.asarray(g.halfSide)), T))
        elif isinstance(g, coal.Cylinder):
            out.append(Body(name, "link", go.parentJoint, "cylinder", (g.radius * MM_PER_M, 2 * g.halfLength * MM_PER_M), T))
        elif isinstance(g, coal.Sphere):
            out.append(Body(name, "link", go.parentJoint, "sphere", (g.radius * MM_PER_M,), T))
    return [b if b.parent > 0 else Body(b.name, "base", BASE, b.shape, b.size_mm, b.local_T_mm, b.points_mm)
            for b in out]


def _track_bodies(robot, first_offset) -> list[Body]:
    """The carriage (on the track joint) of a robot on a linear track."""
    up = np.asarray(first_offset, float)
    n = np.linalg.norm(up)
    up = up / n if n > MIN_LINK_MM else np.array([1.0, 0.0, 0.0])
    along = np.array([0.0, 0.0, 1.0])             # the prismatic joint moves along its frame's z
    across = np.cross(along, up)
    h, w, L = CARRIAGE_MM
    carriage = np.eye(4)
    carriage[:3, :3] = np.stack([up, across, along], axis=1)
    carriage[:3, 3] = -up * h / 2.0
    return [Body("carriage", "link", 1, "box", (h, w, L), carriage)]


def obstacle_bodies(specs, workpiece_T_mm: np.ndarray, base_dir, floor_z_mm: float | None = None) -> tuple[Body, ...]:
    """World-fixed bodies of the job's obstacles (``ObstacleSpec``) and its floor."""
    bodies = []
    for s in specs:
        T = matrix_from_xyz_rpy(s.xyz_mm, s.rpy_deg)
        if s.frame == "workpiece":
            T = np.asarray(workpiece_T_mm, float) @ T
        if s.shape == "mesh":
            pts = mesh_points(Path(base_dir) / s.mesh, s.units)
            bodies.append(Body(s.name, "obstacle", WORLD, "convex", (), T, hull_points(pts)))
        elif s.shape == "box":
            bodies.append(Body(s.name, "obstacle", WORLD, "box", tuple(s.size_mm), T))
        elif s.shape == "cylinder":
            bodies.append(Body(s.name, "obstacle", WORLD, "cylinder", tuple(s.size_mm), T))
        else:
            bodies.append(Body(s.name, "obstacle", WORLD, "sphere", tuple(s.size_mm), T))
    if floor_z_mm is not None:
        bodies.append(Body("floor", "obstacle", WORLD, "halfspace", (float(floor_z_mm),), np.eye(4)))
    return tuple(bodies)
