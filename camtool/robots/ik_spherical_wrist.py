"""Closed-form IK of 6R arms with parallel axes 2 and 3 and a spherical wrist.

This is the family of the ABB IRB2400 (seed 001): a vertical or tilted
joint 1, an offset shoulder, joints 2 and 3 parallel (elbow offset allowed),
axes 4, 5 and 6 meeting in the wrist centre. The geometry is read from the
robot's own joint placements (``ik_common.Chain``), checked, and then:

1. wrist centre ``W = T @ w_flange`` (a constant point of the flange frame);
2. joint 1: the offset of W from the arm plane is constant, one sinusoid in
   q1, 2 roots (shoulder front / back);
3. joint 3: the distance from axis-2's origin to W depends on q3 only, 2 roots
   (elbow up / down);
4. joint 2: the planar angle that carries W into place;
5. joints 4-6: the spherical-group decomposition of the wrist rotation, 2
   branches (wrist flip).

Up to 8 solutions. ``solve`` returns them all with an in-limits flag (joint
values wrapped to (-pi, pi]); ``best`` picks the one nearest to a reference q
inside the limits, trying the 2*pi-equivalents of joints whose range exceeds
+-180 deg (IRB2400 joints 4 and 6), as seed 001 does.
"""
from __future__ import annotations

from dataclasses import dataclass
from itertools import islice, product

import numpy as np

from ..errors import BadInput, PlanInfeasible
from .ik_common import (Chain, axis_intersection, limit_equivalents, nearest_equivalent, rz,
                        sinusoid_roots, spherical_group, wrap_pi)
from .model import Robot

GEOMETRY_TOL_MM = 1e-6


@dataclass(frozen=True)
class IkSolution:
    """One closed-form solution: q (rad), branch signs, whether it fits the limits."""

    q: np.ndarray
    branch: tuple[int, int, int]  # (shoulder, elbow, wrist): +1 / -1 root of each step
    within_limits: bool


class SphericalWristIK:
    """Closed-form IK for one robot of the IRB2400 family (see module doc)."""

    def __init__(self, robot: Robot):
        self.robot = robot
        ch = Chain(robot)
        if robot.dof != 6 or robot.prismatic.any():
            raise BadInput(f"robot {robot.name}: closed-form spherical-wrist IK needs 6 revolute joints, "
                           f"it has {robot.dof} joints ({int(robot.prismatic.sum())} prismatic)")
        self.ch = ch
        q0 = np.zeros(6)
        pts, dirs = ch.axes(q0)
        z2, z3 = dirs[1], dirs[2]
        if np.linalg.norm(np.cross(z2, z3)) > 1e-9:
            raise BadInput(f"robot {robot.name}: axes 2 and 3 are not parallel; it is not of the "
                           "IRB2400 family (offset shoulder, elbow offset, spherical wrist)")
        if np.linalg.norm(np.cross(dirs[0], z2)) < 1e-9:
            raise BadInput(f"robot {robot.name}: axes 1 and 2 are parallel; closed-form IK does not apply")
        wc, miss = axis_intersection(pts[3:], dirs[3:])
        if miss > GEOMETRY_TOL_MM:
            raise BadInput(f"robot {robot.name}: axes 4, 5, 6 do not meet in one point "
                           f"(miss {miss:.3g} mm): no spherical wrist, no closed-form IK")
        F = ch.frames(q0)
        inv = np.linalg.inv
        self.w_flange = (inv(F[-1]) @ np.append(wc, 1.0))[:3]
        self.w3 = (inv(F[2]) @ np.append(wc, 1.0))[:3]          # W in link-3 coordinates
        self.s3 = inv(ch.P[2])[:3, 3]                            # axis-2 origin in joint-3 pre-frame
        P1i = inv(ch.P[0])
        self.P1i = P1i
        n2 = ch.P[1][:3, 2]                                      # axis 2 in link-1 coordinates
        o2 = ch.P[1][:3, 3]
        w1 = (inv(F[0]) @ np.append(wc, 1.0))[:3]
        self.n2, self.o2 = n2, o2
        self.c_plane = float(n2 @ w1)                            # constant offset of W along axis 2
        L = robot.limits
        self.lower, self.upper = L.lower, L.upper
        self.revolute = ~robot.prismatic
        # the controller's axis limits (the IRB2400's coupled axis 3 = j2 + j3), besides the joint box
        self.controller_ok = robot.conventions.within_limits

    def solve(self, T_flange_mm: np.ndarray) -> list[IkSolution]:
        """Every closed-form solution of a flange pose (base frame, mm); [] if unreachable."""
        T = np.asarray(T_flange_mm, float)
        ch = self.ch
        W = T[:3, :3] @ self.w_flange + T[:3, 3]
        Wp = self.P1i[:3, :3] @ W + self.P1i[:3, 3]              # W in joint-1 pre-frame
        n2 = self.n2
        # (Rz(q1) n2) . Wp = c_plane
        r1 = sinusoid_roots(n2[0] * Wp[0] + n2[1] * Wp[1], n2[0] * Wp[1] - n2[1] * Wp[0],
                            n2[2] * Wp[2], self.c_plane)
        if r1 is None or r1[0] is None:
            return []
        out = []
        s3, w3 = self.s3, self.w3
        for q1, g1 in ((r1[0], 1), (r1[1], -1)):
            W1 = rz(q1).T @ Wp
            d2 = float(np.sum((W1 - self.o2) ** 2))
            # |s3 - Rz(q3) w3|^2 = d2  ->  s3 . Rz(q3) w3 = (|s3|^2 + |w3|^2 - d2) / 2
            r3 = sinusoid_roots(s3[0] * w3[0] + s3[1] * w3[1], s3[1] * w3[0] - s3[0] * w3[1], s3[2] * w3[2],
                                0.5 * (s3 @ s3 + w3 @ w3 - d2))
            if r3 is None or r3[0] is None:
                continue
            for q3, g2 in ((r3[0], 1), (r3[1], -1)):
                w2 = ch.P[2][:3, :3] @ (rz(q3) @ w3) + ch.P[2][:3, 3]   # W in link-2 coordinates
                P2 = ch.P[1]
                w2p = P2[:3, :3].T @ (W1 - P2[:3, 3])                   # W in joint-2 pre-frame
                q2 = np.arctan2(w2p[1], w2p[0]) - np.arctan2(w2[1], w2[0])
                qa = np.array([q1, q2, q3, 0.0, 0.0, 0.0])
                R3 = ch.frames(qa)[2][:3, :3]
                R6 = T[:3, :3] @ ch.flange[:3, :3].T
                M = (R3 @ ch.P[3][:3, :3]).T @ R6
                for q4, q5, q6, g3 in spherical_group(M, ch.P[4][:3, :3], ch.P[5][:3, :3]):
                    q = wrap_pi(np.array([q1, q2, q3, q4, q5, q6]))
                    eq = limit_equivalents(q, self.lower, self.upper, self.revolute)
                    ok = eq is not None and any(self.controller_ok(np.array(c)) for c in islice(product(*eq), 64))
                    out.append(IkSolution(q, (g1, g2, g3), ok))
        return out

    def best(self, T_flange_mm: np.ndarray, q_ref) -> np.ndarray:
        """The solution inside the limits with least joint change from ``q_ref`` (rad).

        Raises PlanInfeasible if the pose has no solution inside the limits.
        """
        q_ref = np.asarray(q_ref, float)
        cands = []
        for s in self.solve(T_flange_mm):
            q = nearest_equivalent(s.q, q_ref, self.lower, self.upper, self.revolute)
            if q is not None and self.controller_ok(q):
                cands.append(q)
        if not cands:
            raise PlanInfeasible(f"{self.robot.name}: pose has no closed-form IK solution inside the joint limits")
        return min(cands, key=lambda q: float(np.sum((q - q_ref) ** 2)))


def closed_form_ik(robot: Robot, T_flange_mm: np.ndarray) -> list[IkSolution]:
    """All closed-form solutions of a flange pose for a robot of the IRB2400 family."""
    return SphericalWristIK(robot).solve(T_flange_mm)
