"""Clamping weighted least-norm (CWLN) inverse kinematics and gradient-projection
self-motion, on a Pinocchio model with the tool centre point as a frame.

Task error, in the robot base frame, with orientation weighted against position::

    e = [ p* - p  (mm) ;  L * log(R* R^T)  (rad * mm/rad) ]

``L = orientation_weight_mm``: one radian of orientation error counts as L mm
of position error (the angular rows of J are scaled by L too), so position and
orientation converge together whatever the arm's size. With a free tool spin
the angular task keeps only the two components perpendicular to the target
tool z axis and the error is the tilt between the tool z axes (5-D task).

CWLN update (Huang et al. 2016, as used by Sun et al. 2023)::

    dq = (I - W) phi + W J^T (J W J^T + lambda^2 I)^-1 (e - J (I - W) phi)

- ``W = diag(w_i)``, ``w_i = s(d_i / b_i)`` with ``d_i`` the distance to the
  nearer limit, ``b_i`` the clamp buffer, ``s(x) = 3x^2 - 2x^3`` on [0, 1]: 1 in
  the interior, falling smoothly to 0 at the limit.
- Joint space is measured with ``q_i / s_i`` (``s_i = 1`` for revolute joints,
  ``track_scale_mm`` for prismatic ones): the least-norm step then spends track
  travel and joint rotation in proportion to their effect on the tool.
- ``phi_i = (b_i - d_i) * (+1 near the lower limit, -1 near the upper)`` inside
  the buffer and 0 elsewhere: it pushes a clamped joint back to the buffer's
  inner edge.
- The seed papers print ``+ J (I - W) phi`` inside the bracket; the minus sign
  used here compensates the clamp motion's effect on the task (J dq = e when
  lambda -> 0), which the plus sign would double. The papers' intent (the
  clamp task must not disturb the tool) needs the minus.

Gradient projection (the paper's step 3)::

    dq = J^+ e + (I - J^+ J) alpha (q_ref - q)

moves the arm in the null space of the task towards ``q_ref`` without moving
the tool.

Hand-written on purpose: no kept library offers CWLN or this null-space loop
over Pinocchio (Pinocchio gives FK and Jacobians, used here).
"""
from __future__ import annotations

import math

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..robots.dh import MM_TO_M
from ..robots.model import Robot


@dataclass(frozen=True)
class IkSettings:
    """CWLN settings: damping (mm), orientation weight (mm/rad), tolerances, buffers."""

    damping: float = 0.1
    orientation_weight_mm: float = 200.0
    position_tol_mm: float = 1e-4
    orientation_tol_rad: float = np.radians(1e-4)
    max_iterations: int = 100
    clamp_buffer_rad: float = np.radians(10.0)
    clamp_buffer_mm: float = 50.0
    track_scale_mm: float = 500.0
    posture_gain: float = 0.0
    max_step_rad: float = 0.5
    max_step_mm: float = 200.0


@dataclass
class IkResult:
    q: np.ndarray
    position_error_mm: float
    orientation_error_rad: float
    converged: bool
    iterations: int


class CwlnSolver:
    """CWLN IK for one robot and tool; targets are TCP poses in the robot base frame (mm)."""

    def __init__(self, robot: Robot, settings: IkSettings, free_spin: bool = False):
        self.robot = robot
        self.s = settings
        self.free_spin = free_spin
        model = robot.model.copy()
        flange = model.frames[robot.flange_frame_id]
        tool = pin.SE3(robot.tool_T_mm[:3, :3].copy(), robot.tool_T_mm[:3, 3] * MM_TO_M)
        self.fid = model.addFrame(pin.Frame("camtool_tcp", flange.parentJoint, 0,
                                            flange.placement * tool, pin.FrameType.OP_FRAME))
        self.model = model
        self.data = model.createData()
        self.n = robot.dof
        self.scale = np.where(robot.prismatic, MM_TO_M, 1.0)  # native -> Pinocchio units
        self.lo = robot.limits.lower.copy()
        self.hi = robot.limits.upper.copy()
        self.buffer = np.where(robot.prismatic, settings.clamp_buffer_mm, settings.clamp_buffer_rad)
        self.buffer = np.minimum(self.buffer, 0.25 * (self.hi - self.lo))
        self.max_step = np.where(robot.prismatic, settings.max_step_mm, settings.max_step_rad)
        self.L = settings.orientation_weight_mm
        # joint-space metric: 1 rad of a revolute joint costs as much as track_scale_mm of a
        # prismatic one, so least-norm steps use the track instead of stretching the arm
        self.jscale = np.where(robot.prismatic, settings.track_scale_mm, 1.0)
        self.eye = np.eye(self.n)
        self.unclamped = (np.ones(self.n), np.zeros(self.n))  # weights and clamp motion of clamp=False

    # -- kinematics -------------------------------------------------------
    def pose_and_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """TCP position (mm), rotation, and 6 x n Jacobian (mm and rad per native unit)."""
        qp = q * self.scale
        pin.computeJointJacobians(self.model, self.data, qp)
        pin.updateFramePlacement(self.model, self.data, self.fid)
        J = pin.getFrameJacobian(self.model, self.data, self.fid, pin.LOCAL_WORLD_ALIGNED)
        J = J * self.scale  # per native unit
        J[:3] *= 1.0 / MM_TO_M
        M = self.data.oMf[self.fid]
        return M.translation / MM_TO_M, M.rotation, J

    def tcp_pose(self, q: np.ndarray) -> np.ndarray:
        """4x4 TCP pose (mm) in the base frame."""
        pin.framesForwardKinematics(self.model, self.data, q * self.scale)
        M = self.data.oMf[self.fid]
        T = np.eye(4)
        T[:3, :3] = M.rotation
        T[:3, 3] = M.translation / MM_TO_M
        return T

    def task(self, q, target):
        """(weighted error e, weighted Jacobian, position error mm, orientation error rad)."""
        # per pose in Python loops (smoothing, lifts): the norms are sqrt(x . x) as numpy's norm makes
        # them, and the stacked rows filled in place; the same values, a third of the time
        p, R, J = self.pose_and_jacobian(q)
        dp = target[:3, 3] - p
        if self.free_spin:
            z, zt = R[:, 2], target[:3, 2]
            axis = np.cross(z, zt)
            s = math.sqrt(axis @ axis)
            ang = np.arctan2(s, z @ zt)
            w = axis * (ang / s) if s > 1e-15 else np.zeros(3)
            P = target[:3, :2].T  # 2 x 3: the target's tool x and y axes
            e = np.concatenate([dp, self.L * (P @ w)])
            Jt = np.empty((5, J.shape[1]))
            Jt[:3] = J[:3]
            Jt[3:] = self.L * (P @ J[3:])
        else:
            w = pin.log3(target[:3, :3] @ R.T)
            ang = math.sqrt(w @ w)
            e = np.concatenate([dp, self.L * w])
            Jt = J.copy()
            Jt[3:] *= self.L
        return e, Jt, math.sqrt(dp @ dp), float(ang)

    # -- CWLN -------------------------------------------------------------
    def clamp(self, q) -> tuple[np.ndarray, np.ndarray]:
        """Clamping weights w (n,) and clamp task phi (n,) at q."""
        d_lo, d_hi = q - self.lo, self.hi - q
        d = np.minimum(d_lo, d_hi)
        x = np.clip(d / self.buffer, 0.0, 1.0)
        w = x * x * (3.0 - 2.0 * x)
        phi = np.where(d < self.buffer, (self.buffer - d) * np.where(d_lo < d_hi, 1.0, -1.0), 0.0)
        return w, phi

    def converged(self, pos_err, ori_err) -> bool:
        return pos_err <= self.s.position_tol_mm and ori_err <= self.s.orientation_tol_rad

    def solve(self, target: np.ndarray, q0: np.ndarray, max_iterations: int | None = None,
              clamp: bool = True) -> IkResult:
        """CWLN from q0 to the TCP pose ``target`` (4x4, mm, base frame).

        ``clamp=False``: plain damped least-norm steps (every weight 1, no clamp task), the
        smallest joint change that puts the tool on the target. For a pose between or next
        to poses already solved (densified and smoothed poses): the clamp task would pull a
        joint that its neighbours hold inside the clamping buffer back to the buffer's edge,
        a spike in the joint path.
        """
        q = np.clip(np.array(q0, dtype=float), self.lo, self.hi)
        lam2 = self.s.damping ** 2
        iters = max_iterations or self.s.max_iterations
        for it in range(iters + 1):
            e, J, pe, oe = self.task(q, target)
            if self.converged(pe, oe) or it == iters:
                break
            if clamp:
                w, phi = self.clamp(q)
                clamp_motion = (1.0 - w) * phi
            else:
                w, clamp_motion = self.unclamped
            Js = J * self.jscale
            JW = Js * w
            A = JW @ Js.T
            A.flat[:: len(A) + 1] += lam2   # the diagonal
            dq = clamp_motion + self.jscale * (JW.T @ np.linalg.solve(A, e - J @ clamp_motion))
            # step limit: keeps the Newton step inside the linear region far from the target
            big = np.max(np.abs(dq) / self.max_step)
            if big > 1.0:
                dq /= big
            q = np.clip(q + dq, self.lo, self.hi)
        return IkResult(q, pe, oe, self.converged(pe, oe), it)

    # -- gradient projection ---------------------------------------------
    def self_motion(self, target: np.ndarray, q: np.ndarray, q_ref: np.ndarray,
                    iterations: int = 200, alpha: float = 0.3) -> IkResult:
        """Null-space motion from q towards q_ref while keeping the tool on ``target``."""
        q = np.array(q, dtype=float)
        lam2 = (1e-3 * self.s.damping) ** 2
        for _ in range(iterations):
            e, J, pe, oe = self.task(q, target)
            Js = J * self.jscale  # the same joint-space metric as CWLN
            A = Js @ Js.T
            A[np.diag_indices_from(A)] += lam2
            Jp = Js.T @ np.linalg.inv(A)
            dz = Jp @ e + (self.eye - Jp @ Js) @ (alpha * (q_ref - q) / self.jscale)
            dq = dz * self.jscale
            big = np.max(np.abs(dq) / (0.2 * self.max_step))
            if big > 1.0:
                dq /= big
            q_new = np.clip(q + dq, self.lo, self.hi)
            if np.max(np.abs(q_new - q)) < 1e-7:
                q = q_new
                break
            q = q_new
        # polish back onto the target with CWLN
        res = self.solve(target, q)
        return res
