"""The compiled S-curve fit test (timing/scurve_fit.py) gives numpy's answers, and the first fit is the argmin."""
import numpy as np

from camtool.robots import get_robot
from camtool.timing.pathlaw import A_GRID, J_GRID, PathSpline, _Budget


def _cases(n_cases=60, seed=0):
    rng = np.random.default_rng(seed)
    limits = get_robot("seed8").limits
    for trial in range(n_cases):
        n = int(rng.integers(2, 25))
        q = np.cumsum(rng.normal(0, 0.05, (n, 8)), axis=0)
        s = np.r_[0, np.cumsum(rng.uniform(0.5, 3, n - 1))]
        budget = _Budget(PathSpline(s, q), limits)
        v0, v1 = rng.uniform(0, 3, 2)
        AA, JJ = np.meshgrid(budget.a_ref * A_GRID, budget.j_ref * J_GRID, indexing="ij")
        yield budget, float(v0), float(v1), AA.ravel(), JJ.ravel(), rng.uniform(s[0], s[-1], AA.size)


def test_compiled_fits_agree_with_numpy():
    answers = []
    for budget, v0, v1, A, J, start in _cases():
        got = budget.fits(v0, v1, A, J, start)
        assert np.array_equal(got, budget.fits_numpy(v0, v1, A, J, start))
        answers.append(got)
    share = np.concatenate(answers).mean()
    assert 0.05 < share < 0.95  # both answers occur


def test_first_fit_in_length_order_is_the_shortest_fitting_candidate():
    for budget, v0, v1, A, J, start in _cases(seed=1):
        length = np.where(abs(v1 - v0) * J <= A * A, 2 * np.sqrt(abs(v1 - v0) / J),
                          abs(v1 - v0) / A + A / J)
        ok = budget.fits_numpy(v0, v1, A, J, start)
        order = np.argsort(length, kind="stable")
        c = budget.first_fit(v0, v1, A[order], J[order], start[order])
        if not ok.any():
            assert c == -1
        else:
            assert order[c] == int(np.argmin(np.where(ok, length, np.inf)))
