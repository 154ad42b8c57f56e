"""URDF in and out: load a robot through Pinocchio's URDF parser, or write a
DH robot as URDF (metres, as URDF requires).

Position and velocity limits come from the URDF's ``<limit>``; URDF has no
acceleration or jerk limits, so those default to 4x and 20x the velocity
limit per second (documented in docs/robots.md) unless ``[robot]`` in the job
says otherwise.
"""
from __future__ import annotations

import warnings
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np
import pinocchio as pin
from scipy.spatial.transform import Rotation

from ..errors import BadInput
from .dh import MM_TO_M, rot_x, rot_z, trans
from .model import Limits, Robot

ACC_PER_VEL = 4.0
JERK_PER_VEL = 20.0


def robot_from_urdf(path: Path, flange_link: str | None = None) -> Robot:
    """Load a serial robot from URDF; the flange is ``flange_link`` or the last link."""
    try:
        model = pin.buildModelFromUrdf(str(path))
    except Exception as exc:  # Pinocchio raises plain ValueError/RuntimeError
        raise BadInput(f"{path}: cannot read URDF ({str(exc).splitlines()[0]})") from None
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
    if np.any(~np.isfinite(lower)) or np.any(lower >= upper):
        raise BadInput(f"{path}: every joint needs finite <limit lower upper> with lower < upper")
    if np.any(vel <= 0):
        raise BadInput(f"{path}: every joint needs <limit velocity> > 0")
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
    flange = pending @ (np.eye(4) if flange_T_mm is None else flange_T_mm)
    lines += ['  <link name="flange"/>', '  <joint name="flange_fixed" type="fixed">',
              f'    <parent link="{parent}"/><child link="flange"/>', f'    {_origin(flange)}',
              '  </joint>', '</robot>', '']
    return "\n".join(lines)
