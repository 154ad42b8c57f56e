"""The controller's interpolation of a program at a fixed step: joint-linear joint moves,
straight-line and circular Cartesian moves (orientation by slerp, joints by batch Newton),
and parabolic corner blends (see ``camtool.simulate``)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camtool.program.arcs import arc_point, circle_through
from camtool.program.moves import joint_travel
from camtool.program.targets import _ik_batch, _slerp



@dataclass(frozen=True)
class Samples:
    """The interpolated program: sample times ``t`` (S,), joint values ``q`` (S, dof), the move
    ``m`` (S,) each sample falls in, the move end times ``T`` (M,), the total time (s) and what
    could not be followed (findings)."""

    t: np.ndarray
    q: np.ndarray
    m: np.ndarray
    T: np.ndarray
    total: float
    findings: tuple



def interpolate(prog, robot, chain, q_t, P_t, R_t, dur, dt_s: float) -> Samples:
    """Sample ``prog`` (M >= 1 moves with target joints ``q_t``, poses ``P_t`` / ``R_t`` and
    durations ``dur``) every ``dt_s`` the way the controller interpolates it."""
    findings: list[str] = []
    M = len(prog)
    dur[0] = 0.0
    dur = np.where(np.isfinite(dur), dur, 0.0)
    T = np.cumsum(dur)
    total = float(T[-1])
    cart = prog.kind != "J"
    # --- circular moves: their circle (start, circle point, target), length along the arc
    circ_m = (prog.kind == "C") & np.r_[False, np.ones(M - 1, bool)]
    arc = {}
    if circ_m.any():
        kc = np.flatnonzero(circ_m)
        c, rad, n, r0, sweep, ok = circle_through(P_t[kc - 1], prog.via[kc, :3, 3], P_t[kc])
        arc = {int(k): (c[i], n[i], r0[i], sweep[i]) for i, k in enumerate(kc) if ok[i]}

    def on_move(k, s):
        """TCP points at fractions ``s`` of Cartesian moves ``k`` (a line, or its arc)."""
        pts = P_t[k - 1] + s[:, None] * (P_t[k] - P_t[k - 1])
        for i in np.flatnonzero(np.isin(k, list(arc))) if arc else ():
            c_, n_, r0_, sw_ = arc[int(k[i])]
            pts[i] = arc_point(c_[None], n_[None], r0_[None], np.array([sw_]), s[i:i + 1])[0]
        return pts
    # --- blend windows
    L = np.r_[0.0, np.linalg.norm(np.diff(P_t, axis=0), axis=1)]
    for k, (c_, n_, r0_, sw_) in arc.items():
        L[k] = float(np.linalg.norm(r0_) * sw_)  # a circular move's length is its arc's
    Lj = np.r_[0.0, joint_travel(np.diff(q_t, axis=0), chain.prismatic)] if M > 1 else np.zeros(1)
    Leq = np.where(cart, L, np.maximum(L, Lj))
    r = np.array(prog.blend_mm, float)
    r[0] = r[-1] = 0.0
    k_b = np.flatnonzero(r[:-1] > 0)
    k_b = k_b[k_b > 0]
    f_in = np.where(Leq[k_b] > 1e-9, np.minimum(0.5, r[k_b] / np.maximum(Leq[k_b], 1e-9)), 0.5)
    f_out = np.where(Leq[k_b + 1] > 1e-9, np.minimum(0.5, r[k_b] / np.maximum(Leq[k_b + 1], 1e-9)), 0.5)
    tau = np.minimum(f_in * dur[k_b], f_out * dur[k_b + 1])  # equal times before and after the target
    f_in = np.where(dur[k_b] > 0, tau / np.where(dur[k_b] > 0, dur[k_b], 1.0), 0.0)
    f_out = np.where(dur[k_b + 1] > 0, tau / np.where(dur[k_b + 1] > 0, dur[k_b + 1], 1.0), 0.0)
    t_in = T[k_b] - tau
    t_out = T[k_b] + tau
    # --- samples
    t = np.arange(0.0, total, dt_s)
    t = np.append(t, total)
    S = len(t)
    m = np.clip(np.searchsorted(T, t, side="right"), 1, M - 1) if M > 1 else np.zeros(S, int)
    s = np.where(dur[m] > 0, (t - T[m - 1]) / np.where(dur[m] > 0, dur[m], 1.0), 1.0).clip(0, 1) if M > 1 \
        else np.ones(S)
    q = np.empty((S, robot.dof))
    if M == 1:
        q[:] = q_t[0]
    else:
        for b in _blocks(S):
            q[b] = q_t[m[b] - 1] + s[b, None] * (q_t[m[b]] - q_t[m[b] - 1])
    # Cartesian samples: TCP targets, joints by Newton from the joint-linear guess
    cs = cart[m] if M > 1 else np.zeros(S, bool)
    Pc = None
    if cs.any():
        mm, ss = m[cs], s[cs]
        Pc = P_t[mm - 1] + ss[:, None] * (P_t[mm] - P_t[mm - 1])
        circ = prog.kind[mm] == "C"
        if circ.any():
            c, rad, n, r0, sweep, ok = circle_through(P_t[mm[circ] - 1], prog.via[mm[circ], :3, 3], P_t[mm[circ]])
            pts = arc_point(c, n, r0, sweep, ss[circ])
            Pc[circ] = np.where(ok[:, None], pts, Pc[circ])
    # corners
    in_blend = np.zeros(S, bool)
    if len(k_b):
        j = np.clip(np.searchsorted(t_in, t, side="right") - 1, 0, len(k_b) - 1)
        in_blend = (t >= t_in[j]) & (t <= t_out[j]) & (t_out[j] > t_in[j])
    # Cartesian-Cartesian corners in TCP space; other corners in joint space
    if in_blend.any():  # block by block: each sample's corner is its own
        blend_pos = np.flatnonzero(in_blend)
        cart_samples = np.flatnonzero(cart[m])
        for b in _blocks(len(blend_pos)):
            pos = blend_pos[b]
            jb = j[pos]
            kb = k_b[jb]
            u = ((t[pos] - t_in[jb]) / (t_out[jb] - t_in[jb]))[:, None]
            w0, w1, w2 = (1 - u) ** 2, 2 * u * (1 - u), u ** 2
            both_cart = cart[kb] & cart[kb + 1]
            # corner end points on the two moves
            sa, sb = 1 - f_in[jb], f_out[jb]
            qa = q_t[kb - 1] + sa[:, None] * (q_t[kb] - q_t[kb - 1])
            qb = q_t[kb] + sb[:, None] * (q_t[kb + 1] - q_t[kb])
            jc = ~both_cart
            if jc.any():
                # a Cartesian side's end point: its joints by Newton
                for side, kk, ss_, qq in (("a", kb, sa, qa), ("b", kb + 1, sb, qb)):
                    need = jc & cart[kk]
                    if need.any():
                        k2 = kk[need]
                        Pp = on_move(k2, ss_[need])
                        Rp = _slerp(R_t[k2 - 1], R_t[k2], ss_[need])
                        qq[need] = _ik_batch(chain, Pp, Rp, qq[need], np.ones(robot.dof, bool))[0]
                q[pos[jc]] = w0[jc] * qa[jc] + w1[jc] * q_t[kb[jc]] + w2[jc] * qb[jc]
                cs[pos[jc]] = False
            if both_cart.any():
                bc = both_cart
                Pa = on_move(kb[bc], sa[bc])
                Pb = on_move(kb[bc] + 1, sb[bc])
                Pbl = w0[bc] * Pa + w1[bc] * P_t[kb[bc]] + w2[bc] * Pb
                # orientation: the slerp of the move the sample's time falls in
                idx_c = np.searchsorted(cart_samples, pos[bc])
                Pc[idx_c] = Pbl
                q[pos[bc]] = w0[bc] * qa[bc] + w1[bc] * q_t[kb[bc]] + w2[bc] * qb[bc]  # the Newton guess
    if cs.any():
        findings += _cartesian_joints(prog, chain, (Pc, R_t), q, (t, m, s, cs))
    return Samples(t=t, q=q, m=m, T=T, total=total, findings=tuple(findings))


SIM_BLOCK_SAMPLES = 20_000  # samples interpolated or solved at a time: the Newton's Jacobians (6 x dof
                            # floats a sample) and the slerp's rotations take tens of MB a block, not GB
MAX_CARTESIAN_FINDINGS = 5


def _blocks(n: int):
    """Slices covering range(n) in blocks of ``SIM_BLOCK_SAMPLES``."""
    return [slice(a, min(a + SIM_BLOCK_SAMPLES, n)) for a in range(0, n, SIM_BLOCK_SAMPLES)]


def _cartesian_joints(prog, chain, poses, q, grid) -> list[str]:
    """Solve the joints of the Cartesian samples in place in ``q`` (S, dof), by Newton from ``q``'s
    guesses, block by block (each sample is solved alone: blocks give the same joints); findings for
    the first samples it cannot follow. ``poses``: (Pc, the TCP points of the Cartesian samples in
    order; R_t, the targets' rotations); ``grid``: (t, m, s, cs), the samples' times, moves,
    fractions of their moves and which are Cartesian."""
    Pc, R_t = poses
    t, m, s, cs = grid
    ci = np.flatnonzero(cs)
    sel = np.searchsorted(np.flatnonzero(prog.kind[m] != "J"), ci)
    # joints a Cartesian target fixes (external axes) move joint-linearly
    given = np.isfinite(prog.q)
    free = ~np.all(given[m[ci]] & given[m[ci] - 1], axis=0)
    failed = []
    for b in _blocks(len(ci)):
        k = ci[b]
        R = _slerp(R_t[m[k] - 1], R_t[m[k]], s[k])   # the slerp of the move the sample's time falls in
        q[k], ep, eo = _ik_batch(chain, Pc[sel[b]], R, q[k], free)
        failed += list(k[(ep > 1e-2) | (eo > 1e-4)][:MAX_CARTESIAN_FINDINGS - len(failed)])
    return [f"{prog.where[m[i]]}: the controller cannot follow this Cartesian move "
            f"(no joint solution within 0.01 mm at t = {t[i]:.3f} s)" for i in failed]
