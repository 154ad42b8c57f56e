"""An exact reference for the process map's figures, written without camtool.process.

The removal at a point x of the surface is the direct sum over the TCP
track's intervals in contact (both ends within ``tol_mm`` of the surface),
each a straight segment run at constant speed (the controller's linear
interpolation between samples): the footprint's unit-volume profile in the
tangent plane at the segment's midpoint, integrated exactly along the segment
(k_p F per mm of travel; the part of the segment within the footprint's radius
of x is the root interval of a quadratic, and the flat and parabolic profiles
integrate in closed form over it). As in camtool (docs/process.md), each
segment puts exactly its amount on the surface: on a sphere the footprint is
divided by the integral of the tangent-plane profile over the spherical cap it
covers (2 R^2 (1 - cos t) / a^2 for a flat one, sin t = a / R: 0.04 % for the
sample's 50 mm on R 600 mm). The share within the band is the area integral of the indicator
{|h(x) - mean| <= band * mean} over the material, estimated by stratified
random points, uniform in area (one per stratum; on a sphere uniform in u
and sin v): an unbiased estimate whose standard error is printed with it,
with no grid and no binning. Pairs of points and contacts come from
``scipy.spatial.cKDTree.sparse_distance_matrix``.
"""
from __future__ import annotations

import math

import numpy as np
from matplotlib.path import Path as MplPath
from scipy.spatial import cKDTree

CHUNK_POINTS = 4000


def _profile(profile: str, r: np.ndarray, a: float) -> np.ndarray:
    """Unit-volume footprint density at radius r (1/mm^2): flat 1/(pi a^2), parabolic 2 (1 - r^2/a^2)/(pi a^2)."""
    inside = r <= a
    if profile == "flat":
        return np.where(inside, 1.0 / (math.pi * a * a), 0.0)
    return np.where(inside, 2.0 * (1.0 - (r / a) ** 2) / (math.pi * a * a), 0.0)


def _foot(surface, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(foot on the surface, unit normal there) of points p: the plane or the sphere of ``surface``."""
    if surface.model == "sphere":
        c = np.asarray(surface.center_mm, float)
        d = p - c
        n = d / np.linalg.norm(d, axis=1, keepdims=True)
        return c + float(surface.radius_mm) * n, n
    n = np.asarray(surface.normal, float)
    n = n / np.linalg.norm(n)
    return p - ((p - np.asarray(surface.origin_mm, float)) @ n)[:, None] * n, np.broadcast_to(n, p.shape)


def contacts(surface, t_s, tcp_mm, tol_mm: float, k_um_mm2_per_mm: float):
    """(starts, ends, feet of the midpoints, normals there, amounts um*mm^2) of the track's intervals in contact."""
    p = np.asarray(tcp_mm, float)
    foot, _ = _foot(surface, p)
    on = np.linalg.norm(p - foot, axis=1) <= tol_mm
    k = np.flatnonzero(on[:-1] & on[1:] & (np.diff(np.asarray(t_s, float)) > 0))
    mfoot, mn = _foot(surface, 0.5 * (p[k] + p[k + 1]))
    return p[k], p[k + 1], mfoot, np.ascontiguousarray(mn), k_um_mm2_per_mm * np.linalg.norm(p[k + 1] - p[k], axis=1)


def sample_points(surface, n_points: int, seed: int = 0) -> np.ndarray:
    """(N, 3) stratified random points, uniform in area over the material (outer polygon minus holes)."""
    rng = np.random.default_rng(seed)
    lo, hi = surface.boundary.outer_uv.min(axis=0), surface.boundary.outer_uv.max(axis=0)
    sphere = surface.model == "sphere"
    y_lo, y_hi = (math.sin(lo[1]), math.sin(hi[1])) if sphere else (lo[1], hi[1])
    aspect = (hi[0] - lo[0]) * (float(surface.radius_mm) if sphere else 1.0) / max(
        (y_hi - y_lo) * (float(surface.radius_mm) if sphere else 1.0), 1e-12)
    nx = max(int(round(math.sqrt(n_points * aspect))), 1)
    ny = max(int(round(n_points / nx)), 1)
    ix, iy = np.meshgrid(np.arange(nx), np.arange(ny))
    u = lo[0] + (ix.ravel() + rng.random(ix.size)) / nx * (hi[0] - lo[0])
    y = y_lo + (iy.ravel() + rng.random(iy.size)) / ny * (y_hi - y_lo)
    v = np.arcsin(np.clip(y, -1, 1)) if sphere else y
    uv = np.column_stack([u, v])
    keep = MplPath(surface.boundary.outer_uv).contains_points(uv)
    for hole in surface.boundary.holes_uv:
        keep &= ~MplPath(hole).contains_points(uv)
    uv = uv[keep]
    return surface.point_mm(uv[:, 0], uv[:, 1])


def _along(profile: str, alpha, beta, gamma, a: float) -> np.ndarray:
    """Integral over t in [0, 1] of the unit-volume profile at r(t)^2 = alpha t^2 + 2 beta t + gamma (r <= a)."""
    disc = beta * beta - alpha * (gamma - a * a)
    root = np.sqrt(np.maximum(disc, 0.0))
    safe = np.where(alpha > 0, alpha, 1.0)
    t1 = np.clip((-beta - root) / safe, 0.0, 1.0)
    t2 = np.clip((-beta + root) / safe, 0.0, 1.0)
    t1 = np.where(alpha > 0, t1, 0.0)
    t2 = np.where(alpha > 0, t2, np.where(gamma <= a * a, 1.0, 0.0))
    t2 = np.where(disc > 0, np.maximum(t2, t1), t1)
    if profile == "flat":
        return (t2 - t1) / (math.pi * a * a)
    # integral of 1 - (alpha t^2 + 2 beta t + gamma) / a^2
    F = lambda t: t - (alpha * t ** 3 / 3.0 + beta * t * t + gamma * t) / (a * a)  # noqa: E731
    return 2.0 * (F(t2) - F(t1)) / (math.pi * a * a)


def cap_factor(surface, profile: str, a: float) -> float:
    """The footprint's volume over the surface per unit tangent-plane volume (1 on a plane; on a sphere the cap
    r = R sin t <= a: flat 2 R^2 (1 - c0) / a^2, parabolic 4 R^2 [(1 - R^2/a^2)(1 - c0) + R^2 (1 - c0^3) / (3 a^2)]
    / a^2, c0 = cos t_a)."""
    if surface.model != "sphere":
        return 1.0
    R = float(surface.radius_mm)
    c0 = math.sqrt(1.0 - (a / R) ** 2)
    if profile == "flat":
        return 2.0 * R * R * (1.0 - c0) / (a * a)
    k = (R / a) ** 2
    return 4.0 * R * R * ((1.0 - k) * (1.0 - c0) + k * (1.0 - c0 ** 3) / 3.0) / (a * a)


def removal_at(points: np.ndarray, segments, profile: str, radius_mm: float) -> np.ndarray:
    """h at ``points``: the direct sum of every segment's footprint, integrated along it in its tangent plane."""
    start, end, feet, normals, amounts = segments
    mid = 0.5 * (start + end)
    reach = 1.05 * radius_mm + 0.5 * float(np.max(np.linalg.norm(end - start, axis=1), initial=0.0))
    tree = cKDTree(mid)
    h = np.zeros(len(points))
    for s in range(0, len(points), CHUNK_POINTS):
        chunk = points[s:s + CHUNK_POINTS]
        pairs = cKDTree(chunk).sparse_distance_matrix(tree, reach, output_type="ndarray")
        i, j = pairs["i"], pairs["j"]
        n = normals[j]
        d0 = start[j] - chunk[i]
        d0 = d0 - np.einsum("ij,ij->i", d0, n)[:, None] * n   # in the tangent plane at the segment's midpoint
        e = end[j] - start[j]
        e = e - np.einsum("ij,ij->i", e, n)[:, None] * n
        w = _along(profile, np.einsum("ij,ij->i", e, e), np.einsum("ij,ij->i", d0, e),
                   np.einsum("ij,ij->i", d0, d0), radius_mm)
        h[s:s + len(chunk)] = np.bincount(i, weights=amounts[j] * w, minlength=len(chunk))
    return h


def exact_figures(surface, t_s, tcp_mm, *, profile: str, radius_mm: float, tol_mm: float, k_um_mm2_per_mm: float,
                  band: float = 0.05, n_points: int = 100_000, seed: int = 0) -> dict:
    """mean, the share within ``band`` of it and the share's standard error, by the direct sums above."""
    segments = contacts(surface, t_s, tcp_mm, tol_mm, k_um_mm2_per_mm)
    h = removal_at(sample_points(surface, n_points, seed), segments, profile, radius_mm)
    h /= cap_factor(surface, profile, radius_mm)
    mean = float(h.mean())
    share = float(np.mean(np.abs(h - mean) <= band * mean))
    return {"mean": mean, "share": share, "stderr": math.sqrt(max(share * (1 - share), 1e-12) / len(h)),
            "points": int(len(h))}
