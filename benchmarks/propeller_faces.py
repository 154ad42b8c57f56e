"""A whole propeller's faces (issue #46): each blade side one face.

The BladeX propeller with its shaft (``benchmarks/parts/freeform/bladex_propeller_and_shaft.stl``, MIT, see
LICENSES.md; its file states no unit: taken as mm, blades 125 mm in radius) has 5 blades of 2 sides each, each side
one smooth twisted surface a process engineer picks as one face. ``camtool faces`` of the file (its workpiece and
segmentation, as the command builds them) is checked against the mesh itself:

- **blade**: the connected pieces of the mesh's triangles farther than ``HUB_MM`` from the shaft's axis (x): 5;
- **side**: of a blade's point, the sign of its normal along the blade's thinnest principal direction (its
  vertices'); points whose normal leans more than ``EDGE_DEG`` from that direction (the edges, where the sides
  meet) belong to neither.

Printed: for each of the 10 sides, the faces holding at least ``SHARE`` of its points (their count must be 1) and
the share of the side that face holds, the share of that face's points on the side; then the shaft and hub faces
(model, area, RMS) and the count of sides that are one face.

    PYTHONPATH=. python benchmarks/propeller_faces.py
"""
from __future__ import annotations

import hashlib
import sys
from pathlib import Path

import numpy as np
import trimesh
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from camtool.job import job_for_part  # noqa: E402
from camtool.part.faces import segment_faces  # noqa: E402
from camtool.run.part_stages import faces_settings, workpiece_for_job  # noqa: E402

PART = ROOT / "benchmarks" / "parts" / "freeform" / "bladex_propeller_and_shaft.stl"
SHA256 = "b86dae8deb1570adc44fa30f898bc1ea0044084265777ffe6a85d862945e2ee4"
BLADES = 5
HUB_MM = 42.0      # the hub's radius is 36-38 mm: triangles farther out are the blades'
EDGE_DEG = 60.0    # a point whose normal leans past this from its blade's thin direction is on an edge
SHARE = 0.05       # a face holding this share of a side's points counts as one of its faces


def blade_sides(mesh: trimesh.Trimesh, P: np.ndarray, N: np.ndarray) -> np.ndarray:
    """Reference label of each point: 2 * blade + (0 or 1) for its side; -1 off the blades or on an edge."""
    c = mesh.triangles_center
    out = np.hypot(c[:, 1], c[:, 2]) > HUB_MM
    adj = mesh.face_adjacency[out[mesh.face_adjacency].all(axis=1)]
    from scipy.sparse import coo_matrix

    g = coo_matrix((np.ones(len(adj)), (adj[:, 0], adj[:, 1])), shape=(len(c), len(c)))
    _, comp = connected_components(g, directed=False)
    ids, sizes = np.unique(comp[out], return_counts=True)
    blades = ids[np.argsort(-sizes)][:BLADES]
    tri = cKDTree(c).query(P)[1]
    label = np.full(len(P), -1, np.int64)
    cos_edge = np.cos(np.radians(EDGE_DEG))
    for b, cid in enumerate(blades):
        V = mesh.vertices[np.unique(mesh.faces[comp == cid])]
        thin = np.linalg.svd(V - V.mean(axis=0), full_matrices=False)[2][2]
        mine = out[tri] & (comp[tri] == cid)
        along = N @ thin
        label[mine & (along >= cos_edge)] = 2 * b
        label[mine & (along <= -cos_edge)] = 2 * b + 1
    return label


def main() -> int:
    if hashlib.sha256(PART.read_bytes()).hexdigest() != SHA256:
        print(f"{PART.name}: SHA-256 differs from LICENSES.md's; not the vendored file")
        return 1
    job = job_for_part(PART, "mm", [])
    wp = workpiece_for_job(job)
    seg = segment_faces(faces_settings(job), wp)
    P, N = np.asarray(wp.points_mm, float), np.asarray(wp.normals, float)
    N = N / np.linalg.norm(N, axis=1, keepdims=True)
    label = blade_sides(trimesh.load(PART), P, N)
    owner = np.full(len(P), -1, np.int64)
    for f in seg.faces:
        owner[f.inliers] = f.index
    one = 0
    blade_faces = set()
    for s in range(2 * BLADES):
        mine = label == s
        counts = np.bincount(owner[mine][owner[mine] >= 0], minlength=len(seg.faces))
        faces = [int(k) for k in np.flatnonzero(counts >= SHARE * mine.sum())]
        blade_faces.update(faces)
        if len(faces) == 1:
            f = faces[0]
            held, pure = counts[f] / mine.sum(), float((label[owner == f] == s).mean())
            one += 1
            print(f"blade {s // 2} side {s % 2}: 1 face (face {f}, {seg.faces[f].model}): holds {100 * held:.1f} % "
                  f"of the side, {100 * pure:.1f} % of its points on it")
        else:
            print(f"blade {s // 2} side {s % 2}: {len(faces)} faces {faces}")
    for f in seg.faces:
        if f.index not in blade_faces:
            s = f.summary()
            x = P[f.inliers, 0]
            print(f"shaft/hub face {f.index}: {f.model}, {s['area_mm2']:.0f} mm2, x {x.min():.0f}..{x.max():.0f} mm, "
                  f"RMS {s['rms_mm']:.3f} mm")
    print(f"{one} of {2 * BLADES} blade sides are one face each ({len(seg.faces)} faces in all)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
