"""Segmentation accuracy on the multi-face samples (issue 26): models, parameters, boundaries.

For every part of scripts/make_samples.py (mesh and noisy scan) the faces found by
``camtool.part.segment`` are matched to the truth in samples/faces_truth.json and the
errors printed: normal / axis angle (deg), offset / centre / axis distance and
radius (mm), and the boundary's distance from the true outline (mm; the 95th
percentile and the largest, over the boundary polygons resampled every 0.1 mm
of their length, a full cylinder's seam left out)
next to half the sampling step (median point spacing / 2).

    PYTHONPATH=. python benchmarks/segment_accuracy.py [--json]
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from camtool.part.segment import SegmentSettings, segment  # noqa: E402
from camtool.part.workpiece import load_workpiece  # noqa: E402


def _angle_deg(a, b, signed=False) -> float:
    c = float(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b)))
    if not signed:
        c = abs(c)
    return float(np.degrees(np.arccos(np.clip(c, -1, 1))))


def param_errors(face, truth: dict) -> dict:
    """Errors of one found face against its truth (angles deg, lengths mm)."""
    s = face.surface
    if truth["model"] == "plane":
        n = np.asarray(truth["normal"])
        return {"angle_deg": _angle_deg(s.normal, n), "offset_mm": abs(abs(float(s.normal @ s.origin_mm))
                                                                      - abs(truth["offset_mm"]))
                if _angle_deg(s.normal, n, True) < 90 else abs(float(s.normal @ s.origin_mm) + truth["offset_mm"])}
    if truth["model"] == "sphere":
        return {"center_mm": float(np.linalg.norm(s.center_mm - truth["center_mm"])),
                "radius_mm": abs(s.radius_mm - truth["radius_mm"])}
    a = np.asarray(truth["axis"], float)
    d = s.center_mm - np.asarray(truth["axis_point_mm"], float)
    return {"angle_deg": _angle_deg(s.axis, a), "axis_mm": float(np.linalg.norm(d - (d @ a) * a)),
            "radius_mm": abs(s.radius_mm - truth["radius_mm"])}


def _cost(face, truth: dict) -> float:
    if face.model != truth["model"]:
        return np.inf
    e = param_errors(face, truth)
    outline = np.asarray(truth["outline_mm"])
    pts = face.surface.point_mm(*face.surface.boundary.outer_uv.T)
    # coplanar faces share parameters: the outlines decide
    return sum(e.values()) + 0.01 * float(np.linalg.norm(pts.mean(axis=0) - outline.mean(axis=0)))


def match(faces, truths) -> list:
    """Greedy lowest-cost matching: (truth index, face or None)."""
    pairs = sorted(((_cost(f, t), i, j) for i, t in enumerate(truths) for j, f in enumerate(faces)),
                   key=lambda x: x[0])
    used_t, used_f, out = set(), set(), {}
    for c, i, j in pairs:
        if np.isfinite(c) and i not in used_t and j not in used_f:
            used_t.add(i)
            used_f.add(j)
            out[i] = faces[j]
    return [(i, out.get(i)) for i in range(len(truths))]


def boundary_errors_mm(face, truth: dict) -> tuple[float, float]:
    """(95th percentile, largest) distance of the face's boundary from the true outline (mm)."""
    outline = np.asarray(truth["outline_mm"])
    seg = np.diff(np.vstack([outline, outline[:1]]), axis=0)
    dense = np.vstack([outline[k] + np.linspace(0, 1, max(2, int(np.linalg.norm(seg[k]) / 0.1)),
                                                   endpoint=False)[:, None] * seg[k] for k in range(len(seg))
                       if np.linalg.norm(seg[k]) < 10])  # jumps between border runs are not outline
    d, _ = cKDTree(dense).query(boundary_samples_mm(face))
    return float(np.percentile(d, 95)), float(d.max())


def boundary_samples_mm(face) -> np.ndarray:
    """Points every 0.1 mm along the face's boundary polygons on its surface (n, 3), so that a long straight
    edge weighs as much as its length; a full cylinder's seam (u = +-pi), a polygon edge and not an outline,
    left out."""
    s = face.surface
    out = []
    for poly in [s.boundary.outer_uv, *s.boundary.holes_uv]:
        closed = np.vstack([poly, poly[:1]])
        edge_mm = np.linalg.norm(np.diff(s.point_mm(closed[:, 0], closed[:, 1]), axis=0), axis=1)
        uv = np.vstack([closed[k] + np.linspace(0, 1, max(2, int(np.ceil(edge_mm[k] / 0.1))), endpoint=False)[:, None]
                        * (closed[k + 1] - closed[k]) for k in range(len(poly))])
        if s.model == "cylinder":
            uv = uv[np.abs(uv[:, 0]) < np.pi - 0.05]
        out.append(s.point_mm(uv[:, 0], uv[:, 1]))
    return np.concatenate(out)


def spacing_mm(points: np.ndarray) -> float:
    sub = points[np.linspace(0, len(points) - 1, min(len(points), 20000)).astype(int)]
    d, _ = cKDTree(points).query(sub, k=2)
    return float(np.median(d[:, 1]))


def evaluate(part: str, kind: str, truth_all: dict, settings: SegmentSettings | None = None) -> dict:
    file = ROOT / "samples" / (f"{part}.stl" if kind == "mesh" else f"{part}_scan.ply")
    wp = load_workpiece(file)
    seg = segment(wp, settings or SegmentSettings())
    truths = truth_all[part]["faces"]
    rows = []
    for i, face in match(seg.faces, truths):
        t = truths[i]
        row = {"truth": i, "model": t["model"], "found": face is not None}
        if face is not None:
            row.update(face=face.index, **{k: round(v, 4) for k, v in param_errors(face, t).items()})
            p95, mx = boundary_errors_mm(face, t)
            row.update(boundary_p95_mm=round(p95, 3), boundary_max_mm=round(mx, 3))
        rows.append(row)
    return {"part": part, "kind": kind, "faces_found": len(seg.faces), "faces_true": len(truths),
            "unassigned": seg.unassigned, "n_points": seg.n_points,
            "half_step_mm": round(0.5 * spacing_mm(wp.points_mm), 3), "faces": rows}


def main() -> None:
    truth_all = json.loads((ROOT / "samples" / "faces_truth.json").read_text())
    out = [evaluate(p, k, truth_all) for p in truth_all for k in ("mesh", "scan")]
    if "--json" in sys.argv:
        print(json.dumps(out, indent=1))
        return
    for r in out:
        print(f"{r['part']:<14} {r['kind']:<4} faces {r['faces_found']}/{r['faces_true']}  "
              f"unassigned {r['unassigned']}/{r['n_points']}  half step {r['half_step_mm']} mm")
        for f in r["faces"]:
            if not f["found"]:
                print(f"    truth {f['truth']} {f['model']:<8} NOT FOUND")
                continue
            errs = "  ".join(f"{k} {v:.3f}" for k, v in f.items()
                             if k not in ("truth", "model", "found", "face"))
            print(f"    truth {f['truth']} {f['model']:<8} -> face {f['face']}: {errs}")


if __name__ == "__main__":
    main()
