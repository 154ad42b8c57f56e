"""Issue #46's acceptance figures, computed from a part's own mesh and a set of work poses, with
nothing of camtool: used by benchmarks/freeform.py on camtool's output and on the noether baseline
(rebuilt here, `plane_slicer`), and checked against closed forms by tests/test_freeform_metrics.py.

Work poses are given as rows: a list of (points (n, 3) mm, tool axes (n, 3) unit) arrays, one per
row segment in working order. The figures (issue #46, "Acceptance"):

- ``coverage``: share of the face's area within ``0.6 x step_over`` of a work TCP (area-uniform
  samples of the face, 3-D distance to the nearest TCP);
- ``distance_to_mesh``: distance of each work TCP to the part's mesh (closest point on a triangle);
- ``axis_error_deg``: angle between the tool axis and the part's normal averaged over a disc of
  ``radius_mm`` (12.5 mm: the middle of the issue's 10-15 mm) around the TCP's closest point: the
  area-weighted mean of the triangles' normals whose centroid lies within the radius, each turned
  to agree with the closest triangle's (so a scan's inconsistent winding does not cancel it out).
  Unsigned (a tool axis along +n or -n counts the same); a flip shows in ``turns_deg``;
- ``turns_deg``: the angle between the tool axes of neighbouring work poses of one row;
- ``row_steps``: the distance between neighbouring rows measured on the surface: for each work
  TCP, the geodesic distance to the nearest other row whose nearest pose is not one of its ends
  (a row's end is no neighbour: a row split at a hole or a shorter row beside a longer one);
  geodesics on the mesh by Dijkstra on a Steiner graph (``STEINER`` points on every edge, every
  pair of a triangle's points joined by a straight segment across it: Lanthier, Maheshwari and
  Sack, "Approximating shortest paths on weighted polyhedral surfaces", 2001), which is within
  about 1 % of the true geodesic (the closed-form tests bound it).

The baseline, ``plane_slicer``: ros-industrial/noether's PlaneSlicerRasterPlanner
(noether_tpp/src/tool_path_planners/raster/plane_slicer_raster_planner.cpp) rebuilt: PCA of the
mesh's vertices; the cut direction is the second principal axis (PrincipalAxisDirectionGenerator),
the cutting planes' normal the cut direction x the smallest axis (so the planes advance along the
largest axis), the origin the centroid; planes every ``line_spacing`` measured along that normal
(in space, not on the surface) over the oriented box; each plane's cut polylines (vtkCutter +
vtkStripper: here trimesh's ``mesh_plane`` segments chained end to end) with the normals
interpolated linearly from the mesh's vertex normals along the cut edges, then resampled at a
uniform ``point_spacing`` (noether's uniform-spacing modifier) with the normals interpolated
linearly between the cut points.

Run as a script, it prints the closed-form checks (`make bench` runs every benchmarks/*.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh
from scipy import sparse
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

STEINER = 4          # Steiner points on each edge of the geodesic graph
AXIS_RADIUS_MM = 12.5
COVER_FACTOR = 0.6   # coverage radius, in step-overs (issue #46)


# --- the part -------------------------------------------------------------------------------
def load_mesh(path, scale: float = 1.0) -> trimesh.Trimesh:
    """The mesh in mm: duplicate vertices merged (a triangle soup gets its connectivity), degenerate
    and duplicate triangles and unreferenced vertices dropped."""
    m = trimesh.load(str(path), force="mesh", process=True)
    m = trimesh.Trimesh(m.vertices * scale, m.faces, process=True)
    m.update_faces(m.nondegenerate_faces(height=1e-9))
    m.update_faces(m.unique_faces())
    m.remove_unreferenced_vertices()
    return m


def face_region(mesh: trimesh.Trimesh, up=None, max_tilt_deg: float | None = None,
                radius_mm: float = AXIS_RADIUS_MM) -> np.ndarray:
    """Mask of the triangles that make the face to be worked: the largest connected piece (by area)
    of the triangles whose normal, averaged over ``radius_mm``, lies within ``max_tilt_deg`` of
    ``up`` (either sign: a scan's winding is not trusted); all triangles without ``up``."""
    keep = np.ones(len(mesh.faces), bool)
    if up is not None and max_tilt_deg is not None:
        n = averaged_normals(mesh, mesh.triangles_center, radius_mm, fine=False)
        up = np.asarray(up, float) / np.linalg.norm(up)
        keep = np.abs(n @ up) >= math.cos(math.radians(max_tilt_deg))
    adj = mesh.face_adjacency
    adj = adj[keep[adj[:, 0]] & keep[adj[:, 1]]]
    g = sparse.coo_matrix((np.ones(len(adj)), (adj[:, 0], adj[:, 1])), shape=(len(keep),) * 2)
    _, lab = csgraph.connected_components(g, directed=False)
    area = np.bincount(lab[keep], weights=mesh.area_faces[keep], minlength=lab.max() + 1)
    return keep & (lab == int(np.argmax(area)))


def surface_samples(mesh: trimesh.Trimesh, mask: np.ndarray | None = None, spacing_mm: float = 2.0,
                    seed: int = 0) -> np.ndarray:
    """Area-uniform random points on the masked triangles, about one per spacing_mm^2 (trimesh's sampler)."""
    idx = np.flatnonzero(mask) if mask is not None else np.arange(len(mesh.faces))
    part = trimesh.Trimesh(mesh.vertices, mesh.faces[idx], process=False)
    n = max(1000, int(part.area_faces.sum() / spacing_mm ** 2))
    return np.asarray(trimesh.sample.sample_surface(part, n, seed=seed)[0])


# --- the figures ----------------------------------------------------------------------------
def coverage(samples: np.ndarray, tcps: np.ndarray, radius_mm: float) -> float:
    """Share of the samples (area-uniform on the face) within radius_mm of a TCP."""
    if len(tcps) == 0:
        return 0.0
    d, _ = cKDTree(tcps).query(samples, distance_upper_bound=radius_mm)
    return float(np.mean(np.isfinite(d)))


def closest(mesh: trimesh.Trimesh, pts: np.ndarray):
    """(closest points, distances, triangle ids) on the mesh."""
    c, d, f = trimesh.proximity.closest_point(mesh, np.asarray(pts, float))
    return c, d, f


def distance_to_mesh(mesh: trimesh.Trimesh, pts: np.ndarray) -> np.ndarray:
    return closest(mesh, pts)[1]


AXIS_QUADRATURE_EDGE = 0.2   # the axis figure's disc mean is taken over triangles at most this x its radius


def averaged_normals(mesh: trimesh.Trimesh, pts: np.ndarray, radius_mm: float = AXIS_RADIUS_MM,
                     fine: bool = True) -> np.ndarray:
    """The part's normal at each point: its mean over the mesh within radius_mm of the point's closest point
    (area-weighted, each turned to agree with the closest triangle's normal), a quadrature over the triangles whose
    centroid lies in the disc. ``fine``: over the mesh's triangles cut to edges of at most
    ``AXIS_QUADRATURE_EDGE`` x radius_mm (trimesh's subdivision: each piece keeps its triangle's plane and normal).
    Over the file's own triangles, a coarse mesh's few centroids (noether's wavy sheet: triangles 4-36 mm across)
    fell in or out of a 12.5 mm disc and moved its mean 4.7 deg (p95) from the disc's own
    (benchmarks/freeform_axis_quadrature.py); the face's selection (``face_region``) needs no more than that."""
    c, _, f = closest(mesh, pts)
    if fine:
        V, F, parent = trimesh.remesh.subdivide_to_size(np.asarray(mesh.vertices, float), mesh.faces,
                                                        max_edge=AXIS_QUADRATURE_EDGE * radius_mm, return_index=True)
        pieces = trimesh.Trimesh(V, F, process=False)
        fn, fa, centres = mesh.face_normals[parent], pieces.area_faces, pieces.triangles_center
    else:
        fn, fa, centres = mesh.face_normals, mesh.area_faces, mesh.triangles_center
    tree = cKDTree(centres)
    out = np.empty((len(c), 3))
    for i, (p, f0) in enumerate(zip(c, f)):
        near = tree.query_ball_point(p, radius_mm)
        n0 = mesh.face_normals[f0]
        if not near:
            out[i] = n0
            continue
        nn = fn[near]
        s = np.where(nn @ n0 < 0, -1.0, 1.0)
        v = (nn * (s * fa[near])[:, None]).sum(axis=0) + 1e-12 * n0
        out[i] = v / np.linalg.norm(v)
    return out


TANGENT_SEAM_DEG = 10.0   # two CAD faces are one where the median dihedral angle across their seam is under this
SHARP_EDGE_DEG = 30.0     # a mesh file's faces: its triangles split where neighbours' normals turn more than this


def worked_faces(mesh: trimesh.Trimesh, owner: np.ndarray | None = None) -> np.ndarray:
    """A label per triangle: the part's smooth faces, bounded by sharp edges. ``owner`` (each triangle's B-rep face,
    a STEP part): the CAD's faces joined where they meet tangent, the median dihedral angle of the mesh's edges
    along their seam under ``TANGENT_SEAM_DEG`` (the 1:300 hull's skin patches: 0.1-1.2 deg; its bilge keel's fin
    on the skin: 25-37 deg); without: the triangles joined across edges whose dihedral angle is under
    ``SHARP_EDGE_DEG`` (camtool's own default for ``faces.sharp_edge_deg``; trimesh's face adjacency)."""
    adj, ang = mesh.face_adjacency, np.degrees(mesh.face_adjacency_angles)
    if owner is None:
        join, n, of = adj[ang < SHARP_EDGE_DEG], len(mesh.faces), np.arange(len(mesh.faces))
    else:
        of = np.asarray(owner, np.int64)
        a, b = of[adj[:, 0]], of[adj[:, 1]]
        seam = a != b
        n = int(of.max()) + 1
        pairs, inv = np.unique(np.stack([np.minimum(a, b), np.maximum(a, b)], 1)[seam], axis=0, return_inverse=True)
        median = np.array([np.median(ang[seam][inv.ravel() == k]) for k in range(len(pairs))])
        join = pairs[median < TANGENT_SEAM_DEG] if len(pairs) else np.zeros((0, 2), np.int64)
    g = sparse.coo_matrix((np.ones(len(join)), (join[:, 0], join[:, 1])), shape=(n, n))
    return csgraph.connected_components(g, directed=False)[1][of]


def own_face_normals(mesh: trimesh.Trimesh, pts: np.ndarray, faces: np.ndarray,
                     radius_mm: float = AXIS_RADIUS_MM) -> np.ndarray:
    """The part's normal on the face being worked at each point: ``averaged_normals`` over the triangles of the
    face (``faces``: a label per triangle, ``worked_faces``) that holds the point's closest triangle, and no
    other's (a neighbouring feature across a sharp edge, such as a hull's fin, is left out of the disc)."""
    faces = np.asarray(faces)
    out = np.empty((len(pts), 3))
    if not len(pts):
        return out
    c, _, f = closest(mesh, pts)
    label = faces[f]
    for g in np.unique(label):
        k = np.flatnonzero(label == g)
        out[k] = averaged_normals(trimesh.Trimesh(mesh.vertices, mesh.faces[faces == g], process=False), c[k],
                                  radius_mm)
    return out


WORKED_SHARE = 0.01   # a smooth face holding this share of the work TCPs' closest triangles is a worked face


def worked_coverage(mesh: trimesh.Trimesh, samples: np.ndarray, tcps: np.ndarray, faces: np.ndarray,
                    step_mm: float) -> float:
    """``coverage`` of the face's samples that lie on the faces worked (``faces``: a label per triangle,
    ``worked_faces``; worked: holding ``WORKED_SHARE`` of the TCPs' closest triangles). The face selected by its
    triangles' normals (``face_region``) may take in a strip of a neighbouring face at an angle to it (the IEA
    blade's blunt trailing edge): this figure tells that apart from a miss on the face worked."""
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(np.asarray(mesh.vertices, np.float32)),
                        o3d.core.Tensor(np.asarray(mesh.faces, np.uint32)))

    def tri(p):
        ids = scene.compute_closest_points(o3d.core.Tensor(np.asarray(p, np.float32)))["primitive_ids"]
        return ids.numpy().astype(np.int64)

    label, count = np.unique(np.asarray(faces)[tri(tcps)], return_counts=True)
    on = np.isin(np.asarray(faces)[tri(samples)], label[count >= WORKED_SHARE * len(tcps)])
    return coverage(samples[on], tcps, COVER_FACTOR * step_mm) if on.any() else float("nan")


def axis_error_deg(axes: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Unsigned angle (deg) between each tool axis and the normal line."""
    a = axes / np.linalg.norm(axes, axis=1, keepdims=True)
    return np.degrees(np.arccos(np.clip(np.abs(np.sum(a * normals, axis=1)), 0.0, 1.0)))


def turns_deg(rows: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """Angle (deg) between the tool axes of neighbouring poses of each row (signed axes: a flip is 180)."""
    out = []
    for _, ax in rows:
        if len(ax) > 1:
            a = ax / np.linalg.norm(ax, axis=1, keepdims=True)
            out.append(np.degrees(np.arccos(np.clip(np.sum(a[1:] * a[:-1], axis=1), -1.0, 1.0))))
    return np.concatenate(out) if out else np.zeros(0)


# --- geodesics ------------------------------------------------------------------------------
class SurfaceGeodesic:
    """Approximate geodesic distances on a triangle mesh: Dijkstra on a Steiner graph (STEINER
    points on every edge, a triangle's points joined pairwise by straight segments across it),
    built once; each query adds a source node joined to its points' triangles."""

    def __init__(self, mesh: trimesh.Trimesh, steiner: int = STEINER):
        self.mesh = mesh
        v, e = mesh.vertices, mesh.edges_unique
        t = np.arange(1, steiner + 1) / (steiner + 1)
        st = v[e[:, 0], None, :] + t[None, :, None] * (v[e[:, 1]] - v[e[:, 0]])[:, None, :]
        self.nodes = np.vstack([v, st.reshape(-1, 3)])
        # each face's nodes: its 3 vertices, then the Steiner points of its 3 edges
        fe = mesh.faces_unique_edges
        st_ids = len(v) + fe[:, :, None] * steiner + np.arange(steiner)[None, None, :]
        self.face_nodes = np.hstack([mesh.faces, st_ids.reshape(len(fe), -1)])
        k = self.face_nodes.shape[1]
        pairs = np.array([(i, j) for i in range(k) for j in range(i + 1, k)])
        a = self.face_nodes[:, pairs[:, 0]].ravel()
        b = self.face_nodes[:, pairs[:, 1]].ravel()
        ab = np.unique(np.stack([np.minimum(a, b), np.maximum(a, b)], 1), axis=0)
        ab = ab[ab[:, 0] != ab[:, 1]]
        w = np.maximum(np.linalg.norm(self.nodes[ab[:, 0]] - self.nodes[ab[:, 1]], axis=1), 1e-12)
        n = len(self.nodes)
        self.graph = sparse.csr_matrix((np.concatenate([w, w]), (np.concatenate([ab[:, 0], ab[:, 1]]),
                                        np.concatenate([ab[:, 1], ab[:, 0]]))), shape=(n, n))

    def distances(self, src: np.ndarray, dst: np.ndarray, limit: float, dst_closest=None) -> np.ndarray:
        """Geodesic distance from the nearest of the points src to each point dst (both are projected
        on the mesh first; dst_closest: dst's (points, triangles) on the mesh if known); inf beyond
        limit (mm)."""
        cs, _, fs = closest(self.mesh, src)
        if dst_closest is None:
            cd, _, fd = closest(self.mesh, dst)
        else:
            cd, fd = dst_closest
        G, n = self.graph, len(self.nodes)
        # a source node (index n) joined to each source triangle's nodes at their straight distance,
        # the smallest weight where several sources share a node
        sn = self.face_nodes[fs].ravel()
        sw = np.linalg.norm(self.nodes[self.face_nodes[fs]] - cs[:, None, :], axis=2).ravel()
        o = np.lexsort((sw, sn))
        first = np.ones(len(o), bool)
        first[1:] = sn[o][1:] != sn[o][:-1]
        cols, wts = sn[o][first], np.maximum(sw[o][first], 1e-12)
        g = sparse.csr_matrix((np.concatenate([G.data, wts]), np.concatenate([G.indices, cols]),
                               np.concatenate([G.indptr, [G.nnz + len(cols)]])), shape=(n + 1, n + 1))
        dist = csgraph.dijkstra(g, directed=True, indices=n, limit=limit * 1.05)
        dn = self.face_nodes[fd]                                  # (nd, k)
        out = np.min(dist[dn] + np.linalg.norm(self.nodes[dn] - cd[:, None, :], axis=2), axis=1)
        # a target on a source's own triangle: the straight segment
        same: dict[int, list[int]] = {}
        for i, f in enumerate(fs.tolist()):
            same.setdefault(f, []).append(i)
        for j, f in enumerate(fd.tolist()):
            if f in same:
                out[j] = min(out[j], float(np.min(np.linalg.norm(cs[same[f]] - cd[j], axis=1))))
        out[out > limit] = np.inf
        return out


def _foot(row: np.ndarray, q: np.ndarray, j: np.ndarray) -> np.ndarray:
    """The nearest point of the polyline row to each q, given the nearest vertex j."""
    best, out = np.full(len(q), np.inf), row[j].copy()
    for a in (j - 1, j):
        ok = (a >= 0) & (a + 1 < len(row))
        a = np.clip(a, 0, len(row) - 2)
        s0, s1 = row[a], row[a + 1]
        t = np.clip(np.sum((q - s0) * (s1 - s0), 1) / np.maximum(np.sum((s1 - s0) ** 2, 1), 1e-12), 0, 1)
        f = s0 + t[:, None] * (s1 - s0)
        d = np.linalg.norm(q - f, axis=1)
        take = ok & (d < best)
        best[take], out[take] = d[take], f[take]
    return out


def _chord_path(mesh: trimesh.Trimesh, row: np.ndarray, q: np.ndarray, j: np.ndarray, n: int = 8) -> np.ndarray:
    """Length of the straight segment from q to its foot on the row, projected on the mesh (n pieces):
    a path on the surface, so never much shorter than the geodesic, and much nearer it than the
    Steiner graph's on a smooth stretch; inf where the projection jumps (the segment spans a pocket,
    a fold or a gap: the graph's path counts there)."""
    f = _foot(row, q, j)
    t = np.linspace(0.0, 1.0, n + 1)
    pts = q[:, None, :] + t[None, :, None] * (f - q)[:, None, :]
    proj = closest(mesh, pts.reshape(-1, 3))[0].reshape(pts.shape)
    seg = np.linalg.norm(np.diff(proj, axis=1), axis=2)
    straight = np.linalg.norm(f - q, axis=1)[:, None] / n
    jump = np.any(seg > 2.0 * straight + 0.05, axis=1)
    return np.where(jump, np.inf, seg.sum(axis=1))


def row_steps(geo: SurfaceGeodesic, rows: list[np.ndarray], step_mm: float, reach: float = 3.0,
              end_points: int = 1) -> np.ndarray:
    """The distance between neighbouring rows on the surface, one value per work TCP that has a
    neighbour row within reach x step_mm: the geodesic distance to the nearest other row whose
    nearest pose (straight distance) is not among its first or last end_points poses."""
    rows = [np.asarray(r, float) for r in rows if len(r) >= 2 * end_points + 1]
    if len(rows) < 2:
        return np.zeros(0)
    allp = np.vstack(rows)
    rid = np.concatenate([np.full(len(r), i) for i, r in enumerate(rows)])
    best = np.full(len(allp), np.inf)
    limit = reach * step_mm
    cp, _, cf = closest(geo.mesh, allp)
    for i, r in enumerate(rows):
        tree = cKDTree(r)
        d0, j = tree.query(allp, distance_upper_bound=limit)
        ok = (rid != i) & np.isfinite(d0) & (j >= end_points) & (j < len(r) - end_points)
        if not ok.any():
            continue
        d = np.minimum(geo.distances(r, allp[ok], limit, (cp[ok], cf[ok])),
                       _chord_path(geo.mesh, r, allp[ok], j[ok]))
        best[ok] = np.minimum(best[ok], d)
    return best[np.isfinite(best)]


# --- the baseline: noether's PlaneSlicerRasterPlanner ---------------------------------------
def _chain(segs: np.ndarray, nrm: np.ndarray, tol: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Chain plane-cut segments (m, 2, 3) with per-end normals into polylines (vtkStripper)."""
    key = np.round(segs.reshape(-1, 3) / tol).astype(np.int64)
    _, ids = np.unique(key, axis=0, return_inverse=True)
    ids = ids.reshape(-1, 2)
    adj: dict[int, list[int]] = {}
    for s, (a, b) in enumerate(ids):
        adj.setdefault(int(a), []).append(s)
        adj.setdefault(int(b), []).append(s)
    used = np.zeros(len(segs), bool)
    out = []
    starts = [k for k, v in adj.items() if len(v) == 1] + list(adj)
    for start in starts:
        if all(used[s] for s in adj[start]):
            continue
        node, pts, nor = start, [], []
        while True:
            nxt = [s for s in adj[node] if not used[s]]
            if not nxt:
                break
            s = nxt[0]
            used[s] = True
            e = 0 if ids[s, 0] == node else 1
            if not pts:
                pts.append(segs[s, e])
                nor.append(nrm[s, e])
            pts.append(segs[s, 1 - e])
            nor.append(nrm[s, 1 - e])
            node = int(ids[s, 1 - e])
        if len(pts) >= 2:
            out.append((np.array(pts), np.array(nor)))
    return out


def _resample(p: np.ndarray, n: np.ndarray, spacing: float):
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] < 1e-9:
        return p[:1], n[:1]
    t = np.linspace(0.0, s[-1], max(2, int(math.ceil(s[-1] / spacing)) + 1))
    pp = np.stack([np.interp(t, s, p[:, k]) for k in range(3)], 1)
    nn = np.stack([np.interp(t, s, n[:, k]) for k in range(3)], 1)
    return pp, nn / np.maximum(np.linalg.norm(nn, axis=1, keepdims=True), 1e-12)


def plane_slicer(mesh: trimesh.Trimesh, line_spacing: float, point_spacing: float,
                 cut_normal=None) -> list[tuple[np.ndarray, np.ndarray]]:
    """noether's PlaneSlicerRasterPlanner on mesh: rows of (points, unit normals), in cut order.
    cut_normal: the planes' normal (default: from PCA as noether's principal-axis generator)."""
    v = mesh.vertices
    centroid = v.mean(axis=0)
    _, _, vt = np.linalg.svd(v - centroid, full_matrices=False)
    if cut_normal is None:
        cut_dir, mesh_normal = vt[1], vt[2]
        cut_normal = np.cross(cut_dir, mesh_normal)
    else:
        cut_normal = np.asarray(cut_normal, float)
        cut_dir = np.cross(vt[2], cut_normal)
        if np.linalg.norm(cut_dir) < 1e-9:
            cut_dir = vt[1]
    cut_normal = cut_normal / np.linalg.norm(cut_normal)
    cut_dir = cut_dir / np.linalg.norm(cut_dir)
    h = (v - centroid) @ cut_normal
    k0, k1 = int(math.floor(h.min() / line_spacing)), int(math.ceil(h.max() / line_spacing))
    vn = mesh.vertex_normals
    rows = []
    tol = 1e-6 * max(1.0, float(np.ptp(v, axis=0).max()))
    for k in range(k0, k1 + 1):
        origin = centroid + k * line_spacing * cut_normal
        segs, faces = trimesh.intersections.mesh_plane(mesh, cut_normal, origin, return_faces=True)
        if len(segs) == 0:
            continue
        # the normal at each cut point: linear in the vertex normals along the cut edge
        tri = mesh.faces[faces]
        nrm = np.empty_like(segs)
        for e in range(2):
            p = segs[:, e]
            bc = trimesh.triangles.points_to_barycentric(v[tri], p)
            nrm[:, e] = np.einsum("ij,ijk->ik", bc, vn[tri])
        for pts, nor in _chain(segs, nrm, tol):
            if (pts[-1] - pts[0]) @ cut_dir < 0:    # every row points along the cut direction
                pts, nor = pts[::-1], nor[::-1]
            rows.append(_resample(pts, nor, point_spacing))
    return rows


# --- summaries ------------------------------------------------------------------------------
@dataclass
class Figures:
    coverage: float
    dist_p50: float
    dist_p99: float
    axis_p95: float
    turn_max: float
    step_p5: float
    step_p95: float
    step_samples: int
    work_poses: int
    axis_own_p95: float | None = None   # against the worked face's own triangles (own_face_normals); no target
    coverage_own: float | None = None   # of the face's samples on the worked faces (worked_coverage); no target

    def row(self, step_mm: float) -> str:
        own = "" if self.axis_own_p95 is None else f" (own face {self.axis_own_p95:5.2f})"
        own_cov = "" if self.coverage_own is None else f" (own face {100 * self.coverage_own:6.2f})"
        return (f"cov {100 * self.coverage:6.2f} %{own_cov}  "
                f"dist p50 {self.dist_p50:6.3f} p99 {self.dist_p99:6.3f} mm  "
                f"axis p95 {self.axis_p95:5.2f} deg{own}  turn max {self.turn_max:6.2f} deg  "
                f"step p5-p95 {100 * self.step_p5 / step_mm:5.1f}-{100 * self.step_p95 / step_mm:5.1f} %  "
                f"({self.step_samples} steps, {self.work_poses} poses)")


def measure(mesh: trimesh.Trimesh, region: np.ndarray, rows: list[tuple[np.ndarray, np.ndarray]],
            step_mm: float, geo: SurfaceGeodesic | None = None, samples: np.ndarray | None = None,
            step_rows: list[np.ndarray] | None = None, faces: np.ndarray | None = None) -> Figures:
    """Every figure for one set of work rows on one part (region: the face's triangles); with ``faces`` (the part's
    smooth faces, ``worked_faces``) also the axis against the worked face's own triangles (``own_face_normals``)."""
    pts = np.vstack([r[0] for r in rows]) if rows else np.zeros((0, 3))
    axes = np.vstack([r[1] for r in rows]) if rows else np.zeros((0, 3))
    if samples is None:
        samples = surface_samples(mesh, region, spacing_mm=max(1.0, step_mm / 5))
    cov = coverage(samples, pts, COVER_FACTOR * step_mm)
    d = distance_to_mesh(mesh, pts)
    err = axis_error_deg(axes, averaged_normals(mesh, pts))
    own = None if faces is None or not len(pts) else axis_error_deg(axes, own_face_normals(mesh, pts, faces))
    own_cov = None if faces is None or not len(pts) else worked_coverage(mesh, samples, pts, faces, step_mm)
    turn = turns_deg(rows)
    geo = geo or SurfaceGeodesic(mesh)
    steps = row_steps(geo, step_rows if step_rows is not None else [r[0] for r in rows], step_mm)
    q = (lambda a, p: float(np.percentile(a, p)) if len(a) else float("nan"))
    return Figures(cov, q(d, 50), q(d, 99), q(err, 95), float(turn.max()) if len(turn) else 0.0,
                   q(steps, 5), q(steps, 95), int(len(steps)), int(len(pts)), None if own is None else q(own, 95),
                   own_cov)


def grid_mesh(fn, u, v) -> trimesh.Trimesh:
    """A triangulated (u, v) grid of the surface fn(U, V) -> (..., 3) (tests and samples)."""
    U, V = np.meshgrid(u, v, indexing="ij")
    P = fn(U, V).reshape(-1, 3)
    nu, nv = len(u), len(v)
    i = np.arange(nu - 1)[:, None] * nv + np.arange(nv - 1)[None, :]
    i = i.ravel()
    f = np.vstack([np.stack([i, i + nv, i + 1], 1), np.stack([i + 1, i + nv, i + nv + 1], 1)])
    return trimesh.Trimesh(P, f, process=True)


if __name__ == "__main__":
    # closed forms: a cylinder R 30 mm, rows along the axis 1 rad apart (arc 30 mm, chord 28.8 mm)
    R = 30.0
    cyl = grid_mesh(lambda a, z: np.stack([R * np.cos(a), R * np.sin(a), z], -1),
                    np.linspace(0, 3.0, 91), np.linspace(0, 100, 51))
    rows = [np.stack([R * np.cos(np.full(21, a)), R * np.sin(np.full(21, a)), np.linspace(10, 90, 21)], 1)
            for a in (0.5, 1.5, 2.5)]
    s = row_steps(SurfaceGeodesic(cyl), rows, 30.0)
    print(f"cylinder R 30, rows 1 rad apart: geodesic step {np.median(s):.3f} mm (arc 30.000, chord "
          f"{2 * R * math.sin(0.5):.3f})")
    plane = grid_mesh(lambda x, y: np.stack([x, y * math.cos(math.radians(60)), y * math.sin(math.radians(60))], -1),
                      np.linspace(0, 200, 41), np.linspace(0, 200, 41))
    r = plane_slicer(plane, 10.0, 5.0, cut_normal=[0.0, 1.0, 0.0])
    s = row_steps(SurfaceGeodesic(plane), [p for p, _ in r], 10.0)
    print(f"plane tilted 60 deg from the slicing planes, spacing 10 mm: step on the surface {np.median(s):.3f} mm "
          f"(10 / cos 60 = 20)")
