"""The controller's interpolation of a program at a fixed step: joint-linear joint moves,
straight-line and circular Cartesian moves (orientation by slerp, joints by batch Newton),
and parabolic corner blends (see ``camtool.simulate``)."""
from __future__ import annotations

from dataclasses import dataclass, field

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
    unsolved: np.ndarray = field(default_factory=lambda: np.zeros(0, int))  # samples with no joint solution



def interpolate(prog, robot, chain, q_t, P_t, R_t, dur, dt_s: float) -> Samples:
    """Sample ``prog`` (M >= 1 moves with target joints ``q_t``, poses ``P_t`` / ``R_t`` and
    durations ``dur``) every ``dt_s`` the way the controller interpolates it."""
    M = len(prog)
    dur[0] = 0.0
    dur = np.where(np.isfinite(dur), dur, 0.0)
    T = np.cumsum(dur)
    total = float(T[-1])
    targets = _Targets(q_t, P_t, R_t, prog.kind != "J", _arcs(prog, P_t))
    corners = _corners(prog, chain, targets, dur, T)
    grid = _sample_grid(T, dur, total, dt_s)
    q = _joint_linear(q_t, grid, robot.dof)
    # Cartesian samples: TCP targets, joints by Newton from the joint-linear guess
    cs = targets.cart[grid.m] if M > 1 else np.zeros(len(grid.t), bool)
    Pc = _cartesian_points(prog, P_t, grid, cs)
    _blend_corners(corners, targets, chain, grid, q, cs, Pc)
    findings, unsolved = _cartesian_joints(prog, chain, (Pc, R_t), q, (grid.t, grid.m, grid.s, cs)) if cs.any() \
        else ([], np.zeros(0, int))
    return Samples(t=grid.t, q=q, m=grid.m, T=T, total=total, findings=tuple(findings), unsolved=unsolved)


@dataclass(frozen=True)
class _Targets:
    """The program's targets: joints ``q`` (M, dof), TCP points ``P`` (M, 3) and rotations ``R`` (M, 3, 3),
    which moves are Cartesian (``cart``), and the circle of each circular move (``arc``, by move: centre,
    normal, start radius vector, sweep)."""

    q: np.ndarray
    P: np.ndarray
    R: np.ndarray
    cart: np.ndarray
    arc: dict

    def on_move(self, k, s):
        """TCP points at fractions ``s`` of Cartesian moves ``k`` (a line, or its arc)."""
        P_t, arc = self.P, self.arc
        pts = P_t[k - 1] + s[:, None] * (P_t[k] - P_t[k - 1])
        on_arc = np.flatnonzero(np.isin(k, list(arc))) if arc else ()
        if len(on_arc):   # every point on an arc at once: row by row the same numbers (arc_point works by row)
            c_, n_, r0_, sw_ = (np.array(x) for x in zip(*(arc[int(k[i])] for i in on_arc)))
            pts[on_arc] = arc_point(c_, n_, r0_, sw_, s[on_arc])
        return pts


@dataclass(frozen=True)
class _Corners:
    """The parabolic blends at the targets ``k`` with a blend radius: the fractions of the move before
    (``f_in``) and after (``f_out``) each spends, and its window ``t_in`` .. ``t_out`` (s)."""

    k: np.ndarray
    f_in: np.ndarray
    f_out: np.ndarray
    t_in: np.ndarray
    t_out: np.ndarray

    def window(self, t: np.ndarray):
        """(the samples in a corner's window, each sample's corner or None without corners)."""
        in_blend, j = np.zeros(len(t), bool), None
        if len(self.k):
            j = np.clip(np.searchsorted(self.t_in, t, side="right") - 1, 0, len(self.k) - 1)
            in_blend = (t >= self.t_in[j]) & (t <= self.t_out[j]) & (self.t_out[j] > self.t_in[j])
        return in_blend, j


@dataclass(frozen=True)
class _Grid:
    """The samples: times ``t`` (S,), the move ``m`` each falls in and its fraction ``s`` of that move."""

    t: np.ndarray
    m: np.ndarray
    s: np.ndarray


def _arcs(prog, P_t: np.ndarray) -> dict:
    """The circle of each circular move (start, circle point, target) by move: centre, normal, start radius
    vector, sweep (none where the three points do not make one)."""
    M = len(prog)
    circ_m = (prog.kind == "C") & np.r_[False, np.ones(M - 1, bool)]
    arc = {}
    if circ_m.any():
        kc = np.flatnonzero(circ_m)
        c, rad, n, r0, sweep, ok = circle_through(P_t[kc - 1], prog.via[kc, :3, 3], P_t[kc])
        arc = {int(k): (c[i], n[i], r0[i], sweep[i]) for i, k in enumerate(kc) if ok[i]}
    return arc


def _corners(prog, chain, targets: _Targets, dur: np.ndarray, T: np.ndarray) -> _Corners:
    """The blend windows: each corner takes the same time before and after its target, at most the share of
    each move its blend radius is of the move's length (a circular move's: its arc's; a joint move's: at least
    its joint travel), and at most half of either move."""
    M = len(prog)
    L = np.r_[0.0, np.linalg.norm(np.diff(targets.P, axis=0), axis=1)]
    for k, (c_, n_, r0_, sw_) in targets.arc.items():
        L[k] = float(np.linalg.norm(r0_) * sw_)  # a circular move's length is its arc's
    Lj = np.r_[0.0, joint_travel(np.diff(targets.q, axis=0), chain.prismatic)] if M > 1 else np.zeros(1)
    Leq = np.where(targets.cart, L, np.maximum(L, Lj))
    r = np.array(prog.blend_mm, float)
    r[0] = r[-1] = 0.0
    k_b = np.flatnonzero(r[:-1] > 0)
    k_b = k_b[k_b > 0]
    f_in = np.where(Leq[k_b] > 1e-9, np.minimum(0.5, r[k_b] / np.maximum(Leq[k_b], 1e-9)), 0.5)
    f_out = np.where(Leq[k_b + 1] > 1e-9, np.minimum(0.5, r[k_b] / np.maximum(Leq[k_b + 1], 1e-9)), 0.5)
    tau = np.minimum(f_in * dur[k_b], f_out * dur[k_b + 1])  # equal times before and after the target
    f_in = np.where(dur[k_b] > 0, tau / np.where(dur[k_b] > 0, dur[k_b], 1.0), 0.0)
    f_out = np.where(dur[k_b + 1] > 0, tau / np.where(dur[k_b + 1] > 0, dur[k_b + 1], 1.0), 0.0)
    return _Corners(k_b, f_in, f_out, T[k_b] - tau, T[k_b] + tau)


def _sample_grid(T: np.ndarray, dur: np.ndarray, total: float, dt_s: float) -> _Grid:
    """Samples every ``dt_s`` and at the end, with the move each falls in and its fraction of it."""
    M = len(T)
    t = np.arange(0.0, total, dt_s)
    t = np.append(t, total)
    S = len(t)
    m = np.clip(np.searchsorted(T, t, side="right"), 1, M - 1) if M > 1 else np.zeros(S, int)
    s = np.where(dur[m] > 0, (t - T[m - 1]) / np.where(dur[m] > 0, dur[m], 1.0), 1.0).clip(0, 1) if M > 1 \
        else np.ones(S)
    return _Grid(t, m, s)


def _joint_linear(q_t: np.ndarray, grid: _Grid, dof: int) -> np.ndarray:
    """The samples' joints interpolated linearly between the targets' (S, dof)."""
    m, s = grid.m, grid.s
    q = np.empty((len(grid.t), dof))
    if len(q_t) == 1:
        q[:] = q_t[0]
    else:
        for b in _blocks(len(grid.t)):
            q[b] = q_t[m[b] - 1] + s[b, None] * (q_t[m[b]] - q_t[m[b] - 1])
    return q


def _cartesian_points(prog, P_t: np.ndarray, grid: _Grid, cs: np.ndarray):
    """The TCP points of the Cartesian samples ``cs`` in order (on the line, or the arc, of their move), or
    None without any."""
    Pc = None
    if cs.any():
        mm, ss = grid.m[cs], grid.s[cs]
        Pc = P_t[mm - 1] + ss[:, None] * (P_t[mm] - P_t[mm - 1])
        circ = prog.kind[mm] == "C"
        if circ.any():
            c, rad, n, r0, sweep, ok = circle_through(P_t[mm[circ] - 1], prog.via[mm[circ], :3, 3], P_t[mm[circ]])
            pts = arc_point(c, n, r0, sweep, ss[circ])
            Pc[circ] = np.where(ok[:, None], pts, Pc[circ])
    return Pc


def _blend_corners(corners: _Corners, targets: _Targets, chain, grid: _Grid, q: np.ndarray, cs: np.ndarray,
                   Pc) -> None:
    """The samples in a corner's window, blended in place: Cartesian-Cartesian corners in TCP space (``Pc``,
    with the Newton's guess in ``q``); other corners in joint space (``q``; no longer Cartesian in ``cs``)."""
    t, q_t, cart = grid.t, targets.q, targets.cart
    in_blend, j = corners.window(t)
    if not in_blend.any():
        return
    blend_pos = np.flatnonzero(in_blend)
    cart_samples = np.flatnonzero(cart[grid.m])
    for b in _blocks(len(blend_pos)):  # block by block: each sample's corner is its own
        pos = blend_pos[b]
        jb = j[pos]
        kb = corners.k[jb]
        u = ((t[pos] - corners.t_in[jb]) / (corners.t_out[jb] - corners.t_in[jb]))[:, None]
        w0, w1, w2 = (1 - u) ** 2, 2 * u * (1 - u), u ** 2
        both_cart = cart[kb] & cart[kb + 1]
        # corner end points on the two moves
        sa, sb = 1 - corners.f_in[jb], corners.f_out[jb]
        qa = q_t[kb - 1] + sa[:, None] * (q_t[kb] - q_t[kb - 1])
        qb = q_t[kb] + sb[:, None] * (q_t[kb + 1] - q_t[kb])
        jc = ~both_cart
        if jc.any():
            _solve_cartesian_ends(targets, chain, kb, jc, ((kb, sa, qa), (kb + 1, sb, qb)))
            q[pos[jc]] = w0[jc] * qa[jc] + w1[jc] * q_t[kb[jc]] + w2[jc] * qb[jc]
            cs[pos[jc]] = False
        if both_cart.any():
            bc = both_cart
            Pa = targets.on_move(kb[bc], sa[bc])
            Pb = targets.on_move(kb[bc] + 1, sb[bc])
            Pbl = w0[bc] * Pa + w1[bc] * targets.P[kb[bc]] + w2[bc] * Pb
            # orientation: the slerp of the move the sample's time falls in
            idx_c = np.searchsorted(cart_samples, pos[bc])
            Pc[idx_c] = Pbl
            q[pos[bc]] = w0[bc] * qa[bc] + w1[bc] * q_t[kb[bc]] + w2[bc] * qb[bc]  # the Newton guess


def _solve_cartesian_ends(targets: _Targets, chain, kb: np.ndarray, jc: np.ndarray, ends) -> None:
    """A joint-space corner's end point on a Cartesian move: its joints by Newton, in place in the end's joints
    (``ends``: the move, the fraction of it and the joints of each corner's end before and after its target)."""
    for kk, ss_, qq in ends:
        need = jc & targets.cart[kk]
        if need.any():
            k2 = kk[need]
            Pp = targets.on_move(k2, ss_[need])
            Rp = _slerp(targets.R[k2 - 1], targets.R[k2], ss_[need])
            qq[need] = _ik_batch(chain, Pp, Rp, qq[need], np.ones(qq.shape[1], bool))[0]


SIM_BLOCK_SAMPLES = 20_000  # samples interpolated or solved at a time: the Newton's Jacobians (6 x dof
                            # floats a sample) and the slerp's rotations take tens of MB a block, not GB
MAX_CARTESIAN_FINDINGS = 5


def _blocks(n: int):
    """Slices covering range(n) in blocks of ``SIM_BLOCK_SAMPLES``."""
    return [slice(a, min(a + SIM_BLOCK_SAMPLES, n)) for a in range(0, n, SIM_BLOCK_SAMPLES)]


def _cartesian_joints(prog, chain, poses, q, grid) -> tuple[list[str], np.ndarray]:
    """Solve the joints of the Cartesian samples in place in ``q`` (S, dof), by Newton from ``q``'s
    guesses, block by block (each sample is solved alone: blocks give the same joints); findings for
    the first samples it cannot follow, and every such sample. ``poses``: (Pc, the TCP points of the Cartesian samples in
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
        failed += list(k[(ep > 1e-2) | (eo > 1e-4)])
    return [f"{prog.where[m[i]]}: the controller cannot follow this Cartesian move "
            f"(no joint solution within 0.01 mm at t = {t[i]:.3f} s)"
            for i in failed[:MAX_CARTESIAN_FINDINGS]], np.asarray(failed, int)
