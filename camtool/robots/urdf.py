"""URDF in and out: load a robot through Pinocchio's URDF parser, or write a
DH robot as URDF (metres, as URDF requires).

Position and velocity limits come from the URDF's ``<limit>``; URDF has no
acceleration or jerk limits, so those default to 4x and 20x the velocity
limit per second (documented in docs/robots.md) unless ``[robot]`` in the job
says otherwise.

Before Pinocchio sees a file, :func:`check_urdf` reads its XML and rejects what
Pinocchio would crash on (a robot without a movable joint ends in a segfault
later) or reject with a vague message: not XML, no ``<robot>``, unknown or
unsupported joint types, duplicate names, parents or children that are not
links, origins and axes without 3 finite numbers, a zero axis, missing or
non-finite ``<limit lower upper velocity>``, and lengths beyond 1 km
(``MAX_LENGTH_MM``). Each is one BadInput line naming the file and the joint.
"""
from __future__ import annotations

import math
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np
import pinocchio as pin

from ..errors import BadInput
from .dh import MAX_LENGTH_MM, MM_TO_M, rot_x, rot_z, trans
from .model import Limits, Robot

ACC_PER_VEL = 4.0
JERK_PER_VEL = 20.0


_MOVABLE = ("revolute", "prismatic")
_URDF_JOINT_TYPES = ("revolute", "prismatic", "continuous", "fixed", "floating", "planar")


def _floats(text: str | None, where: str, default: str) -> list[float]:
    """The 3 finite numbers of an xyz / rpy attribute (URDF's default when absent)."""
    tokens = (default if text is None else text).split()
    try:
        values = [float(t) for t in tokens]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise BadInput(f"{where}: expected 3 finite numbers, found {text!r}")
    return values


def _limit(joint: ET.Element, key: str, where: str) -> float:
    limit = joint.find("limit")
    text = None if limit is None else limit.get(key)
    if text is None:
        raise BadInput(f"{where}: <limit {key}=...> missing (every revolute or prismatic joint needs "
                       "lower, upper and velocity)")
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise BadInput(f"{where}: <limit {key}={text!r}> is not a finite number")
    return value


def check_urdf(path: Path, data: bytes | None = None) -> str:
    """BadInput for a URDF camtool cannot use, before Pinocchio reads it (see module doc); returns the
    checked text, which is what Pinocchio parses (``buildModelFromXML``): the file is opened once."""
    text, root = _urdf_root(path, data)
    links = _link_names(path, root)
    names: set[str] = set()
    children: set[str] = set()
    movable = sum(_check_joint(path, joint, links, names, children) for joint in root.findall("joint"))
    if movable == 0:
        raise BadInput(f"{path}: the URDF has no movable joint (revolute or prismatic); "
                       "a robot needs at least one joint to move")
    roots = links - children
    if not roots:
        raise BadInput(f"{path}: the joints form a loop (every link is some joint's child); a robot has one base link")
    if len(roots) != 1:
        raise BadInput(f"{path}: the links form {len(roots)} separate trees ({', '.join(sorted(roots)[:3])}); "
                       "a robot has one base link")
    return text


def _urdf_root(path: Path, data: bytes | None):
    """The URDF's text and its parsed <robot> element (read once through safe_io unless ``data`` is given)."""
    try:
        from ..safe_io import read_input_bytes  # regular file under the cap: never a FIFO hang

        data = read_input_bytes(path, "robot") if data is None else data
        text = data.decode("utf-8")
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        raise BadInput(f"{path}: not a URDF: XML error ({exc})") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise BadInput(f"{path}: cannot read the URDF ({type(exc).__name__}: {exc})") from None
    if root.tag != "robot":
        raise BadInput(f"{path}: not a URDF: the root element is <{root.tag}>, expected <robot>")
    return text, root


def _link_names(path: Path, root) -> set[str]:
    """The names of the robot's links: each named, none twice."""
    links: set[str] = set()
    for link in root.findall("link"):
        name = link.get("name")
        if not name:
            raise BadInput(f"{path}: a <link> has no name")
        if name in links:
            raise BadInput(f"{path}: link {name!r} is defined twice")
        links.add(name)
    return links


def _check_joint(path: Path, joint, links: set[str], names: set[str], children: set[str]) -> int:
    """One <joint> checked (name, type, parent and child links, origin, and a movable one's axis and limits);
    its name and child link added to ``names`` and ``children``. Returns 1 for a movable joint, else 0."""
    name, kind = joint.get("name"), joint.get("type")
    if not name:
        raise BadInput(f"{path}: a <joint> has no name")
    where = f"{path}: joint {name!r}"
    if name in names:
        raise BadInput(f"{where} is defined twice; joint names must be unique")
    names.add(name)
    if kind not in _URDF_JOINT_TYPES:
        raise BadInput(f"{where}: type {kind!r} is not a URDF joint type ({', '.join(_URDF_JOINT_TYPES)})")
    if kind in ("continuous", "floating", "planar"):
        hint = " (write it as revolute with wide limits)" if kind == "continuous" else ""
        raise BadInput(f"{where}: {kind} joints are not supported; camtool plans revolute and prismatic "
                       f"joints with limits{hint}")
    for tag in ("parent", "child"):
        el = joint.find(tag)
        link = None if el is None else el.get("link")
        if link not in links:
            raise BadInput(f"{where}: <{tag} link={link!r}> is not a <link> of the robot")
    child = joint.find("child").get("link")
    if child in children:
        raise BadInput(f"{where}: link {child!r} is the child of two joints; a robot is a tree")
    children.add(child)
    origin = joint.find("origin")
    xyz = _floats(None if origin is None else origin.get("xyz"), f"{where}: <origin xyz>", "0 0 0")
    _floats(None if origin is None else origin.get("rpy"), f"{where}: <origin rpy>", "0 0 0")
    if math.hypot(*xyz) / MM_TO_M > MAX_LENGTH_MM:
        raise BadInput(f"{where}: <origin xyz> is {math.hypot(*xyz):g} m from its parent; that is not a "
                       f"robot (more than {MAX_LENGTH_MM * MM_TO_M:g} m): check the value and its unit (m)")
    if kind not in _MOVABLE:
        return 0
    _check_motion_limits(joint, kind, where)
    return 1


def _check_motion_limits(joint, kind: str, where: str) -> None:
    """A movable joint's axis (not zero) and limits (lower below upper, a positive speed, a real reach)."""
    axis = joint.find("axis")
    ax = _floats(None if axis is None else axis.get("xyz"), f"{where}: <axis xyz>", "1 0 0")
    if math.hypot(*ax) < 1e-9:
        raise BadInput(f"{where}: <axis xyz> is zero; give the joint's axis direction")
    lower, upper = _limit(joint, "lower", where), _limit(joint, "upper", where)
    velocity = _limit(joint, "velocity", where)
    if lower >= upper:
        raise BadInput(f"{where}: <limit lower={lower:g} upper={upper:g}>: lower must be below upper")
    if velocity <= 0:
        raise BadInput(f"{where}: <limit velocity={velocity:g}> must be > 0")
    if kind == "prismatic" and max(abs(lower), abs(upper)) / MM_TO_M > MAX_LENGTH_MM:
        raise BadInput(f"{where}: <limit lower upper> reach {max(abs(lower), abs(upper)):g} m; that is not a "
                       f"robot (more than {MAX_LENGTH_MM * MM_TO_M:g} m): check the value and its unit (m)")


def robot_from_urdf(path: Path, flange_link: str | None = None) -> Robot:
    """Load a serial robot from URDF; the flange is ``flange_link`` or the last link."""
    path = Path(path)
    text = check_urdf(path)
    try:
        model = pin.buildModelFromXML(text)  # the checked text: Pinocchio never reopens the file by name
    except Exception as exc:  # Pinocchio raises plain ValueError/RuntimeError
        raise BadInput(f"{path}: cannot read URDF ({(str(exc).splitlines() or [''])[0]})") from None
    if model.nq == 0:
        raise BadInput(f"{path}: the URDF has no movable joint; a robot needs at least one joint to move")
    names, prismatic = [], []
    for jid in range(1, model.njoints):
        j = model.joints[jid]
        if j.nq != 1:
            raise BadInput(f"{path}: joint {model.names[jid]!r} has {j.nq} DOF; only 1-DOF joints are supported")
        names.append(model.names[jid])
        prismatic.append(j.shortname().startswith("JointModelP"))
    prismatic = np.array(prismatic)
    scale = np.where(prismatic, 1.0 / MM_TO_M, 1.0)
    lower = np.array(model.lowerPositionLimit) * scale
    upper = np.array(model.upperPositionLimit) * scale
    vel = np.array(model.velocityLimit) * scale
    if not (np.isfinite(lower).all() and np.isfinite(upper).all()) or np.any(lower >= upper):
        raise BadInput(f"{path}: every joint needs finite <limit lower upper> with lower < upper")
    if not np.isfinite(vel).all() or np.any(vel <= 0):
        raise BadInput(f"{path}: every joint needs a finite <limit velocity> > 0")
    frame_name = flange_link or model.frames[len(model.frames) - 1].name
    if not model.existFrame(frame_name):
        raise BadInput(f"{path}: no link named {frame_name!r}")
    return Robot(
        name=path.stem, joint_names=tuple(names), prismatic=prismatic,
        limits=Limits(lower, upper, vel, vel * ACC_PER_VEL, vel * JERK_PER_VEL),
        model=model, flange_frame_id=model.getFrameId(frame_name),
        convention="urdf", source=str(path),
    )


def _origin(T_mm: np.ndarray) -> str:
    from scipy.spatial.transform import Rotation  # here, not at the top: scipy.spatial costs start-up time

    xyz = T_mm[:3, 3] * MM_TO_M
    with warnings.catch_warnings():  # gimbal lock still gives a valid rpy
        warnings.simplefilter("ignore")
        rpy = Rotation.from_matrix(T_mm[:3, :3]).as_euler("xyz")
    return (f'<origin xyz="{xyz[0]:.12g} {xyz[1]:.12g} {xyz[2]:.12g}" '
            f'rpy="{rpy[0]:.15g} {rpy[1]:.15g} {rpy[2]:.15g}"/>')


def urdf_from_robot(robot: Robot, flange_T_mm: np.ndarray | None = None) -> str:
    """URDF text of a DH robot: one link per joint, a fixed 'flange' link at the end."""
    if not robot.dh:
        raise BadInput(f"{robot.name}: only DH robots can be written as URDF")
    lines = ['<?xml version="1.0"?>', f'<robot name="{escape(robot.name)}">', '  <link name="base"/>']
    parent, pending = "base", np.eye(4)
    L = robot.limits
    for i, (row, name) in enumerate(zip(robot.dh, robot.joint_names)):
        if robot.convention == "modified":
            before = pending @ rot_x(row.alpha_rad) @ trans(x=row.a_mm) @ rot_z(row.theta_rad)
            pending = trans(z=row.d_mm)
        else:
            before = pending
            pending = rot_z(row.theta_rad) @ trans(z=row.d_mm) @ trans(x=row.a_mm) @ rot_x(row.alpha_rad)
        s = MM_TO_M if robot.prismatic[i] else 1.0
        child = f"link{i + 1}"
        lines += [f'  <link name="{child}"/>',
                  f'  <joint name="{escape(name)}" type="{"prismatic" if robot.prismatic[i] else "revolute"}">',
                  f'    <parent link="{parent}"/><child link="{child}"/>',
                  f'    {_origin(before)}', '    <axis xyz="0 0 1"/>',
                  f'    <limit lower="{L.lower[i] * s:.12g}" upper="{L.upper[i] * s:.12g}" '
                  f'velocity="{L.velocity[i] * s:.12g}" effort="1000"/>', '  </joint>']
        parent = child
    if flange_T_mm is None:  # the model's own flange frame (the controller's tool0 on the manufacturer robots)
        M = robot.model.frames[robot.flange_frame_id].placement
        flange = np.eye(4)
        flange[:3, :3], flange[:3, 3] = M.rotation, M.translation / MM_TO_M
    else:
        flange = pending @ flange_T_mm
    lines += ['  <link name="flange"/>', '  <joint name="flange_fixed" type="fixed">',
              f'    <parent link="{parent}"/><child link="flange"/>', f'    {_origin(flange)}',
              '  </joint>', '</robot>', '']
    return "\n".join(lines)
