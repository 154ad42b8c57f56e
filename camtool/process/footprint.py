"""The tool's footprint: a radial profile of pressure (polish, grind) or deposition (paint).

``Footprint.density(r_mm)`` is the profile scaled to unit volume, so that
``density`` integrated over the disc is 1 (1/mm^2): the pressure is then
``force_n * density`` and the film rate ``deposition_mm3_s * density``.
Profiles: flat (1 inside the radius), parabolic (1 - r^2/a^2), gaussian
(exp(-r^2 / 2 sigma^2), cut at the radius) and table (linear between measured
radii, 0 beyond the last). The unit-volume constant is computed in closed form
for flat and parabolic and by a fine radial quadrature otherwise.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..settings import ProcessSettings

RADIAL_QUADRATURE = 4000  # radial nodes of the unit-volume integral (gaussian, table)
SEGMENT_QUADRATURE = 8    # Gauss-Legendre nodes of a footprint of no closed form along a segment
KERNEL_SUPERSAMPLE = 5    # sub-samples per cell side when a footprint is put on a grid


@dataclass(frozen=True)
class Footprint:
    """A round footprint of ``radius_mm``; ``table`` is ((r_mm, value), ...) for profile = table."""

    profile: str
    radius_mm: float
    sigma_mm: float = 0.0
    table: tuple[tuple[float, float], ...] = ()

    @classmethod
    def from_settings(cls, s: ProcessSettings) -> "Footprint":
        return cls(s.profile, 0.5 * s.diameter_mm, s.gaussian_sigma_mm, s.profile_table)

    def shape(self, r_mm) -> np.ndarray:
        """The profile at radii ``r_mm`` (any scale; 0 outside the radius)."""
        r = np.asarray(r_mm, float)
        a = self.radius_mm
        inside = r <= a
        if self.profile == "flat":
            v = np.ones_like(r)
        elif self.profile == "parabolic":
            v = 1.0 - (r / a) ** 2
        elif self.profile == "gaussian":
            v = np.exp(-0.5 * (r / self.sigma_mm) ** 2)
        else:
            rt, vt = np.array(self.table, float).T
            v = np.interp(r, rt, vt, left=vt[0], right=0.0)
        return np.where(inside, np.maximum(v, 0.0), 0.0)

    def segment_shape(self, alpha, beta, gamma) -> np.ndarray:
        """The mean of ``shape`` along a straight segment, t in [0, 1] with r(t)^2 = alpha t^2 + 2 beta t + gamma:
        what a contact that stands for a stretch of path run at constant speed puts at a point. Flat and parabolic
        in closed form (the part of the segment within the radius is the root interval of a quadratic); others by
        ``SEGMENT_QUADRATURE``-point Gauss-Legendre over that part (the grid map spreads its contacts along the
        path instead, ``integrate._along_path``; no library integrates a footprint along a chord)."""
        alpha, beta, gamma = (np.asarray(x, float) for x in (alpha, beta, gamma))
        a = self.radius_mm
        moving = alpha > 1e-18
        disc = beta * beta - alpha * (gamma - a * a)
        root = np.sqrt(np.maximum(disc, 0.0))
        safe = np.where(moving, alpha, 1.0)
        t1 = np.where(moving, np.clip((-beta - root) / safe, 0.0, 1.0), 0.0)
        t2 = np.where(moving, np.clip((-beta + root) / safe, 0.0, 1.0), np.where(gamma <= a * a, 1.0, 0.0))
        t2 = np.where(moving & (disc <= 0), t1, t2)
        if self.profile == "flat":
            return t2 - t1
        if self.profile != "parabolic":  # Gauss-Legendre over the part within the radius (smooth there)
            x, w = np.polynomial.legendre.leggauss(SEGMENT_QUADRATURE)
            t = t1[..., None] + (t2 - t1)[..., None] * 0.5 * (x + 1.0)
            r2 = alpha[..., None] * t * t + 2.0 * beta[..., None] * t + gamma[..., None]
            return (t2 - t1) * np.sum(self.shape(np.sqrt(np.maximum(r2, 0.0))) * (0.5 * w), axis=-1)
        # the integral of 1 - (alpha t^2 + 2 beta t + gamma) / a^2 from t1 to t2
        mean_r2 = alpha * (t2 * t2 + t1 * t2 + t1 * t1) / 3.0 + beta * (t1 + t2) + gamma
        return np.maximum((t2 - t1) * (1.0 - mean_r2 / (a * a)), 0.0)

    @property
    def volume(self) -> float:
        """Integral of ``shape`` over the disc (mm^2)."""
        a = self.radius_mm
        if self.profile == "flat":
            return math.pi * a * a
        if self.profile == "parabolic":
            return 0.5 * math.pi * a * a
        r = (np.arange(RADIAL_QUADRATURE) + 0.5) * (a / RADIAL_QUADRATURE)
        return float(np.sum(self.shape(r) * 2.0 * math.pi * r) * (a / RADIAL_QUADRATURE))

    def density(self, r_mm) -> np.ndarray:
        """``shape`` scaled to unit volume (1/mm^2)."""
        return self.shape(r_mm) / self.volume

    def kernel(self, cell_mm: float) -> np.ndarray:
        """(2n+1, 2n+1) cell weights on a square grid of ``cell_mm``: the density averaged over each cell
        (``KERNEL_SUPERSAMPLE``^2 sub-samples) times the cell area, rescaled to sum to exactly 1."""
        n = int(math.ceil(self.radius_mm / cell_mm)) + 1
        m = KERNEL_SUPERSAMPLE
        sub = ((np.arange(m) + 0.5) / m - 0.5) * cell_mm
        c = np.arange(-n, n + 1) * cell_mm
        x = (c[:, None] + sub[None, :]).ravel()
        r = np.hypot(x[:, None], x[None, :])
        w = self.shape(r).reshape(2 * n + 1, m, 2 * n + 1, m).mean(axis=(1, 3))
        return w / w.sum()

    def cell_kernel(self, du_mm: float, dv_mm: float, sub_mm: float) -> np.ndarray:
        """(2nv+1, 2nu+1) weights on a grid of ``du_mm`` x ``dv_mm`` cells (rows along v): the density averaged over
        each cell with sub-samples at most ``sub_mm`` apart on each axis, rescaled to sum to exactly 1.
        For the refined grids of ``grid.refined`` (cells long along the rows, short across them)."""
        a = self.radius_mm
        nu, nv = int(math.ceil(a / du_mm)) + 1, int(math.ceil(a / dv_mm)) + 1
        mu, mv = max(int(math.ceil(du_mm / sub_mm)), 1), max(int(math.ceil(dv_mm / sub_mm)), 1)
        x = (np.arange(-nu, nu + 1)[:, None] + ((np.arange(mu) + 0.5) / mu - 0.5)[None, :]).ravel() * du_mm
        y = (np.arange(-nv, nv + 1)[:, None] + ((np.arange(mv) + 0.5) / mv - 0.5)[None, :]).ravel() * dv_mm
        w = self.shape(np.hypot(x[None, :], y[:, None])).reshape(2 * nv + 1, mv, 2 * nu + 1, mu).mean(axis=(1, 3))
        return w / w.sum()

    def pass_profile(self, y_mm) -> np.ndarray:
        """Integral of ``density`` along a straight line at lateral offset ``y_mm`` (1/mm): a straight pass at
        unit speed leaves this times the rate. Closed form for flat and parabolic, quadrature otherwise."""
        y = np.abs(np.asarray(y_mm, float))
        a = self.radius_mm
        w = np.sqrt(np.maximum(a * a - y * y, 0.0))
        if self.profile == "flat":
            return 2.0 * w / (math.pi * a * a)
        if self.profile == "parabolic":
            return 8.0 * w ** 3 / (3.0 * math.pi * a ** 4)
        x = (np.arange(RADIAL_QUADRATURE) + 0.5) / RADIAL_QUADRATURE * 2.0 - 1.0
        xs = x[None, :] * w[..., None]
        r = np.hypot(xs, y[..., None])
        return np.sum(self.density(r), axis=-1) * (2.0 * w / RADIAL_QUADRATURE)
