"""Issue #46's tool-axis figure on a coarse CAD mesh: how much of it is the metric's quadrature.

benchmarks/freeform_metrics.averaged_normals averages the normals of the triangles whose *centroid* lies within
the radius (12.5 mm) of the TCP's closest point. On a mesh whose triangles are as large as the disc (noether's
wavy sheet at 0.05 m a unit: a 25 mm grid, triangles 4-36 mm) a handful of centroids fall in or out of the disc
as the radius or the point moves, so that figure is a coarse quadrature of the disc's mean normal. Here the same
disc mean is also taken over area-uniform samples of the mesh (about 2 per mm^2, each with its triangle's normal):
the mean normal over the disc itself. The script runs camtool on the part as benchmarks/freeform.py does and
prints the tool axes' p50 / p95 angle against both, at 10, 12.5 and 15 mm, and the two against each other.

    .venv/bin/python benchmarks/freeform_axis_quadrature.py [--part noether_wavy_hole]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import freeform as ff            # noqa: E402
import freeform_metrics as fm    # noqa: E402

RADII_MM = (10.0, 12.5, 15.0)
SAMPLE_SPACING_MM = 0.7


def disc_normals(mesh, pts, radius_mm: float, samples, sample_normals) -> np.ndarray:
    """Mean normal of the mesh over the disc (ball) of ``radius_mm`` round each point's closest point, from
    area-uniform samples, each turned to agree with the closest triangle's (as ``averaged_normals`` does)."""
    c, _, f = fm.closest(mesh, pts)
    tree = fm.cKDTree(samples)
    out = np.zeros_like(c)
    for i, ids in enumerate(tree.query_ball_point(c, radius_mm)):
        n = sample_normals[np.asarray(ids, int)]
        out[i] = (n * np.sign(n @ mesh.face_normals[f[i]])[:, None]).sum(axis=0)
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def angles_deg(a, b) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", a, b)), 0.0, 1.0)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", default="noether_wavy_hole", choices=sorted(ff.PARTS))
    a = ap.parse_args(argv)
    fname, _kind, _sha, step, pitch = ff.PARTS[a.part]
    scale = ff.SCALE.get(a.part, 1000.0)
    mesh = fm.load_mesh(ff.PARTS_DIR / fname, scale)
    _, _, vt = np.linalg.svd(mesh.vertices - mesh.vertices.mean(0), full_matrices=False)
    region = fm.face_region(mesh, up=vt[2], max_tilt_deg=60.0)
    T = ff.placement(mesh, region, long_side_up=a.part in ff.LONG_SIDE_UP)
    with tempfile.TemporaryDirectory(prefix="ffaxis-") as tmp:
        job = Path(tmp) / f"{a.part}.toml"
        job.write_text(ff.job_text(a.part, ff.PARTS_DIR / fname, T, step, pitch, scale))
        wall, rc, so, se = ff.camtool(["run", str(job), "-o", str(Path(tmp) / "out")], ff.ROOT)
        if rc != 0:
            print(f"camtool refused (exit {rc}): {ff.first_line(se or so)}")
            return 1
        rows, _ = ff.work_rows(Path(tmp) / "out" / "points.csv", ff.Fk(), T)
    P = np.concatenate([p for p, _ in rows])
    A = np.concatenate([x for _, x in rows])
    samples = fm.surface_samples(mesh, None, spacing_mm=SAMPLE_SPACING_MM, seed=1)
    _, _, fs = fm.closest(mesh, samples)
    print(f"{a.part}: {len(P)} work poses; triangles' edges p5-p95 "
          f"{np.percentile(mesh.edges_unique_length, 5):.1f}-{np.percentile(mesh.edges_unique_length, 95):.1f} mm")
    print(f"{'radius':>8s}  {'axis vs centroids (metric)':>28s}  {'axis vs disc samples':>22s}  "
          f"{'centroids vs disc p95':>22s}")
    for r in RADII_MM:
        m = fm.averaged_normals(mesh, P, r)
        d = disc_normals(mesh, P, r, samples, mesh.face_normals[fs])
        am, ad, md = angles_deg(A, m), angles_deg(A, d), angles_deg(m, d)
        print(f"{r:6.1f} mm  p50 {np.median(am):5.2f} p95 {np.percentile(am, 95):5.2f} deg        "
              f"p50 {np.median(ad):5.2f} p95 {np.percentile(ad, 95):5.2f} deg   {np.percentile(md, 95):6.2f} deg")
    return 0


if __name__ == "__main__":
    sys.exit(main())
