"""Which meshes camtool judges as scans (camtool/part/roughness.py), on every vendored free-form part, every
shipped sample mesh and the scans the tests make, with what each is known to be.

Columns: vertices, the median |residual| of a vertex from the quadric through its 12 nearest others (mm; a mesh
is rough above ``SCAN_ROUGHNESS_MM``), the share of triangle pairs sharing an edge that are coplanar (a rough
mesh is CAD at ``CAD_COPLANAR_SHARE`` or more), the verdict, the truth. The sample scans (*_scan.ply, wall.ply)
are point clouds: always scans, their residuals shown for scale. The last column says whether the verdict is
right; the script exits 1 if any is not. A part whose source does not say what it is (``UNKNOWN``: truth "?") is
shown, not judged. Bezier's two Blender sheets (ocean, complex shape: CAD, 15-22 mm facets on waves and folds) read
as rough (0.07 mm) with no coplanar pairs: judged scans, as roughness.py's coarse tessellations are meant to be
unless coplanar facets say CAD; on them the rows still lie on the mesh (benchmarks/freeform.py: TCP p99 0.000 mm).

    .venv/bin/python benchmarks/scan_or_cad.py
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import trimesh

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from camtool.part.roughness import CAD_COPLANAR_SHARE, SCAN_ROUGHNESS_MM, mesh_roughness  # noqa: E402

PARTS = ROOT / "benchmarks" / "parts" / "freeform"
SCALE = {"noether_wavy_hole.ply": 50.0}    # as benchmarks/freeform.py: 0.05 m a unit; the rest in metres
UNKNOWN = {"reach_demo_part.ply"}   # its repository does not say whether it is a scan or CAD: shown, not judged


def noisy_sheet(noise_mm: float, n: int = 60, spacing_mm: float = 2.0, seed: int = 0):
    """tests/test_roughness.py's saddle sheet with normal noise, triangulated (two triangles a cell)."""
    x, y = np.meshgrid(np.arange(n) * spacing_mm, np.arange(n) * spacing_mm)
    x, y = x.ravel() - x.mean(), y.ravel() - y.mean()
    z = x ** 2 / 400.0 - y ** 2 / 600.0 + np.random.default_rng(seed).normal(0.0, noise_mm, x.size)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1))
    a = (j * n + i).ravel()
    return np.c_[x, y, z], np.r_[np.c_[a, a + 1, a + n + 1], np.c_[a, a + n + 1, a + n]]


def cases():
    """(name, vertices mm, faces or None, truth: "scan" / "cad")."""
    for f in sorted([*PARTS.glob("*.ply"), *PARTS.glob("*.obj")]):   # the .obj: the door, when fetched
        m = trimesh.load(f, process=False, force="mesh")
        yield f.name, np.asarray(m.vertices) * SCALE.get(f.name, 1000.0), m.faces, \
            "?" if f.name in UNKNOWN else "scan" if "scan" in f.name else "cad"
    for f in sorted((ROOT / "samples").glob("*.stl")):
        m = trimesh.load(f, process=False)
        yield "samples/" + f.name, np.asarray(m.vertices), m.faces, "cad"
    for f in sorted((ROOT / "samples").glob("*.ply")):
        m = trimesh.load(f, process=False)
        yield "samples/" + f.name + " (cloud)", np.asarray(m.vertices), None, "scan"
    for sigma in (0.01, 0.05, 1.0):
        V, F = noisy_sheet(sigma)
        yield f"tests: saddle sheet, noise {sigma:g} mm", V, F, "scan"


def main() -> int:
    print(f"rough above {SCAN_ROUGHNESS_MM} mm median |residual|; a rough mesh is CAD with >= "
          f"{100 * CAD_COPLANAR_SHARE:g} % of its triangle pairs coplanar")
    print(f"{'mesh':44s} {'vertices':>8s} {'median mm':>10s} {'coplanar':>9s}  verdict  truth")
    wrong = 0
    for name, V, F, truth in cases():
        r = mesh_roughness(V, faces=F)
        verdict = "scan" if (r.is_scan or F is None) else "cad"
        share = "-" if r.coplanar_share is None else f"{100 * r.coplanar_share:.2f} %"
        ok = verdict == truth or truth == "?"
        wrong += not ok
        print(f"{name:44s} {len(V):8d} {r.median_mm:10.2e} {share:>9s}  {verdict:7s}  {truth:5s} {'' if ok else 'WRONG'}")
    return 1 if wrong else 0


if __name__ == "__main__":
    sys.exit(main())
