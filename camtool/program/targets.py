"""Joint values of a program's targets: what a controller does with a Cartesian target.

A joint target is taken as written. A Cartesian target (MoveL / MOVL, MoveC / MOVC) is
solved for the joints it leaves open by damped least squares, starting from the previous
target (the controller keeps its configuration), and its configuration (ABB confdata,
Yaskawa RCONF) is compared with the program's. The readers of every plugin and the
simulator share this reading; it uses the robot's own chain (``Robot.chain``) and shares
no code with the writers.
"""
from __future__ import annotations

import numpy as np

from .kinematics import walk_chain
from .moves import CONF_UNKNOWN

class _Chain:
    """Batch TCP pose and 6 x n Jacobian in the robot **base** frame, from the DH chain that
    ``camtool.motion.BatchFK`` builds (Pinocchio one by one for other robots)."""

    def __init__(self, robot):
        from camtool.motion.fk_batch import BatchFK

        self.robot = robot
        self.bfk = BatchFK(robot)  # for robots whose model is no z-axis chain
        self.prismatic = np.asarray(robot.prismatic, bool)
        base = np.asarray(robot.base_T_mm, float)
        self.Rb, self.pb = base[:3, :3], base[:3, 3]
        chain = robot.chain
        self.uses_chain = chain is not None
        self._tool_T = np.asarray(robot.tool_T_mm, float)

    def fk(self, q) -> tuple[np.ndarray, np.ndarray]:
        """TCP positions (S, 3) and rotations (S, 3, 3) in the base frame."""
        q = np.asarray(q, float)
        if not self.uses_chain:
            f = self.bfk(q)
            return (f.tcp - self.pb) @ self.Rb, np.einsum("ji,sjk->sik", self.Rb, f.tcp_R)
        return walk_chain(self.robot.chain, self._tool_T, self.prismatic, q)

    def fk_jac(self, q):
        q = np.asarray(q, float)
        if not self.uses_chain:
            p, R = self.fk(q)
            n = q.shape[1]
            J = np.zeros((len(q), 6, n))
            for i in range(n):
                h = 1e-3 if self.prismatic[i] else 1e-6
                dq = q.copy()
                dq[:, i] += h
                p2, R2 = self.fk(dq)
                J[:, :3, i] = (p2 - p) / h
                J[:, 3:, i] = _rotvec(R2 @ np.transpose(R, (0, 2, 1))) / h
            return p, R, J
        S, n = q.shape
        zs = np.empty((S, n, 3))
        os_ = np.empty((S, n, 3))
        tcp, tR = walk_chain(self.robot.chain, self._tool_T, self.prismatic, q, axes=zs, origins=os_)
        J = np.zeros((S, 6, n))
        lin = np.where(self.prismatic[None, :, None], zs, np.cross(zs, tcp[:, None, :] - os_))
        J[:, :3] = np.transpose(lin, (0, 2, 1))
        J[:, 3:] = np.transpose(np.where(self.prismatic[None, :, None], 0.0, zs), (0, 2, 1))
        return tcp, tR, J


def _rotvec(R: np.ndarray) -> np.ndarray:
    """Rotation vectors (S, 3) of rotations (S, 3, 3) (angles below pi)."""
    w = 0.5 * np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], axis=1)
    sn = np.linalg.norm(w, axis=1)
    ang = np.arctan2(sn, (np.trace(R, axis1=1, axis2=2) - 1.0) / 2.0)
    scale = np.where(sn > 1e-12, ang / np.maximum(sn, 1e-300), 1.0)
    return w * scale[:, None]


def _slerp(Ra, Rb, s):
    from scipy.spatial.transform import Rotation
    rel = Rotation.from_matrix(np.transpose(Ra, (0, 2, 1)) @ Rb).as_rotvec()
    return Ra @ Rotation.from_rotvec(rel * s[:, None]).as_matrix()


MAX_IK_STEP = 0.2      # rad (or mm) per Newton step at most
ORI_WEIGHT_MM = 500.0  # orientation error of 1 rad weighs like 500 mm in the IK


def _ik_batch(chain, P, R, q0, free, iters=12):
    """Joint values reaching TCP poses (P, R), base frame, from guesses q0, moving only the
    joints ``free`` (bool, (dof,) or (S, dof)). Returns (q, position error mm, orientation
    error rad). Each sample iterates until it is within 1e-5 mm / 1e-8 rad."""
    q = np.array(q0, float)
    mask = np.broadcast_to(np.asarray(free, bool), q.shape).astype(float)
    lam2 = 1e-6
    act = np.arange(len(q))
    for _ in range(iters):
        if not len(act):
            break
        p, Rc, J = chain.fk_jac(q[act])
        ep = P[act] - p
        eo = _rotvec(R[act] @ np.transpose(Rc, (0, 2, 1)))
        going = (np.abs(ep).max(axis=1) >= 1e-5) | (np.abs(eo).max(axis=1) >= 1e-8)
        act, ep, eo, J = act[going], ep[going], eo[going], J[going]
        if not len(act):
            break
        e = np.concatenate([ep, eo * ORI_WEIGHT_MM], axis=1)
        Jw = J * mask[act][:, None, :]
        Jw[:, 3:] *= ORI_WEIGHT_MM
        A = Jw @ np.transpose(Jw, (0, 2, 1)) + lam2 * np.eye(6)[None]
        dq = np.einsum("sji,sj->si", Jw, np.linalg.solve(A, e[:, :, None])[:, :, 0])
        big = np.abs(dq).max(axis=1, keepdims=True) / MAX_IK_STEP
        q[act] += dq / np.maximum(big, 1.0)  # short steps: stay on the branch of the guess
    p, Rc = chain.fk(q)
    return q, np.linalg.norm(P - p, axis=1), np.linalg.norm(_rotvec(R @ np.transpose(Rc, (0, 2, 1))), axis=1)


def _robot_for(prog, robot):
    if prog.tool_T_mm is not None:
        return robot.with_placement(tool_T_mm=np.asarray(prog.tool_T_mm, float))
    return robot


def _abb_axes(profile, robot):
    """(joint index, sign, offset) of rax_1, rax_4, rax_5, rax_6 (identity on joints 1..6
    without a profile)."""
    out = {}
    if profile is not None:
        for a in profile.axes:
            if a.axis in ("rax_1", "rax_4", "rax_5", "rax_6"):
                out[a.axis] = (robot.joint_names.index(a.joint), a.sign, a.offset)
    else:
        out = {"rax_1": (0, 1, 0.0), "rax_4": (3, 1, 0.0), "rax_5": (4, 1, 0.0), "rax_6": (5, 1, 0.0)}
    return out if len(out) == 4 else None


def _abb_conf(q, ax) -> np.ndarray:
    """(cf1, cf4, cf6, axis 5 negative) of joint values (rad), (S, 4)."""
    def deg(name):
        i, sign, off = ax[name]
        return sign * np.degrees(q[:, i]) + off
    return np.stack([np.floor(deg("rax_1") / 90), np.floor(deg("rax_4") / 90), np.floor(deg("rax_6") / 90),
                     (deg("rax_5") < 0).astype(float)], axis=1)


def _conf_seeds(seed, conf, ax):
    """Seeds in the configuration a confdata asks for: axes 1, 4, 6 in their quadrants
    (nearest the seed's turn) and axis 5 on its side; with and without a wrist flip."""
    out = []
    for flip in (False, True):
        s = seed.copy()
        if flip:
            for name, d in (("rax_4", np.pi), ("rax_5", None), ("rax_6", np.pi)):
                i, sign, _off = ax[name]
                s[i] = -s[i] if d is None else s[i] + d
        for name, cf in (("rax_1", conf[0]), ("rax_4", conf[1]), ("rax_6", conf[2])):
            i, sign, off = ax[name]
            want = ((cf + 0.5) * 90.0 - off) / sign  # joint degrees at the middle of the quadrant
            cur = np.degrees(s[i])
            if np.floor((sign * cur + off) / 90) != cf:
                s[i] = np.radians(want)
        i5, sign5, off5 = ax["rax_5"]
        neg = (sign5 * np.degrees(s[i5]) + off5) < 0
        if bool(conf[3] % 2) != neg:
            s[i5] = -s[i5] if abs(s[i5]) > 1e-3 else np.radians(-10.0 if conf[3] % 2 else 10.0)
        out.append(s)
    return out


CONF_EDGE_DEG = 0.01  # a joint this close to a quadrant boundary (or axis 5 to 0) matches either side


def _conf_ok(q, want, ax) -> np.ndarray:
    """(S,) True where joint values (S, dof) are in the configuration ``want`` (S, 4) asks for;
    a joint within ``CONF_EDGE_DEG`` of a boundary matches either side."""
    ok = np.ones(len(q), bool)
    for col, name in ((0, "rax_1"), (1, "rax_4"), (2, "rax_6")):
        i, sign, off = ax[name]
        d = sign * np.degrees(q[:, i]) + off
        ok &= (np.floor((d - CONF_EDGE_DEG) / 90) == want[:, col]) | (np.floor((d + CONF_EDGE_DEG) / 90) == want[:, col])
    i, sign, off = ax["rax_5"]
    d5 = sign * np.degrees(q[:, i]) + off
    neg = (want[:, 3] % 2) == 1
    ok &= np.where(neg, d5 < CONF_EDGE_DEG, d5 > -CONF_EDGE_DEG)
    return ok


def _conf_matches(q1, want, ax) -> bool:
    return bool(_conf_ok(q1[None], np.asarray(want)[None], ax)[0])


def cartesian_targets(prog) -> np.ndarray:
    """(M,) True for targets stated as a pose: linear and circular moves, and joint moves to a
    Cartesian position (a Yaskawa MOVJ to a ///RECTAN position, written without pulse factors)."""
    pose_only = np.isfinite(prog.pose).all(axis=(1, 2)) & ~np.isfinite(prog.q).all(axis=1)
    return (prog.kind != "J") | pose_only


_SOLVED: dict = {}   # the last programs' solved targets: a run checks a program, then simulates it
SOLVED_KEEP = 4


def forget_solved() -> None:
    """Drop the solved targets kept (the post stage, when a format is done)."""
    _SOLVED.clear()


def target_joints(prog, robot, profile=None) -> np.ndarray:
    """(M, dof) joint values of every target: joint targets as written; each Cartesian target
    solved for the joints it leaves open, from the previous target's joints, in the
    configuration the program asks for (ABB confdata: the quadrants of axes 1, 4, 6 and the
    side of axis 5); NaN where no solution within 1e-3 mm / 1e-5 rad is found.

    The answer depends only on the program's targets, the robot and the profile's axes, so a
    program read twice (its check, then its simulation) is solved once."""
    import hashlib

    robot = _robot_for(prog, robot)
    h = hashlib.sha256()
    for a in (prog.kind, prog.q, prog.pose, prog.conf, robot.base_T_mm, robot.tool_T_mm,
              robot.limits.lower, robot.limits.upper):
        h.update(np.ascontiguousarray(a).tobytes())
    for M in robot.model.jointPlacements:   # the kinematics itself, not only the robot's name
        h.update(np.asarray(M.homogeneous).tobytes())
    h.update(f"{robot.name}|{prog.conf_convention}|{None if profile is None else repr(profile.axes)}".encode())
    key = h.hexdigest()
    if key not in _SOLVED:
        if len(_SOLVED) >= SOLVED_KEEP:
            _SOLVED.pop(next(iter(_SOLVED)))
        _SOLVED[key] = _solve_targets(prog, robot, profile)
    return _SOLVED[key].copy()


def _solve_targets(prog, robot, profile) -> np.ndarray:
    """``target_joints`` without the memo."""
    q = np.array(prog.q, float)
    stated = cartesian_targets(prog)
    cart = np.flatnonzero(stated)
    if not len(cart):
        return q
    solve = _TargetSolve(prog, robot, profile, q, stated)
    solve.joint_moves_to_poses()
    # Cartesian targets with no joint target before them (a Yaskawa job written without pulse
    # factors): the controller moves on from the target before, keeping its configuration, so each
    # is solved in run order from the joints of the one before it (a batch solve from the middle of
    # the limits lands on other branches: the joints would jump between neighbouring targets)
    for i in np.flatnonzero(~solve.done & (solve.src < 0)):
        solve.from_previous(i)
    solve.batch_passes()
    # a run of targets the batch missed: each in run order from the one before it (the passes above
    # reseed a target from its predecessor only once, which leaves all but the first of a run unsolved)
    for i in np.flatnonzero(~solve.done):
        solve.from_previous(i)
    solve.nearest_turns()
    return q


class _TargetSolve:
    """The joints of a program's Cartesian targets (``cart``, the indices of ``stated``), solved in passes
    (``target_joints``): ``q`` (M, dof) filled in place, ``done`` set per Cartesian target once accepted."""

    def __init__(self, prog, robot, profile, q: np.ndarray, stated: np.ndarray):
        self.prog, self.robot, self.q = prog, robot, q
        self.cart = cart = np.flatnonzero(stated)
        self.chain = _Chain(robot)
        self.mid = (robot.limits.lower + robot.limits.upper) / 2
        self.ax = ax = _abb_axes(profile, robot) if prog.conf_convention == "abb" else None
        self.known = np.isfinite(q[cart])
        # seeds: the joints of the last joint target before each Cartesian one (the controller keeps its
        # configuration); then, for any that misses, the solution of the target before it, then seeds in
        # the asked configuration
        last_joint = np.maximum.accumulate(np.where(stated, -1, np.arange(len(q))))
        self.src = src = last_joint[cart]
        seed = np.where(src[:, None] >= 0, q[np.maximum(src, 0)], self.mid[None, :])
        self.seed = np.where(self.known, q[cart], seed)
        self.done = np.zeros(len(cart), bool)
        self.check = ax is not None and (prog.conf[cart] != CONF_UNKNOWN).all(axis=1) if ax is not None else \
            np.zeros(len(cart), bool)

    def joint_moves_to_poses(self) -> None:
        """Joint moves to Cartesian positions with no joint target before them (a job written without
        pulse factors): the controller moves from where it is, so each is solved from the one before
        (Yaskawa: in the configuration its ///RCONF asks for, the turn nearest the previous target)."""
        prog, q, cart = self.prog, self.q, self.cart
        pose_only = np.flatnonzero((self.src < 0) & (prog.kind[cart] == "J"))
        if not len(pose_only):
            return
        far = self._from_fixed_starts(pose_only)
        for n_i, i in enumerate(pose_only):
            k = cart[i]
            ref = q[k - 1] if k > 0 and np.isfinite(q[k - 1]).all() else self.mid
            cands = self._candidates(i, ref, [b_[n_i] for b_ in far])
            if cands:
                q[k], self.done[i] = min(cands, key=lambda w: float(np.sum((w - ref) ** 2))), True

    def _from_fixed_starts(self, pose_only: np.ndarray) -> list[np.ndarray]:
        """(solutions, position errors, orientation errors) of each of the targets ``cart[pose_only]``
        from 48 fixed starts: they do not depend on where the robot is, so every target's are solved in
        one batch (rows are solved independently); only the start from the previous target waits for it."""
        robot, q = self.robot, self.q
        starts = np.random.default_rng(0).uniform(robot.limits.lower, robot.limits.upper, (48, robot.dof))
        K, free = self.cart[pose_only], ~self.known[pose_only]
        S0 = np.where(self.known[pose_only][:, None, :], q[K][:, None, :], starts[None, :, :]).reshape(-1, robot.dof)
        TS = np.repeat(self.prog.pose[K], len(starts), axis=0)
        return [x.reshape(len(K), len(starts), *x.shape[1:]) for x in
                _ik_batch(self.chain, TS[:, :3, 3], TS[:, :3, :3], S0, np.repeat(free, len(starts), 0), iters=80)]

    def _candidates(self, i: int, ref: np.ndarray, far: list[np.ndarray]) -> list[np.ndarray]:
        """The joint solutions of target ``cart[i]`` from ``ref`` and the fixed starts (``far``), each turned
        to its equivalent within the limits nearest ``ref``, in the configuration the target asks for."""
        from camtool.robots.confdata import yaskawa_rconf
        from camtool.robots.ik_common import nearest_equivalent

        prog, robot, q, known = self.prog, self.robot, self.q, self.known
        k = self.cart[i]
        T = prog.pose[[k]]
        near = _ik_batch(self.chain, T[:, :3, 3], T[:, :3, :3], np.where(known[i], q[k], ref)[None], ~known[i][None],
                         iters=80)
        sol, ep, eo = (np.concatenate([a_, b_]) for a_, b_ in zip(near, far))
        cands = [w for w in (nearest_equivalent(c, ref, robot.limits.lower, robot.limits.upper, ~robot.prismatic)
                             for c in sol[(ep < 1e-3) & (eo < 1e-5)]) if w is not None]
        if cands and (prog.conf[k] != CONF_UNKNOWN).all() and robot.dof == len(robot.conventions.axis_joints) >= 6:
            rc = yaskawa_rconf(robot, np.array(cands), 6)   # every candidate's flags in one call
            flags = np.stack([rc[:, 0], rc[:, 1], rc[:, 2], rc[:, 3] * 4 + rc[:, 4] * 2 + rc[:, 5]], axis=1)
            cands = [w for w, f in zip(cands, flags) if list(f) == list(prog.conf[k])]
        return cands

    def from_previous(self, i) -> bool:
        """Solve target ``cart[i]`` from the joints of the target before it; True if accepted."""
        prog, q, known, ax = self.prog, self.q, self.known, self.ax
        k = self.cart[i]
        if k == 0 or not np.isfinite(q[k - 1]).all():
            return False
        s0 = np.where(known[i], q[k], q[k - 1])[None]
        T = prog.pose[[k]]
        sol, ep, eo = _ik_batch(self.chain, T[:, :3, 3], T[:, :3, :3], s0, ~known[i][None], iters=400)
        if not (ep[0] < 1e-3 and eo[0] < 1e-5):
            return False
        if ax is not None and self.check[i] and not _conf_ok(sol, prog.conf[[k]], ax)[0]:
            if not np.isfinite(q[k]).all():
                q[k] = sol[0]  # reached, but not in the asked configuration: configuration_findings says so
            return False
        q[k], self.done[i] = sol[0], True
        return True

    def batch_passes(self) -> None:
        """Up to four batch solves of the targets not done, each from the seeds the pass before left: the
        previous target's joints once known, then seeds in the asked configuration."""
        q, cart = self.q, self.cart
        for attempt in range(4):
            todo = np.flatnonzero(~self.done)
            if not len(todo):
                break
            sol, good, accept = self._batch(todo)
            q[cart[todo[accept]]] = sol[accept]
            self.done[todo[accept]] = True
            if attempt == 3:
                # reached, but not in the asked configuration: configuration_findings says so
                q[cart[todo[good & ~accept]]] = sol[good & ~accept]
                break
            self._reseed(todo, attempt, sol, good)

    def _batch(self, todo: np.ndarray):
        """(solutions, reached, accepted) of the targets ``cart[todo]`` from their seeds: accepted when reached
        in the asked configuration (ABB confdata)."""
        prog, cart, ax = self.prog, self.cart, self.ax
        T = prog.pose[cart[todo]]
        sol, ep, eo = _ik_batch(self.chain, T[:, :3, 3], T[:, :3, :3], self.seed[todo], ~self.known[todo], iters=80)
        good = (ep < 1e-3) & (eo < 1e-5)
        if ax is not None:
            conf_ok = np.ones(len(todo), bool)
            chk = self.check[todo] & good
            if chk.any():
                conf_ok[chk] = _conf_ok(sol[chk], prog.conf[cart[todo[chk]]], ax)
            accept = good & conf_ok
        else:
            accept = good
        return sol, good, accept

    def _reseed(self, todo: np.ndarray, attempt: int, sol: np.ndarray, good: np.ndarray) -> None:
        """The next seeds of the targets not done: the previous target's joints now known, else a
        configuration seed."""
        q, known, seed, ax = self.q, self.known, self.seed, self.ax
        for j, i in enumerate(todo):
            if self.done[i]:
                continue
            k = self.cart[i]
            prev = q[k - 1] if k > 0 and np.isfinite(q[k - 1]).all() else None
            if attempt == 0 and prev is not None:
                seed[i] = np.where(known[i], q[k], prev)
            elif ax is not None and self.check[i]:
                cs = _conf_seeds(sol[j] if good[j] else seed[i], self.prog.conf[k], ax)
                seed[i] = np.where(known[i], q[k], cs[min(attempt - 1, 1)] if attempt >= 1 else cs[0])

    def nearest_turns(self) -> None:
        """A revolute joint the controller solves turns to the 2*pi-equivalent inside its limits nearest
        the previous target (a numerical solution may land a turn away)."""
        from camtool.robots.ik_common import nearest_equivalent

        robot, q = self.robot, self.q
        rev = ~robot.prismatic
        for k in self.cart:
            if np.isfinite(q[k]).all() and not robot.within_limits(q[k]):
                ref = q[k - 1] if k > 0 and np.isfinite(q[k - 1]).all() else self.mid
                w = nearest_equivalent(q[k], ref, robot.limits.lower, robot.limits.upper, rev)
                if w is not None:
                    q[k] = w


def configuration_findings(prog, robot, q, profile=None) -> list[str]:
    """Findings where a Cartesian target's solved joints are not in the configuration the
    program asks for (ABB confdata: cf1, cf4, cf6 quadrants and the sign of axis 5)."""
    if prog.conf_convention != "abb":
        return []
    out = []
    cart = np.flatnonzero((prog.kind != "J") & np.isfinite(q).all(axis=1) & (prog.conf != CONF_UNKNOWN).all(axis=1))
    if not len(cart):
        return out
    ax = _abb_axes(profile, robot)
    if ax is None:
        return out
    c = _abb_conf(q[cart], ax)
    got = c[:, :3]
    flip_got = c[:, 3] == 1
    bad = np.flatnonzero(~_conf_ok(q[cart], prog.conf[cart], ax))
    for i in bad[:20]:
        k = cart[i]
        out.append(f"{prog.where[k]}: the target is reached in configuration "
                   f"[{int(got[i, 0])},{int(got[i, 1])},{int(got[i, 2])},{'odd' if flip_got[i] else 'even'} cfx], "
                   f"the program asks for {list(map(int, prog.conf[k]))}")
    if len(bad) > 20:
        out.append(f"{prog.where[0].rsplit(':', 1)[0]}: ... and {len(bad) - 20} more configuration mismatches")
    return out


def _target_poses(prog, robot, q):
    chain = _Chain(robot)
    ok = np.isfinite(q).all(axis=1)
    P = np.full((len(q), 3), np.nan)
    R = np.full((len(q), 3, 3), np.nan)
    if ok.any():
        P[ok], R[ok] = chain.fk(q[ok])
    cart = prog.kind != "J"
    P[cart] = prog.pose[cart, :3, 3]
    R[cart] = prog.pose[cart, :3, :3]
    return P, R
