"""The robot's closed-form IK families, batched over many poses, for the placement screen.

``ClosedForm.for_robot(robot)`` wraps the closed-form solvers the planner seeds
from (``AnalyticSeeds``): SRS arm-angle IK (``robots.ik_srs``: sia20, and
seed8's 7R arm behind its track, the track handled by moving the target by
the track's shift as ``AnalyticSeeds`` does) and 6R spherical-wrist IK
(``robots.ik_spherical_wrist``: irb2400). Everything here works on stacks of
poses with numpy, thousands of poses per call:

- ``wrist_centres`` / ``bound``: the wrist-centre reach bound. The distance
  from the shoulder (SRS: the point where the first three arm axes meet; 6R:
  the origin of axis 2 for either root of joint 1) to the wrist centre is set
  by the elbow joint alone, ``d(q_e)^2 = |s|^2 + |w|^2 - 2 s.Rz(q_e) w``; it
  must lie in the range d takes for q_e inside its limits. With seed8's track
  the shoulder slides along a segment, so the nearest and farthest shoulder
  points bound d. ``reach_used`` is d / d_max, d_max the straight-elbow
  distance (the arm's geometric reach from the shoulder).
- ``best``: per pose, the closed-form solution with the largest joint-limit
  margin over a fixed sample of the redundancy (arm angle; track value near the
  one that puts the shoulder nearest to the wrist centre; tool spin when the
  path leaves it free). The margin of a configuration is the smallest distance
  of a joint to its nearer limit as a share of that joint's range (each
  revolute joint taking its 2*pi-equivalent farthest inside); ``-inf`` where no
  sampled solution is inside the limits.
- ``jacobian``: the TCP Jacobian (6 x n, base frame, mm / rad rows) of stacked
  configurations, from the robot's own joint placements.

Lengths are mm, angles rad, poses 4x4 in the robot base frame.
"""
from __future__ import annotations

import numpy as np

from ..errors import BadInput
from ..robots.ik_common import Chain, rot_axis_batch, rz_batch, spherical_group_batch, wrap_pi
from ..robots.ik_srs import track_shift

TWO_PI = 2.0 * np.pi
ARM_ANGLES = 8                        # arm angles sampled per pose (SRS)
TRACK_OFFSETS_MM = (0.0, -250.0, 250.0)  # track values tried round the one nearest the wrist centre
SPINS_SRS = 4                         # tool spins sampled when the path leaves the spin free (SRS)
SPINS_6R = 12                         # the same for 6R arms (their only redundancy)
ELBOW_SAMPLES = 2001                  # samples of the elbow joint's range for the reach bound
LIGHT_RECHECK = 0.10                  # poses below this margin after the light sample get the full one


def roots(kc, ks, k0, value, tol: float = 1e-9):
    """Vectorised roots of ``kc cos x + ks sin x + k0 = value``: (x_plus, x_minus, margin); NaN where none.

    ``margin = 1 - |c|`` as in ``ik_common.sinusoid_roots`` (negative: no real root).
    """
    kc, ks, k0, value = (np.asarray(a, float) for a in (kc, ks, k0, value))
    r = np.hypot(kc, ks)
    with np.errstate(invalid="ignore", divide="ignore"):
        c = (value - k0) / r
    margin = 1.0 - np.abs(c)
    bad = (r < 1e-12) | (margin < -tol) | ~np.isfinite(c)
    a = np.arccos(np.clip(np.where(bad, 0.0, c), -1.0, 1.0))
    phi = np.arctan2(ks, kc)
    return np.where(bad, np.nan, phi + a), np.where(bad, np.nan, phi - a), np.where(bad, -np.inf, margin)


class _Elbow:
    """Shoulder-wrist distance as a function of the elbow joint: ``d^2 = |s|^2 + |w|^2 - 2 s.Rz(q) w``."""

    def __init__(self, s: np.ndarray, w: np.ndarray, lower: float, upper: float):
        self.s, self.w = np.asarray(s, float), np.asarray(w, float)
        s, w = self.s, self.w
        self.kc, self.ks, self.k0 = s[0] * w[0] + s[1] * w[1], s[1] * w[0] - s[0] * w[1], s[2] * w[2]
        self.c = float(s @ s + w @ w)
        self.d_max = float(np.sqrt(max(self.c - 2.0 * (self.k0 - np.hypot(self.kc, self.ks)), 0.0)))
        q = np.linspace(lower, upper, ELBOW_SAMPLES)
        d = self.distance(q)
        self.d_lo, self.d_hi = float(d.min()), float(d.max())  # the range of d inside the joint limits

    def distance(self, q) -> np.ndarray:
        q = np.asarray(q, float)
        dot = self.kc * np.cos(q) + self.ks * np.sin(q) + self.k0
        return np.sqrt(np.maximum(self.c - 2.0 * dot, 0.0))


def _spin_stack(n: int) -> np.ndarray:
    """(n, 4, 4) rotations about tool z, evenly round the circle (the first is the identity)."""
    a = np.linspace(0.0, TWO_PI, n, endpoint=False)
    S = np.zeros((n, 4, 4))
    S[:, :3, :3] = rz_batch(a)
    S[:, 3, 3] = 1.0
    return S


def best_of(cands: np.ndarray, lower: np.ndarray, upper: np.ndarray, revolute: np.ndarray, controller_ok=None):
    """Best candidate per pose by joint-limit margin.

    ``cands`` (C, K, n), NaN rows = no solution. Returns (K, n) q (each revolute
    joint at its 2*pi-equivalent nearest mid-range, which is the one farthest
    inside its limits), (K,) margin (``-inf``: no candidate inside the limits)
    and (K,) any-solution flags. ``controller_ok`` (optional, (..., n) -> (...)
    bool, e.g. ``robot.conventions.within_limits``) also refuses candidates beyond
    the controller's axis limits (the IRB2400's coupled axis 3 = j2 + j3).
    """
    span = upper - lower
    mid = 0.5 * (lower + upper)
    dev = cands - mid
    dev = np.where(revolute, wrap_pi(dev), dev)
    with np.errstate(invalid="ignore"):
        m = (0.5 * span - np.abs(dev)) / span
        m = m.min(axis=-1)
    valid = ~np.isnan(m)
    ok = valid & (m >= 0.0)
    if controller_ok is not None:
        with np.errstate(invalid="ignore"):
            ok &= np.asarray(controller_ok(np.nan_to_num(mid + dev)), bool).reshape(m.shape)
    m = np.where(ok, m, -np.inf)
    c = np.argmax(m, axis=0)
    K = cands.shape[1]
    return mid + dev[c, np.arange(K)], m[c, np.arange(K)], valid.any(axis=0)


def _all_of(*checks):
    """One check (..., n) -> (...) bool that passes where every given one does (None: no check)."""
    checks = [c for c in checks if c is not None]
    if not checks:
        return None
    if len(checks) == 1:
        return checks[0]
    return lambda Q: np.logical_and.reduce([np.asarray(c(Q), bool) for c in checks])


def screen_model(robot, settings=None, free_spin: bool = False) -> "ClosedForm | None":
    """``ClosedForm.for_robot`` that also refuses a wrist bend that brings the job's tool closer than the
    cell's clearance to the link before the wrist (``collision.wrist_bend``), as the planner would;
    ``settings``: the job's ``JobSettings`` (None: the limits alone). The bend joint's range is narrowed to the
    free bend, so that the joint-limit margin (and the search's cost) counts from where the tool meets the link."""
    joint_ok, free = None, None
    if settings is not None:
        from ..collision.stage import collision_world
        from ..collision.wrist_bend import WristBend

        bend = WristBend(collision_world(settings, robot))
        if bend.matters:
            joint_ok = bend.ok
            free = bend.free_range_deg()
    model = ClosedForm.for_robot(robot, free_spin, joint_ok)
    if model is not None and joint_ok is not None and free is not None:
        model.narrow(bend.bend_joint, np.radians(free[0]), np.radians(free[1]))   # margins count from the free bend
    return model


class ClosedForm:
    """Batched closed-form IK, reach bound and Jacobian of one robot (see the module doc)."""

    def __init__(self, robot, kind: str, ik, free_spin: bool = False, track_shift=None, joint_ok=None):
        self.robot, self.kind, self.ik, self.free_spin = robot, kind, ik, bool(free_spin)
        self.ch: Chain = ik.ch
        L = robot.limits
        self.lower, self.upper = np.asarray(L.lower, float), np.asarray(L.upper, float)
        self.revolute = ~np.asarray(robot.prismatic, bool)
        # the controller's axis limits (the IRB2400's coupled axis 3), besides the joint box
        axes_ok = None if robot.conventions.identity else robot.conventions.within_limits
        self.controller_ok = _all_of(axes_ok, joint_ok)
        self.tool_inv = np.linalg.inv(robot.tool_T_mm)
        self.tool = np.asarray(robot.tool_T_mm, float)
        self.shift = track_shift
        if kind == "spherical_wrist":
            self.elbow_joint = 2
            self.elbow = _Elbow(ik.s3, ik.w3, self.lower[2], self.upper[2])
        else:
            self.n_pre = robot.dof - 7
            self.elbow_joint = self.n_pre + 3
            self.elbow = _Elbow(ik.s4, ik.w4, self.lower[self.elbow_joint], self.upper[self.elbow_joint])
            if self.n_pre:
                self.t0 = float(ik.fixed[0])
                self.t_lo, self.t_hi = float(self.lower[0]), float(self.upper[0])
        n_spin = (SPINS_6R if kind == "spherical_wrist" else SPINS_SRS) if self.free_spin else 1
        self.spins = _spin_stack(n_spin)

    def narrow(self, joint: int, lower: float, upper: float) -> None:
        """Narrow one joint's range (rad or mm) for the screen: solutions and margins count within it."""
        self.lower, self.upper = self.lower.copy(), self.upper.copy()
        self.lower[joint] = max(self.lower[joint], float(lower))
        self.upper[joint] = min(self.upper[joint], float(upper))

    @staticmethod
    def for_robot(robot, free_spin: bool = False, joint_ok=None) -> "ClosedForm | None":
        """The closed-form model of ``robot``: SRS (7R, or a linear track + 7R) or 6R spherical wrist; else None.
        ``joint_ok`` (optional, (..., n) rad -> (...) bool): a further check of a solution besides the limits
        (the tool's wrist bend, ``screen_model``)."""
        from ..robots.ik_spherical_wrist import SphericalWristIK
        from ..robots.ik_srs import SrsIK

        try:
            if robot.dof == 7:
                return ClosedForm(robot, "srs", SrsIK(robot), free_spin, joint_ok=joint_ok)
            if robot.dof == 8 and robot.prismatic[0] and not robot.prismatic[1:].any():
                mid = 0.5 * (robot.limits.lower[0] + robot.limits.upper[0])
                ik = SrsIK(robot, [mid])
                shift = track_shift(robot, ik)
                if shift is None:
                    return None
                return ClosedForm(robot, "srs_track", ik, free_spin, shift, joint_ok=joint_ok)
            if robot.dof == 6:
                return ClosedForm(robot, "spherical_wrist", SphericalWristIK(robot), free_spin, joint_ok=joint_ok)
        except BadInput:
            return None
        return None

    @property
    def families(self) -> str:
        return {"srs": "SRS arm-angle IK", "srs_track": "SRS arm-angle IK behind a linear track",
                "spherical_wrist": "6R spherical-wrist IK"}[self.kind]

    # -- the wrist-centre reach bound ---------------------------------------------------------
    def wrist_centres(self, T_tcp: np.ndarray) -> np.ndarray:
        """(K, 3) wrist centres of TCP poses (base frame): the flange's wrist point."""
        F = np.asarray(T_tcp, float) @ self.tool_inv
        return np.einsum("kij,j->ki", F[:, :3, :3], self.ik.w_flange) + F[:, :3, 3]

    def wrist_offset(self) -> np.ndarray:
        """The wrist centre in the TCP frame (a constant point): W = T_tcp @ this."""
        return (self.tool_inv[:3, :3] @ self.ik.w_flange) + self.tool_inv[:3, 3]

    def bound(self, W: np.ndarray):
        """Reach bound of wrist centres W (..., 3), base frame: (ok, reach_used, near_track_mm or None).

        ``ok``: some shoulder position (track value / joint-1 root) puts W at a
        distance the elbow can make inside its limits. ``reach_used``: the
        smallest shoulder-wrist distance available over d_max.
        """
        W = np.asarray(W, float)
        e = self.elbow
        if self.kind == "spherical_wrist":
            ik = self.ik
            Wp = W @ ik.P1i[:3, :3].T + ik.P1i[:3, 3]
            n2 = ik.n2
            r1p, r1m, _ = roots(n2[0] * Wp[..., 0] + n2[1] * Wp[..., 1], n2[0] * Wp[..., 1] - n2[1] * Wp[..., 0],
                                n2[2] * Wp[..., 2], ik.c_plane)
            ok = np.zeros(W.shape[:-1], bool)
            used = np.full(W.shape[:-1], np.inf)
            for q1 in (r1p, r1m):
                c, s = np.cos(q1), np.sin(q1)
                W1 = np.stack([c * Wp[..., 0] + s * Wp[..., 1], -s * Wp[..., 0] + c * Wp[..., 1], Wp[..., 2]], -1)
                d = np.linalg.norm(W1 - ik.o2, axis=-1)
                with np.errstate(invalid="ignore"):
                    ok |= (d >= e.d_lo - 1e-6) & (d <= e.d_hi + 1e-6)
                used = np.fmin(used, d / e.d_max)
            return ok, used, None
        S = self.ik.S
        if self.kind == "srs":
            d = np.linalg.norm(W - S, axis=-1)
            return (d >= e.d_lo - 1e-6) & (d <= e.d_hi + 1e-6), d / e.d_max, None
        u = self.shift / np.linalg.norm(self.shift)
        per_mm = float(np.linalg.norm(self.shift))
        a = (W - S) @ u                                     # along the track from the mid shoulder
        t_star = np.clip(self.t0 + a / per_mm, self.t_lo, self.t_hi)
        near = np.linalg.norm(W - (S + np.multiply.outer(t_star - self.t0, self.shift)), axis=-1)
        far = np.maximum(*(np.linalg.norm(W - (S + (t - self.t0) * self.shift), axis=-1)
                           for t in (self.t_lo, self.t_hi)))
        ok = (near <= e.d_hi + 1e-6) & (far >= e.d_lo - 1e-6)
        return ok, near / e.d_max, t_star

    def reach_used_q(self, q: np.ndarray) -> np.ndarray:
        """Shoulder-wrist distance over d_max at configurations q (..., dof): set by the elbow joint alone."""
        q = np.asarray(q, float)
        return self.elbow.distance(q[..., self.elbow_joint]) / self.elbow.d_max

    # -- closed-form solutions -----------------------------------------------------------------
    def candidates(self, T_tcp: np.ndarray, light: bool = False) -> np.ndarray:
        """(C, K, dof) closed-form solutions (NaN: none) of K TCP poses over the redundancy sample
        (``light``: the track only at the value nearest the wrist centre)."""
        T = np.asarray(T_tcp, float)
        K = len(T)
        out = []
        for S in self.spins:
            F = T @ S @ self.tool_inv
            if self.kind == "spherical_wrist":
                from ..report.redundancy_map import spherical_wrist_batch

                with np.errstate(invalid="ignore"):
                    out.append(spherical_wrist_batch(self.ik, F))
            elif self.kind == "srs":
                out.append(self._srs(F, None))
            else:
                W = np.einsum("kij,j->ki", F[:, :3, :3], self.ik.w_flange) + F[:, :3, 3]
                _, _, t_star = self.bound(W)
                for off in TRACK_OFFSETS_MM[:1] if light else TRACK_OFFSETS_MM:
                    t = np.clip(t_star + off, self.t_lo, self.t_hi)
                    arm = self._srs(F, t)
                    out.append(np.concatenate([np.broadcast_to(t[None, :, None], arm.shape[:2] + (1,)), arm],
                                              axis=-1))
        return np.concatenate(out, axis=0).reshape(-1, K, self.robot.dof)

    def best(self, T_tcp: np.ndarray, chunk: int = 4096, recheck_below: float = LIGHT_RECHECK):
        """Per pose the sampled closed-form solution with the largest joint-limit margin: (q, margin, has_ik).

        With a track, a light sample (the track value nearest the wrist centre)
        goes first and only poses whose margin stays below ``recheck_below``
        are solved again over the full sample.
        """
        T = np.asarray(T_tcp, float)
        if len(T) == 0:
            return np.zeros((0, self.robot.dof)), np.zeros(0), np.zeros(0, bool)
        light = self.kind == "srs_track" and len(TRACK_OFFSETS_MM) > 1
        q, m, h = self._best(T, chunk, light)
        if light:
            again = np.flatnonzero(m < recheck_below)
            if len(again):
                q2, m2, h2 = self._best(T[again], chunk, False)
                better = m2 > m[again]
                q[again[better]], m[again[better]] = q2[better], m2[better]
                h[again] |= h2
        return q, m, h

    def _best(self, T, chunk, light):
        qs, ms, hs = [], [], []
        for a in range(0, len(T), chunk):
            q, m, h = best_of(self.candidates(T[a:a + chunk], light), self.lower, self.upper, self.revolute,
                              self.controller_ok)
            qs.append(q), ms.append(m), hs.append(h)
        return np.concatenate(qs), np.concatenate(ms), np.concatenate(hs)

    def _srs(self, F: np.ndarray, track) -> np.ndarray:
        """(8 * ARM_ANGLES, K, 7) SRS solutions of flange poses F (the track at ``track``, mm, or none)."""
        ik = self.ik
        P = ik.P
        K = len(F)
        R, p = F[:, :3, :3], F[:, :3, 3].copy()
        if track is not None:  # the track moves the arm: move the target instead
            p = p - np.multiply.outer(np.asarray(track) - self.t0, self.shift)
        W = np.einsum("kij,j->ki", R, ik.w_flange) + p
        d = W - ik.S
        nd = np.linalg.norm(d, axis=1)
        s, w = ik.s4, ik.w4
        e = self.elbow
        plus, minus, margin = roots(e.kc, e.ks, e.k0, 0.5 * (s @ s + w @ w - nd * nd))
        straight = margin < 1e-8
        plus, minus = np.where(straight, np.nan, plus), np.where(straight, np.nan, minus)
        u = d / np.maximum(nd, 1e-12)[:, None]
        R7 = R @ ik.ch.flange[:3, :3].T
        ud = u @ ik.R0                                       # R0^T d / |d|, per row
        A = P[1][:3, :3]
        a = A[2, :]
        angles = np.linspace(-np.pi, np.pi, ARM_ANGLES, endpoint=False)
        psi = np.repeat(angles, K)
        out = np.full((2, 2, 2, ARM_ANGLES * K, 7), np.nan)
        with np.errstate(invalid="ignore"):
            for i1, q4 in enumerate((minus, plus)):          # gamma1 = +1, -1 (SrsIK.elbow's order)
                q4n = np.nan_to_num(q4)
                w2 = (rz_batch(q4n) @ w) @ P[3][:3, :3].T + P[3][:3, 3]
                w2 = w2 @ P[2][:3, :3].T + P[2][:3, 3] - ik.s2
                x2, _, m2 = roots(a[0] * w2[:, 0] + a[1] * w2[:, 1], a[1] * w2[:, 0] - a[0] * w2[:, 1],
                                  a[2] * w2[:, 2], ud[:, 2] * nd, tol=1e-7)
                v = np.einsum("ij,kjl,kl->ki", A, rz_batch(np.nan_to_num(x2)), w2)
                x1 = np.arctan2(ud[:, 1], ud[:, 0]) - np.arctan2(v[:, 1], v[:, 0])
                R3ref = ik.R0 @ rz_batch(x1) @ A @ rz_batch(np.nan_to_num(x2)) @ P[2][:3, :3]
                bad = np.isnan(q4) | np.isnan(x2)
                R3 = rot_axis_batch(np.tile(u, (ARM_ANGLES, 1)), psi) @ np.tile(R3ref, (ARM_ANGLES, 1, 1))
                q4t = np.tile(q4n, ARM_ANGLES)
                R4 = R3 @ P[3][:3, :3] @ rz_batch(q4t)
                Mw = np.transpose(R4 @ P[4][:3, :3], (0, 2, 1)) @ np.tile(R7, (ARM_ANGLES, 1, 1))
                M3 = np.einsum("ji,kjl->kil", ik.R0, R3)
                badt = np.tile(bad, ARM_ANGLES)
                wrists = [spherical_group_batch(Mw, P[5][:3, :3], P[6][:3, :3], g3) for g3 in (1, -1)]
                for i2, g2 in enumerate((1, -1)):
                    sh = spherical_group_batch(M3, P[1][:3, :3], P[2][:3, :3], g2)
                    for i3, wr in enumerate(wrists):
                        q = np.column_stack([sh, wrap_pi(q4t), wr])
                        q[badt | np.isnan(q).any(axis=1)] = np.nan
                        out[i1, i2, i3] = q
        return out.reshape(8, ARM_ANGLES, K, 7).reshape(8 * ARM_ANGLES, K, 7)

    # -- Jacobian ---------------------------------------------------------------------------------
    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """(K, 6, dof) TCP Jacobians (base frame; rows vx, vy, vz in mm and wx, wy, wz in rad per joint unit)."""
        q = np.atleast_2d(np.asarray(q, float))
        K, n = q.shape
        ch = self.ch
        T = np.broadcast_to(np.eye(4), (K, 4, 4)).copy()
        origins, axes = np.zeros((n, K, 3)), np.zeros((n, K, 3))
        for i in range(n):
            B = T @ ch.P[i]
            origins[i], axes[i] = B[:, :3, 3], B[:, :3, 2]
            M = np.broadcast_to(np.eye(4), (K, 4, 4)).copy()
            if self.robot.prismatic[i]:
                M[:, 2, 3] = q[:, i]
            else:
                M[:, :3, :3] = rz_batch(q[:, i])
            T = B @ M
        tcp = (T @ ch.flange @ self.tool)[:, :3, 3]
        J = np.zeros((K, 6, n))
        for i in range(n):
            if self.robot.prismatic[i]:
                J[:, :3, i] = axes[i]
            else:
                J[:, :3, i] = np.cross(axes[i], tcp - origins[i])
                J[:, 3:, i] = axes[i]
        return J


def dexterity(J: np.ndarray, prismatic: np.ndarray, orientation_mm: float = 200.0,
              track_scale_mm: float = 500.0) -> np.ndarray:
    """Inverse condition number (0 = singular, 1 = isotropic) of stacked Jacobians (K, 6, n).

    Scaled as the planner weighs errors and joints: angular rows times
    ``orientation_mm`` (1 rad counts as that many mm), prismatic columns times
    ``track_scale_mm`` (1 rad of a revolute joint weighs as much as that much
    track travel).
    """
    J = np.array(J, float)
    J[:, 3:, :] *= orientation_mm
    J[:, :, np.asarray(prismatic, bool)] *= track_scale_mm
    s = np.linalg.svd(J, compute_uv=False)
    return s[:, -1] / np.maximum(s[:, 0], 1e-300)


def yoshikawa(J: np.ndarray) -> np.ndarray:
    """Yoshikawa's manipulability sqrt(det(J J^T)) of stacked Jacobians (K, 6, n), unscaled (as the redundancy map)."""
    JJ = J @ np.transpose(J, (0, 2, 1))
    return np.sqrt(np.maximum(np.linalg.det(JJ), 0.0))
