"""Where the TOOLING4G mould's trough is not covered and where its tool axis misses (issue #46), from a kept run.

``benchmarks/freeform.py --parts tooling4g_polishing_mold --keep DIR`` keeps the job and the run; this reads them
back (the work poses through the same independent FK, freeform.work_rows) and prints:

- **coverage** of the benchmark's face (freeform.cavity_region, the same samples as freeform.py), and its uncovered
  samples by the ``camtool faces JOB`` face their nearest workpiece point is on (-1: on no face), and by zone of
  the trough (its wall-side edge x < 27 mm where the chamfer is, its rim side x > 170 mm, the rest);
- **the tool axis** (p50 / p95 / max, deg) against four references, each the area mean of the part's normal within
  a ball around the pose's closest point (freeform_metrics.averaged_normals' quadrature: triangles cut to 2.5 mm):
  ``ball``: every triangle in the ball (the benchmark's figure, 12.5 mm, and at 6.25 mm); ``face``: the benchmark
  face's triangles only; ``smooth side``: the triangles reached from the pose's own triangle without crossing an
  edge where the mesh turns by more than 30 deg (``faces.sharp_edge_deg``), i.e. the surface under the tool, not
  the rim or the wall across a crease from it. By zone: the wall side, the rim side (x > 165), the curl at the
  trough's far end into the rim (y > 765), the rest.

    PYTHONPATH=. python benchmarks/mould_trough.py DIR      # DIR: freeform.py's --keep
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial import cKDTree

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent)]
import freeform as fb  # noqa: E402
import freeform_metrics as fm  # noqa: E402

NAME = "tooling4g_polishing_mold"
SHARP_DEG = 30.0


def smooth_side_normals(mesh, pts: np.ndarray, radius_mm: float, sharp_deg: float = SHARP_DEG) -> np.ndarray:
    """The area mean normal over the triangles within radius_mm of each point's closest point that are reached from
    its closest triangle across edges turning by at most sharp_deg (a breadth-first walk on trimesh's face
    adjacency, each triangle touching the ball); the quadrature as freeform_metrics.averaged_normals'."""
    ang = np.degrees(mesh.face_adjacency_angles)
    nbrs = [[] for _ in range(len(mesh.faces))]
    for a, b in mesh.face_adjacency[ang <= sharp_deg]:
        nbrs[a].append(b)
        nbrs[b].append(a)
    c, _, f = fm.closest(mesh, pts)
    V, F, parent = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, return_index=True,
                                                    max_edge=fm.AXIS_QUADRATURE_EDGE * radius_mm)
    pieces = trimesh.Trimesh(V, F, process=False)
    tree, area, tri = cKDTree(pieces.triangles_center), pieces.area_faces, mesh.triangles
    out = np.empty((len(c), 3))
    for i, (p, f0) in enumerate(zip(c, f)):
        seen, todo = {int(f0)}, [int(f0)]
        while todo:
            for q in nbrs[todo.pop()]:
                if q not in seen and np.linalg.norm(trimesh.triangles.closest_point(tri[q:q + 1], p[None])[0] - p) \
                        <= radius_mm:
                    seen.add(q)
                    todo.append(q)
        near = np.array(tree.query_ball_point(p, radius_mm), int)
        near = near[np.isin(parent[near], list(seen))]
        v = (mesh.face_normals[parent[near]] * area[near, None]).sum(axis=0) + 1e-12 * mesh.face_normals[f0]
        out[i] = v / np.linalg.norm(v)
    return out


def face_labels(job_path: Path, samples_part: np.ndarray) -> tuple[np.ndarray, dict]:
    """Each sample's ``camtool faces JOB`` face (its nearest workpiece point's; -1: none) and {index: model}."""
    from camtool.job import load_job
    from camtool.part.faces import segment_faces
    from camtool.run.part_stages import faces_settings, workpiece_for_job
    from camtool.transforms import matrix_from_xyz_rpy

    job = load_job(job_path, [])
    wp = workpiece_for_job(job)
    seg = segment_faces(faces_settings(job), wp)
    lab = np.full(seg.n_points, -1)
    for f in seg.faces:
        lab[f.inliers] = f.index
    inv = np.linalg.inv(matrix_from_xyz_rpy(job.cell.workpiece_xyz_mm, job.cell.workpiece_rpy_deg))
    W = np.asarray(wp.points_mm) @ inv[:3, :3].T + inv[:3, 3]
    return lab[cKDTree(W).query(samples_part)[1]], {f.index: f.model for f in seg.faces}


def main(keep: Path) -> None:
    mesh = fm.load_mesh(fb.PARTS_DIR / fb.PARTS[NAME][0], 1000.0)
    region = fb.cavity_region(mesh, fb.CAVITY[NAME])
    step = fb.PARTS[NAME][3]
    samples = fm.surface_samples(mesh, region, spacing_mm=max(1.0, step / 5))
    T = fb.placement(mesh, region)
    rows, _ = fb.work_rows(keep / NAME / "points.csv", fb.Fk(), T)
    P, A = np.vstack([r[0] for r in rows]), np.vstack([r[1] for r in rows])
    unc = cKDTree(P).query(samples)[0] > fm.COVER_FACTOR * step
    print(f"coverage {100 * (1 - unc.mean()):.2f} % of {len(samples)} samples; uncovered by camtool face:")
    lab, models = face_labels(keep / f"{NAME}.toml", samples[unc])
    for i in np.unique(lab):
        print(f"  face {i:>3} {models.get(int(i), 'none'):<9} {100 * np.mean(lab == i) * unc.mean():5.2f} %")
    x = samples[unc][:, 0]
    for name, m in (("wall side x < 27", x < 27), ("rim side x > 170", x > 170), ("rest", (x >= 27) & (x <= 170))):
        print(f"  {name:<17} {100 * m.sum() / len(samples):5.2f} %")
    sub = mesh.submesh([np.flatnonzero(region)], append=True)
    refs = {"ball 12.5": fm.averaged_normals(mesh, P), "ball 6.25": fm.averaged_normals(mesh, P, 6.25),
            "face 12.5": fm.averaged_normals(sub, P), "face 6.25": fm.averaged_normals(sub, P, 6.25),
            "smooth side 12.5": smooth_side_normals(mesh, P, 12.5),
            "smooth side 6.25": smooth_side_normals(mesh, P, 6.25)}
    zones = {"wall side": P[:, 0] < 32, "rim side": P[:, 0] > 165,
             "far-end curl": (P[:, 1] > 765) & (P[:, 0] >= 32) & (P[:, 0] <= 165)}
    zones["rest"] = ~np.any(list(zones.values()), axis=0)
    print(f"tool axis of {len(P)} work poses, deg (p50 p95 max; p95 by zone: "
          + ", ".join(f"{k} {v.sum()}" for k, v in zones.items()) + ")")
    for name, n in refs.items():
        e = fm.axis_error_deg(A, n)
        by = "  ".join(f"{np.percentile(e[m], 95):5.2f}" for m in zones.values())
        print(f"  vs {name:<17} {np.percentile(e, 50):5.2f} {np.percentile(e, 95):5.2f} {e.max():5.2f}   {by}")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit(__doc__.strip().splitlines()[-1].strip())
    main(Path(sys.argv[1]))
