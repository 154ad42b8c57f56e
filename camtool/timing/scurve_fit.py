"""Compiled S-curve fit test (numba): does a jerk-limited speed change keep every joint within its limits?

Why by hand: the time law tries ~65 (A, J) candidates per S-curve and refines
the best by bisection; thousands of S-curves per job. The same test in numpy
(``pathlaw._Budget.fits``'s reference, kept in ``fits_numpy``) builds
(candidates x instants x joints) temporaries and costs ~0.4 ms per call, most
of it per-call overhead. This loop does the same arithmetic in the same order
(cubes as products: the answers agree with numpy's except within an ulp of a
limit), stops at a candidate's first instant that breaks a limit, and can stop
at the first candidate that fits (candidates sorted by S-curve length).
"""
from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, fastmath=False)
def _fits(v0, v1, A, J, s_start, frac, s_knots, p1, p2, p3, a_lim, j_lim, v_lim_tol, out, first_only):
    dv = abs(v1 - v0)
    sign = 1.0 if v1 > v0 else -1.0
    n_pieces, dof = p1.shape
    n_inst = len(frac) + 2
    for c in range(len(A)):
        Jc, Ac = J[c], A[c]
        short = dv * Jc <= Ac * Ac
        if short:
            tj = np.sqrt(dv / Jc)
            ta = 0.0
        else:
            tj = Ac / Jc
            ta = dv / Ac - tj
        T = 2 * tj + ta
        a1 = Jc * tj
        half_jtt = Jc * tj * tj / 2
        ok = True
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
            x = s_start[c] + pos
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
                    ok = False
                    break
            if not ok:
                break
        out[c] = ok
        if ok and first_only:
            return c
    return -1


def fits_compiled(v0: float, v1: float, A: np.ndarray, J: np.ndarray, s_start: np.ndarray, frac: np.ndarray,
                  s_knots: np.ndarray, p1: np.ndarray, p2: np.ndarray, p3: np.ndarray, a_lim: np.ndarray,
                  j_lim: np.ndarray, v_lim_tol: np.ndarray) -> np.ndarray:
    """Per candidate c: True if the S-curve v0 -> v1 with (A[c], J[c]) starting at s_start[c] fits.

    ``frac``: the instants as shares of the S-curve's duration (the phase ends are added);
    ``s_knots`` the spline's knots, ``p1..p3`` (pieces, dof) the piece maxima of |q'|, |q''|, |q'''|;
    ``v_lim_tol`` the speed limit with its tolerance."""
    out = np.empty(len(A), np.bool_)
    _fits(float(v0), float(v1), A, J, s_start, frac, s_knots, p1, p2, p3, a_lim, j_lim, v_lim_tol, out, False)
    return out


def first_fit_compiled(v0: float, v1: float, A: np.ndarray, J: np.ndarray, s_start: np.ndarray, frac: np.ndarray,
                       s_knots: np.ndarray, p1: np.ndarray, p2: np.ndarray, p3: np.ndarray, a_lim: np.ndarray,
                       j_lim: np.ndarray, v_lim_tol: np.ndarray) -> int:
    """The first candidate (in the given order) that ``fits_compiled`` would accept, or -1: the
    candidates after it are not tested."""
    out = np.empty(len(A), np.bool_)
    return int(_fits(float(v0), float(v1), A, J, s_start, frac, s_knots, p1, p2, p3, a_lim, j_lim, v_lim_tol,
                     out, True))
