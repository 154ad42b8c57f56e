"""RANSAC plane, sphere and cylinder fitting, least-squares refinement, model choice and boundary.

The RANSAC is written here in vectorised numpy rather than taken from a
library: open3d's ``segment_plane`` has no sphere model and its result depends
on thread scheduling (not seeded-deterministic), and pyransac3d scores one
hypothesis at a time on every point (slow, see benchmarks/fit_speed.py). Here
all minimal-sample hypotheses are built at once, scored in batches on a random
subsample, the best few are rescored (MSAC cost) on all points, and the winner
is refined by least squares on its inliers:

- plane: total least squares (SVD of the centred inliers);
- sphere: Gauss-Newton on the geometric residual |p - c| - R;
- cylinder: hypotheses from two points with their normals (the axis is
  n1 x n2, the centre where the two normal lines meet across it), refined by
  scipy's ``least_squares`` on the distance to the axis minus R.

Every random draw comes from ``numpy.random.default_rng([seed, model])``:
the same seed gives the same surface, and ``auto`` fits each model exactly as
an explicit ``plane``, ``sphere`` or ``cylinder`` would. ``auto`` chooses between
plane and sphere as it always did; a cylinder replaces that choice only when it
holds ``CYLINDER_MARGIN`` more inliers (a sphere patch or a plane is never
taken for a cylinder).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .boundary import boundary_from_uv
from ..errors import BadInput
from ..settings import FitSettings
from .surface import Cylinder, FitStats, PlaneSurface, SpherePatch

MIN_POINTS = {"plane": 3, "sphere": 4, "cylinder": 5}
MODEL_STREAM = {"plane": 0, "sphere": 1, "cylinder": 2}  # rng stream of each model: default_rng([seed, stream])
CYLINDER_MARGIN = 0.05    # a cylinder replaces auto's plane / sphere only with 5 % more inliers
CYLINDER_NORMAL_DEG = 30.0  # cylinder RANSAC: a point's normal within this of the radial direction counts
MIN_SURFACE_POINTS = 100  # fewer points than this describe no part's surface (a 20-point grid, a 3-point cloud)
SUBSAMPLE = 1000          # points used to score every hypothesis (rank only; top K rescored on all)
TOP_K = 16                # hypotheses rescored on all points
BATCH = 256               # hypotheses scored per numpy batch
LARGE_SPHERE_FACTOR = 10.0  # a sphere wider than this many cloud extents is a plane
PLANE_MARGIN = 0.02       # plane wins if its inliers are within 2 % of the sphere's


@dataclass(frozen=True)
class ModelFit:
    """A refined model in world mm: params (plane: n, d; sphere: c, R) and inlier mask."""

    model: str
    params: tuple
    inliers: np.ndarray
    residuals_mm: np.ndarray  # absolute residual of every point

    @property
    def n_inliers(self) -> int:
        return int(self.inliers.sum())


def _plane_hypotheses(P: np.ndarray, idx: np.ndarray):
    a, b, c = P[idx[:, 0]], P[idx[:, 1]], P[idx[:, 2]]
    n = np.cross(b - a, c - a)
    norm = np.linalg.norm(n, axis=1)
    scale = np.linalg.norm(b - a, axis=1) * np.linalg.norm(c - a, axis=1)
    ok = norm > 1e-6 * np.maximum(scale, 1e-300)
    n = n[ok] / norm[ok, None]
    return n, np.einsum("ij,ij->i", n, a[ok])


def _plane_residuals(P: np.ndarray, n: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(len(P), H) absolute distances to H planes."""
    return np.abs(P @ n.T - d)


def _sphere_hypotheses(P: np.ndarray, idx: np.ndarray, max_radius: float):
    """Spheres through 4 points: 2 (p_i - p_0) . c' = |p_i - p_0|^2, batched 3x3 solves."""
    p0 = P[idx[:, 0]]
    A = P[idx[:, 1:]] - p0[:, None, :]
    b = 0.5 * np.einsum("hij,hij->hi", A, A)
    det = np.linalg.det(A)
    scale = np.prod(np.linalg.norm(A, axis=2), axis=1)
    ok = np.abs(det) > 1e-6 * np.maximum(scale, 1e-300)
    A[~ok] = np.eye(3)
    cprime = np.linalg.solve(A, b[..., None])[..., 0]
    r = np.linalg.norm(cprime, axis=1)
    ok &= np.isfinite(r) & (r < max_radius)
    return cprime[ok] + p0[ok], r[ok]


def _sphere_residuals(P: np.ndarray, P2: np.ndarray, c: np.ndarray, r: np.ndarray) -> np.ndarray:
    """(len(P), H) absolute distances to H spheres; P2 = |P|^2 (rows)."""
    d2 = P2[:, None] - 2.0 * (P @ c.T) + np.einsum("ij,ij->i", c, c)
    return np.abs(np.sqrt(np.maximum(d2, 0.0)) - r)


def _orthonormal(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing unit ``a`` (3,) to a right-handed frame (e1, e2, a)."""
    helper = np.eye(3)[int(np.argmin(np.abs(a)))]
    e1 = np.cross(helper, a)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(a, e1)


def cylinder_hypotheses(P: np.ndarray, N: np.ndarray, i: np.ndarray, j: np.ndarray, max_radius: float,
                        tol_mm: float):
    """Cylinders through point pairs with normals: (axis points c, unit axes a, radii r) of the good pairs.

    The axis is n_i x n_j; across it the normal lines p + t n meet at the axis.
    A pair whose normals are within ~3 deg of parallel, or whose two radii
    differ by more than ``tol_mm``, gives no hypothesis.
    """
    ni, nj = N[i], N[j]
    a = np.cross(ni, nj)
    s = np.linalg.norm(a, axis=1)
    ok = s > 0.05
    a = a[ok] / s[ok, None]
    pi, pj, ni, nj = P[i][ok], P[j][ok], ni[ok], nj[ok]
    # in the plane across a: pi + t ni = pj + u nj (normals made exactly perpendicular to a)
    ni = ni - np.einsum("ij,ij->i", ni, a)[:, None] * a
    nj = nj - np.einsum("ij,ij->i", nj, a)[:, None] * a
    d = pj - pi
    d = d - np.einsum("ij,ij->i", d, a)[:, None] * a
    A11, A12, A22 = (np.einsum("ij,ij->i", ni, ni), -np.einsum("ij,ij->i", ni, nj), np.einsum("ij,ij->i", nj, nj))
    b1, b2 = np.einsum("ij,ij->i", ni, d), -np.einsum("ij,ij->i", nj, d)
    det = A11 * A22 - A12 * A12
    good = np.abs(det) > 1e-9
    det = np.where(good, det, 1.0)
    t = (A22 * b1 - A12 * b2) / det
    u = (A11 * b2 - A12 * b1) / det
    c = pi + t[:, None] * ni
    ri = np.abs(t) * np.linalg.norm(ni, axis=1)
    rj = np.abs(u) * np.linalg.norm(nj, axis=1)
    good &= (np.abs(ri - rj) < tol_mm) & (ri < max_radius) & (ri > 1e-3)
    return c[good], a[good], 0.5 * (ri + rj)[good]


def cylinder_residuals(P: np.ndarray, c: np.ndarray, a: np.ndarray, r: np.ndarray) -> np.ndarray:
    """(len(P), H) absolute distances of points to H cylinders (axis point c, unit axis a, radius r)."""
    d2 = (np.einsum("ij,ij->i", P, P)[:, None] - 2.0 * (P @ c.T) + np.einsum("ij,ij->i", c, c)[None, :])
    along = P @ a.T - np.einsum("ij,ij->i", c, a)[None, :]
    return np.abs(np.sqrt(np.maximum(d2 - along ** 2, 0.0)) - r[None, :])


def cylinder_radial(P: np.ndarray, c: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Unit radial directions (N x 3) of points from the axis through c along unit a."""
    d = P - c
    d = d - (d @ a)[:, None] * a
    return d / np.maximum(np.linalg.norm(d, axis=1), 1e-12)[:, None]


def refine_cylinder(P: np.ndarray, c: np.ndarray, a: np.ndarray, r: float, thr: float, rounds: int = 2,
                    max_points: int = 20000):
    """Least-squares cylinder (scipy ``least_squares``) on the points within ``thr`` of it; (c, a, r).

    At most ``max_points`` inliers (evenly strided, deterministic) enter each round.
    """
    from scipy.optimize import least_squares

    for _ in range(rounds):
        inl = cylinder_residuals(P, c[None], a[None], np.array([r]))[:, 0] < thr
        if inl.sum() < MIN_POINTS["cylinder"]:
            break
        Q = P[inl]
        if len(Q) > max_points:
            Q = Q[np.linspace(0, len(Q) - 1, max_points).astype(int)]
        e1, e2 = _orthonormal(a)

        def unpack(x, a=a, c=c, e1=e1, e2=e2):
            ax = a + x[0] * e1 + x[1] * e2
            return c + x[2] * e1 + x[3] * e2, ax / np.linalg.norm(ax), x[4]

        def f(x):
            cc, aa, rr = unpack(x)
            d = Q - cc
            return np.sqrt(np.maximum(np.einsum("ij,ij->i", d, d) - (d @ aa) ** 2, 0.0)) - rr

        sol = least_squares(f, np.array([0.0, 0.0, 0.0, 0.0, r]), method="lm", xtol=1e-12, ftol=1e-12)
        c_new, a_new, r_new = unpack(sol.x)
        if not (np.isfinite(r_new) and np.isfinite(c_new).all() and np.isfinite(a_new).all()) or r_new <= 0:
            break
        c, a, r = c_new, a_new, float(r_new)
    # the axis point nearest the origin of the (centred) data keeps c well defined along the axis
    c = c - (c @ a) * a
    if a[np.argmax(np.abs(a))] < 0:
        a = -a
    return c, a, float(r)


def _cylinder_ransac(P: np.ndarray, N: np.ndarray, iterations: int, thr: float, rng: np.random.Generator,
                     extent: float):
    """Best cylinder (c, a, r) by subsample inlier count (distance and normal), then full-data MSAC cost."""
    n_pts = len(P)
    idx = rng.integers(0, n_pts, size=(iterations, 2))
    hyp = cylinder_hypotheses(P, N, idx[:, 0], idx[:, 1], 1e3 * extent, 4.0 * thr)
    if len(hyp[0]) == 0:
        return None
    pick = rng.choice(n_pts, SUBSAMPLE, replace=False) if n_pts > SUBSAMPLE else np.arange(n_pts)
    sub, nsub = P[pick], N[pick]
    cos_tol = np.cos(np.radians(CYLINDER_NORMAL_DEG))
    counts = []
    for s in range(0, len(hyp[0]), BATCH):
        c, a, r = (h[s:s + BATCH] for h in hyp)
        res = cylinder_residuals(sub, c, a, r)
        # radial of every point to every axis: the normal must agree (either sign)
        d = sub[:, None, :] - c[None, :, :]
        d = d - np.einsum("ijk,jk->ij", d, a)[..., None] * a[None]
        cosn = np.abs(np.einsum("ijk,ik->ij", d, nsub)) / np.maximum(np.linalg.norm(d, axis=2), 1e-12)
        counts.append(((res < thr) & (cosn > cos_tol)).sum(axis=0))
    counts = np.concatenate(counts)
    top = np.argsort(-counts, kind="stable")[:TOP_K]
    cost = [float((np.minimum(cylinder_residuals(P, hyp[0][k:k + 1], hyp[1][k:k + 1], hyp[2][k:k + 1])[:, 0],
                              thr) ** 2).sum()) for k in top]
    best = int(top[int(np.argmin(cost))])
    return tuple(h[best] for h in hyp)


def _ransac(P: np.ndarray, model: str, iterations: int, thr: float, rng: np.random.Generator,
            extent: float):
    """Best hypothesis (params) by subsample inlier count, then full-data MSAC cost."""
    n_pts = len(P)
    idx = rng.integers(0, n_pts, size=(iterations, MIN_POINTS[model]))
    sub = P[rng.choice(n_pts, SUBSAMPLE, replace=False)] if n_pts > SUBSAMPLE else P
    if model == "plane":
        hyp = _plane_hypotheses(P, idx)
        resid = lambda Q, s, e: _plane_residuals(Q, hyp[0][s:e], hyp[1][s:e])  # noqa: E731
    else:
        hyp = _sphere_hypotheses(P, idx, 1e3 * extent)
        sub2, all2 = np.einsum("ij,ij->i", sub, sub), np.einsum("ij,ij->i", P, P)
        resid = lambda Q, s, e: _sphere_residuals(  # noqa: E731
            Q, sub2 if Q is sub else all2, hyp[0][s:e], hyp[1][s:e])
    n_hyp = len(hyp[0])
    if n_hyp == 0:
        return None
    counts = np.concatenate([(resid(sub, s, min(s + BATCH, n_hyp)) < thr).sum(axis=0)
                             for s in range(0, n_hyp, BATCH)])
    top = np.argsort(-counts, kind="stable")[:TOP_K]
    cost = [float((np.minimum(resid(P, i, i + 1)[:, 0], thr) ** 2).sum()) for i in top]
    best = int(top[int(np.argmin(cost))])
    return tuple(h[best] for h in hyp)


def _refine_plane(P, n, d, thr, rounds=3):
    for _ in range(rounds):
        inl = np.abs(P @ n - d) < thr
        if inl.sum() < 3:
            break
        Q = P[inl]
        mean = Q.mean(axis=0)
        D = Q - mean
        _, vecs = np.linalg.eigh(D.T @ D)  # 3x3 scatter: smallest eigenvector is the normal
        n_new = vecs[:, 0] if vecs[:, 0] @ n >= 0 else -vecs[:, 0]
        n, d = n_new, float(n_new @ mean)
    return n, d


def _refine_sphere(P, c, r, thr, rounds=3, steps=6):
    for _ in range(rounds):
        inl = np.abs(np.linalg.norm(P - c, axis=1) - r) < thr
        if inl.sum() < 4:
            break
        Q = P[inl]
        for _ in range(steps):  # Gauss-Newton on f_i = |q_i - c| - r
            diff = Q - c
            dist = np.linalg.norm(diff, axis=1)
            J = np.hstack([-diff / np.maximum(dist, 1e-300)[:, None], -np.ones((len(Q), 1))])
            f = dist - r
            A, g = J.T @ J, -J.T @ f
            # a huge sphere (flat data, a car hood) walks its centre off towards infinity: its normal equations
            # overflow before r does, and LAPACK, handed inf or NaN, prints "illegal value" on stderr; such a
            # step is never taken (the sphere so far stays, and a plane wins over it)
            if not (np.isfinite(A).all() and np.isfinite(g).all()):
                break
            # lstsq on the 4x4 normal equations: a huge sphere (flat data) is near singular
            step = np.linalg.lstsq(A, g, rcond=None)[0]
            if not np.isfinite(step).all() or not np.isfinite(r + step[3]) or not np.isfinite(c + step[:3]).all():
                break
            c, r = c + step[:3], r + step[3]
            if np.abs(step).max() < 1e-9:
                break
    return c, float(r)


def fit_model(points_mm: np.ndarray, model: str, threshold_mm: float = 0.5, iterations: int = 1000,
              seed: int = 0, source: str = "points", normals: np.ndarray | None = None) -> ModelFit | None:
    """RANSAC + least-squares fit of one model ('plane', 'sphere' or 'cylinder') to points (mm).

    A cylinder needs the points' ``normals``. Returns None when the data cannot
    hold the model (degenerate samples only). Cylinder params: (axis point,
    unit axis, R).
    """
    P_world = np.asarray(points_mm, dtype=float)
    centroid = P_world.mean(axis=0)
    P = P_world - centroid  # centred: keeps |p|^2 expansions well conditioned
    extent = float(np.linalg.norm(P.max(axis=0) - P.min(axis=0)))
    rng = np.random.default_rng([seed, MODEL_STREAM[model]])
    if model == "cylinder":
        N = np.asarray(normals, dtype=float)
        best = _cylinder_ransac(P, N, iterations, threshold_mm, rng, extent)
        if best is None:
            return None
        c, a, r = refine_cylinder(P, best[0], best[1], float(best[2]), threshold_mm)
        res = cylinder_residuals(P, c[None], a[None], np.array([r]))[:, 0]
        c_world = c + centroid
        return ModelFit(model, (c_world - (c_world @ a) * a, a, r), res < threshold_mm, res)
    best = _ransac(P, model, iterations, threshold_mm, rng, extent)
    if best is None:
        return None
    if model == "plane":
        n, d = _refine_plane(P, best[0], float(best[1]), threshold_mm)
        res = np.abs(P @ n - d)
        params = (n, d + float(n @ centroid))
    else:
        c, r = _refine_sphere(P, best[0], float(best[1]), threshold_mm)
        if not (np.isfinite(r) and np.isfinite(c).all()):
            return None
        res = np.abs(np.linalg.norm(P - c, axis=1) - r)
        params = (c + centroid, r)
    return ModelFit(model, params, res < threshold_mm, res)


def _shape_check(P: np.ndarray, model: str, source: str) -> bool:
    """Raise on too few / coincident / collinear points; False when too flat for a sphere."""
    need = MIN_POINTS["plane" if model == "auto" else model]
    if len(P) < need:
        raise BadInput(f"{source}: {len(P)} points, but a {'plane' if model == 'auto' else model} "
                       f"needs at least {need}; give a denser scan or mesh")
    D = P - P.mean(axis=0)
    s = np.sqrt(np.maximum(np.linalg.eigvalsh(D.T @ D)[::-1], 0.0))  # singular values
    if s[0] == 0:
        raise BadInput(f"{source}: all points coincide; the file holds no surface")
    if s[1] < 1e-6 * s[0]:
        raise BadInput(f"{source}: the points lie on a line, so no plane or sphere is defined; "
                       "check the scan or mesh")
    return s[2] >= 1e-6 * s[0] and len(P) >= MIN_POINTS["sphere"]


def _choose(plane: ModelFit | None, sphere: ModelFit | None, extent: float) -> ModelFit:
    """Most inliers wins, but a plane wins whenever it explains the data about as well."""
    if sphere is None:
        return plane
    if plane is None:
        return sphere
    if sphere.params[1] > LARGE_SPHERE_FACTOR * extent:
        return plane
    if plane.n_inliers >= (1.0 - PLANE_MARGIN) * sphere.n_inliers:
        return plane
    return sphere


def fit_surface(workpiece, settings: FitSettings) -> PlaneSurface | SpherePatch:
    """Fit a plane or sphere patch (world mm) to a Workpiece, with its (u, v) boundary.

    ``settings.model`` is 'plane', 'sphere', 'cylinder', 'auto' or 'freeform' (a ``FreeformSurface``). Raises BadInput when the
    points are degenerate or no model reaches ``settings.min_inlier_ratio``.
    """
    model, threshold_mm, min_inlier_ratio = settings.model, settings.threshold_mm, settings.min_inlier_ratio
    if model == "freeform":  # the whole workpiece as one free-form face (docs/freeform.md)
        from .freeform import freeform_surface

        return freeform_surface(workpiece, settings)
    P = np.asarray(workpiece.points_mm, dtype=float)
    source = getattr(workpiece, "source", "") or "workpiece"
    sphere_ok = _shape_check(P, model, source)
    if model == "sphere" and not sphere_ok:
        raise BadInput(f"{source}: the points lie in a plane (or are too few), so no sphere is defined; "
                       "use fit.model = \"plane\"")
    if model == "cylinder" and not sphere_ok:
        raise BadInput(f"{source}: the points lie in a plane (or are too few), so no cylinder is defined; "
                       "use fit.model = \"plane\"")
    extent = float(np.linalg.norm(P.max(axis=0) - P.min(axis=0)))
    kw = dict(threshold_mm=threshold_mm, iterations=settings.iterations, seed=settings.seed, source=source)
    plane = fit_model(P, "plane", **kw) if model in ("auto", "plane") else None
    sphere = fit_model(P, "sphere", **kw) if model in ("auto", "sphere") and sphere_ok else None
    cylinder = None
    if model in ("auto", "cylinder") and sphere_ok and len(P) >= MIN_POINTS["cylinder"]:
        cylinder = fit_model(P, "cylinder", normals=np.asarray(workpiece.normals, float), **kw)
    fit = _choose_cylinder(_choose(plane, sphere, extent), cylinder, extent)
    if fit is None and model == "cylinder":
        raise BadInput(f"{source}: no cylinder is defined: the points' normals are (nearly) parallel, as on a "
                       "plane; use fit.model = \"plane\" or \"auto\"")
    if fit is None:
        raise BadInput(f"{source}: every RANSAC sample was degenerate; check the points")
    if len(P) < MIN_SURFACE_POINTS:  # a plane through 3 points is no scan of a part: refuse, do not guess
        raise BadInput(f"{source}: too few points for a surface: {len(P)}, need at least {MIN_SURFACE_POINTS}; "
                       "give a denser scan or mesh")
    ratio = fit.n_inliers / len(P)
    if ratio < min_inlier_ratio:
        tried = " or ".join(m.model for m in (plane, sphere, cylinder) if m is not None)
        raise BadInput(f"{source}: no {tried} reaches fit.min_inlier_ratio = {min_inlier_ratio:g} "
                       f"(best: {fit.model} with {ratio:.3f} at threshold_mm = {threshold_mm:g}); "
                       "check the units, raise fit.threshold_mm or crop the scan")
    inl = fit.inliers
    res = fit.residuals_mm[inl]
    stats = FitStats(float(ratio), float(np.sqrt(np.mean(res ** 2))), float(res.max()), int(len(P)),
                     int(inl.sum()))
    bkw = dict(cell_mm=settings.boundary_cell_mm, close_gaps_mm=settings.close_gaps_mm,
               simplify_mm=settings.simplify_mm, source=source)
    normals = np.asarray(workpiece.normals, dtype=float)[inl]
    if fit.model == "plane":
        return _plane_surface(P[inl], normals, *fit.params, stats, bkw)
    if fit.model == "cylinder":
        return cylinder_surface(P[inl], normals, *fit.params, stats, bkw)
    return _sphere_patch(P[inl], normals, *fit.params, stats, bkw)


def _choose_cylinder(chosen: ModelFit | None, cylinder: ModelFit | None, extent: float) -> ModelFit | None:
    """auto's plane / sphere, unless a (not huge) cylinder holds CYLINDER_MARGIN more inliers."""
    if cylinder is None:
        return chosen
    if chosen is None:
        return cylinder
    if cylinder.params[2] > LARGE_SPHERE_FACTOR * extent:
        return chosen
    return cylinder if cylinder.n_inliers > (1.0 + CYLINDER_MARGIN) * chosen.n_inliers else chosen


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def plane_surface(Q, normals, n, d, stats, bkw) -> PlaneSurface:
    """The plane n.x = d through inlier points Q (their normals give the tool side), with its boundary."""
    return _plane_surface(Q, normals, n, d, stats, bkw)


def sphere_patch(Q, normals, c, r, stats, bkw) -> SpherePatch:
    """The sphere patch (centre c, radius r) through inlier points Q, with its boundary and material side."""
    return _sphere_patch(Q, normals, c, r, stats, bkw)


def cylinder_surface(Q, normals, c, a, r, stats, bkw) -> Cylinder:
    """The cylinder patch through inlier points Q: axis through c along unit a, radius r (mm).

    e3 is the axis (pointing up, or along its largest positive component), e1
    the mean radial direction of the points (so u = 0 is the patch's middle and
    the seam u = +-pi is opposite it); ``centre_mm`` is the axis point at the
    middle of the points' axial span. The material side comes from the
    normals: most normals towards the axis make it concave (an inside). The
    boundary is taken in the (R u, v) chart, an isometry of the cylinder.
    """
    a = np.asarray(a, float) / np.linalg.norm(a)
    if a[2] < -1e-6 or (abs(a[2]) <= 1e-6 and a[np.argmax(np.abs(a))] < 0):
        a = -a
    rad = cylinder_radial(Q, c, a)
    concave = bool(np.median(np.sum(np.asarray(normals, float) * rad, axis=1)) < 0) if len(normals) else False
    m = rad.mean(axis=0)
    m = m - (m @ a) * a
    if np.linalg.norm(m) > 1e-6:
        e1 = _unit(m)
    else:
        e1 = _orthonormal(a)[0]
    frame = np.column_stack([e1, np.cross(a, e1), a])
    along = (Q - c) @ a
    c = c + 0.5 * (along.min() + along.max()) * a
    probe = Cylinder(c, float(r), frame, None, stats, concave)
    uv = probe.uv_from_points(Q)
    b = boundary_from_uv(np.stack([r * uv[:, 0], uv[:, 1]], axis=-1), None, **bkw)
    scale = np.array([1.0 / r, 1.0])
    boundary = type(b)(b.outer_uv * scale, tuple(h * scale for h in b.holes_uv))
    return Cylinder(c, float(r), frame, boundary, stats, concave)


def _plane_surface(Q, normals, n, d, stats, bkw) -> PlaneSurface:
    """Plane with its normal towards the workpiece normals (tool side); v = world up if it can."""
    s = float(np.sum(normals @ n))
    if s < 0 or (s == 0 and n[np.argmax(np.abs(n))] < 0):
        n, d = -n, -d
    z, x = np.array([0.0, 0, 1]), np.array([1.0, 0, 0])
    zp = z - (z @ n) * n
    if np.linalg.norm(zp) > 0.1:  # tilted plane (a wall): v is up, rows are horizontal
        v_axis = _unit(zp)
        u_axis = np.cross(v_axis, n)
    else:  # (nearly) horizontal plane: u follows world x (or y)
        xp = x - (x @ n) * n
        u_axis = _unit(xp if np.linalg.norm(xp) > 0.1 else np.array([0.0, 1, 0]) - n[1] * n)
        v_axis = np.cross(n, u_axis)
    mean = Q.mean(axis=0)
    origin = mean - (mean @ n - d) * n
    uv = np.stack([(Q - origin) @ u_axis, (Q - origin) @ v_axis], axis=-1)
    boundary = boundary_from_uv(uv, None, **bkw)
    return PlaneSurface(origin, n, u_axis, v_axis, boundary, stats)


def _sphere_patch(Q, normals, c, r, stats, bkw) -> SpherePatch:
    """Sphere patch with e3 = world up when the patch keeps clear of the poles.

    The material side comes from the data's normals: when most of them point
    to the centre, the patch is a bowl (``concave``), worked from inside.
    """
    dirs = (Q - c) / np.linalg.norm(Q - c, axis=1)[:, None]
    concave = bool(np.median(np.sum(np.asarray(normals, float) * dirs, axis=1)) < 0) if len(normals) else False
    m = dirs.mean(axis=0)
    m = _unit(m) if np.linalg.norm(m) > 1e-9 else np.array([1.0, 0, 0])
    z, x = np.array([0.0, 0, 1]), np.array([1.0, 0, 0])
    mh = m - (m @ z) * z
    if np.linalg.norm(mh) > 0.1 and np.abs(dirs[:, 2]).max() <= np.sin(np.radians(80)):
        e1, e3 = _unit(mh), z  # v is the world elevation: rows of constant v are horizontal
    else:
        e1 = m
        e3 = z - (z @ e1) * e1
        e3 = _unit(e3 if np.linalg.norm(e3) > 0.1 else x - (x @ e1) * e1)
    frame = np.column_stack([e1, np.cross(e3, e1), e3])
    patch = SpherePatch(c, r, frame, None, stats)  # boundary filled below
    boundary = boundary_from_uv(patch.uv_from_points(Q), r, **bkw)
    return SpherePatch(c, r, frame, boundary, stats, concave)
