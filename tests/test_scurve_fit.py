"""The compiled S-curve fit test (timing/scurve_fit.py) gives numpy's answers, and the first fit is the argmin."""
import numpy as np

from camtool.robots import get_robot
from camtool.timing.pathlaw import A_GRID, J_GRID, REFINE_STEPS, PathSpline, _Budget


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


def _search_numpy(budget, v0, v1, s_edge, before):
    """The search as it was written in numpy (the reference): the grid, the shortest fit, the bisection."""
    dv, vbar = abs(v1 - v0), 0.5 * (v0 + v1)

    def dist(A, J):
        A, J = np.asarray(A, float), np.asarray(J, float)
        return vbar * np.where(dv * J <= A * A, 2 * np.sqrt(dv / J), dv / A + A / J)

    def start(A, J):
        return (s_edge - dist(A, J)) if before else np.full(np.shape(A), s_edge)

    AA, JJ = np.meshgrid(budget.a_ref * A_GRID, budget.j_ref * J_GRID, indexing="ij")
    AA, JJ = AA.ravel(), JJ.ravel()
    ok = budget.fits_numpy(v0, v1, AA, JJ, start(AA, JJ))
    if not ok.any():
        return False, 0.0, 0.0
    c = int(np.argmin(np.where(ok, dist(AA, JJ), np.inf)))
    A, J = float(AA[c]), float(JJ[c])
    for which in ("J", "A"):
        lo = A if which == "A" else J
        hi = lo * (4.0 if which == "A" else 2.0)
        for _ in range(REFINE_STEPS):
            mid = 0.5 * (lo + hi)
            a_, j_ = (mid, J) if which == "A" else (A, mid)
            if dist(a_, j_) < dist(A, J) and budget.fits_numpy(v0, v1, [a_], [j_], start([a_], [j_]))[0]:
                lo, A, J = mid, a_, j_
            else:
                hi = mid
    return True, A, J


def test_compiled_search_finds_what_the_numpy_search_finds():
    found = 0
    for k, (budget, v0, v1, _, _, start) in enumerate(_cases(seed=1)):
        before = bool(k % 2)
        edge = float(start[0])
        want = _search_numpy(budget, v0, v1, edge, before)
        got = budget.search(v0, v1, edge, before, budget.a_ref * A_GRID, budget.j_ref * J_GRID, REFINE_STEPS)
        assert got == want
        found += want[0]
        if k < 5:  # far above every speed limit: nothing fits
            none = budget.search(v0, 1e6, edge, before, budget.a_ref * A_GRID, budget.j_ref * J_GRID, REFINE_STEPS)
            assert none == _search_numpy(budget, v0, 1e6, edge, before) == (False, 0.0, 0.0)
    assert found > 0
