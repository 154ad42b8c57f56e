"""Smooth surface runs in the null space of the task, so the row can run at the commanded feed.

Where a joint runs into its clamping buffer (the track at the end of its travel,
a wrist at its limit) CWLN stops it within a pose or two and the other joints
take over just as abruptly. The tool stays exactly on the path, but the joint
path has a kink there: its third derivative along the path, times the feed
cubed, is the joint jerk at constant feed, and at the kink it is several times
the jerk limit. No time law through those poses can then hold the feed.

For each run whose joint path needs more than ``jerk_ratio`` of any joint's
jerk limit at the feed (or ``accel_ratio`` of its acceleration limit), this
module solves the sparse least-squares problem::

    min_dq  sum_j ||D3 (q_j + dq_j) * feed^3 / jerk_j||^2
          + sum_j ||D2 (q_j + dq_j) * feed^2 / accel_j||^2
          + mu * sum_k ||dq_k / scale||^2
    s.t.    J_k dq_k = e_k              (the tool stays on pose k, linearised)
            lo + margin <= q + dq <= hi - margin   (active set)

with D3 and D2 the third and second divided differences along the TCP's arc
length, then puts every pose back on its target by least-norm Newton steps
(``CwlnSolver.solve(..., clamp=False)``: CWLN's clamping task would pull the joint back to its
buffer's edge and bring the kink back), and repeats a few times. A run is replaced only if every pose converges, stays inside the joint
limits (so does the cubic spline through the poses, as the timing
interpolates the run) and the run's worst ratio falls; otherwise it is kept as
planned.

Hand-written on purpose: this is a null-space trajectory optimisation over one
row (a sparse equality-constrained least-squares problem, solved with
scipy.sparse); no kept library optimises a redundant arm's joint path under a
pose constraint per waypoint. The maths is the linearised KKT system of that
problem.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.interpolate import CubicSpline

from ..robots.model import Robot
from ..path.toolpath import Path, row_segments, run_bounds
from ..trajectory import JointPath
from .cwln import CwlnSolver


@dataclass(frozen=True)
class SmoothSettings:
    """What the run smoothing aims at (the commanded feed) and how hard it tries."""

    feed_mm_s: float            # the commanded feed the run should hold
    jerk_ratio: float = 0.85    # smooth a run needing more than this share of a jerk limit at the feed
    accel_ratio: float = 0.85   # ... or of an acceleration limit
    regularisation: float = 1.0  # mu: weight of moving a pose (per rad, per planner.track_scale_mm of track)
    iterations: int = 8         # linearise - solve - put back on the path, this many times at most
    limit_margin_rad: float = np.radians(3.0)  # kept off the joint limits (the timing bounds its pieces
                                                # with a pad of a few tenths of a degree near them)
    limit_margin_mm: float = 5.0


def divided_difference(s: np.ndarray, order: int) -> sp.csr_matrix:
    """Sparse (n - order, n) matrix: the ``order``-th derivative along ``s`` by divided differences.

    On a uniform grid of spacing h this is the usual finite difference / h**order.
    """
    n = len(s)
    D = sp.identity(n, format="csr")
    for k in range(1, order + 1):
        m = n - k
        span = (s[k:] - s[:m]) / k  # order k divided difference times k!/(k-1)! -> derivative
        step = sp.diags([-np.ones(m), np.ones(m)], [0, 1], shape=(m, m + 1), format="csr")
        D = sp.diags(1.0 / span) @ step @ D
    return D.tocsr()


def derivatives(q: np.ndarray, s_mm: np.ndarray, order: int) -> list[np.ndarray]:
    """q (n, dof) and its first ``order`` derivatives along ``s_mm`` by sequential divided differences.

    Entry k, (n - k, dof), is ``divided_difference(s_mm, k) @ q`` up to rounding, without building
    the matrix (``run_ratios`` runs for every run at every iteration).
    """
    out = [q]
    for k in range(1, order + 1):
        m = len(s_mm) - k
        span = (s_mm[k:] - s_mm[:m]) / k
        out.append(np.diff(out[-1], axis=0) / span[:, None])
    return out


def run_ratios(q: np.ndarray, s_mm: np.ndarray, robot: Robot, feed_mm_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Per joint, the largest |q'''| v^3 / jerk limit and |q''| v^2 / acceleration limit along one run."""
    lim, none = robot.limits, np.zeros((1, q.shape[1]))
    d = derivatives(q, s_mm, min(3, len(q) - 1))  # as many as the run has poses for
    jerk = np.abs(d[3]) * feed_mm_s ** 3 / lim.jerk if len(q) > 3 else none
    acc = np.abs(d[2]) * feed_mm_s ** 2 / lim.acceleration if len(q) > 2 else none
    return jerk.max(axis=0), acc.max(axis=0)


def _worst(q, s_mm, robot, st: SmoothSettings) -> float:
    jerk, acc = run_ratios(q, s_mm, robot, st.feed_mm_s)
    return float(max((jerk / st.jerk_ratio).max(), (acc / st.accel_ratio).max()))


def _task_matrix(J_rows: np.ndarray, n: int) -> sp.csr_matrix:
    """The linearised pose constraints J_k dq_k, one block of rows per pose (joint-major variables)."""
    _, m, dof = J_rows.shape
    k, r, j = np.meshgrid(np.arange(n), np.arange(m), np.arange(dof), indexing="ij")
    return sp.csr_matrix((J_rows[k, r, j].ravel(), ((k * m + r).ravel(), (j * n + k).ravel())),
                         shape=(n * m, n * dof))


def _kkt_step(q, e_rows, J_rows, D3, D2, robot, st: SmoothSettings, lo, hi, scale, w3, w2):
    """One linearised smoothing step dq (n, dof) for the joint values q (n, dof), or None.

    ``w3`` (n - 3, dof) and ``w2`` (n - 2, dof) weigh each pose's jerk and acceleration
    term; ``D3``, ``D2`` the divided differences along the run. Joint limits by an active set."""
    n, dof = q.shape
    lim = robot.limits
    blocks_H, g = [], []
    # variables in the planner's joint-space metric, joint-major: x[j * n + k] = dq[k, j] / scale[j]
    # (a track in mm next to angles in rad would make the system numerically singular)
    for j in range(dof):
        c3 = scale[j] * st.feed_mm_s ** 3 / lim.jerk[j]
        c2 = scale[j] * st.feed_mm_s ** 2 / lim.acceleration[j]
        Hj = (c3 * c3) * (D3.T @ sp.diags(w3[:, j]) @ D3) + (c2 * c2) * (D2.T @ sp.diags(w2[:, j]) @ D2)
        blocks_H.append(Hj + st.regularisation * sp.identity(n))
        g.append(Hj @ (q[:, j] / scale[j]))
    H = sp.block_diag(blocks_H, format="csr")
    grad = np.concatenate(g)
    h_max = float(H.diagonal().max())  # the KKT system is solved with O(1) entries
    H, grad = H / h_max, grad / h_max
    A = _task_matrix(J_rows * scale, n)
    b = e_rows.reshape(-1)
    row_norm = np.maximum(np.sqrt(np.asarray(A.multiply(A).sum(axis=1)).ravel()), 1e-12)
    A, b = sp.diags(1.0 / row_norm) @ A, b / row_norm
    fixed: dict[int, float] = {}
    free_per_pose = dof - J_rows.shape[1]   # a pose's joints its task rows leave free
    for _ in range(6):  # active set on the joint limits
        idx = np.array(sorted(fixed), dtype=int)
        if len(idx) and np.bincount(idx % n, minlength=n).max() > free_per_pose:
            # a pose with more joints held at a limit than its task leaves free: its task rows and the held
            # joints are dependent, K is singular. Said here: SuperLU would find it only after printing
            # BLAS's "DGEMV parameter number 2 had an illegal value" on stderr (issue #46) and raising
            return None
        F = sp.csr_matrix((np.ones(len(idx)), (np.arange(len(idx)), idx)), shape=(len(idx), n * dof))
        A_all = sp.vstack([A, F]).tocsr()
        b_all = np.concatenate([b, [fixed[i] for i in idx]])
        K = sp.bmat([[H, A_all.T], [A_all, None]], format="csc")
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error", spla.MatrixRankWarning)
                x = spla.spsolve(K, np.concatenate([-grad, b_all]))[: n * dof]
        except (RuntimeError, spla.MatrixRankWarning):  # singular (dependent constraints): keep the run as planned
            return None
        if not np.all(np.isfinite(x)):
            return None
        dq = x.reshape(dof, n).T * scale
        new = q + dq
        over = np.flatnonzero(((new < lo) | (new > hi)).T.reshape(-1))
        if len(over) == 0:
            return dq
        for i in over:
            j, k = divmod(int(i), n)
            fixed[int(i)] = ((lo[j] if new[k, j] < lo[j] else hi[j]) - q[k, j]) / scale[j]
    return None


def smooth_poses(q0: np.ndarray, targets: np.ndarray, s_mm: np.ndarray, robot: Robot, solver: CwlnSolver,
                 st: SmoothSettings) -> np.ndarray | None:
    """Smoothed joint values (n, dof) for poses ``targets`` (base frame) at arc lengths ``s_mm``.

    Every pose stays on its target (CWLN tolerance). Stops once the worst ratio
    (``_worst``) is at most 1; entries above the target ratios weigh more at each
    iteration (iteratively reweighted least squares, towards a min-max). None when no
    iterate is better than ``q0`` or a pose cannot be put back on its target.
    """
    n, dof = q0.shape
    margin = np.where(robot.prismatic, st.limit_margin_mm, st.limit_margin_rad)
    lo = np.minimum(robot.limits.lower + margin, q0.min(axis=0))
    hi = np.maximum(robot.limits.upper - margin, q0.max(axis=0))
    scale = solver.jscale  # the planner's joint-space metric
    best, best_cost = None, _worst(q0, s_mm, robot, st)
    q = q0.copy()
    w3, w2 = np.ones((n - 3, dof)), np.ones((n - 2, dof))
    D3, D2 = divided_difference(s_mm, 3), divided_difference(s_mm, 2)
    lim = robot.limits
    for _ in range(st.iterations):
        # iteratively reweighted: entries over the target ratio weigh more next time (towards min-max)
        w3 *= np.maximum(1.0, np.abs(D3 @ q) * st.feed_mm_s ** 3 / lim.jerk / st.jerk_ratio) ** 2
        w2 *= np.maximum(1.0, np.abs(D2 @ q) * st.feed_mm_s ** 2 / lim.acceleration / st.accel_ratio) ** 2
        tasks = [solver.task(qk, Tk) for qk, Tk in zip(q, targets)]
        dq = _kkt_step(q, np.array([t[0] for t in tasks]), np.array([t[1] for t in tasks]), D3, D2, robot, st,
                       lo, hi, scale, w3, w2)
        if dq is None:
            break
        q_new = np.empty_like(q)
        for k in range(n):
            res = solver.solve(targets[k], q[k] + dq[k], clamp=False)  # no clamping task: it would bring the kink back
            if not res.converged or np.any(res.q < robot.limits.lower) or np.any(res.q > robot.limits.upper):
                return best
            q_new[k] = res.q
        q = q_new
        cost = _worst(q, s_mm, robot, st)
        if cost < best_cost - 1e-9:
            best, best_cost = q.copy(), cost
        if cost <= 1.0:
            break
    return best


def spline_within_limits(q: np.ndarray, s_mm: np.ndarray, robot: Robot, per_piece: int = 16) -> bool:
    """Whether the cubic spline through the run's poses (as the timing interpolates a run) stays inside the
    joint limits: smoothed poses may lie close to a limit, and a spline bending there may overshoot it."""
    if len(q) < 3:
        return True
    x = np.concatenate([np.linspace(a, b, per_piece, endpoint=False) for a, b in zip(s_mm[:-1], s_mm[1:])])
    v = CubicSpline(s_mm, q, bc_type="not-a-knot")(x)
    return bool(np.all(v >= robot.limits.lower) and np.all(v <= robot.limits.upper))


def smooth_runs(joint_path: JointPath, path: Path, robot: Robot, solver: CwlnSolver,
                st: SmoothSettings) -> JointPath:
    """``joint_path`` with every surface run that needs more than the set share of a limit at the feed smoothed.

    The events get ``smoothed_runs``: per smoothed run its segment, the Path indices of its
    first and last pose and the worst limit ratio at the feed before and after (1 = the set share).
    """
    jp = joint_path
    seg = row_segments(jp.path_index, jp.zone, path.segment)
    _, start, end = run_bounds(jp.zone, seg)
    base_inv = np.linalg.inv(robot.base_T_mm)
    q_all = np.array(jp.q, dtype=float)
    pos_err = np.array(jp.position_error_mm, dtype=float)
    ori_err = np.array(jp.orientation_error_rad, dtype=float)
    done = []
    for a, b in zip(np.flatnonzero(start), np.flatnonzero(end)):
        rows = np.arange(a, b + 1)
        pidx = jp.path_index[rows]
        if len(rows) < 5 or np.any(pidx < 0) or not np.all(jp.reached[rows]):
            continue
        poses = path.poses_mm[pidx]
        s_mm = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1))]
        if np.any(np.diff(s_mm) <= 1e-6):
            continue
        before = _worst(q_all[rows], s_mm, robot, st)
        if before <= 1.0:
            continue
        targets = base_inv @ poses
        q_new = smooth_poses(q_all[rows], targets, s_mm, robot, solver, st)
        if q_new is None or not spline_within_limits(q_new, s_mm, robot):
            continue
        q_all[rows] = q_new
        for r, qk, Tk in zip(rows, q_new, targets):
            _, _, pos_err[r], ori_err[r] = solver.task(qk, Tk)
        done.append({"segment": int(path.segment[pidx[0]]), "path_index": [int(pidx[0]), int(pidx[-1])],
                     "worst_ratio_before": round(before, 3),
                     "worst_ratio_after": round(_worst(q_new, s_mm, robot, st), 3)})
    if not done:
        return jp
    return replace(jp, q=q_all, position_error_mm=pos_err, orientation_error_rad=ori_err,
                   events={**jp.events, "smoothed_runs": done})
