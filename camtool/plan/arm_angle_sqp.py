"""Arm-angle SQP planner of seed 002 (Taniai & Naniwa 2019) for SRS arms.

For a sequence of flange poses and each of the 8 arm-angle IK families
(``robots.ik_srs``), the joint values are a function of one arm angle per
pose. The planner:

1. solves every pose at the fixed arm angle Theta0 = pi/4 (the paper's start);
2. runs scipy's SLSQP over the arm angles from there, minimising
   ``E = sum_k ||theta(k+1) - theta(k)||`` (rad) subject to the joint limits
   (kept ``margin_rad`` inside, default 0.2 deg, so that the timing stage's
   sampled moves stay clear of the limits). Gradients: each pose's joints depend on its
   own arm angle only, so dtheta_k/dTheta_k comes from a central difference
   and both E's gradient and the constraint Jacobian follow exactly from it;
3. reports E and feasibility per family, fixed and optimised, and keeps the
   feasible result with the least E. Feasible means every joint of every
   pose lies at least ``margin_rad`` inside its limits.

``plan_arm_angle_sqp`` wraps this for the pipeline: Path in (world-frame TCP
poses), JointPath plus the per-family table out.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize

from ..errors import BadInput, PlanInfeasible
from ..robots.ik_common import wrap_pi
from ..robots.ik_srs import FAMILIES, SrsIK
from ..robots.model import Robot
from ..trajectory import JointPath
from ..transforms import rotation_angle_rad

FD_STEP_RAD = 1e-6
LIMIT_MARGIN_RAD = float(np.radians(0.2))


@dataclass(frozen=True)
class FamilyResult:
    """E (rad) and feasibility of one family, at the fixed arm angle and after SQP."""

    family: tuple[int, int, int]
    fixed_E_rad: float
    fixed_feasible: bool
    opt_E_rad: float
    opt_feasible: bool
    arm_angles_rad: np.ndarray = field(repr=False)   # optimised, one per pose
    q_opt: np.ndarray = field(repr=False)            # (K, 7) arm joints, optimised
    q_fixed: np.ndarray = field(repr=False)          # (K, 7) arm joints at Theta0
    iterations: int = 0
    message: str = ""

    def row(self) -> dict:
        return {"family": list(self.family),
                "fixed_E_rad": _num(self.fixed_E_rad), "fixed_feasible": self.fixed_feasible,
                "optimised_E_rad": _num(self.opt_E_rad), "optimised_feasible": self.opt_feasible,
                "sqp_iterations": self.iterations}


def _num(x: float):
    return float(x) if np.isfinite(x) else None


@dataclass(frozen=True)
class ArmAngleResult:
    families: tuple[FamilyResult, ...]
    best: int                 # index into families, -1 if none is feasible
    best_source: str          # "optimised" or "fixed"
    theta0_rad: float

    @property
    def q_best(self) -> np.ndarray:
        f = self.families[self.best]
        return f.q_opt if self.best_source == "optimised" else f.q_fixed

    def table(self) -> list[dict]:
        return [f.row() for f in self.families]


def path_length_rad(q: np.ndarray) -> float:
    """E = sum of Euclidean joint-space steps (rad)."""
    return float(np.linalg.norm(np.diff(q, axis=0), axis=1).sum())


class _FamilyProblem:
    """theta(Theta) for one family over K prepared poses, with cached evaluation."""

    def __init__(self, ik: SrsIK, stacked: dict, family: tuple[int, int, int]):
        self.ik, self.stacked, self.family = ik, stacked, family
        self._x = None

    def q_of(self, x: np.ndarray) -> np.ndarray:
        return self.ik.family_q_batch(self.stacked, x, self.family)

    def eval(self, x):
        if self._x is None or not np.array_equal(x, self._x):
            self._x = np.array(x, float)
            self._q = self.q_of(self._x)
            self._dq = wrap_pi(self.q_of(self._x + FD_STEP_RAD) - self.q_of(self._x - FD_STEP_RAD)) / (2 * FD_STEP_RAD)
        return self._q, self._dq


def optimise_family(ik: SrsIK, stacked: dict, family, theta0_rad: float, margin_rad: float,
                    max_iterations: int) -> FamilyResult:
    """Fixed-angle and SLSQP-optimised arm angles for one family."""
    prob = _FamilyProblem(ik, stacked, family)
    K = len(stacked["u"])
    lo, hi = ik.lower, ik.upper
    x0 = np.full(K, theta0_rad)
    q_fixed = prob.q_of(x0)

    def feasible(q):
        return bool(np.all(np.isfinite(q)) and np.all(q >= lo + margin_rad - 1e-9)
                    and np.all(q <= hi - margin_rad + 1e-9))

    def fun(x):
        q, _ = prob.eval(x)
        return path_length_rad(q)

    def jac(x):
        q, dq = prob.eval(x)
        diff = np.diff(q, axis=0)
        n = np.linalg.norm(diff, axis=1, keepdims=True)
        unit = diff / np.where(n > 1e-12, n, 1.0)
        g = np.zeros_like(q)
        g[1:] += unit
        g[:-1] -= unit
        return np.sum(g * dq, axis=1)

    def cons(x):
        q, _ = prob.eval(x)
        return np.concatenate([(q - lo - margin_rad).ravel(), (hi - margin_rad - q).ravel()])

    def cons_jac(x):
        _, dq = prob.eval(x)
        J = np.zeros((K, 7, K))
        J[np.arange(K), :, np.arange(K)] = dq
        J = J.reshape(K * 7, K)
        return np.vstack([J, -J])

    if not np.all(np.isfinite(q_fixed)):
        nan = float("nan")
        return FamilyResult(tuple(family), nan, False, nan, False, x0, q_fixed, q_fixed, 0, "no IK solution")
    res = minimize(fun, x0, jac=jac, method="SLSQP",
                   constraints=[{"type": "ineq", "fun": cons, "jac": cons_jac}],
                   options={"maxiter": max_iterations, "ftol": 1e-9})
    x = wrap_pi(res.x)
    q_opt = prob.q_of(x)
    return FamilyResult(tuple(family), path_length_rad(q_fixed), feasible(q_fixed),
                        path_length_rad(q_opt) if np.all(np.isfinite(q_opt)) else float("nan"),
                        feasible(q_opt), x, q_opt, q_fixed, int(res.nit), str(res.message))


def optimise_arm_angles(robot: Robot, targets_flange_mm: np.ndarray, fixed=(), theta0_rad: float = np.pi / 4,
                        margin_rad: float = LIMIT_MARGIN_RAD, max_iterations: int = 200) -> ArmAngleResult:
    """Run every family on flange poses (base frame, mm); see module doc."""
    targets = np.asarray(targets_flange_mm, float)
    if targets.ndim != 3 or targets.shape[1:] != (4, 4) or len(targets) < 2:
        raise BadInput(f"arm-angle SQP needs at least 2 target poses, got an array of shape {targets.shape}")
    ik = SrsIK(robot, fixed)
    preps = []
    for k, T in enumerate(targets):
        try:
            preps.append(ik.prepare(T))
        except PlanInfeasible as exc:
            raise PlanInfeasible(f"target {k}: {exc}") from None
    stacked = ik.stack(preps)
    fams = tuple(optimise_family(ik, stacked, f, theta0_rad, margin_rad, max_iterations) for f in FAMILIES)
    cands = []
    for i, f in enumerate(fams):
        if f.opt_feasible:
            cands.append((f.opt_E_rad, i, "optimised"))
        if f.fixed_feasible:
            cands.append((f.fixed_E_rad, i, "fixed"))
    best, src = (min(cands)[1], min(cands)[2]) if cands else (-1, "")
    return ArmAngleResult(fams, best, src, float(theta0_rad))


def plan_arm_angle_sqp(path, robot: Robot, theta0_deg: float = 45.0, max_iterations: int = 200,
                       track_mm: float = 0.0) -> tuple[JointPath, ArmAngleResult]:
    """Plan a Path (world-frame TCP poses) with the arm-angle SQP; the best feasible family's JointPath.

    ``track_mm`` fixes the joints in front of the 7R arm (seed8's track).
    Raises PlanInfeasible (with the table in ``report``) if no family is feasible.
    """
    t0 = time.perf_counter()
    n_pre = robot.dof - 7
    fixed = np.full(max(n_pre, 0), float(track_mm))
    base_inv = np.linalg.inv(robot.base_T_mm)
    tool_inv = np.linalg.inv(robot.tool_T_mm)
    targets = np.array([base_inv @ T @ tool_inv for T in np.asarray(path.poses_mm)])
    res = optimise_arm_angles(robot, targets, fixed, np.radians(theta0_deg), max_iterations=max_iterations)
    if res.best < 0:
        raise PlanInfeasible("arm-angle SQP: no family keeps every target inside the joint limits",
                             report={"families": res.table()})
    q = np.hstack([np.tile(fixed, (len(targets), 1)), res.q_best])
    pos_err = np.empty(len(q))
    ori_err = np.empty(len(q))
    for k, (qk, T) in enumerate(zip(q, path.poses_mm)):
        Tk = robot.base_T_mm @ robot.fk_tcp(qk)
        pos_err[k] = np.linalg.norm(Tk[:3, 3] - T[:3, 3])
        ori_err[k] = rotation_angle_rad(Tk, T)
    n = len(q)
    false = np.zeros(n, bool)
    jp = JointPath(q=q, path_index=np.arange(n), zone=np.asarray(path.zone).copy(),
                   position_error_mm=pos_err, orientation_error_rad=ori_err, jump=false.copy(),
                   reverse_planned=false.copy(), retract=false.copy(), singular=false.copy(),
                   reached=(pos_err < 1e-6) & (ori_err < 1e-9),
                   events={"plan_seconds": time.perf_counter() - t0,
                           "arm_angle_sqp": {"best_family": list(res.families[res.best].family),
                                             "best_source": res.best_source,
                                             "families": res.table()}})
    return jp, res
