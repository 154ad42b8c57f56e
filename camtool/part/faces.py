"""Faces of a job's workpiece: the segmentation the job asks for, the selection, the picture.

``[faces] select`` (docs/faces.md) decides:

- ``"single"`` (the default): no segmentation; [fit] finds one surface, as before;
- ``"all"``, a model name, ``[indices]``, ``{largest = N}``, ``{nearest_mm = [x, y, z]}``:
  the placed workpiece is split into faces (``camtool.part.segment``), numbered
  largest first, and the selection picks from them.

A selection of several faces is worked in one program (``camtool.path.face_set``).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import BadInput
from .segment import Face, Segmentation, SegmentSettings, segment


@dataclass(frozen=True)
class FacesSettings:
    """What the faces of a job depend on, read from the job once (``camtool.run.part_stages.faces_settings``):
    the ``[faces] select`` value, the segmentation settings, the workpiece file, its placement (4x4, mm,
    units included) and the job's name for messages."""

    select: object
    segment: SegmentSettings
    workpiece_file: Path
    placement_mm: np.ndarray
    source: str = "job"

    @property
    def segmented(self) -> bool:
        """True when the job works faces of a segmentation (``faces.select`` is not 'single')."""
        return self.select != "single"


_LAST: dict = {}   # the last segmentation of this process: the fit stage's, read again by the report


def segment_faces(settings: FacesSettings, workpiece) -> Segmentation:
    """The faces of the job's placed workpiece; a STEP part's analytic faces are taken exactly.
    The last result is kept for the same workpiece object and settings (the fit stage segments,
    the report shows the same faces without segmenting again)."""
    key = (id(workpiece), str(settings.workpiece_file), settings.segment, settings.placement_mm.tobytes())
    if _LAST.get("key") == key and _LAST.get("workpiece") is workpiece:
        return _LAST["value"]
    value = _segment(settings, workpiece)
    _LAST.clear()
    _LAST.update(key=key, workpiece=workpiece, value=value)
    return value


def faces_report(settings: FacesSettings, workpiece) -> dict:
    """report.json's ``faces``: the selection and every face's ``camtool faces --json`` entry, with
    ``selected``, plus each workpiece point's face (``labels``, -1 for none; for report.html only)."""
    seg = segment_faces(settings, workpiece)
    chosen = {f.index for f in select_faces(seg, settings.select, workpiece, settings.source)}
    labels = np.full(seg.n_points, -1, int)
    for f in seg.faces:
        labels[f.inliers] = f.index
    return {"select": settings.select, "unassigned_points": int(seg.unassigned),
            "dropped_faces": int(seg.dropped_faces),
            "faces": [{**f.summary(), "selected": f.index in chosen} for f in seg.faces], "labels": labels}


def _segment(settings: FacesSettings, workpiece) -> Segmentation:
    file = settings.workpiece_file
    if file.suffix.lower() in (".step", ".stp"):
        return step_segmentation(file, workpiece, settings.placement_mm, settings.segment)
    return segment(workpiece, settings.segment)


def step_segmentation(file: Path, workpiece, T_mm: np.ndarray, settings: SegmentSettings) -> Segmentation:
    """The faces of a STEP part: plane, sphere and cylinder B-rep faces exactly (``camtool.part.step``), the
    others as free-form faces, B-rep faces meeting tangentially joined (``step_freeform``; RANSAC takes the points
    of those that give none). Each workpiece point belongs to the B-rep face of its nearest triangle."""
    import trimesh

    from .fit import cylinder_surface, plane_surface, sphere_patch
    from .sampling import MIN_FACE_SAMPLES
    from .segment import area_mm2, boundaries_on_edges, boundary_on_points
    from .step import read_step_faces, step_mesh
    from .step_freeform import BrepMesh, freeform_step_faces
    from .surface import FitStats

    R, t = T_mm[:3, :3], T_mm[:3, 3]
    scale = float(np.cbrt(np.linalg.det(R)))
    rot = R / scale
    verts, tris, owner = step_mesh(file)
    mesh = trimesh.Trimesh(verts @ R.T + t, tris, process=False)
    P = np.asarray(workpiece.points_mm, float)
    N = np.asarray(workpiece.normals, float)
    label = owner[nearest_triangle(mesh, P)]
    bkw = dict(cell_mm=settings.boundary_cell_mm, close_gaps_mm=settings.close_gaps_mm,
               simplify_mm=settings.simplify_mm, source=str(file))
    built, rest = [], []
    step_faces = read_step_faces(file)
    by_face = np.argsort(label, kind="stable")   # each face's points, ascending: one sort, not a pass per face
    starts = np.searchsorted(label[by_face], np.arange(len(step_faces) + 1))
    for k, f in enumerate(step_faces):
        idx = by_face[starts[k]:starts[k + 1]]
        if f.model == "other":
            rest.append(idx)
            continue
        if len(idx) < MIN_FACE_SAMPLES:
            continue
        Q, NQ = P[idx], N[idx]
        if f.model == "plane":
            n = rot @ f.params[0]
            d = scale * f.params[1] + float(n @ t)
            res = np.abs(Q @ n - d)
            make = lambda st, Q=Q, NQ=NQ, n=n, d=d: plane_surface(Q, NQ, n, d, st, bkw)  # noqa: E731
        elif f.model == "sphere":
            c, r = R @ f.params[0] + t, scale * f.params[1]
            res = np.abs(np.linalg.norm(Q - c, axis=1) - r)
            make = lambda st, Q=Q, NQ=NQ, c=c, r=r: sphere_patch(Q, NQ, c, r, st, bkw)  # noqa: E731
        else:
            c, a, r = R @ f.params[0] + t, rot @ f.params[1], scale * f.params[2]
            res = np.abs(np.linalg.norm((Q - c) - ((Q - c) @ a)[:, None] * a, axis=1) - r)
            make = lambda st, Q=Q, NQ=NQ, c=c, a=a, r=r: cylinder_surface(Q, NQ, c, a, r, st, bkw)  # noqa: E731
        stats = FitStats(len(idx) / len(P), float(np.sqrt(np.mean(res ** 2))), float(res.max()), len(P), len(idx))
        built.append((boundary_on_points(make(stats), Q), idx))
    dropped, free, held = 0, [], None
    if rest and settings.freeform_faces:   # the other faces: free-form faces, tangent ones joined
        other = np.array([k for k, f in enumerate(step_faces) if f.model == "other"], np.int64)
        free, rest = freeform_step_faces(BrepMesh(mesh.vertices.view(np.ndarray), tris, owner), other, label,
                                         lambda k: by_face[starts[k]:starts[k + 1]], workpiece, settings)
        # the points of the B-rep faces made free-form (on a face or not) are no analytic face's extent
        made = np.concatenate([by_face[starts[k]:starts[k + 1]] for k in other])
        held = np.setdiff1d(made, np.concatenate(rest)) if rest else made
    if rest:  # the other faces that gave no free-form face: RANSAC on their points
        found, dropped = _ransac_faces(P, N, np.concatenate(rest), file, settings)
        built += found
    kept = [(s, idx) for s, idx in built if area_mm2(s) >= settings.min_area_mm2]
    dropped += len(built) - len(kept)
    if kept:  # the B-rep faces' exact surfaces meet exactly: their boundaries go onto those edges
        moved = boundaries_on_edges([s for s, _ in kept], [idx for _, idx in kept], workpiece, settings.threshold_mm,
                                    held)
        kept = [(s, idx) for s, (_, idx) in zip(moved, kept)]
    kept += free   # (a free-form face's boundary is its own triangles': on its B-rep edges already)
    areas = [area_mm2(s) for s, _ in kept]
    order = sorted(range(len(kept)), key=lambda k: (-round(areas[k], 6), k))
    faces = tuple(Face(i, kept[k][0], kept[k][1], areas[k]) for i, k in enumerate(order))
    return Segmentation(faces, len(P), len(P) - sum(len(f.inliers) for f in faces), dropped)


def _ransac_faces(P: np.ndarray, N: np.ndarray, idx: np.ndarray, file: Path, settings: SegmentSettings):
    """(the ``(surface, inliers)`` RANSAC finds on the points ``idx`` as planes, spheres and cylinders only, the
    faces it dropped): a STEP part's other B-rep faces that gave no free-form face. Their free-form charts would not
    take the B-rep edges' boundary pass. Too few points, or none found (the leftovers of free-form groups, small
    strips): none, the points on no face."""
    from .sampling import MIN_FACE_SAMPLES
    from .workpiece import Workpiece

    if len(idx) < 4 * MIN_FACE_SAMPLES:
        return [], 0
    try:
        sub = segment(Workpiece(P[idx], N[idx], source=str(file)), replace(settings, freeform_faces=False))
    except BadInput:
        return [], 0
    return [(f.surface, idx[f.inliers]) for f in sub.faces], sub.dropped_faces


ON_MESH_MM = 1e-7       # a point this near a triangle lies on the mesh (sampled from it)
CHUNK_POINTS = 20000    # points per block of the nearest-triangle search: bounds its memory


def nearest_triangle(mesh, P: np.ndarray) -> np.ndarray:
    """The index of the triangle of ``mesh`` nearest to each point P (n, 3), as ``trimesh.proximity.closest_point``
    gives it, in bounded memory and time (at an exact tie, as on the coincident faces of two bodies of an
    assembly, the lowest-numbered triangle).

    The workpiece's points are sampled from this very mesh, so each lies on a triangle: its candidates are the
    triangles whose box holds the point (within ``ON_MESH_MM``; found by ``box_grid.BoxGrid``), a handful,
    where trimesh's search takes every triangle within the distance to the nearest vertex (on a part of large
    flat triangles, thousands per point: gigabytes). The nearest candidate is the nearest triangle; a point on
    no candidate (not on the mesh) takes the nearest triangle within a reach grown tenfold until one is met,
    farther than a grid cell by trimesh itself. Block by block (``CHUNK_POINTS``)."""
    import trimesh

    from .box_grid import BoxGrid

    P = np.asarray(P, float)
    tri_id = np.full(len(P), -1, np.int64)
    triangles = mesh.triangles.view(np.ndarray)
    grid = BoxGrid(triangles.min(axis=1) - ON_MESH_MM, triangles.max(axis=1) + ON_MESH_MM, P)
    for a in range(0, len(P), CHUNK_POINTS):
        Q = P[a:a + CHUNK_POINTS]
        row, hit = grid.holding(Q)
        if len(hit):
            close = trimesh.triangles.closest_point(triangles[hit], Q[row])
            d2 = np.einsum("ij,ij->i", Q[row] - close, Q[row] - close)
            order = np.lexsort((hit, d2, row))   # per point, its candidates nearest first (a tie: the first)
            first = order[np.r_[True, row[order][1:] != row[order][:-1]]]
            on = d2[first] <= ON_MESH_MM ** 2
            tri_id[a + row[first[on]]] = hit[first[on]]
    rest = np.flatnonzero(tri_id < 0)
    reach = 10 * ON_MESH_MM
    while len(rest) and reach <= grid.cell:   # points off the mesh (the loader merged vertices within 1e-8 of
        Q = P[rest]                           # each other): the nearest triangle within ``reach`` is the nearest
        row, hit = grid.holding(Q, reach)     # of all (every triangle that near is among those met)
        close = trimesh.triangles.closest_point(triangles[hit], Q[row])
        d2 = np.einsum("ij,ij->i", Q[row] - close, Q[row] - close)
        order = np.lexsort((hit, d2, row))
        first = order[np.r_[True, row[order][1:] != row[order][:-1]]] if len(order) else order
        found = d2[first] <= reach ** 2
        tri_id[rest[row[first[found]]]] = hit[first[found]]
        rest, reach = np.flatnonzero(tri_id < 0), reach * 10.0
    for a in range(0, len(rest), CHUNK_POINTS // 10):   # farther off: trimesh's own search
        idx = rest[a:a + CHUNK_POINTS // 10]
        tri_id[idx] = trimesh.proximity.closest_point(mesh, P[idx])[2]
    return tri_id


def _distance_mm(face: Face, workpiece, point_mm: np.ndarray) -> float:
    pts = np.asarray(workpiece.points_mm)[face.inliers]
    return float(np.min(np.linalg.norm(pts - point_mm, axis=1)))


def select_faces(seg: Segmentation, select, workpiece=None, source: str = "job") -> list[Face]:
    """The faces ``select`` names (see the module docstring), in index order; BadInput when none."""
    faces = list(seg.faces)
    if select == "all":
        chosen = faces
    elif isinstance(select, str):
        chosen = [f for f in faces if f.model == select]
    elif isinstance(select, list):
        missing = [i for i in select if i >= len(faces)]
        if missing:
            raise BadInput(f"{source}: faces.select names face {missing[0]}, but the workpiece has {len(faces)} "
                           f"faces (0..{len(faces) - 1}); see `camtool faces JOB`")
        chosen = [faces[i] for i in sorted(select)]
    elif "largest" in select:
        chosen = faces[:select["largest"]]
    else:
        p = np.asarray(select["nearest_mm"], float)
        chosen = [min(faces, key=lambda f: (_distance_mm(f, workpiece, p), f.index))]
    if not chosen:
        raise BadInput(f"{source}: faces.select = {select!r} selects no face (the workpiece has "
                       f"{', '.join(f'{f.index}: {f.model}' for f in faces)}); see `camtool faces JOB`")
    return chosen


def faces_png(seg: Segmentation, workpiece, path: Path, title: str = "") -> Path:
    """A picture of the faces: the points coloured by face, each face numbered at its middle (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..files import output_file

    P = np.asarray(workpiece.points_mm)
    fig = plt.figure(figsize=(8, 7), dpi=110)
    ax = fig.add_subplot(projection="3d")
    cmap = plt.get_cmap("tab20")
    rng = np.random.default_rng(0)
    for f in seg.faces:
        idx = f.inliers
        if len(idx) > 4000:
            idx = np.sort(rng.choice(idx, 4000, replace=False))
        Q = P[idx]
        ax.scatter(Q[:, 0], Q[:, 1], Q[:, 2], s=1, color=cmap(f.index % 20), depthshade=False)
        mid = P[f.inliers].mean(axis=0)
        ax.text(*mid, f"{f.index}: {f.model}", fontsize=9, weight="bold", color="black")
    lo, hi = P.min(axis=0), P.max(axis=0)
    half = 0.5 * float((hi - lo).max())
    c = 0.5 * (lo + hi)
    ax.set_xlim(c[0] - half, c[0] + half)
    ax.set_ylim(c[1] - half, c[1] + half)
    ax.set_zlim(c[2] - half, c[2] + half)
    ax.set_xlabel("x mm")
    ax.set_ylabel("y mm")
    ax.set_zlabel("z mm")
    ax.set_title(title or f"{len(seg.faces)} faces")
    out = output_file(path)
    fig.savefig(out)
    plt.close(fig)
    return out
