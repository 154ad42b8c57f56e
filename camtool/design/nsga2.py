"""NSGA-II (pymoo, the optional ``design`` extra) on the same arm-design problem.

Same evaluation function as MOPSO; an invalid design (unreachable points) is
a constraint violation G = unreachable > 0. Designs are rounded to the same
resolution by a pymoo Repair, and the run stops after ``budget`` evaluations
so both fronts can be compared at equal cost.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..errors import BadInput
from .pareto import nondominated_mask


def pymoo_available() -> bool:
    """True when pymoo can be imported."""
    try:
        import pymoo  # noqa: F401
    except ImportError:
        return False
    return True


def _require_pymoo():
    if not pymoo_available():
        raise BadInput("--method nsga2 needs pymoo: pip install 'camtool[design]'")


@dataclass
class Nsga2Result:
    """Every evaluation and the feasible non-dominated front."""

    X: np.ndarray
    F: np.ndarray
    violation: np.ndarray
    front_X: np.ndarray
    front_F: np.ndarray
    evaluations: int


def run_nsga2(evaluate: Callable, lower, upper, budget: int, pop_size: int, seed: int = 0,
              resolution=None) -> Nsga2Result:
    """Run pymoo's NSGA-II for ``budget`` evaluations of ``evaluate(X) -> (F, violation)``."""
    _require_pymoo()
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.core.problem import Problem
    from pymoo.core.repair import Repair
    from pymoo.optimize import minimize

    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    res = None if resolution is None else np.broadcast_to(np.asarray(resolution, float), lower.shape)
    log = {"X": [], "F": [], "v": []}

    class Snap(Repair):
        def _do(self, problem, X, **kwargs):
            if res is None:
                return X
            return np.clip(np.round(X / res) * res, lower, upper)

    class ArmProblem(Problem):
        def __init__(self):
            super().__init__(n_var=len(lower), n_obj=2, n_ieq_constr=1, xl=lower, xu=upper)

        def _evaluate(self, X, out, *args, **kwargs):
            X = np.asarray(X, float)
            F, v = evaluate(X)
            log["X"].extend(X); log["F"].extend(F); log["v"].extend(v)
            out["F"] = np.asarray(F, float)
            out["G"] = np.asarray(v, float).reshape(-1, 1)

    algorithm = NSGA2(pop_size=pop_size, repair=Snap(), eliminate_duplicates=True)
    minimize(ArmProblem(), algorithm, ("n_eval", budget), seed=int(seed), verbose=False)
    X = np.array(log["X"]).reshape(-1, len(lower))
    F = np.array(log["F"]).reshape(-1, 2)
    v = np.array(log["v"])
    ok = v == 0
    fx, ff = X[ok], F[ok]
    if len(ff):
        keep = nondominated_mask(ff)
        fx, ff = fx[keep], ff[keep]
        _, first = np.unique(fx, axis=0, return_index=True)
        fx, ff = fx[np.sort(first)], ff[np.sort(first)]
        order = np.lexsort(tuple(np.column_stack([ff, fx]).T[::-1]))
        fx, ff = fx[order], ff[order]
    return Nsga2Result(X, F, v, fx, ff, len(F))


def hypervolume(F, reference) -> float:
    """Hypervolume (pymoo) of the front F (minimised) against a fixed reference point."""
    _require_pymoo()
    from pymoo.indicators.hv import HV

    F = np.asarray(F, float).reshape(-1, len(reference))
    if len(F) == 0:
        return 0.0
    return float(HV(ref_point=np.asarray(reference, float))(F))
