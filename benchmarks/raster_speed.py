"""Time the raster stage on the seed patch (default 10 x 5 mm and dense 2 x 2 mm).

Prints times, work-point counts and coverage; never asserts on time. The anchor
is a naive per-point Python loop of the same sampling (rows of constant
elevation, points every pitch along each row, Boundary.contains and a tool
frame per point), so the ratio stays meaningful on a noisy machine.

    .venv/bin/python benchmarks/raster_speed.py [--repeat N]
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np

from camtool.path.raster import coverage, raster_path
from camtool.part.surface import Boundary, SpherePatch
from camtool.settings import RasterSettings


def seed_patch() -> SpherePatch:
    """The seed sphere patch (R 600 mm at (1000, 0, 100), az -40..40, el -10..60 deg)."""
    frame = np.array([[-1.0, 0, 0], [0, -1.0, 0], [0, 0, 1.0]]).T
    outer = np.radians([[-40, -10], [40, -10], [40, 60], [-40, 60]])
    return SpherePatch(np.array([1000.0, 0, 100]), 600.0, frame, Boundary(outer))


def naive_raster(surface: SpherePatch, step_over_mm: float, pitch_mm: float) -> list[np.ndarray]:
    """Work poses (4x4) the straightforward way: one Python iteration per point."""
    (u0, v0), (u1, v1) = surface.boundary.bounds()
    R = surface.radius_mm
    n_rows = math.ceil((v1 - v0) * R / step_over_mm)
    first = v0 + ((v1 - v0) - (n_rows - 1) * step_over_mm / R) / 2
    poses = []
    for k in range(n_rows):
        v = first + k * step_over_mm / R
        du = pitch_mm / (R * math.cos(v))
        n = max(math.ceil((u1 - u0) / du - 0.01) - 1, 0)  # strictly inside, as raster_path
        us = [u0 + ((u1 - u0) - n * du) / 2 + i * du for i in range(n + 1)]
        if k % 2:
            us = us[::-1]
        for u in us:
            if not surface.boundary.contains(np.array([[u, v]]))[0]:
                continue
            p = surface.point_mm(u, v)
            z = -surface.normal_at(u, v)
            x = np.array([0.0, 0.0, 1.0]) - z[2] * z
            x /= np.linalg.norm(x)
            T = np.eye(4)
            T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, np.cross(z, x), z, p
            poses.append(T)
    return poses


def best_of(fn, repeat: int) -> tuple[float, object]:
    best, out = float("inf"), None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="runs per timing; the best is shown")
    args = ap.parse_args()
    surface = seed_patch()
    print(f"{'variant':<18}{'raster_path s':>14}{'work pts':>10}{'poses':>9}{'coverage %':>12}"
          f"{'naive loop s':>14}{'naive pts':>11}{'ratio':>8}")
    for name, step, pitch in (("default 10x5 mm", 10.0, 5.0), ("dense 2x2 mm", 2.0, 2.0)):
        t, path = best_of(lambda: raster_path(surface, RasterSettings.make(step_over_mm=step, pitch_mm=pitch)), args.repeat)
        cov = coverage(surface, path, step)
        tn, naive = best_of(lambda: naive_raster(surface, step, pitch), 1)
        print(f"{name:<18}{t:>14.3f}{np.count_nonzero(path.is_work):>10}{len(path):>9}{100 * cov:>12.3f}"
              f"{tn:>14.3f}{len(naive):>11}{tn / t:>8.1f}")


if __name__ == "__main__":
    main()
