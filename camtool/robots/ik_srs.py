"""Arm-angle IK of 7R spherical-revolute-spherical (SRS) arms (Shimizu et al. 2008).

Used by seed 002 for the Yaskawa SIA-20; it also fits the 7 revolute joints of
``seed8`` at a fixed track position. The geometry comes from the robot's own
joint placements (``ik_common.Chain``) and is checked: axes 1-3 of the arm
must meet in the shoulder S, axes 5-7 in the wrist W, joint 4 is the elbow.

Given a flange pose and an arm angle Theta (rad):

1. ``W = T @ w_flange``; the elbow angle q4 follows from ``|SW|`` alone: two
   roots, gamma1 (as in seed 002's eq. 10).
2. Reference plane: the shoulder solution with q3 = 0 that puts W in place
   (the ``+`` root, so the reference is one well-defined plane).
3. ``R_3 = Rot(SW, Theta) @ R_3_ref``: the arm plane turned by Theta about
   the S-W line (W does not move).
4. Shoulder q1..q3 from R_3: two branches, gamma2; wrist q5..q7 from
   ``R_4^T R_7``: two branches, gamma3.

So every (pose, Theta) has 2 x 2 x 2 = 8 solution families (gamma1, gamma2,
gamma3). Each gamma is the side (+1 / -1) of the middle joint's root from that
step's singular value: elbow straight for joint 4, axes aligned for the
shoulder and wrist groups. For the SIA-20 (gamma1, gamma2, gamma3) are the
signs of joints 4, 2 and 6; families are numbered 1-8 in the order of the
paper's Table 3 (``FAMILIES``). A straight elbow (S, E, W in line) leaves Theta undefined and
raises PlanInfeasible; so does a pose out of reach.
"""
from __future__ import annotations

from dataclasses import dataclass
from itertools import product

import numpy as np

from ..errors import BadInput, PlanInfeasible
from .ik_common import (Chain, axis_intersection, limit_equivalents, rot_axis, rot_axis_batch, rz, rz_batch,
                        sinusoid_roots, spherical_group, spherical_group_batch, wrap_pi)
from .model import Robot

GEOMETRY_TOL_MM = 1e-6
STRAIGHT_ELBOW_MARGIN = 1e-8  # 1 - |cos| of the elbow sinusoid below this: elbow straight (~1.4e-4 rad)
FAMILIES = tuple(product((1, -1), repeat=3))  # (gamma1 elbow, gamma2 shoulder, gamma3 wrist), Table 3 order


@dataclass(frozen=True)
class SrsSolution:
    """One arm-angle solution: the 7 arm joints (rad), family, limits flag."""

    q: np.ndarray
    family: tuple[int, int, int]  # (gamma1 elbow, gamma2 shoulder, gamma3 wrist)
    within_limits: bool


class SrsIK:
    """Arm-angle IK for one SRS robot; ``fixed`` gives values (mm / rad) of joints before the 7R arm."""

    def __init__(self, robot: Robot, fixed=()):
        self.robot = robot
        ch = Chain(robot)
        n_pre = robot.dof - 7
        if n_pre < 0:
            raise BadInput(f"robot {robot.name}: SRS arm-angle IK needs 7 revolute joints, it has {robot.dof}")
        if robot.prismatic[n_pre:].any():
            raise BadInput(f"robot {robot.name}: the last 7 joints must be revolute for SRS arm-angle IK")
        fixed = np.asarray(fixed, float).reshape(-1)
        if len(fixed) != n_pre:
            raise BadInput(f"robot {robot.name}: SRS IK needs {n_pre} fixed value(s) for the joints before "
                           f"the 7R arm, got {len(fixed)}")
        self.ch, self.n_pre, self.fixed = ch, n_pre, fixed
        pre = np.eye(4)
        for i in range(n_pre):
            pre = pre @ ch.P[i] @ ch.motion(i, fixed[i])
        self.pre = pre                                 # base -> frame before the arm's first joint
        P = ch.P[n_pre:]
        self.P = P
        q0 = np.concatenate([fixed, np.zeros(7)])
        pts, dirs = ch.axes(q0)
        pts, dirs = pts[n_pre:], dirs[n_pre:]
        S, miss_s = axis_intersection(pts[:3], dirs[:3])
        W0, miss_w = axis_intersection(pts[4:], dirs[4:])
        if miss_s > GEOMETRY_TOL_MM or miss_w > GEOMETRY_TOL_MM:
            raise BadInput(f"robot {robot.name}: not an SRS arm (shoulder axes miss by {miss_s:.3g} mm, "
                           f"wrist axes by {miss_w:.3g} mm); arm-angle IK does not apply")
        F = ch.frames(q0)[n_pre:]
        inv = np.linalg.inv

        def local(Tf, p):
            return (inv(Tf) @ np.append(p, 1.0))[:3]
        self.S = S
        self.w_flange = local(F[-1], W0)
        self.w4 = local(F[3], W0)                      # W in link-4 coordinates
        self.s4 = local(F[2] @ P[3], S)                # S in joint-4 pre-frame (fixed in link 3)
        self.s2 = local(F[1], S)                       # S in link-2 coordinates
        self.R0 = (pre @ P[0])[:3, :3]                 # joint-1 pre-frame rotation in base
        L = robot.limits
        self.lower, self.upper = L.lower[n_pre:], L.upper[n_pre:]

    def elbow(self, d2: float) -> tuple[float, float]:
        """The two elbow roots (gamma1 = +1, -1) for squared shoulder-wrist distance d2 (mm^2).

        The roots lie either side of the straight-elbow angle ``phi + pi``;
        gamma1 = +1 is the one above it (``phi - acos``, wrapped).
        """
        s, w = self.s4, self.w4
        r = sinusoid_roots(s[0] * w[0] + s[1] * w[1], s[1] * w[0] - s[0] * w[1], s[2] * w[2],
                           0.5 * (s @ s + w @ w - d2))
        if r is None or r[0] is None:
            raise PlanInfeasible(f"{self.robot.name}: pose out of reach (shoulder-wrist distance "
                                 f"{np.sqrt(d2):.1f} mm)")
        if r[2] < STRAIGHT_ELBOW_MARGIN:
            raise PlanInfeasible(f"{self.robot.name}: elbow straight (shoulder, elbow and wrist in line); "
                                 "the arm angle is undefined at this pose")
        return r[1], r[0]

    def prepare(self, T_flange_mm: np.ndarray) -> dict:
        """The arm-angle-free part of ``solve`` for one pose (reuse it over many arm angles)."""
        T = np.asarray(T_flange_mm, float)
        P = self.P
        W = T[:3, :3] @ self.w_flange + T[:3, 3]
        d = W - self.S
        nd = float(np.linalg.norm(d))
        ref = {}
        for g1, q4 in zip((1, -1), self.elbow(nd * nd)):
            # reference plane q3 = 0: solve R0 Rz(q1) A Rz(q2) w2 = d, w2 = W - S in link-2 coordinates
            w2 = P[2][:3, :3] @ (P[3][:3, :3] @ (rz(q4) @ self.w4) + P[3][:3, 3]) + P[2][:3, 3] - self.s2
            sol = _two_axis(self.R0.T @ d, P[1][:3, :3], w2)
            if sol is None:
                raise PlanInfeasible(f"{self.robot.name}: no reference plane for this pose")
            R3ref = self.R0 @ rz(sol[0]) @ P[1][:3, :3] @ rz(sol[1]) @ P[2][:3, :3]
            ref[g1] = (float(q4), R3ref)
        return {"u": d / nd, "R7": T[:3, :3] @ self.ch.flange[:3, :3].T, "ref": ref}

    def prepare_batch(self, T_flange_mm: np.ndarray) -> tuple[dict, np.ndarray]:
        """``prepare`` for K flange poses at once: (the ``stack`` of the poses it can prepare, (K,)
        which those are). A pose ``prepare`` refuses (out of reach, straight elbow, no reference
        plane) is left out."""
        T = np.asarray(T_flange_mm, float).reshape(-1, 4, 4)
        P = self.P
        W = T[:, :3, :3] @ self.w_flange + T[:, :3, 3]
        d = W - self.S
        nd = np.linalg.norm(d, axis=1)
        s_, w_ = self.s4, self.w4
        kc, ks, k0 = s_[0] * w_[0] + s_[1] * w_[1], s_[1] * w_[0] - s_[0] * w_[1], s_[2] * w_[2]
        r = np.hypot(kc, ks)
        ok = np.full(len(T), r >= 1e-12)
        with np.errstate(invalid="ignore", divide="ignore"):
            c = (0.5 * (s_ @ s_ + w_ @ w_ - nd * nd) - k0) / r
        ok &= (1.0 - np.abs(c)) >= STRAIGHT_ELBOW_MARGIN        # a root, and the elbow not straight
        a = np.arccos(np.clip(c, -1.0, 1.0))
        phi = np.arctan2(ks, kc)
        q4s = {1: phi - a, -1: phi + a}                          # ``elbow``: (x_minus, x_plus)
        u_ref = d @ self.R0                                      # R0^T d, per pose
        A = P[1][:3, :3]
        R3ref = {}
        for g1, q4 in q4s.items():
            w2 = (np.einsum("kij,j->ki", rz_batch(q4), self.w4) @ P[3][:3, :3].T + P[3][:3, 3]) @ P[2][:3, :3].T \
                + P[2][:3, 3] - self.s2
            # _two_axis: Rz(x1) A Rz(x2) w2 = u_ref, the + root
            kc2 = A[2, 0] * w2[:, 0] + A[2, 1] * w2[:, 1]
            ks2 = A[2, 1] * w2[:, 0] - A[2, 0] * w2[:, 1]
            r2 = np.hypot(kc2, ks2)
            with np.errstate(invalid="ignore", divide="ignore"):
                c2 = (u_ref[:, 2] - A[2, 2] * w2[:, 2]) / r2
            ok &= (r2 >= 1e-12) & ((1.0 - np.abs(c2)) >= -1e-7)
            x2 = np.arctan2(ks2, kc2) + np.arccos(np.clip(np.nan_to_num(c2), -1.0, 1.0))
            v = np.einsum("kij,kj->ki", A @ rz_batch(x2), w2)
            x1 = np.arctan2(u_ref[:, 1], u_ref[:, 0]) - np.arctan2(v[:, 1], v[:, 0])
            R3ref[g1] = self.R0 @ rz_batch(x1) @ A @ rz_batch(x2) @ P[2][:3, :3]
        k = np.flatnonzero(ok)
        stacked = {"u": d[k] / nd[k, None], "R7": T[k, :3, :3] @ self.ch.flange[:3, :3].T,
                   "q4": {g: q4s[g][k] for g in (1, -1)}, "R3ref": {g: R3ref[g][k] for g in (1, -1)}}
        return stacked, ok

    def solve_prepared(self, prep: dict, arm_angle_rad: float, families=FAMILIES) -> list[SrsSolution]:
        """``solve`` from a ``prepare``d pose, for the given families (gamma1, gamma2, gamma3) only."""
        P = self.P
        out = []
        for g1 in (1, -1):                                   # elbow
            if not any(f[0] == g1 for f in families):
                continue
            q4, R3ref = prep["ref"][g1]
            R3 = rot_axis(prep["u"], arm_angle_rad) @ R3ref
            for q1, q2, q3, g2 in spherical_group(self.R0.T @ R3, P[1][:3, :3], P[2][:3, :3]):  # shoulder
                if not any(f[:2] == (g1, g2) for f in families):
                    continue
                R4 = R3 @ P[3][:3, :3] @ rz(q4)
                Mw = (R4 @ P[4][:3, :3]).T @ prep["R7"]
                for q5, q6, q7, g3 in spherical_group(Mw, P[5][:3, :3], P[6][:3, :3]):  # wrist
                    if (g1, g2, g3) not in families:
                        continue
                    q = wrap_pi(np.array([q1, q2, q3, q4, q5, q6, q7]))
                    ok = limit_equivalents(q, self.lower, self.upper, np.ones(7, bool)) is not None
                    out.append(SrsSolution(q, (g1, g2, g3), ok))
        return sorted(out, key=lambda s: FAMILIES.index(s.family))

    def stack(self, preps: list[dict]) -> dict:
        """Stack ``prepare``d poses for ``family_q_batch``."""
        return {"u": np.array([p["u"] for p in preps]), "R7": np.array([p["R7"] for p in preps]),
                "q4": {g: np.array([p["ref"][g][0] for p in preps]) for g in (1, -1)},
                "R3ref": {g: np.array([p["ref"][g][1] for p in preps]) for g in (1, -1)}}

    def family_q_batch(self, stacked: dict, arm_angles_rad: np.ndarray, family) -> np.ndarray:
        """(K, 7) arm joints of one family for K stacked poses, one arm angle each (NaN: no root)."""
        g1, g2, g3 = family
        P = self.P
        R3 = rot_axis_batch(stacked["u"], np.asarray(arm_angles_rad, float)) @ stacked["R3ref"][g1]
        sh = spherical_group_batch(self.R0.T @ R3, P[1][:3, :3], P[2][:3, :3], g2)
        q4 = stacked["q4"][g1]
        R4 = R3 @ P[3][:3, :3] @ rz_batch(q4)
        Mw = np.transpose(R4 @ P[4][:3, :3], (0, 2, 1)) @ stacked["R7"]
        wr = spherical_group_batch(Mw, P[5][:3, :3], P[6][:3, :3], g3)
        return np.column_stack([sh, wrap_pi(q4), wr])

    def solve(self, T_flange_mm: np.ndarray, arm_angle_rad: float) -> list[SrsSolution]:
        """The 8 family solutions (7 arm joints, wrapped to (-pi, pi]) of a flange pose at an arm angle."""
        return self.solve_prepared(self.prepare(T_flange_mm), arm_angle_rad)

    def full_q(self, q_arm: np.ndarray) -> np.ndarray:
        """Arm joints plus the fixed joints in front: a q for ``robot.fk``."""
        return np.concatenate([self.fixed, q_arm])

    def arm_angle(self, q_arm: np.ndarray) -> float:
        """The arm angle (rad) of a configuration: inverse of ``solve``, for seeding from a q."""
        T = self.ch.fk(self.full_q(q_arm))
        P = self.P
        W = T[:3, :3] @ self.w_flange + T[:3, 3]
        d = W - self.S
        u = d / np.linalg.norm(d)
        q4 = q_arm[3]
        w2 = P[2][:3, :3] @ (P[3][:3, :3] @ (rz(q4) @ self.w4) + P[3][:3, 3]) + P[2][:3, 3] - self.s2
        q1r, q2r = _two_axis(self.R0.T @ d, P[1][:3, :3], w2)
        R3ref = self.R0 @ rz(q1r) @ P[1][:3, :3] @ rz(q2r) @ P[2][:3, :3]
        R3 = self.R0 @ rz(q_arm[0]) @ P[1][:3, :3] @ rz(q_arm[1]) @ P[2][:3, :3] @ rz(q_arm[2])
        Rd = R3 @ R3ref.T                              # rotation about u by the arm angle
        return float(np.arctan2(0.5 * u @ np.array([Rd[2, 1] - Rd[1, 2], Rd[0, 2] - Rd[2, 0], Rd[1, 0] - Rd[0, 1]]),
                                0.5 * (np.trace(Rd) - 1.0)))


def _two_axis(u: np.ndarray, A: np.ndarray, b: np.ndarray):
    """(x1, x2) with ``Rz(x1) A Rz(x2) b = u`` (|u| = |b|), the ``+`` root; None if none."""
    a = A[2, :]
    r = sinusoid_roots(a[0] * b[0] + a[1] * b[1], a[1] * b[0] - a[0] * b[1], a[2] * b[2], u[2], tol=1e-7)
    if r is None or r[0] is None:
        return None
    x2 = r[0]
    v = A @ rz(x2) @ b
    x1 = np.arctan2(u[1], u[0]) - np.arctan2(v[1], v[0])
    return float(x1), float(x2)


def srs_solutions(robot: Robot, T_flange_mm: np.ndarray, arm_angle_rad: float, fixed=()) -> list[SrsSolution]:
    """The 8 arm-angle families of a flange pose (see ``SrsIK``)."""
    return SrsIK(robot, fixed).solve(T_flange_mm, arm_angle_rad)


def srs_seed_solutions(robot: Robot, T_tcp_mm: np.ndarray, q_ref=None, arm_angles_rad=None) -> list[np.ndarray]:
    """Exact full-robot q's (inside the limits) for a TCP pose, nearest to ``q_ref`` first.

    A fast exact seed for the CWLN planner: the joints in front of the 7R arm
    (seed8's track) stay at ``q_ref``'s values (0 without q_ref); the arm angle
    is swept over ``arm_angles_rad`` (default 16 values round the circle) plus
    q_ref's own arm angle. Returns [] if none fits the limits.
    """
    n_pre = robot.dof - 7
    q_ref = np.zeros(robot.dof) if q_ref is None else np.asarray(q_ref, float)
    ik = SrsIK(robot, q_ref[:max(n_pre, 0)])
    T = np.asarray(T_tcp_mm, float) @ np.linalg.inv(robot.tool_T_mm)
    angles = list(np.linspace(-np.pi, np.pi, 16, endpoint=False) if arm_angles_rad is None else arm_angles_rad)
    try:
        angles.append(ik.arm_angle(q_ref[n_pre:]))
    except (PlanInfeasible, TypeError):
        pass
    found = []
    for psi in angles:
        try:
            sols = ik.solve(T, psi)
        except PlanInfeasible:
            continue
        for s in sols:
            eq = limit_equivalents(s.q, ik.lower, ik.upper, np.ones(7, bool))
            if eq is None:
                continue
            q = np.array([min(v, key=lambda x: abs(x - r)) for v, r in zip(eq, q_ref[n_pre:])])
            found.append(ik.full_q(q))
    return sorted(found, key=lambda q: float(np.sum((q - q_ref) ** 2)))


def track_shift(robot, ik: "SrsIK") -> np.ndarray | None:
    """Base-frame translation of the 7R arm per mm of a single track joint in front of it, or None when the
    track is not a pure translation. Then one ``SrsIK`` (built at the track value ``ik.fixed[0]``) serves
    every track value t: solving T at t is solving T moved by -(t - t0) * shift at t0."""
    t0 = float(ik.fixed[0])
    other = SrsIK(robot, [t0 + 100.0])
    d = (other.pre[:3, 3] - ik.pre[:3, 3]) / 100.0
    if not (np.allclose(other.pre[:3, :3], ik.pre[:3, :3], atol=1e-12)
            and np.allclose(other.S - ik.S, 100.0 * d, atol=1e-9)):
        return None
    return d
