"""Compiled CWLN kernel for DH robots (numba): the hot loop of the planner.

Why by hand: the planner solves IK for ~10^4-10^5 poses per job; one
Pinocchio call from Python costs ~10 us of interpreter overhead, which caps a
Python loop near 3k poses/s. This kernel evaluates the DH chain, the
geometric Jacobian and the CWLN update (identical maths to
``camtool.plan.cwln.CwlnSolver``, which stays the reference and serves robots
without a DH table) in compiled code. ``DhKernel`` checks itself against the
Pinocchio model when it is built and refuses to run if they disagree.
"""
from __future__ import annotations

import numpy as np
import numba as nb

from ..robots.model import Robot
from .cwln import IkSettings


@nb.njit(cache=True, fastmath=False)
def _mul44(A, B, out):
    for i in range(4):
        for j in range(4):
            s = 0.0
            for k in range(4):
                s += A[i, k] * B[k, j]
            out[i, j] = s


@nb.njit(cache=True)
def _dh(a, al, d, th, modified, out):
    ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(al), np.sin(al)
    out[:] = 0.0
    out[3, 3] = 1.0
    if modified:
        out[0, 0] = ct; out[0, 1] = -st; out[0, 3] = a
        out[1, 0] = st * ca; out[1, 1] = ct * ca; out[1, 2] = -sa; out[1, 3] = -sa * d
        out[2, 0] = st * sa; out[2, 1] = ct * sa; out[2, 2] = ca; out[2, 3] = ca * d
    else:
        out[0, 0] = ct; out[0, 1] = -st * ca; out[0, 2] = st * sa; out[0, 3] = a * ct
        out[1, 0] = st; out[1, 1] = ct * ca; out[1, 2] = -ct * sa; out[1, 3] = a * st
        out[2, 1] = sa; out[2, 2] = ca; out[2, 3] = d


@nb.njit(cache=True)
def fk_jacobian(q, dh, modified, tail, T, J):
    """TCP pose T (4x4, mm) and Jacobian J (6 x n; mm and rad per native unit) in the base frame."""
    n = q.shape[0]
    A = np.empty((4, 4)); tmp = np.empty((4, 4))
    axes = np.empty((n, 3)); origins = np.empty((n, 3))
    T[:] = 0.0
    for i in range(4):
        T[i, i] = 1.0
    for i in range(n):
        a, al, d, th, pr = dh[i, 0], dh[i, 1], dh[i, 2], dh[i, 3], dh[i, 4]
        if pr > 0.5:
            d += q[i]
        else:
            th += q[i]
        if not modified:
            for r in range(3):
                axes[i, r] = T[r, 2]; origins[i, r] = T[r, 3]
        _dh(a, al, d, th, modified, A)
        _mul44(T, A, tmp)
        T[:] = tmp
        if modified:
            for r in range(3):
                axes[i, r] = T[r, 2]; origins[i, r] = T[r, 3]
    _mul44(T, tail, tmp)
    T[:] = tmp
    for i in range(n):
        z0, z1, z2 = axes[i, 0], axes[i, 1], axes[i, 2]
        if dh[i, 4] > 0.5:
            J[0, i] = z0; J[1, i] = z1; J[2, i] = z2
            J[3, i] = 0.0; J[4, i] = 0.0; J[5, i] = 0.0
        else:
            r0 = T[0, 3] - origins[i, 0]; r1 = T[1, 3] - origins[i, 1]; r2 = T[2, 3] - origins[i, 2]
            J[0, i] = z1 * r2 - z2 * r1; J[1, i] = z2 * r0 - z0 * r2; J[2, i] = z0 * r1 - z1 * r0
            J[3, i] = z0; J[4, i] = z1; J[5, i] = z2


@nb.njit(cache=True)
def tcp_jacobians(qs, dh, modified, tail, out):
    """``fk_jacobian``'s Jacobian (6 x n) at every row of ``qs`` (m, n) into ``out`` (m, 6, n)."""
    T = np.empty((4, 4))
    J = np.empty((6, qs.shape[1]))
    for k in range(qs.shape[0]):
        fk_jacobian(qs[k], dh, modified, tail, T, J)
        out[k] = J
    return out


@nb.njit(cache=True)
def _log3(R, w):
    """Rotation vector (rad) of a rotation matrix; robust near 0 and pi."""
    v0 = R[2, 1] - R[1, 2]; v1 = R[0, 2] - R[2, 0]; v2 = R[1, 0] - R[0, 1]
    s = 0.5 * np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    c = 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)
    ang = np.arctan2(s, c)
    if s > 1e-7:
        f = ang / (2.0 * s)
        w[0] = v0 * f; w[1] = v1 * f; w[2] = v2 * f
    elif c > 0.0:
        w[0] = 0.5 * v0; w[1] = 0.5 * v1; w[2] = 0.5 * v2
    else:  # near pi: axis from the largest diagonal of (R + I) / 2
        k = 0
        if R[1, 1] > R[k, k]:
            k = 1
        if R[2, 2] > R[k, k]:
            k = 2
        ax = np.empty(3)
        for r in range(3):
            ax[r] = 0.25 * (R[r, k] + R[k, r])  # (R + I) / 2 = a a^T: off-diagonals are a_r a_k
        ax[k] = 0.5 * (R[k, k] + 1.0)
        nrm = np.sqrt(ax[0] ** 2 + ax[1] ** 2 + ax[2] ** 2)
        for r in range(3):
            w[r] = ax[r] / nrm * ang
    return ang


@nb.njit(cache=True)
def _task(q, target, dh, modified, tail, L, free_spin, T, J, e, Jt):
    """Weighted error e and task Jacobian Jt (first m rows used); returns (m, pos_err, ori_err)."""
    fk_jacobian(q, dh, modified, tail, T, J)
    n = q.shape[0]
    dp0 = target[0, 3] - T[0, 3]; dp1 = target[1, 3] - T[1, 3]; dp2 = target[2, 3] - T[2, 3]
    pe = np.sqrt(dp0 * dp0 + dp1 * dp1 + dp2 * dp2)
    e[0] = dp0; e[1] = dp1; e[2] = dp2
    for i in range(n):
        Jt[0, i] = J[0, i]; Jt[1, i] = J[1, i]; Jt[2, i] = J[2, i]
    w = np.empty(3)
    if free_spin:
        z0, z1, z2 = T[0, 2], T[1, 2], T[2, 2]
        t0, t1, t2 = target[0, 2], target[1, 2], target[2, 2]
        a0 = z1 * t2 - z2 * t1; a1 = z2 * t0 - z0 * t2; a2 = z0 * t1 - z1 * t0
        s = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
        oe = np.arctan2(s, z0 * t0 + z1 * t1 + z2 * t2)
        f = oe / s if s > 1e-15 else 0.0
        w[0] = a0 * f; w[1] = a1 * f; w[2] = a2 * f
        for r in range(2):  # components along the target's tool x and y
            e[3 + r] = L * (target[0, r] * w[0] + target[1, r] * w[1] + target[2, r] * w[2])
            for i in range(n):
                Jt[3 + r, i] = L * (target[0, r] * J[3, i] + target[1, r] * J[4, i] + target[2, r] * J[5, i])
        return 5, pe, oe
    Rerr = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            Rerr[i, j] = target[i, 0] * T[j, 0] + target[i, 1] * T[j, 1] + target[i, 2] * T[j, 2]
    oe = _log3(Rerr, w)
    for r in range(3):
        e[3 + r] = L * w[r]
        for i in range(n):
            Jt[3 + r, i] = L * J[3 + r, i]
    return 6, pe, oe


@nb.njit(cache=True)
def cwln_solve(target, q, dh, modified, tail, lo, hi, buf, jscale, max_step, L, lam2,
               ptol, otol, max_it, free_spin):
    """CWLN iterations on q (in place); returns (pos_err_mm, ori_err_rad, converged, iterations)."""
    n = q.shape[0]
    T = np.empty((4, 4)); J = np.empty((6, n)); e = np.empty(6); Jt = np.empty((6, n))
    for i in range(n):
        q[i] = min(max(q[i], lo[i]), hi[i])
    pe = 0.0; oe = 0.0
    it = 0
    cm = np.empty(n); wv = np.empty(n); dq = np.empty(n)  # work arrays, reused every iteration
    while True:
        m, pe, oe = _task(q, target, dh, modified, tail, L, free_spin, T, J, e, Jt)
        if (pe <= ptol and oe <= otol) or it >= max_it:
            break
        for i in range(n):
            dlo = q[i] - lo[i]; dhi = hi[i] - q[i]
            dd = min(dlo, dhi)
            x = min(max(dd / buf[i], 0.0), 1.0)
            wv[i] = x * x * (3.0 - 2.0 * x)
            phi = 0.0
            if dd < buf[i]:
                phi = (buf[i] - dd) * (1.0 if dlo < dhi else -1.0)
            cm[i] = (1.0 - wv[i]) * phi
        A = np.zeros((m, m)); rhs = np.empty(m)
        for r in range(m):
            s = e[r]
            for i in range(n):
                s -= Jt[r, i] * cm[i]
            rhs[r] = s
            for c in range(r, m):
                s2 = 0.0
                for i in range(n):
                    s2 += Jt[r, i] * Jt[c, i] * jscale[i] * jscale[i] * wv[i]
                A[r, c] = s2; A[c, r] = s2
            A[r, r] += lam2
        y = np.linalg.solve(A, rhs)
        big = 0.0
        for i in range(n):
            s = 0.0
            for r in range(m):
                s += Jt[r, i] * y[r]
            dq[i] = cm[i] + jscale[i] * jscale[i] * wv[i] * s
            big = max(big, abs(dq[i]) / max_step[i])
        scale = 1.0 / big if big > 1.0 else 1.0
        for i in range(n):
            q[i] = min(max(q[i] + dq[i] * scale, lo[i]), hi[i])
        it += 1
    return pe, oe, (pe <= ptol and oe <= otol), it


@nb.njit(cache=True)
def _projected_step(q, target, q_ref, dh, modified, tail, L, free_spin, jscale, lam2, gain, track_task):
    """Scaled joint step z_task + (I - J+ J) gain (q_ref - q) / s, with J+ = Js^T (Js Js^T + lam2)^-1
    (Js = J S); z_task = J+ e when ``track_task``, else 0 (pure null-space motion). Returns dq."""
    n = q.shape[0]
    T = np.empty((4, 4)); J = np.empty((6, n)); e = np.empty(6); Jt = np.empty((6, n))
    m, pe, oe = _task(q, target, dh, modified, tail, L, free_spin, T, J, e, Jt)
    Js = np.empty((m, n))
    for r in range(m):
        for i in range(n):
            Js[r, i] = Jt[r, i] * jscale[i]
    A = Js @ Js.T
    for r in range(m):
        A[r, r] += lam2
    z = np.empty(n)
    for i in range(n):
        z[i] = gain * (q_ref[i] - q[i]) / jscale[i]
    rhs = -(Js @ z)
    if track_task:
        rhs += e[:m]
    dz = z + Js.T @ np.linalg.solve(A, rhs)
    return dz * jscale


@nb.njit(cache=True)
def null_step(q, target, dh, modified, tail, L, free_spin, jscale, lam2, gain, q_ref):
    """One null-space step of q (in place) towards q_ref (gain in 0..1), in the scaled joint metric."""
    q += _projected_step(q, target, q_ref, dh, modified, tail, L, free_spin, jscale, lam2, gain, False)


@nb.njit(cache=True)
def gp_self_motion(q, target, q_ref, dh, modified, tail, lo, hi, jscale, max_step, L, lam2, free_spin,
                   iterations, alpha):
    """Gradient projection: dq = J+ e + (I - J+ J) alpha (q_ref - q), in the scaled metric (in place)."""
    n = q.shape[0]
    for _ in range(iterations):
        dq = _projected_step(q, target, q_ref, dh, modified, tail, L, free_spin, jscale, lam2, alpha, True)
        big = 0.0
        for i in range(n):
            big = max(big, abs(dq[i]) / (0.2 * max_step[i]))
        sc = 1.0 / big if big > 1.0 else 1.0
        moved = 0.0
        for i in range(n):
            qi = min(max(q[i] + dq[i] * sc, lo[i]), hi[i])
            moved = max(moved, abs(qi - q[i]))
            q[i] = qi
        if moved < 1e-7:
            break


@nb.njit(cache=True)
def cwln_run(targets, q_start, dh, modified, tail, lo, hi, buf, jscale, max_step, L, lam2,
             ptol, otol, max_it, free_spin, thr, out_q, out_pe, out_oe, posture_gain, q_ref):
    """Warm-started CWLN over targets in order from q_start. Stops at the first pose that
    does not converge or jumps (returns its index, with its result stored); else len(targets)."""
    n = q_start.shape[0]
    q = q_start.copy()
    for k in range(targets.shape[0]):
        prev = q.copy()
        if posture_gain > 0.0:
            null_step(q, targets[k], dh, modified, tail, L, free_spin, jscale, lam2, posture_gain, q_ref)
        pe, oe, conv, it = cwln_solve(targets[k], q, dh, modified, tail, lo, hi, buf, jscale,
                                      max_step, L, lam2, ptol, otol, max_it, free_spin)
        out_q[k] = q; out_pe[k] = pe; out_oe[k] = oe
        if not conv:
            return k
        for i in range(n):
            if abs(q[i] - prev[i]) > thr[i]:
                return k
    return targets.shape[0]


class DhKernel:
    """The compiled CWLN for one DH robot with its tool; None-safe construction via ``build``."""

    def __init__(self, robot: Robot, s: IkSettings, free_spin: bool, jump_thr: np.ndarray):
        self.dh = np.array([[r.a_mm, r.alpha_rad, r.d_mm, r.theta_rad, float(r.prismatic)] for r in robot.dh])
        self.modified = robot.convention == "modified"
        zero = np.zeros(robot.dof)
        T0, J0 = np.empty((4, 4)), np.empty((6, robot.dof))
        fk_jacobian(zero, self.dh, self.modified, np.eye(4), T0, J0)
        flange = np.linalg.solve(T0, robot.fk(zero))  # the constant flange offset after the DH chain
        self.tail = flange @ robot.tool_T_mm
        self.lo, self.hi = robot.limits.lower.copy(), robot.limits.upper.copy()
        self.buf = np.minimum(np.where(robot.prismatic, s.clamp_buffer_mm, s.clamp_buffer_rad), 0.25 * (self.hi - self.lo))
        self.jscale = np.where(robot.prismatic, s.track_scale_mm, 1.0)
        self.max_step = np.where(robot.prismatic, s.max_step_mm, s.max_step_rad)
        self.s, self.free_spin, self.thr = s, free_spin, jump_thr
        self.posture_gain = s.posture_gain
        self.q_ref = 0.5 * (self.lo + self.hi)
        self._check(robot)

    @staticmethod
    def build(robot, s, free_spin, jump_thr):
        """A kernel for a DH robot, or None for robots without a DH table (URDF)."""
        return DhKernel(robot, s, free_spin, jump_thr) if robot.dh else None

    def _check(self, robot: Robot) -> None:
        rng = np.random.default_rng(0)
        T, J = np.empty((4, 4)), np.empty((6, robot.dof))
        for _ in range(5):
            q = self.lo + (self.hi - self.lo) * rng.random(robot.dof)
            fk_jacobian(q, self.dh, self.modified, self.tail, T, J)
            if not (np.allclose(T, robot.fk_tcp(q), atol=1e-6) and np.allclose(J, robot.jacobian(q, tcp=True), atol=1e-6)):
                raise RuntimeError(f"compiled kinematics of {robot.name} disagree with Pinocchio")

    def jacobians(self, qs: np.ndarray) -> np.ndarray:
        """(m, 6, n) TCP Jacobians in the base frame (``Robot.jacobian(q, tcp=True)``) of the rows of ``qs``."""
        qs = np.ascontiguousarray(qs, float).reshape(-1, len(self.lo))
        return tcp_jacobians(qs, self.dh, self.modified, self.tail, np.empty((len(qs), 6, qs.shape[1])))

    def run(self, targets: np.ndarray, q_start: np.ndarray):
        """CWLN over targets from q_start; returns (stop index, q, pos_err, ori_err)."""
        m, n = len(targets), len(q_start)
        out_q, out_pe, out_oe = np.empty((m, n)), np.empty(m), np.empty(m)
        s = self.s
        stop = cwln_run(np.ascontiguousarray(targets), np.asarray(q_start, float), self.dh, self.modified,
                        self.tail, self.lo, self.hi, self.buf, self.jscale, self.max_step,
                        s.orientation_weight_mm, s.damping ** 2, s.position_tol_mm, s.orientation_tol_rad,
                        s.max_iterations, self.free_spin, self.thr, out_q, out_pe, out_oe,
                        self.posture_gain, self.q_ref)
        return stop, out_q, out_pe, out_oe

    def solve(self, target: np.ndarray, q0: np.ndarray, max_iterations: int | None = None):
        """One CWLN solve; returns (q, pos_err_mm, ori_err_rad, converged, iterations)."""
        q = np.array(q0, dtype=float)
        s = self.s
        pe, oe, conv, it = cwln_solve(np.ascontiguousarray(target), q, self.dh, self.modified, self.tail,
                                      self.lo, self.hi, self.buf, self.jscale, self.max_step,
                                      s.orientation_weight_mm, s.damping ** 2, s.position_tol_mm,
                                      s.orientation_tol_rad, max_iterations or s.max_iterations, self.free_spin)
        return q, pe, oe, conv, it

    def self_motion(self, target: np.ndarray, q: np.ndarray, q_ref: np.ndarray, iterations: int = 200,
                    alpha: float = 0.3):
        """Gradient-projection self-motion towards q_ref, then a CWLN polish (as CwlnSolver)."""
        q = np.array(q, dtype=float)
        s = self.s
        gp_self_motion(q, np.ascontiguousarray(target), np.asarray(q_ref, float), self.dh, self.modified,
                       self.tail, self.lo, self.hi, self.jscale, self.max_step, s.orientation_weight_mm,
                       (1e-3 * s.damping) ** 2, self.free_spin, iterations, alpha)
        return self.solve(target, q)


_LOADED = False   # whether this process has loaded the compiled kernels (``load_compiled``)


def load_compiled() -> None:
    """Load the compiled kernels into this process once (``warm_up``; about 0.25 s of numba's own set-up
    the first time, nothing after): what a kernel's timing leaves out, as a benchmark's warm-up does."""
    global _LOADED
    if not _LOADED:
        warm_up()
        _LOADED = True


def warm_up() -> None:
    """Compile (and cache) the kernels (CWLN, the S-curve test) on a tiny problem; used by the set-up script."""
    from ..robots import get_robot

    robot = get_robot("seed8")
    k = DhKernel(robot, IkSettings(), False, np.full(robot.dof, 1.0))
    T = robot.fk_tcp(np.full(robot.dof, 0.3))
    k.run(T[None], np.full(robot.dof, 0.25))
    k.self_motion(T, np.full(robot.dof, 0.3), np.zeros(robot.dof), iterations=2)
    k.jacobians(np.full((2, robot.dof), 0.3))
    from ..timing.pathlaw import PathSpline, _Budget  # the time law's compiled S-curve test too

    budget = _Budget(PathSpline(np.array([0.0, 1.0]), np.zeros((2, robot.dof)) + [[0.0], [0.1]]), robot.limits)
    budget.fits(0.0, 1.0, [1.0], [1.0], [0.0])
    budget.search(0.0, 1.0, 0.5, True, np.array([1.0]), np.array([1.0]), 1)
