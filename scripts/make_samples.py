"""Write the sample workpieces into samples/ (deterministic; run from anywhere).

- sphere_patch.stl: the seed patch (R 600 mm, elevation -10..60 deg, azimuth
  -40..40 deg) in its own frame: centre at the origin, outward normals towards -x;
  0.5 deg grid, chordal error below 0.02 mm.
- sphere_scan.ply: a scan of that patch, 50k points, sigma 0.1 mm, no normals.
- wall.ply: seed 002's target plane y = 600 mm, x -450..450, z 150..1050 mm,
  sigma 0.1 mm plus 20 % outliers (50k points).
- plate_hole.stl: the top face (z = 0) of a 400 x 300 mm plate with an 80 x 80 mm
  square hole centred at (60, 30) mm; one-sided, normals +z.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

OUT = Path(__file__).resolve().parent.parent / "samples"
R_MM = 600.0
AZ_DEG = (-40.0, 40.0)
EL_DEG = (-10.0, 60.0)


def patch_point(az, el, r=R_MM):
    """Point on the seed patch (own frame), facing -x."""
    return np.asarray(r)[..., None] * np.stack([-np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=-1)


def sphere_patch_mesh(step_deg: float = 0.5) -> trimesh.Trimesh:
    az = np.radians(np.linspace(*AZ_DEG, int(round((AZ_DEG[1] - AZ_DEG[0]) / step_deg)) + 1))
    el = np.radians(np.linspace(*EL_DEG, int(round((EL_DEG[1] - EL_DEG[0]) / step_deg)) + 1))
    A, E = np.meshgrid(az, el, indexing="ij")
    verts = patch_point(A, E).reshape(-1, 3)
    ne = len(el)
    i, j = np.meshgrid(np.arange(len(az) - 1), np.arange(ne - 1), indexing="ij")
    a, b = (i * ne + j).ravel(), ((i + 1) * ne + j).ravel()
    c, d = (i * ne + j + 1).ravel(), ((i + 1) * ne + j + 1).ravel()
    faces = np.vstack([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    mesh = trimesh.Trimesh(verts, faces, process=False)
    outward = np.einsum("ij,ij->i", mesh.face_normals, mesh.triangles_center) > 0
    if not outward.all():
        mesh.faces = mesh.faces[:, ::-1]
    return mesh


def sphere_scan(rng, n: int = 50_000, sigma_mm: float = 0.1) -> np.ndarray:
    az = rng.uniform(*np.radians(AZ_DEG), n)
    el = np.arcsin(rng.uniform(*np.sin(np.radians(EL_DEG)), n))  # uniform in area
    return patch_point(az, el, R_MM + rng.normal(0.0, sigma_mm, n))


def wall_cloud(rng, n: int = 50_000, outlier_ratio: float = 0.2, sigma_mm: float = 0.1) -> np.ndarray:
    n_out = int(round(n * outlier_ratio))
    n_in = n - n_out
    inl = np.stack([rng.uniform(-450, 450, n_in), 600 + rng.normal(0, sigma_mm, n_in),
                    rng.uniform(150, 1050, n_in)], axis=1)
    out = np.stack([rng.uniform(-450, 450, n_out), rng.uniform(500, 700, n_out),
                    rng.uniform(150, 1050, n_out)], axis=1)
    return np.vstack([inl, out])[rng.permutation(n)]


def plate_hole_mesh(cell_mm: float = 10.0) -> trimesh.Trimesh:
    xs = np.arange(-200, 200 + cell_mm / 2, cell_mm)
    ys = np.arange(-150, 150 + cell_mm / 2, cell_mm)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    verts = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], axis=1)
    ny = len(ys)
    faces = []
    for i in range(len(xs) - 1):
        for j in range(ny - 1):
            cx, cy = xs[i] + cell_mm / 2, ys[j] + cell_mm / 2
            if 20 < cx < 100 and -10 < cy < 70:  # the 80 x 80 mm hole
                continue
            a, b, c, d = i * ny + j, (i + 1) * ny + j, i * ny + j + 1, (i + 1) * ny + j + 1
            faces += [[a, b, d], [a, d, c]]  # counter-clockwise seen from +z
    mesh = trimesh.Trimesh(verts, np.array(faces), process=False)
    mesh.remove_unreferenced_vertices()
    return mesh


def main() -> None:
    OUT.mkdir(exist_ok=True)
    rng = np.random.default_rng(20230601)
    sphere_patch_mesh().export(OUT / "sphere_patch.stl")
    trimesh.PointCloud(sphere_scan(rng).astype(np.float32)).export(OUT / "sphere_scan.ply")
    trimesh.PointCloud(wall_cloud(rng).astype(np.float32)).export(OUT / "wall.ply")
    plate_hole_mesh().export(OUT / "plate_hole.stl")
    for name in ("sphere_patch.stl", "sphere_scan.ply", "wall.ply", "plate_hole.stl"):
        print(f"wrote {OUT / name} ({(OUT / name).stat().st_size / 1e6:.2f} MB)")


if __name__ == "__main__":
    main()
