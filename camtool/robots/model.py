"""``Robot``: a kinematic chain with limits, built on a Pinocchio model.

Units at this API: joint values are rad (revolute) or mm (prismatic); poses are
4x4 matrices in mm in the **robot base frame**; the Jacobian is 6 x n with rows
(vx, vy, vz, wx, wy, wz): linear rows in mm per joint unit, angular rows in rad
per joint unit, both expressed in the base frame at the frame's origin
(Pinocchio's LOCAL_WORLD_ALIGNED).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import threading

import numpy as np
import pinocchio as pin

from .conventions import ControllerConventions, identity
from .dh import MM_TO_M, DHRow

# Pinocchio's Data is a mutable work buffer: it belongs to whoever computes, not to the
# immutable Robot. Each thread keeps one per model (solvers such as CwlnSolver own theirs).
_DATA = threading.local()


@dataclass(frozen=True)
class Limits:
    """Per-joint limits in native units (rad or mm, per s, s^2, s^3)."""

    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray


@dataclass(frozen=True)
class Robot:
    """A serial robot: Pinocchio model, joint names and types, limits, base and tool.

    ``base_T_mm`` places the robot base in the world (cell) frame and
    ``tool_T_mm`` the tool centre point in the flange frame; both come from the
    job. ``fk`` gives the flange, ``fk_tcp`` the TCP, both in the base frame.
    ``conventions`` say how the robot's controller sees the joints and frames
    (``robots/conventions.py``); a robot without controller data gets identity
    conventions, declared ``source = "user"``.
    """

    name: str
    joint_names: tuple[str, ...]
    prismatic: np.ndarray
    limits: Limits
    model: pin.Model = field(repr=False)
    flange_frame_id: int
    convention: str = ""
    dh: tuple[DHRow, ...] = ()
    source: str = "builtin"
    base_T_mm: np.ndarray = field(default_factory=lambda: np.eye(4))
    tool_T_mm: np.ndarray = field(default_factory=lambda: np.eye(4))
    notes: str = ""
    conventions: ControllerConventions | None = field(default=None, repr=False)

    def __post_init__(self):
        if self.conventions is None:
            object.__setattr__(self, "conventions", identity(
                self.name, self.joint_names, self.prismatic, self.limits.lower, self.limits.upper, "user",
                "none given: the controller's axes are the robot's joints, unchanged"))

    @property
    def _q_scale(self) -> np.ndarray:
        return np.where(self.prismatic, MM_TO_M, 1.0)

    def _work_data(self) -> pin.Data:
        """Pinocchio's work buffers for this model, owned by the calling thread (``_DATA``), not by the Robot."""
        cache = _DATA.__dict__.setdefault("by_model", {})
        entry = cache.get(id(self.model))
        if entry is None or entry[0] is not self.model:
            entry = cache[id(self.model)] = (self.model, self.model.createData())
        return entry[1]

    @property
    def dof(self) -> int:
        return len(self.joint_names)

    @property
    def chain(self) -> "tuple[tuple[np.ndarray, ...], np.ndarray] | None":
        """The kinematic chain as constant 4 x 4 placements in mm: (placement before each joint,
        flange in the last joint), when every joint turns about / slides along its local z axis
        (DH robots); None otherwise. Program writers, readers and the simulator share it."""
        model = self.model
        kinds = [model.joints[i].shortname() for i in range(1, model.njoints)]
        if len(kinds) != self.dof or [k == "JointModelPZ" for k in kinds] != [bool(p) for p in self.prismatic] \
                or any(k not in ("JointModelRZ", "JointModelPZ") for k in kinds):
            return None
        frame = model.frames[self.flange_frame_id]
        if frame.parentJoint != model.njoints - 1:
            return None

        def mm(M):
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = M.rotation, np.asarray(M.translation) * 1000.0
            return T
        return tuple(mm(model.jointPlacements[i]) for i in range(1, model.njoints)), mm(frame.placement)

    def with_placement(self, base_T_mm: np.ndarray | None = None, tool_T_mm: np.ndarray | None = None) -> "Robot":
        """A copy with another base placement and/or tool."""
        return replace(
            self,
            base_T_mm=self.base_T_mm if base_T_mm is None else np.asarray(base_T_mm, float),
            tool_T_mm=self.tool_T_mm if tool_T_mm is None else np.asarray(tool_T_mm, float),
        )

    def _pin_q(self, q) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        if q.shape != (self.dof,):
            raise ValueError(f"{self.name} takes {self.dof} joint values, got shape {q.shape}")
        return q * self._q_scale

    def fk(self, q) -> np.ndarray:
        """Flange pose (4x4, mm) in the base frame at joint values q (rad / mm)."""
        data = self._work_data()
        pin.framesForwardKinematics(self.model, data, self._pin_q(q))
        M = data.oMf[self.flange_frame_id]
        T = np.eye(4)
        T[:3, :3] = M.rotation
        T[:3, 3] = M.translation / MM_TO_M
        return T

    def fk_tcp(self, q) -> np.ndarray:
        """Tool-centre-point pose (4x4, mm) in the base frame."""
        return self.fk(q) @ self.tool_T_mm

    def jacobian(self, q, tcp: bool = False) -> np.ndarray:
        """6 x n Jacobian of the flange (or TCP) in the base frame; see module doc for units."""
        qp = self._pin_q(q)
        J = pin.computeFrameJacobian(self.model, self._work_data(), qp, self.flange_frame_id, pin.LOCAL_WORLD_ALIGNED)
        J = np.array(J)
        # Pinocchio: linear rows in m per (rad | m). Convert to mm per (rad | mm).
        J[:3, :] /= MM_TO_M
        J *= self._q_scale[None, :]
        if tcp:
            r = self.fk(q)[:3, :3] @ self.tool_T_mm[:3, 3]
            J[:3, :] -= np.cross(r, J[3:, :].T).T
        return J

    def q_from_edge(self, values) -> np.ndarray:
        """Joint values from edge units (deg for revolute joints, mm for prismatic) to native (rad / mm)."""
        v = np.asarray(values, dtype=float)
        return np.where(self.prismatic, v, np.radians(v))

    def q_to_edge(self, q) -> np.ndarray:
        """Joint values from native units (rad / mm) to edge units (deg / mm); rows of q are configurations."""
        q = np.asarray(q, dtype=float)
        return np.where(self.prismatic, q, np.degrees(q))

    def within_limits(self, q, tol: float = 1e-9) -> bool:
        """True if q is inside the joint limits and inside the controller's axis limits (the coupled J3)."""
        q = np.asarray(q)
        return bool(np.all(q >= self.limits.lower - tol) and np.all(q <= self.limits.upper + tol)
                    and self.conventions.within_limits(q, tol))

    def describe(self) -> dict:
        """Name, dof, joint types and limits in degrees / mm (for ``camtool robots``)."""
        def edge(x, i):
            return float(x[i]) if self.prismatic[i] else float(np.degrees(x[i]))
        joints = []
        L = self.limits
        for i, n in enumerate(self.joint_names):
            unit = "mm" if self.prismatic[i] else "deg"
            joints.append({
                "name": n,
                "type": "prismatic" if self.prismatic[i] else "revolute",
                "unit": unit,
                "lower": edge(L.lower, i), "upper": edge(L.upper, i),
                "velocity_per_s": edge(L.velocity, i),
                "acceleration_per_s2": edge(L.acceleration, i),
                "jerk_per_s3": edge(L.jerk, i),
            })
        return {"name": self.name, "dof": self.dof, "convention": self.convention,
                "source": self.source, "joints": joints, "controller": self.conventions.describe()}
