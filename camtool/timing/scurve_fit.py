"""Compiled S-curve fit test (numba): does a jerk-limited speed change keep every joint within its limits?

Why by hand: the time law tries ~65 (A, J) candidates per S-curve and refines
the best by bisection; thousands of S-curves per job. The same test in numpy
(``pathlaw._Budget.fits``'s reference, kept in ``fits_numpy``) builds
(candidates x instants x joints) temporaries and costs ~0.4 ms per call, most
of it per-call overhead. This loop does the same arithmetic in the same order
(cubes as products: the answers agree with numpy's except within an ulp of a
limit), stops at a candidate's first instant that breaks a limit; ``search_compiled``
runs ``_scurve_at``'s whole search (grid shortest first up to the first fit,
then the bisection) in one call.
"""
from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, fastmath=False)
def _fits_one(v0, v1, Ac, Jc, s0, frac, s_knots, p1, p2, p3, a_lim, j_lim, v_lim_tol):
    """One candidate (A, J, start s0) of the S-curve v0 -> v1: True if every instant keeps every joint within."""
    dv = abs(v1 - v0)
    sign = 1.0 if v1 > v0 else -1.0
    n_pieces, dof = p1.shape
    n_inst = len(frac) + 2
    if dv * Jc <= Ac * Ac:
        tj = np.sqrt(dv / Jc)
        ta = 0.0
    else:
        tj = Ac / Jc
        ta = dv / Ac - tj
    T = 2 * tj + ta
    a1 = Jc * tj
    half_jtt = Jc * tj * tj / 2
    for m in range(n_inst):
        if m < len(frac):
            u = frac[m] * T
        elif m == len(frac):
            u = tj
        else:
            u = tj + ta
        t1 = min(u, tj)
        t2 = min(max(u - tj, 0.0), ta)
        t3 = min(max(u - (tj + ta), 0.0), tj)
        acc = Jc * t1 - Jc * t3
        vel = v0 + sign * (Jc * t1 * t1 / 2 + a1 * t2 + a1 * t3 - Jc * t3 * t3 / 2)
        pos = v0 * u + sign * (Jc * (t1 * t1 * t1) / 6 + half_jtt * t2 + a1 * t2 * t2 / 2
                               + (half_jtt + a1 * ta) * t3 + a1 * t3 * t3 / 2 - Jc * (t3 * t3 * t3) / 6)
        x = s0 + pos
        k = np.searchsorted(s_knots, x, side="right") - 1
        k = min(max(k, 0), n_pieces - 1)
        v = max(vel, 0.0)
        a = abs(acc)
        v3 = v * v * v
        for i in range(dof):
            q1, q2, q3 = p1[k, i], p2[k, i], p3[k, i]
            if not (q2 * v * v + q1 * a <= a_lim[i]
                    and q3 * v3 + 3 * q2 * v * a + q1 * Jc <= j_lim[i]
                    and q1 * v <= v_lim_tol[i]):
                return False
    return True


@nb.njit(cache=True, fastmath=False)
def _fits(v0, v1, A, J, s_start, frac, s_knots, p1, p2, p3, a_lim, j_lim, v_lim_tol, out):
    for c in range(len(A)):
        out[c] = _fits_one(v0, v1, A[c], J[c], s_start[c], frac, s_knots, p1, p2, p3, a_lim, j_lim, v_lim_tol)
    return out


@nb.njit(cache=True, fastmath=False)
def _dist(dv, vbar, A, J):
    if dv * J <= A * A:
        return vbar * (2 * np.sqrt(dv / J))
    return vbar * (dv / A + A / J)


@nb.njit(cache=True, fastmath=False)
def _search(v0, v1, s_edge, before, a_grid, j_grid, refine_steps, frac, s_knots, p1, p2, p3, a_lim, j_lim,
            v_lim_tol):
    dv, vbar = abs(v1 - v0), 0.5 * (v0 + v1)
    na, nj = len(a_grid), len(j_grid)
    AA = np.empty(na * nj)
    JJ = np.empty(na * nj)
    D = np.empty(na * nj)
    for i in range(na):          # row-major: as np.meshgrid(a_grid, j_grid, indexing="ij").ravel()
        for j in range(nj):
            AA[i * nj + j] = a_grid[i]
            JJ[i * nj + j] = j_grid[j]
            D[i * nj + j] = _dist(dv, vbar, a_grid[i], j_grid[j])
    order = np.argsort(D, kind="mergesort")   # stable: ties keep the grid order
    found = False
    A = 0.0
    J = 0.0
    for c in order:
        s0 = s_edge - D[c] if before else s_edge
        if _fits_one(v0, v1, AA[c], JJ[c], s0, frac, s_knots, p1, p2, p3, a_lim, j_lim, v_lim_tol):
            found = True
            A, J = AA[c], JJ[c]
            break
    if not found:
        return False, 0.0, 0.0
    for which in range(2):       # bisection upwards on J (grid factor 2), then on A (factor 4)
        lo = A if which == 1 else J
        hi = lo * (4.0 if which == 1 else 2.0)
        for _ in range(refine_steps):
            mid = 0.5 * (lo + hi)
            if which == 1:
                a_, j_ = mid, J
            else:
                a_, j_ = A, mid
            d_ = _dist(dv, vbar, a_, j_)
            s0 = s_edge - d_ if before else s_edge
            if d_ < _dist(dv, vbar, A, J) and _fits_one(v0, v1, a_, j_, s0, frac, s_knots, p1, p2, p3, a_lim,
                                                        j_lim, v_lim_tol):
                lo = mid
                A, J = a_, j_
            else:
                hi = mid
    return True, A, J


def search_compiled(v0: float, v1: float, s_edge: float, before: bool, a_grid: np.ndarray, j_grid: np.ndarray,
                    refine_steps: int, frac: np.ndarray, s_knots, p1, p2, p3, a_lim, j_lim, v_lim_tol):
    """(found, A, J): the shortest S-curve v0 -> v1 on the grid ``a_grid`` x ``j_grid`` (path values) that
    fits, refined by ``refine_steps`` bisection steps upwards on J, then A (``pathlaw._scurve_at``).
    ``before``: it ends at ``s_edge`` (decelerating into it), else it starts there."""
    found, A, J = _search(float(v0), float(v1), float(s_edge), bool(before), a_grid, j_grid, int(refine_steps),
                          frac, s_knots, p1, p2, p3, a_lim, j_lim, v_lim_tol)
    return bool(found), float(A), float(J)


def fits_compiled(v0: float, v1: float, A: np.ndarray, J: np.ndarray, s_start: np.ndarray, frac: np.ndarray,
                  s_knots: np.ndarray, p1: np.ndarray, p2: np.ndarray, p3: np.ndarray, a_lim: np.ndarray,
                  j_lim: np.ndarray, v_lim_tol: np.ndarray) -> np.ndarray:
    """Per candidate c: True if the S-curve v0 -> v1 with (A[c], J[c]) starting at s_start[c] fits.

    ``frac``: the instants as shares of the S-curve's duration (the phase ends are added);
    ``s_knots`` the spline's knots, ``p1..p3`` (pieces, dof) the piece maxima of |q'|, |q''|, |q'''|;
    ``v_lim_tol`` the speed limit with its tolerance."""
    out = np.empty(len(A), np.bool_)
    return _fits(float(v0), float(v1), A, J, s_start, frac, s_knots, p1, p2, p3, a_lim, j_lim, v_lim_tol, out)
