"""Fit accuracy and speed, camtool against pyransac3d (prints figures, never asserts).

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/fit_speed.py

Data: the seed sphere patch (R 600 mm, el -10..60, az -40..40 deg) and a tilted
plane, sigma 0.1 mm noise plus 30 % uniform outliers in the bounding box.
"""
import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"  # one core, before numpy loads

import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from camtool.part.fit import fit_model, fit_surface  # noqa: E402
from test_fit import CENTER, _with_outliers, plane_points, sphere_patch_points  # noqa: E402
from camtool.settings import FitSettings

PLANE_N = np.array([0.2, -1.0, 0.3]) / np.linalg.norm([0.2, -1.0, 0.3])
PLANE_D = -550.0


def sphere_cloud(n, seed):
    rng = np.random.default_rng(seed)
    pts, d = sphere_patch_points(int(n * 0.7), rng)
    return _with_outliers(pts, d, rng)


def plane_cloud(n, seed):
    rng = np.random.default_rng(seed)
    pts, nrm = plane_points(int(n * 0.7), rng, PLANE_N, PLANE_D)
    return _with_outliers(pts, nrm, rng, pad=100.0)


def timed(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def sphere_err(c, r):
    return abs(r - 600.0), float(np.linalg.norm(np.asarray(c) - CENTER))


def plane_err(n, d):
    n = np.asarray(n, float)
    s = np.sign(n @ PLANE_N)
    return float(np.degrees(np.arccos(np.clip(abs(n @ PLANE_N), -1, 1)))), abs(s * d - PLANE_D)


def ours_sphere(wp, **kw):
    s, t = timed(lambda: fit_surface(wp, FitSettings.make(model="sphere", **kw)))
    return sphere_err(s.center_mm, s.radius_mm), t


def ours_plane(wp, **kw):
    s, t = timed(lambda: fit_surface(wp, FitSettings.make(model="plane", **kw)))
    return plane_err(s.normal, s.offset_mm), t


def ours_model_only(wp, model):
    """RANSAC + least-squares refinement alone: what pyransac3d does (no boundary, no normals)."""
    f, t = timed(lambda: fit_model(wp.points_mm, model, 0.5, 1000, 0))
    if model == "sphere":
        return sphere_err(*f.params), t
    return plane_err(*f.params), t


def pyr_sphere(wp, iterations):
    import pyransac3d as pyr
    np.random.seed(0)
    (c, r, _), t = timed(lambda: pyr.Sphere().fit(wp.points_mm, thresh=0.5, maxIteration=iterations))
    return sphere_err(c, r), t


def pyr_plane(wp, iterations):
    import pyransac3d as pyr
    np.random.seed(0)
    (eq, _), t = timed(lambda: pyr.Plane().fit(wp.points_mm, thresh=0.5, maxIteration=iterations))
    n = np.asarray(eq[:3]); k = np.linalg.norm(n)
    return plane_err(n / k, -eq[3] / k), t


def row(label, err, t, units):
    print(f"  {label:<28} {units[0]} {err[0]:10.5f}   {units[1]} {err[1]:8.5f}   time {t:7.3f} s")


def main():
    try:
        import pyransac3d  # noqa: F401
        have_pyr = True
    except ImportError:
        have_pyr = False
        print("pyransac3d not installed (pip install 'camtool[bench]'): comparison skipped")
    su, pu = ("radius err mm", "centre err mm"), ("normal err deg", "offset err mm")

    print("accuracy, 100k points (70k on the surface, 30 % outliers), 1000 iterations")
    row("camtool sphere", *ours_sphere(sphere_cloud(100_000, 1)), su)
    row("camtool plane", *ours_plane(plane_cloud(100_000, 2)), pu)
    fit_surface(sphere_cloud(5000, 9), FitSettings.make())  # warm-up (imports, caches)
    _, t = timed(lambda: fit_surface(sphere_cloud(100_000, 1), FitSettings.make()))
    print(f"  camtool auto (sphere data)   time {t:.3f} s")

    for label, make, ours, theirs, units in (("sphere", sphere_cloud, ours_sphere, pyr_sphere, su),
                                             ("plane", plane_cloud, ours_plane, pyr_plane, pu)):
        for n in (10_000, 1_000_000):
            wp = make(n, 3)
            print(f"{label}, {n:,} points, 1000 iterations, one core")
            e1, t1 = ours(wp)
            row("camtool (fit + boundary)", e1, t1, units)
            e0, t0 = ours_model_only(wp, label)
            row("camtool (RANSAC + refine)", e0, t0, units)
            if have_pyr:
                e2, t2 = theirs(wp, 1000)
                row("pyransac3d (RANSAC only)", e2, t2, units)
                print(f"  speed-up, like for like (RANSAC + refine): {t2 / t0:6.1f}x;"
                      f" with our boundary on top: {t2 / t1:6.1f}x")


if __name__ == "__main__":
    main()
