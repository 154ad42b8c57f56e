"""Program simulator: re-execute a written program the way the controller interpolates it.

It reads what a program says (``ProgramMoves``, from the plugin's
``read_program``), never the planner's data, and shares no code with the
writers:

- **Targets.** Joint targets as written. A Cartesian target (MoveL / MOVL,
  MoveC / MOVC) is solved for the joints it leaves open by damped least squares,
  starting from the previous target (the controller keeps its configuration),
  and its configuration (ABB confdata) is compared with the program's.
- **Timing.** A move takes its written duration (``\\T``, or the VJ estimate), or
  its length over its TCP speed (the slower of TCP and reorientation speed);
  along a move the speed is constant (the controller's acceleration ramps are
  not modelled).
- **Interpolation** at ``dt_s`` (<= 4 ms): joint-linear for joint moves; a
  straight TCP line (orientation by slerp) for linear moves; a circle through
  the start, the circle point and the target for circular moves, with its joint
  values by batch Newton from the joint-linear guess.
- **Corners.** A target with a blend radius r (zone, PL) is cut by a parabolic
  blend: from ``tau`` before the target to ``tau`` after it, with
  ``tau = min(f_in T_in, f_out T_out)`` and ``f = min(1/2, r / L)`` of each move,
  the path is the quadratic curve with the target as its control point, so the
  velocity goes linearly from the incoming move's to the outgoing one's. It is
  computed in joint space for joint moves (L of a joint move: the larger of its
  TCP length and its largest joint travel in deg over 0.15 deg/mm) and in TCP
  space for Cartesian ones; r = 0 (``fine``, ``PL=0``) stops exactly at the
  target.
- **The surface** is where the program says the process runs: from the move
  after a row-start marker (``! Row`` comment, tool on) to the move before the
  row-end marker (tool off).

``simulate`` reports, against a planned path (``Reference``): the largest
distance of the simulated TCP from the planned path on work (mm), TCP feed
statistics on work, exact stops and module / job switches on the surface,
joint position and speed limit violations, and the program's time against the
plan's. ``SimReport.findings`` lists what breaks the acceptance rules.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from postprocessors.program import CONF_UNKNOWN

SIM_DT_S = 0.004
ZONE_DEG_PER_MM = 0.15     # the joint travel of 1 mm of blend, for joint moves (deg)
TIME_REL_TOL = 0.005       # program time within 0.5 % of the plan
SPEED_REL_TOL = 1e-3       # joint speeds may exceed the limit by 0.1 % (written resolution)
DEV_ABS_TOL_MM = 1e-3      # the written resolution of positions


# --- kinematics (independent of the writers) ---------------------------------------------------

def _model_chain(robot):
    """(constant placements before each joint, flange placement in the last joint) as 4 x 4
    in mm, from the robot's Pinocchio model, when every joint turns about / slides along its
    local z axis (DH robots); None otherwise."""
    model = robot.model
    names = [model.joints[i].shortname() for i in range(1, model.njoints)]
    if len(names) != robot.dof or any(n not in ("JointModelRZ", "JointModelPZ") for n in names):
        return None
    if [n == "JointModelPZ" for n in names] != [bool(p) for p in robot.prismatic]:
        return None
    frame = model.frames[robot.flange_frame_id]
    if frame.parentJoint != model.njoints - 1:
        return None

    def mm(M):
        T = np.eye(4)
        T[:3, :3] = M.rotation
        T[:3, 3] = np.asarray(M.translation) * 1000.0
        return T
    return [mm(model.jointPlacements[i]) for i in range(1, model.njoints)], mm(frame.placement)


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
        chain = _model_chain(robot)
        self.uses_chain = chain is not None
        if chain is not None:
            self._before, self._flange = chain
            tool = np.asarray(robot.tool_T_mm, float)
            self._tool_R, self._tool_p = tool[:3, :3], tool[:3, 3]

    @staticmethod
    def _combo(w, cols):
        """sum_j w[j] cols[j] for a constant vector w (mostly 0 and +-1 in a DH chain)."""
        out = None
        for c, col in zip(w, cols):
            if abs(c) < 1e-15:
                continue
            term = col if c == 1.0 else (-col if c == -1.0 else col * c)
            out = term if out is None else out + term
        return np.zeros_like(cols[0]) if out is None else out

    def fk(self, q) -> tuple[np.ndarray, np.ndarray]:
        """TCP positions (S, 3) and rotations (S, 3, 3) in the base frame."""
        q = np.asarray(q, float)
        if not self.uses_chain:
            f = self.bfk(q)
            return (f.tcp - self.pb) @ self.Rb, np.einsum("ji,sjk->sik", self.Rb, f.tcp_R)
        b = self
        S = len(q)
        # the rotation as its three columns (S, 3) each: every step is a few contiguous products
        x = np.zeros((S, 3)); x[:, 0] = 1.0
        y = np.zeros((S, 3)); y[:, 1] = 1.0
        z = np.zeros((S, 3)); z[:, 2] = 1.0
        p = np.zeros((S, 3))

        combo = self._combo

        def turn(C):
            return tuple(combo(C[:, j], (x, y, z)) for j in range(3))

        for i, before in enumerate(b._before):
            if np.any(before[:3, 3]):
                p = p + combo(before[:3, 3], (x, y, z))
            x, y, z = turn(before[:3, :3])
            if self.prismatic[i]:
                p = p + z * q[:, i, None]
            else:
                c, s = np.cos(q[:, i])[:, None], np.sin(q[:, i])[:, None]
                x, y = c * x + s * y, c * y - s * x
        for T in (b._flange, None):
            if T is None:
                v, C = b._tool_p, b._tool_R
            else:
                v, C = T[:3, 3], T[:3, :3]
            if np.any(v):
                p = p + combo(v, (x, y, z))
            x, y, z = turn(C)
        return p, np.stack([x, y, z], axis=2)

    def fk_jac(self, q):
        q = np.asarray(q, float)
        b = self
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
        x, y, z = (np.zeros((S, 3)) for _ in range(3))
        x[:, 0] = y[:, 1] = z[:, 2] = 1.0
        p = np.zeros((S, 3))
        zs = np.empty((S, n, 3))
        os_ = np.empty((S, n, 3))
        comb = self._combo
        for i, before in enumerate(b._before):
            if np.any(before[:3, 3]):
                p = p + comb(before[:3, 3], (x, y, z))
            x, y, z = (comb(before[:3, j], (x, y, z)) for j in range(3))
            zs[:, i] = z
            if self.prismatic[i]:
                p = p + z * q[:, i, None]
            else:
                c, s = np.cos(q[:, i])[:, None], np.sin(q[:, i])[:, None]
                x, y = c * x + s * y, c * y - s * x
            os_[:, i] = p
        for v, C in ((b._flange[:3, 3], b._flange[:3, :3]), (b._tool_p, b._tool_R)):
            if np.any(v):
                p = p + comb(v, (x, y, z))
            x, y, z = (comb(C[:, j], (x, y, z)) for j in range(3))
        tcp, tR = p, np.stack([x, y, z], axis=2)
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


def target_joints(prog, robot, profile=None) -> np.ndarray:
    """(M, dof) joint values of every target: joint targets as written; each Cartesian target
    solved for the joints it leaves open, from the previous target's joints, in the
    configuration the program asks for (ABB confdata: the quadrants of axes 1, 4, 6 and the
    side of axis 5); NaN where no solution within 1e-3 mm / 1e-5 rad is found."""
    robot = _robot_for(prog, robot)
    q = np.array(prog.q, float)
    cart = np.flatnonzero(prog.kind != "J")
    if not len(cart):
        return q
    chain = _Chain(robot)
    mid = (robot.limits.lower + robot.limits.upper) / 2
    ax = _abb_axes(profile, robot) if prog.conf_convention == "abb" else None
    known = np.isfinite(q[cart])
    # seeds: the joints of the last joint target before each Cartesian one (the controller keeps its
    # configuration); then, for any that misses, the solution of the target before it, then seeds in
    # the asked configuration
    last_joint = np.maximum.accumulate(np.where(prog.kind != "J", -1, np.arange(len(q))))
    src = last_joint[cart]
    seed = np.where(src[:, None] >= 0, q[np.maximum(src, 0)], mid[None, :])
    seed = np.where(known, q[cart], seed)
    done = np.zeros(len(cart), bool)
    check = ax is not None and (prog.conf[cart] != CONF_UNKNOWN).all(axis=1) if ax is not None else \
        np.zeros(len(cart), bool)
    for attempt in range(4):
        todo = np.flatnonzero(~done)
        if not len(todo):
            break
        T = prog.pose[cart[todo]]
        sol, ep, eo = _ik_batch(chain, T[:, :3, 3], T[:, :3, :3], seed[todo], ~known[todo], iters=80)
        good = (ep < 1e-3) & (eo < 1e-5)
        if ax is not None:
            conf_ok = np.ones(len(todo), bool)
            chk = check[todo] & good
            if chk.any():
                conf_ok[chk] = _conf_ok(sol[chk], prog.conf[cart[todo[chk]]], ax)
            accept = good & conf_ok
        else:
            accept = good
        q[cart[todo[accept]]] = sol[accept]
        done[todo[accept]] = True
        if attempt == 3:
            # reached, but not in the asked configuration: configuration_findings says so
            q[cart[todo[good & ~accept]]] = sol[good & ~accept]
            break
        # next seeds: the previous target's joints now known, else a configuration seed
        for j, i in enumerate(todo):
            if done[i]:
                continue
            k = cart[i]
            prev = q[k - 1] if k > 0 and np.isfinite(q[k - 1]).all() else None
            if attempt == 0 and prev is not None:
                seed[i] = np.where(known[i], q[k], prev)
            elif ax is not None and check[i]:
                cs = _conf_seeds(sol[j] if good[j] else seed[i], prog.conf[k], ax)
                seed[i] = np.where(known[i], q[k], cs[min(attempt - 1, 1)] if attempt >= 1 else cs[0])
    return q


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


def _joint_travel(dq, prismatic):
    dq = np.abs(np.atleast_2d(dq))
    return np.where(prismatic[None, :], dq, np.degrees(dq) / ZONE_DEG_PER_MM).max(axis=1)


def _arc(P0, Pv, P1):
    """Circle through P0, Pv, P1 (each (K, 3)): centre, radius, unit axis, start vector, sweep (rad)."""
    a, b = P0 - Pv, P1 - Pv
    axb = np.cross(a, b)
    den = 2 * np.einsum("ki,ki->k", axb, axb)
    ok = den > 1e-12
    den = np.where(ok, den, 1.0)
    c = Pv + (np.cross(np.einsum("ki,ki->k", a, a)[:, None] * b - np.einsum("ki,ki->k", b, b)[:, None] * a, axb)
              / den[:, None])
    n = axb / np.maximum(np.linalg.norm(axb, axis=1, keepdims=True), 1e-12)
    n = -n  # P0 -> Pv -> P1 turns positively about n
    r0, r1, rv = P0 - c, P1 - c, Pv - c
    rad = np.linalg.norm(r0, axis=1)

    def ang(u, v):
        return np.arctan2(np.einsum("ki,ki->k", np.cross(u, v), n), np.einsum("ki,ki->k", u, v)) % (2 * np.pi)
    sweep = ang(r0, r1)
    bad_dir = ang(r0, rv) > sweep  # via not between: go the other way round
    n = np.where(bad_dir[:, None], -n, n)
    sweep = np.where(bad_dir, 2 * np.pi - sweep, sweep)
    return c, rad, n, r0, sweep, ok


def _arc_point(c, n, r0, sweep, s):
    th = sweep * s
    ct, st = np.cos(th)[:, None], np.sin(th)[:, None]
    return c + r0 * ct + np.cross(n, r0) * st + n * np.einsum("ki,ki->k", n, r0)[:, None] * (1 - ct)


def move_durations(prog, robot, q=None, profile=None) -> np.ndarray:
    """(M,) each move's duration (s): as written, else its length over its TCP speed (the
    slower of TCP and reorientation); NaN for the first move (from wherever the robot is)."""
    robot = _robot_for(prog, robot)
    q = target_joints(prog, robot, profile) if q is None else q
    M = len(prog)
    P, R = _target_poses(prog, robot, q)
    dur = np.array(prog.duration_s, float)
    need = np.isnan(dur) & np.isfinite(prog.speed_mm_s)
    need[0] = False
    for k in np.flatnonzero(need):
        if prog.kind[k] == "C" and np.isfinite(prog.via[k]).all():
            c, rad, n, r0, sweep, ok = _arc(P[k - 1][None], prog.via[k][None, :3, 3], P[k][None])
            L = float(rad[0] * sweep[0]) if ok[0] else float(np.linalg.norm(P[k] - P[k - 1]))
        else:
            L = float(np.linalg.norm(P[k] - P[k - 1]))
        t = L / prog.speed_mm_s[k] if prog.speed_mm_s[k] > 0 else np.inf
        if np.isfinite(prog.ori_speed_deg_s[k]) and prog.ori_speed_deg_s[k] > 0:
            ang = np.degrees(np.linalg.norm(_rotvec((R[k] @ R[k - 1].T)[None])[0]))
            t = max(t, ang / prog.ori_speed_deg_s[k])
        dur[k] = t
    if M:
        dur[0] = np.nan
    return dur


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


# --- the planned path ------------------------------------------------------------------------------

@dataclass(frozen=True)
class Reference:
    """The planned path: TCP points (mm, robot base frame) in order, ``breaks`` where the
    polyline does not continue (between rows), the plan's duration (s, or None), its number
    of work rows and feed; ``motion`` (optional) the timed motion's own TCP curve: a point
    is on the planned path when it is near either (the poses' polyline, or the curve the
    plan itself moves along between them)."""

    points: np.ndarray
    breaks: np.ndarray
    duration_s: float | None = None
    rows: int | None = None
    feed_mm_s: float | None = None
    motion: "Reference | None" = None  # the planned motion's own TCP curve, when it bows off the poses
    times: np.ndarray | None = None    # the plan's time at each point (s from its start), when known
    window: int = 1                    # segments either side of the plan's one searched first (with times)
    _tree: object = field(default=None, compare=False, repr=False)

    def tree(self):
        """A KD-tree of the points, built once."""
        if self._tree is None:
            from scipy.spatial import cKDTree
            object.__setattr__(self, "_tree", cKDTree(self.points))
        return self._tree


REF_SAG_MM = 0.005  # the planned motion's curve is kept where it bows more than this off the poses' chords


def _hermite(t_s, q, qd, qdd, k, tt):
    """Joint values at times ``tt`` inside steps ``k`` (waypoint k to k+1) of the timed motion."""
    from camtool.trajectory import quintic_coefficients

    h = (t_s[k + 1] - t_s[k])[:, None]
    s = (tt - t_s[k])[:, None] / np.where(h > 0, h, 1.0)
    c = quintic_coefficients(q[k], qd[k] * h, qdd[k] * h ** 2, q[k + 1], qd[k + 1] * h, qdd[k + 1] * h ** 2)
    out = np.zeros_like(q[k])
    for coef in c[::-1]:
        out = out * s + coef
    return out


def reference_from_trajectory(trajectory, robot, feed_mm_s: float | None = None) -> Reference:
    """The planned path of a timed trajectory: the polyline through the TCP of its path poses
    (``path_index >= 0``) on its process zones (lead-in, work, lead-out), broken between
    stretches; and, where the timed motion itself bows off that polyline by more than
    ``REF_SAG_MM`` (its quintic pieces between waypoints), that motion's TCP curve as
    ``Reference.motion``."""
    from camtool.toolpath import ZONE_CODE

    zone = np.asarray(trajectory.zone)
    t = np.asarray(trajectory.t_s, float)
    qa = np.asarray(trajectory.q, float)
    proc = np.isin(zone, [ZONE_CODE["work"], ZONE_CODE["lead_in"], ZONE_CODE["lead_out"]])
    pose = np.asarray(trajectory.path_index) >= 0
    stretch = np.cumsum(np.r_[1, np.diff(proc.astype(int)) != 0])  # stretch number of every waypoint
    idx = np.flatnonzero(proc & pose)
    chain = _Chain(robot)
    P = chain.fk(qa[idx])[0]
    breaks = np.r_[stretch[idx[1:]] != stretch[idx[:-1]], True]  # the polyline ends after point i
    work = zone == ZONE_CODE["work"]
    rows = int(np.sum(np.diff(np.r_[0, work.astype(int)]) == 1))
    motion = None
    steps = np.flatnonzero(proc[:-1] & proc[1:] & (t[1:] > t[:-1]))  # steps of the timed motion on the zones
    if len(steps) and getattr(trajectory, "qd", None) is not None:
        qd, qdd = np.asarray(trajectory.qd, float), np.asarray(trajectory.qdd, float)
        Pw = chain.fk(qa)[0]
        mid = chain.fk(_hermite(t, qa, qd, qdd, steps, (t[steps] + t[steps + 1]) / 2))[0]
        sag = np.linalg.norm(mid - (Pw[steps] + Pw[steps + 1]) / 2, axis=1)
        bow = steps[sag > REF_SAG_MM]
        if len(bow):
            n = 8  # points per bowed step
            kk = np.repeat(bow, n + 1)
            frac = np.tile(np.arange(n + 1) / n, len(bow))
            Pm = chain.fk(_hermite(t, qa, qd, qdd, kk, t[kk] + frac * (t[kk + 1] - t[kk])))[0]
            mb = np.zeros(len(Pm), bool)
            mb[n::n + 1] = True  # each bowed step is its own polyline
            tm = t[kk] + frac * (t[kk + 1] - t[kk]) - t[0]
            motion = Reference(Pm, mb, times=tm, window=2)
    return Reference(P, breaks, float(t[-1] - t[0]), rows, feed_mm_s, motion, t[idx] - t[0])


def reference_from_path(path, robot, duration_s: float | None = None, feed_mm_s: float | None = None) -> Reference:
    """The planned path from the raster ``Path`` itself: its poses of the process zones (world
    frame) in the robot base frame, broken between stretches."""
    from camtool.toolpath import ZONE_CODE

    zone = np.asarray(path.zone)
    proc = np.isin(zone, [ZONE_CODE["work"], ZONE_CODE["lead_in"], ZONE_CODE["lead_out"]])
    idx = np.flatnonzero(proc)
    Tb = np.linalg.inv(np.asarray(robot.base_T_mm, float))
    P = np.asarray(path.poses_mm, float)[idx, :3, 3] @ Tb[:3, :3].T + Tb[:3, 3]
    breaks = np.r_[np.diff(idx) != 1, True]
    work = zone == ZONE_CODE["work"]
    rows = int(np.sum(np.diff(np.r_[0, work.astype(int)]) == 1))
    return Reference(P, breaks, duration_s, rows, feed_mm_s)


def reference_from_samples(t_s, q, robot, feed_mm_s: float | None = None) -> Reference:
    """A planned path from timed joint samples without zones (a CSV program): one polyline."""
    P, _R = _Chain(robot).fk(np.asarray(q, float))
    breaks = np.zeros(len(P), bool)
    breaks[-1] = True
    return Reference(P, breaks, float(t_s[-1] - t_s[0]) if len(t_s) else None, None, feed_mm_s)


def _distance_to_polyline(X: np.ndarray, ref: Reference, t: np.ndarray | None = None,
                          exact_above: float = 0.0) -> np.ndarray:
    """Distance (mm) of points X from the reference: the nearer of its polyline and, when it
    has one, the planned motion's curve (``Reference.motion``).

    With the points' times ``t`` (s from the program's start) and the reference's times, each
    point is first measured against the five segments around the one the plan is on at that
    time (exact while the program keeps the plan's clock, an upper bound always); only points
    farther than ``exact_above`` (the tolerance) are searched over the whole reference."""
    d = _distance_to_lines(X, ref, t, exact_above)
    if ref.motion is not None and len(ref.motion.points):
        far = np.flatnonzero(d > max(REF_SAG_MM, 0.5 * exact_above))
        if len(far):
            d[far] = np.minimum(d[far], _distance_to_lines(X[far], ref.motion, None if t is None else t[far],
                                                           exact_above))
    return d


def _segments(X, V, brk, starts):
    """Distance of X from the segments starting at ``starts`` (clipped; across a break, from
    the start point alone)."""
    a = np.clip(starts, 0, len(V) - 2)
    va = V[a]
    d = V[a + 1] - va
    w = X - va
    dd = np.einsum("ki,ki->k", d, d)
    s = np.einsum("ki,ki->k", w, d) / np.where(dd > 0, dd, 1.0)
    np.clip(s, 0.0, 1.0, out=s)
    s[brk[a]] = 0.0
    w -= s[:, None] * d
    return np.sqrt(np.einsum("ki,ki->k", w, w))


def _distance_to_lines(X: np.ndarray, ref: Reference, t=None, exact_above: float = 0.0) -> np.ndarray:
    """Distance (mm) of points X from a polyline: from the vertices the plan is at about the
    points' times (when known), else from each point's two nearest vertices, the segments on
    either side of them."""
    V = ref.points
    if len(V) == 0 or len(X) == 0:
        return np.full(len(X), np.nan)
    if len(V) == 1:
        return np.linalg.norm(X - V[0], axis=1)
    best = np.full(len(X), np.inf)
    todo = np.arange(len(X))
    if t is not None and ref.times is not None and len(ref.times) == len(V):
        i = np.searchsorted(ref.times, t)
        # the program keeps the plan's clock: the plan is near here (``window`` segments either side)
        for off in range(-ref.window - 1, ref.window + 1):
            best = np.minimum(best, _segments(X, V, ref.breaks, i + off))
        todo = np.flatnonzero(best > exact_above)
    if len(todo):
        Xt = X[todo]
        dist, nn = ref.tree().query(Xt, k=2)
        b = np.min(dist, axis=1)
        for j in range(2):
            for off in (-1, 0):
                b = np.minimum(b, _segments(Xt, V, ref.breaks, nn[:, j] + off))
        best[todo] = np.minimum(best[todo], b)
    return best


# --- the simulation -----------------------------------------------------------------------------

@dataclass
class SimReport:
    """What a program does when the controller runs it (see module doc)."""

    moves: int
    duration_s: float
    planned_duration_s: float | None
    rows: int
    work_length_mm: float
    work_time_s: float
    moves_on_work: int
    max_deviation_mm: float | None
    p99_deviation_mm: float | None
    feed: dict
    exact_stops: int
    exact_stops_on_surface: int
    part_switches: int
    part_switches_on_surface: int
    limit_violations: int
    speed_violations: int
    samples: int
    findings: list = field(default_factory=list)

    def as_dict(self) -> dict:
        from dataclasses import asdict
        return asdict(self)


def simulate(prog, robot, reference: Reference | None = None, *, dt_s: float = SIM_DT_S,
             path_tol_mm: float | None = None, profile=None) -> SimReport:
    """Re-execute ``prog`` (a ``ProgramMoves``) at ``dt_s`` and measure it (module doc).

    ``reference`` (optional) is the planned path; without it there is no deviation and no
    time comparison. ``path_tol_mm`` makes a larger deviation a finding.
    """
    robot = _robot_for(prog, robot)
    findings: list[str] = []
    M = len(prog)
    if M == 0:
        return SimReport(0, 0.0, None, 0, 0.0, 0.0, 0, None, None, {}, 0, 0, 0, 0, 0, 0, 0, ["no moves"])
    chain = _Chain(robot)
    q_t = target_joints(prog, robot, profile)
    bad_t = np.flatnonzero(~np.isfinite(q_t).all(axis=1))
    for k in bad_t[:20]:
        findings.append(f"{prog.where[k]}: no joint values reach this target")
    if len(bad_t):
        return SimReport(M, float("nan"), None, 0, 0.0, 0.0, 0, None, None, {}, 0, 0, 0, 0, 0, 0, 0, findings)
    findings += configuration_findings(prog, robot, q_t, profile)
    P_t, R_t = _target_poses(prog, robot, q_t)
    dur = move_durations(prog, robot, q_t)
    dur[0] = 0.0
    dur = np.where(np.isfinite(dur), dur, 0.0)
    T = np.cumsum(dur)
    total = float(T[-1])
    cart = prog.kind != "J"
    # --- blend windows
    L = np.r_[0.0, np.linalg.norm(np.diff(P_t, axis=0), axis=1)]
    Lj = np.r_[0.0, _joint_travel(np.diff(q_t, axis=0), chain.prismatic)] if M > 1 else np.zeros(1)
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
        q[:] = q_t[m - 1] + s[:, None] * (q_t[m] - q_t[m - 1])
    # Cartesian samples: TCP targets, joints by Newton from the joint-linear guess
    cs = cart[m] if M > 1 else np.zeros(S, bool)
    Pc = Rc = None
    if cs.any():
        mm, ss = m[cs], s[cs]
        Pc = P_t[mm - 1] + ss[:, None] * (P_t[mm] - P_t[mm - 1])
        circ = prog.kind[mm] == "C"
        if circ.any():
            c, rad, n, r0, sweep, ok = _arc(P_t[mm[circ] - 1], prog.via[mm[circ], :3, 3], P_t[mm[circ]])
            pts = _arc_point(c, n, r0, sweep, ss[circ])
            Pc[circ] = np.where(ok[:, None], pts, Pc[circ])
        Rc = _slerp(R_t[mm - 1], R_t[mm], ss)
    # corners
    in_blend = np.zeros(S, bool)
    if len(k_b):
        j = np.clip(np.searchsorted(t_in, t, side="right") - 1, 0, len(k_b) - 1)
        in_blend = (t >= t_in[j]) & (t <= t_out[j]) & (t_out[j] > t_in[j])
    # Cartesian-Cartesian corners in TCP space; other corners in joint space
    if in_blend.any():
        jb = j[in_blend]
        kb = k_b[jb]
        u = ((t[in_blend] - t_in[jb]) / (t_out[jb] - t_in[jb]))[:, None]
        w0, w1, w2 = (1 - u) ** 2, 2 * u * (1 - u), u ** 2
        both_cart = cart[kb] & cart[kb + 1]
        # corner end points on the two moves
        sa, sb = 1 - f_in[jb], f_out[jb]
        qa = q_t[kb - 1] + sa[:, None] * (q_t[kb] - q_t[kb - 1])
        qb = q_t[kb] + sb[:, None] * (q_t[kb + 1] - q_t[kb])
        pos = np.flatnonzero(in_blend)
        jc = ~both_cart
        if jc.any():
            # a Cartesian side's end point: its joints by Newton
            for side, kk, ss_, qq in (("a", kb, sa, qa), ("b", kb + 1, sb, qb)):
                need = jc & cart[kk]
                if need.any():
                    k2 = kk[need]
                    Pp = P_t[k2 - 1] + ss_[need, None] * (P_t[k2] - P_t[k2 - 1])
                    Rp = _slerp(R_t[k2 - 1], R_t[k2], ss_[need])
                    qq[need] = _ik_batch(chain, Pp, Rp, qq[need], np.ones(robot.dof, bool))[0]
            q[pos[jc]] = w0[jc] * qa[jc] + w1[jc] * q_t[kb[jc]] + w2[jc] * qb[jc]
            cs[pos[jc]] = False
        if both_cart.any():
            bc = both_cart
            Pa = P_t[kb[bc] - 1] + sa[bc, None] * (P_t[kb[bc]] - P_t[kb[bc] - 1])
            Pb = P_t[kb[bc]] + sb[bc, None] * (P_t[kb[bc] + 1] - P_t[kb[bc]])
            Pbl = w0[bc] * Pa + w1[bc] * P_t[kb[bc]] + w2[bc] * Pb
            # orientation: the slerp of the move the sample's time falls in
            idx_c = np.searchsorted(np.flatnonzero(cart[m]), pos[bc])
            Pc[idx_c] = Pbl
            q[pos[bc]] = w0[bc] * qa[bc] + w1[bc] * q_t[kb[bc]] + w2[bc] * qb[bc]  # the Newton guess
    if cs.any():
        ci = np.flatnonzero(cs)
        sel = np.searchsorted(np.flatnonzero(cart[m]), ci)
        Pc_s, Rc_s = Pc[sel], Rc[sel]
        free = np.ones(robot.dof, bool)
        known = np.isfinite(prog.q[m[ci]]) & np.isfinite(prog.q[m[ci] - 1])
        # joints a Cartesian target fixes (external axes) move joint-linearly
        free = ~np.all(known, axis=0)
        sol, ep, eo = _ik_batch(chain, Pc_s, Rc_s, q[ci], free)
        q[ci] = sol
        nb = np.flatnonzero((ep > 1e-2) | (eo > 1e-4))
        for i in nb[:5]:
            findings.append(f"{prog.where[m[ci[i]]]}: the controller cannot follow this Cartesian move "
                            f"(no joint solution within 0.01 mm at t = {t[ci[i]]:.3f} s)")
    # --- limits
    Lm = robot.limits
    tol = np.where(chain.prismatic, 5e-4, np.radians(5e-5)) + 1e-9
    over = (q < Lm.lower - tol) | (q > Lm.upper + tol)
    n_lim = int(over.any(axis=1).sum())
    if n_lim:
        k0 = int(np.flatnonzero(over.any(axis=1))[0])
        i0 = int(np.flatnonzero(over[k0])[0])
        findings.append(f"{prog.where[m[k0]] if M > 1 else prog.where[0]}: {robot.joint_names[i0]} leaves its limits "
                        f"at t = {t[k0]:.3f} s ({n_lim} samples)")
    n_speed = 0
    if S > 1:
        dts = np.diff(t)
        good = dts > 1e-9
        v = np.abs(np.diff(q, axis=0))[good] / dts[good, None]
        allowed = Lm.velocity[None, :] * (1 + SPEED_REL_TOL) + 2 * tol[None, :] / dts[good, None]
        sp = v > allowed
        n_speed = int(sp.any(axis=1).sum())
        if n_speed:
            k0 = int(np.flatnonzero(good)[np.flatnonzero(sp.any(axis=1))[0]])
            i0 = int(np.flatnonzero(sp[np.flatnonzero(sp.any(axis=1))[0]])[0])
            unit = "mm/s" if chain.prismatic[i0] else "deg/s"
            conv = (lambda x: x) if chain.prismatic[i0] else np.degrees
            findings.append(f"{prog.where[m[k0 + 1]]}: {robot.joint_names[i0]} moves at "
                            f"{conv(v[np.flatnonzero(sp.any(axis=1))[0], i0]):.2f} {unit}, above its limit "
                            f"{conv(Lm.velocity[i0]):.2f} {unit} ({n_speed} samples)")
    # --- the surface: rows from the program's markers
    starts = np.flatnonzero(prog.row_start)
    ends = np.flatnonzero(prog.row_end)
    rows = []
    e_i = 0
    for a in starts:
        e = ends[ends >= a]
        if not len(e):
            findings.append(f"{prog.where[a]}: a row starts and never ends")
            break
        rows.append((int(a), int(e[0])))
    on_work = np.zeros(S, bool)
    moves_on_work = 0
    stops_surface = 0
    switches_surface = 0
    part = np.asarray(prog.part)
    switch_after = np.r_[part[1:] != part[:-1], False]
    blend_zero = np.asarray(prog.blend_mm) <= 0
    for a, b in rows:
        lo, hi = np.searchsorted(t, [T[a], T[b]], side="left")
        on_work[lo:hi + 1] = True
        moves_on_work += b - a
        st = np.flatnonzero(blend_zero[a:b + 1]) + a
        st = st[(st > 0) & (st < M - 1)]  # the first move comes from anywhere; the last ends the program
        if a == b:  # a row of one point is a touch (seed 002's targets): the process stops there
            st = st[:0]
        for k in st:
            stops_surface += 1
            if stops_surface <= 10:
                findings.append(f"{prog.where[k]}: exact stop on the surface")
        sw = np.flatnonzero(switch_after[a:b + 1]) + a
        for k in sw:
            switches_surface += 1
            if switches_surface <= 10:
                findings.append(f"{prog.where[k]}: the program switches module / job on the surface")
    del e_i
    # --- feed and deviation on work
    work_len = 0.0
    feed = {}
    X = np.full((S, 3), np.nan)
    if on_work.any():  # the TCP is measured where it is on the surface
        X[on_work] = chain.fk(q[on_work])[0]
    if S > 1 and on_work.any():
        seg = on_work[1:] & on_work[:-1]
        d = np.where(seg, np.linalg.norm(np.diff(X, axis=0), axis=1), 0.0)
        dts = np.diff(t)
        work_len = float(d[seg].sum())
        vv = d[seg & (dts > 1e-9)] / dts[seg & (dts > 1e-9)]
        if len(vv):
            feed = {"mean_mm_s": float(work_len / max(dts[seg].sum(), 1e-12)), "min_mm_s": float(vv.min()),
                    "max_mm_s": float(vv.max()), "p1_mm_s": float(np.percentile(vv, 1)),
                    "p99_mm_s": float(np.percentile(vv, 99))}
            target = reference.feed_mm_s if reference is not None else None
            if target:
                w = dts[seg & (dts > 1e-9)]
                rel = np.abs(vv / target - 1)
                feed.update(commanded_mm_s=float(target),
                            within_1pct=float(w[rel <= 0.01].sum() / w.sum()),
                            within_2pct=float(w[rel <= 0.02].sum() / w.sum()))
    max_dev = p99 = None
    planned = None
    if reference is not None:
        planned = reference.duration_s
        if on_work.any():
            dev = _distance_to_polyline(X[on_work], reference, t[on_work],
                                        path_tol_mm if path_tol_mm is not None else 0.0)
            max_dev, p99 = float(np.max(dev)), float(np.percentile(dev, 99))
            if path_tol_mm is not None and max_dev > path_tol_mm + DEV_ABS_TOL_MM:
                worst = int(np.flatnonzero(on_work)[int(np.argmax(dev))])
                findings.append(f"{prog.where[m[worst]] if M > 1 else prog.where[0]}: the simulated TCP is "
                                f"{max_dev:.3f} mm from the planned path (tolerance {path_tol_mm:g} mm) at "
                                f"t = {t[worst]:.3f} s")
        if reference.rows is not None and reference.rows != len(rows):
            findings.append(f"{prog.where[0].rsplit(':', 1)[0]}: the program has {len(rows)} rows, the plan "
                            f"{reference.rows}")
        if planned and abs(total - planned) > TIME_REL_TOL * planned:
            findings.append(f"{prog.where[0].rsplit(':', 1)[0]}: the program takes {total:.3f} s, the plan "
                            f"{planned:.3f} s ({100 * (total / planned - 1):+.2f} %, allowed "
                            f"{100 * TIME_REL_TOL:.1f} %)")
    stops = int(blend_zero.sum())
    return SimReport(moves=M, duration_s=total, planned_duration_s=planned, rows=len(rows),
                     work_length_mm=work_len, work_time_s=float(np.diff(t)[on_work[1:] & on_work[:-1]].sum())
                     if S > 1 else 0.0, moves_on_work=moves_on_work, max_deviation_mm=max_dev,
                     p99_deviation_mm=p99, feed=feed, exact_stops=stops, exact_stops_on_surface=stops_surface,
                     part_switches=int(switch_after.sum()), part_switches_on_surface=switches_surface,
                     limit_violations=n_lim, speed_violations=n_speed, samples=S, findings=findings)


def summary_lines(rep: SimReport) -> list[str]:
    """A few human lines about a simulation."""
    out = [f"simulated {rep.moves} moves, {rep.duration_s:.3f} s"
           + (f" (plan {rep.planned_duration_s:.3f} s)" if rep.planned_duration_s else "")
           + f", {rep.samples} samples"]
    out.append(f"work: {rep.rows} rows, {rep.work_length_mm / 1000:.3f} m, {rep.moves_on_work} moves "
               f"({rep.moves_on_work / max(rep.work_length_mm / 1000, 1e-9):.1f} per m)")
    if rep.max_deviation_mm is not None:
        out.append(f"deviation from the planned path on work: max {rep.max_deviation_mm:.4f} mm, "
                   f"p99 {rep.p99_deviation_mm:.4f} mm")
    if rep.feed:
        f = rep.feed
        line = f"feed on work: mean {f['mean_mm_s']:.2f}, p1 {f['p1_mm_s']:.2f}, p99 {f['p99_mm_s']:.2f} mm/s"
        if "within_1pct" in f:
            line += f"; {100 * f['within_1pct']:.1f} % within 1 %, {100 * f['within_2pct']:.1f} % within 2 %"
        out.append(line)
    out.append(f"exact stops: {rep.exact_stops} ({rep.exact_stops_on_surface} on the surface); module/job "
               f"switches: {rep.part_switches} ({rep.part_switches_on_surface} on the surface); limit "
               f"violations: {rep.limit_violations} position, {rep.speed_violations} speed samples")
    return out

