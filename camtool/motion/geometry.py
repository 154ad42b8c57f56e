"""The part as the motion check sees it: signed distance to an open surface.

A workpiece is often an open patch (a scan, one face of a part), so "inside"
cannot be a closed solid. Here it is **behind the surface within its
footprint**: with ``c`` the closest surface point of ``p`` and ``n`` the
outward normal there (towards the tool side),

- ``value(p) = +|p - c|`` when ``p`` is in front (``(p - c).n >= 0``),
- ``value(p) = -|p - c|`` when ``p`` is behind, inside the footprint,
- ``value(p) = +|p - c|`` (unsigned) when ``c`` lies on the patch's edge (``p``
  is beyond the footprint: "behind" means nothing there) or when ``p`` is
  more than ``horizon_mm`` from the surface (the part counts as material down
  to ``horizon_mm`` behind its surface).

Meshes: open3d's ``RaycastingScene`` gives the closest point and triangle;
the patch edge is the mesh's boundary edges (used by one triangle) and their
corners; where the closest point is an edge or a corner, the side comes from
the angle-weighted pseudo-normal there. Where either reads a point behind,
the faces within the closest point's precision, measured again in float64,
may tell otherwise (``_side_of_the_faces``): at a knife edge (a blade's
trailing edge, a fin's tip) the pseudo-normal nearly cancels, and a point
beyond it within that precision of the plane of the side it is behind reads
as over that side. Point clouds: a scipy ``cKDTree``;
``c`` is the nearest point; the edge is the points whose neighbours leave an
angular gap > 120 deg round them (and a band of 3 spacings inside them); ``p``
is beyond it when its in-plane offset from such a point exceeds
``lateral_tol_mm`` and points out of the cloud. Inside, in-plane offsets up to
``lateral_tol_mm`` are sampling holes, not shape, and come off the distance,
so a point on the surface between two samples reads ~0; and a point that near
the surface is measured from the least-squares plane of its 8 nearest points
(one step of moving least squares), not from one noisy point along that
point's normal, which a scanner estimates from a neighbourhood and which blends
across an edge.

Outward normals are made consistent with a hint: points with outward
directions, normally the work poses of the path (outward = -tool z). Mesh
windings are made consistent per connected piece and each piece is turned to
agree with the hint (area-weighted vote of its faces near hint points); cloud
normals are flipped one by one to agree with the nearest hint point.

For speed, a grid over the part's box grown by ``horizon_mm`` keeps, per
node, a lower bound of the distance and a "clean" radius: the ball round the
node in which no point can be behind the surface (it touches neither the
surface nor the "wall" swept from the patch edge along -normal, the only ways
behind). ``lower_bound`` uses it to drop capsule pieces that are provably far
(the distance is 1-Lipschitz); only the rest are measured exactly.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..errors import BadInput
from ..part.folds import folded_triangles

DEFAULT_HORIZON_MM = 300.0
DEFAULT_GRID_NODES = 100_000
POSITION_TOL_MM = 0.2        # mesh closest points (float32) are this exact along the surface
EDGE_EPS_REL = 2e-5          # ... plus this share of the part's size
CLOUD_NEIGHBOURS = 30        # neighbours of the angular-gap edge test
EDGE_GAP_RAD = 2 * np.pi / 3  # a point with a larger angular gap round it is on the cloud's edge
EDGE_BAND = 3.0              # points this many spacings (p90) from a flagged edge point count as edge too
CREASE_NEIGHBOURS = 8        # cloud: normals averaged for the sign where the offset is in-plane
MLS_NEIGHBOURS = 8           # cloud: a point this near the surface is measured from the plane of this many points
MLS_OUTLIER_SIGMAS = 6.0     # cloud: a neighbour this many RMS offsets off the plane of the others is a stray
MLS_OUTLIER_FLOOR_MM = 0.05  # ... and farther than this off it (a noise-free cloud keeps its curvature)
MLS_MIN_SPREAD = 0.01        # ... and only where the others span a plane (not points along one scan line)
MLS_REACH_SPACINGS = 1.0     # ... when within this many lateral tolerances of its nearest point
MLS_PLANE_AGREE_COS = 0.866  # cloud: the plane's normal counts where within 30 deg of the points' mean normal ...
MLS_PLANE_DEFINED = 0.25     # ... and its points scatter off it at most this share (variance) of their spread across it
NORMAL_AGREE_DEG = 25.0      # cloud: a point's normal farther than this from its neighbours' plane's is re-estimated
LATERAL_SPACINGS = 3.0       # cloud: in-plane offsets up to this many spacings (p90) are sampling holes
HINT_NEAR_FACTOR = 3.0       # mesh orientation vote: faces within this many hint spacings vote
COVER_CELLS = 0.25           # mesh: a point cover of the surface within this many grid cells (``above``)
MIN_COVER_MM = 1.0           # ... and never finer than this
NEEDLE_ASPECT = 100.0        # mesh: a triangle this many times longer than wide, and narrower than the closest
                             # point's precision, is a needle (``needle_triangles``)
KNIFE_SUM = 0.1              # mesh: two sides whose unit normals sum to less than this meet at a knife edge ...
KNIFE_SQUARE_COS = 0.5       # ... and a needle there within 60 deg of square to them keeps its own normal
NEEDLE_RINGS = 2             # mesh: a needle's pseudo-normal takes the corners of the needles this many edges away
FACE_SQUARE_SIN = 0.05       # mesh: an offset within this sine (2.9 deg) of a face's normal takes the face's side
FRONT_REACH = 3.0            # mesh: the faces round the vertices this many closest-point precisions from an edge's
                             # or a corner's closest point tell its side (``_side_of_the_faces``)
ABOVE_CAP_RATIO = 1.1        # ``above`` queries points whose caps differ by up to this factor together


@dataclass(frozen=True)
class PartQuery:
    """Exact query result per point: value (signed, see module doc), distance, closest point,
    footprint flag and the offset along the normal there."""

    value_mm: np.ndarray
    distance_mm: np.ndarray
    closest_mm: np.ndarray
    in_footprint: np.ndarray
    normal_offset_mm: np.ndarray  # (p - c).n: the offset along the outward normal at c


class PartGeometry:
    """Signed distance to the placed workpiece (world frame, mm); build with ``from_workpiece``."""

    def __init__(self):
        raise TypeError("use PartGeometry.from_workpiece(...) or part_from_path(...)")

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_workpiece(cls, workpiece, outward_points_mm=None, outward_dirs=None, *,
                       horizon_mm: float = DEFAULT_HORIZON_MM,
                       grid_nodes: int = DEFAULT_GRID_NODES) -> "PartGeometry":
        """Build from a placed Workpiece; a mesh when it has faces, else its point cloud.

        ``outward_points_mm`` (K, 3) and ``outward_dirs`` (K, 3) orient the
        surface: the outward normal near each hint point agrees with its
        direction. Without a hint, mesh windings and cloud normals are taken
        as they are.
        """
        self = object.__new__(cls)
        if not horizon_mm > 0:
            raise BadInput(f"horizon_mm: expected a length > 0 mm, found {horizon_mm!r}")
        self.horizon_mm = float(horizon_mm)
        hint_p, hint_d = _hint(outward_points_mm, outward_dirs)
        mesh = (workpiece.faces is not None and workpiece.vertices_mm is not None
                and len(workpiece.faces) > 0)
        pts = np.asarray(workpiece.vertices_mm if mesh else workpiece.points_mm, dtype=float)
        if len(pts) == 0 or not np.isfinite(pts).all():
            raise BadInput("workpiece: no finite points to check the motion against")
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        self.origin_mm = (lo + hi) / 2.0  # queries are made relative to it (float32 in open3d)
        self.size_mm = float(np.linalg.norm(hi - lo))
        self._lo, self._hi = lo - self.origin_mm, hi - self.origin_mm
        if hint_p is not None:
            hint_p = hint_p - self.origin_mm
        self._grid_setup(int(grid_nodes))
        if mesh:
            self.kind = "mesh"
            self._build_mesh(pts - self.origin_mm, np.array(workpiece.faces, dtype=np.int64), hint_p, hint_d)
        else:
            self.kind = "cloud"
            self._build_cloud(pts - self.origin_mm, np.asarray(workpiece.normals, dtype=float), hint_p, hint_d)
        self._build_grid()
        return self

    def _build_mesh(self, V, F, hint_p, hint_d):
        from ..part.open3d_import import import_open3d
        o3d = import_open3d()
        import trimesh

        m = trimesh.Trimesh(V, F, process=False, validate=False)
        m.merge_vertices()
        m.update_faces(m.nondegenerate_faces())
        if len(m.faces) == 0:
            raise BadInput("workpiece: the mesh has no triangles with area")
        trimesh.repair.fix_winding(m)
        normals = np.asarray(m.face_normals, dtype=float).copy()
        faces = np.array(m.faces, dtype=np.int64)
        verts = np.array(m.vertices, dtype=float)
        if hint_p is not None:
            centroids = verts[faces].mean(axis=1)
            tree = cKDTree(hint_p)
            dist, idx = tree.query(centroids, workers=-1)
            agree = np.einsum("ij,ij->i", normals, hint_d[idx])
            if m.is_winding_consistent:
                labels = trimesh.graph.connected_component_labels(m.face_adjacency, node_count=len(faces))
                spacing = _spacing(hint_p) if len(hint_p) > 1 else 10.0
                near = dist <= HINT_NEAR_FACTOR * spacing + 1.0
                area = np.asarray(m.area_faces)
                w = area * np.where(near, 1.0, 1e-6 / (1.0 + dist))  # far faces only break ties
                vote = np.bincount(labels, weights=w * np.sign(agree), minlength=labels.max() + 1)
                flip = vote[labels] < 0
            else:  # no consistent winding: each face follows its nearest hint
                flip = agree < 0
            normals[flip] *= -1
            faces[flip] = faces[flip][:, ::-1]
        # a CAD surface folded over itself: its middle layer faces against the surface it lies on; the side of a
        # point whose closest triangle it is comes from that surface (``part.folds``)
        self.folded = folded_triangles(verts, faces)
        normals[self.folded.mask] *= -1
        self.verts_mm = verts
        self.faces = faces
        self.face_normals = normals
        # boundary edges: an edge used by one face only; edge k of a face joins corners k and k+1
        e = np.sort(np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2), axis=1)
        # one int64 key an edge: a 1-D unique is much faster than the rows' (same order)
        _, inv, cnt = np.unique(e[:, 0] * np.int64(len(verts)) + e[:, 1], return_inverse=True, return_counts=True)
        self.edge_boundary = (cnt[inv.ravel()] == 1).reshape(-1, 3)
        bvert = np.zeros(len(verts), bool)
        bvert[faces[self.edge_boundary]] = True
        bvert[np.roll(faces, -1, axis=1)[self.edge_boundary]] = True
        self.vertex_boundary = bvert[faces]  # (F, 3): corner k is on the patch's edge
        self.boundary_edges = int(self.edge_boundary.sum())
        # open3d's closest points are off by up to ~0.1 mm along the surface (float32)
        self._pos_tol = POSITION_TOL_MM + EDGE_EPS_REL * self.size_mm
        # needles: their closest points are taken as their edges' or corners', whose pseudo-normals leave them out
        self.needle = needle_triangles(verts[faces], self._pos_tol)
        self.edge_normals, self.vertex_normals, self.needle_normals = _pseudo_normals(verts, faces, normals, inv,
                                                                                      cnt.size, self.needle)
        self._slack = self._pos_tol  # |value| >= distance - this
        from scipy.sparse import csr_matrix
        self._vertex_faces = csr_matrix((np.ones(faces.size), (faces.ravel(), np.repeat(np.arange(len(faces)), 3))),
                                        shape=(len(verts), len(faces)))  # per vertex, the faces round it
        self._vertex_tree = cKDTree(verts)
        self._sheet = 1e-3 + 1e-6 * self.size_mm
        self._scene = o3d.t.geometry.RaycastingScene()
        self._scene.add_triangles(o3d.core.Tensor(verts.astype(np.float32)),
                                  o3d.core.Tensor(faces.astype(np.uint32)))
        step = self._g_cell / 2.0
        self._surface_samples = _sample_triangles(verts[faces], step)
        self._surface_gap = step  # every surface point lies within this of a sample
        self._cover_tree, self._cover_gap = _covering_tree(verts, faces, max(COVER_CELLS * self._g_cell, MIN_COVER_MM))
        self._wall_points = self._mesh_wall(verts, faces, normals, step) if self.boundary_edges else np.zeros((0, 3))
        self._wall_tol = step + self._slack

    def _mesh_wall(self, verts, faces, normals, step):
        """Points (spacing <= step) of the wall: each boundary edge swept along -(its face normal)
        to depth 2 x horizon, and at each boundary vertex the fans between the normals of the
        faces round it (where the closest point passes from inside the patch to its edge)."""
        D = 2.0 * self.horizon_mm
        fi, k = np.nonzero(self.edge_boundary)
        a, b = faces[fi, k], faces[fi, (k + 1) % 3]
        n = normals[fi]
        parts = [_sample_ruled(verts[a], verts[b], n, n, D, step)]
        bverts = np.unique(np.concatenate([a, b]))
        vf_face = np.repeat(np.arange(len(faces)), 3)
        vf_vert = faces.ravel()
        sel = np.isin(vf_vert, bverts)
        order = np.argsort(vf_vert[sel], kind="stable")
        vv, ff = vf_vert[sel][order], vf_face[sel][order]
        starts = np.r_[0, np.nonzero(np.diff(vv))[0] + 1]
        counts = np.diff(np.r_[starts, len(vv)])
        for c in np.unique(counts):
            if c < 2:
                continue
            grp = starts[counts == c][:, None] + np.arange(c)  # (groups, c)
            v = verts[vv[grp[:, 0]]]
            nn = normals[ff[grp]]
            i, j = np.triu_indices(c, 1)
            ni, nj = nn[:, i].reshape(-1, 3), nn[:, j].reshape(-1, 3)
            vb = np.repeat(v, len(i), axis=0)
            parts.append(_sample_ruled(vb, vb, ni, nj, D, step))
        return np.concatenate(parts)

    def _build_cloud(self, P, N, hint_p, hint_d):
        if len(P) < 4:
            raise BadInput("workpiece: a point cloud needs at least 4 points for the motion check")
        length = np.linalg.norm(N, axis=1) if N.shape == P.shape else np.zeros(len(P))
        N = np.where(length[:, None] > 1e-9, N / np.maximum(length, 1e-12)[:, None], 0.0) \
            if N.shape == P.shape else np.zeros_like(P)
        self._tree = cKDTree(P)
        h = None
        if hint_p is not None:
            _, idx = cKDTree(hint_p).query(P, workers=-1)
            h = hint_d[idx]
            missing = np.linalg.norm(N, axis=1) < 0.5
            N[missing] = h[missing]
            N[np.einsum("ij,ij->i", N, h) < 0] *= -1
        missing = np.linalg.norm(N, axis=1) < 0.5
        if missing.any():
            raise BadInput(f"workpiece: {int(missing.sum())} cloud points have no normal; "
                           "give an outward hint (the path) to orient them")
        self.points_mm = P
        k = min(CLOUD_NEIGHBOURS, len(P) - 1)
        dist, nb = self._tree.query(P, k=k + 1, workers=-1)
        nn1 = dist[:, 1]
        self.spacing_mm = float(np.median(nn1))
        s90 = float(np.percentile(nn1, 90))
        # Random sampling leaves holes of a few spacings: up to this in-plane offset from the
        # nearest point is sampling, not shape.
        self.lateral_tol_mm = LATERAL_SPACINGS * s90
        N = _checked_normals(P, N, nb, np.zeros(len(P), bool), h)
        self.is_edge, self.near_edge, _ = _cloud_edges(P, N, nb, dist, s90)
        # the edge's normals from its points' own neighbours' plane, and its outward directions in that plane
        self.normals = N = _checked_normals(P, N, nb, self.near_edge, h)
        _, _, self.out_dir = _cloud_edges(P, N, nb, dist, s90, self.is_edge)
        self.boundary_edges = int(self.is_edge.sum())
        self._slack = self.lateral_tol_mm
        self._sheet = self.lateral_tol_mm  # a ball this far from every point does not pass the sheet
        self._surface_samples = P
        self._surface_gap = 0.0  # the cloud is the point set
        self._cover_tree, self._cover_gap = self._tree, 0.0
        self._wall_points = np.zeros((0, 3))
        self._wall_tol = 0.0
        if self.boundary_edges:
            step = max(2.0 * s90, self.horizon_mm / 60.0)
            b = P[self.is_edge]
            bn = N[self.is_edge]
            keep = np.unique(np.floor(b / step).astype(np.int64), axis=0, return_index=True)[1]
            b, bn = b[keep], bn[keep]
            t = np.arange(0.0, 2.0 * self.horizon_mm + step, step)
            self._wall_points = (b[:, None, :] - t[None, :, None] * bn[:, None, :]).reshape(-1, 3)
            # gaps of the sampled wall (along depth and between kept edge points), the
            # out-of-gap tolerance of the footprint test and the normals' spread
            self._wall_tol = np.sqrt(3.0) * step + (EDGE_BAND + 1.0) * s90 + self.lateral_tol_mm \
                + 0.05 * self.horizon_mm

    # ------------------------------------------------------------------ exact query
    def query(self, points_mm: np.ndarray) -> PartQuery:
        """Exact value (see module doc), distance, closest point and footprint flag per point."""
        p = np.asarray(points_mm, dtype=float).reshape(-1, 3) - self.origin_mm
        value, dist, closest, inside, behind, normal = self._query_local(p, with_normal=True)
        return PartQuery(value, dist, closest + self.origin_mm, inside, normal)

    def signed_distance(self, points_mm: np.ndarray) -> np.ndarray:
        """Signed distance (mm) of each point: + in front or beyond the edge, - behind the surface."""
        p = np.asarray(points_mm, dtype=float).reshape(-1, 3) - self.origin_mm
        return self._query_local(p)[0]

    def _query_local(self, p: np.ndarray, with_normal: bool = False):
        """(value, distance, closest point, in footprint, behind[, normal offset]) per local point."""
        if len(p) == 0:
            z = np.zeros(0)
            out = (z, z, np.zeros((0, 3)), np.zeros(0, bool), np.zeros(0, bool))
            return out + (z,) if with_normal else out
        if self.kind == "mesh":
            from ..part.open3d_import import import_open3d
            o3d = import_open3d()

            ans = self._scene.compute_closest_points(o3d.core.Tensor(p.astype(np.float32)))
            c = ans["points"].numpy().astype(float)
            prim = ans["primitive_ids"].numpy().astype(np.int64)
            off = p - c
            dist = np.linalg.norm(off, axis=1)
            normal = np.einsum("ij,ij->i", off, self.face_normals[prim])
            outside = np.zeros(len(p), bool)
            # offset not along the face normal: the closest point is an edge or a corner; on a needle, always
            feature = (dist**2 - normal**2 > self._pos_tol**2) | self.needle[prim]
            rows = np.nonzero(feature)[0]
            if len(rows):
                pn, outside[rows] = self._feature(c[rows], prim[rows])
                normal[rows] = np.einsum("ij,ij->i", off[rows], pn)
            # read as behind: unless the faces there, measured in float64, tell otherwise (a point beyond a knife
            # edge within the closest point's precision of the plane of the side it is behind reads as over it)
            back = np.flatnonzero((normal < 0) & ~outside & (feature | (dist > 2.0 * self._pos_tol)))
            if len(back):
                side = self._side_of_the_faces(p[back], c[back], prim[back])
                normal[back] = np.where(np.isfinite(side), side, normal[back])
                feature[back[side > 0]] = True     # in front: by its distance
            behind = normal < 0
            # along the face normal, the normal offset (the closest point's float32 error
            # along the surface drops out); elsewhere the distance
            mag = np.where(feature, dist, np.abs(normal))
            value = np.where(outside, dist, np.where(behind & (dist <= self.horizon_mm), -mag, mag))
            out = (value, dist, c, ~outside, behind)
            return out + (normal,) if with_normal else out
        dist, idx = self._tree.query(p, workers=-1)
        c = self.points_mm[idx]
        off = p - c
        n = self.normals[idx]
        normal_part = np.einsum("ij,ij->i", off, n)
        lateral = np.sqrt(np.maximum(dist**2 - normal_part**2, 0.0))
        side = lateral > self.lateral_tol_mm
        outside = side & self.near_edge[idx] & (np.einsum("ij,ij->i", off, self.out_dir[idx]) > 0)
        inner = np.sqrt(np.maximum(dist**2 - np.minimum(lateral, self.lateral_tol_mm) ** 2, 0.0))
        rows = np.nonzero(side & ~outside)[0]
        if len(rows):  # offset mostly in-plane (a crease): the neighbours' mean normal decides
            _, nb = self._tree.query(p[rows], k=min(CREASE_NEIGHBOURS, len(self.points_mm)), workers=-1)
            normal_part[rows] = np.einsum("ij,ij->i", off[rows], _unit(self.normals[nb].sum(axis=1)))
        near = np.nonzero(~side & ~outside & (dist <= MLS_REACH_SPACINGS * self.lateral_tol_mm))[0]
        if len(near):  # on the surface: the offset from the plane of the nearest points, not from one of them
            plane = self._local_plane_offset(p[near])
            normal_part[near] = plane
            inner[near] = np.abs(plane)
        behind = normal_part < 0
        value = np.where(outside | (dist > self.horizon_mm), dist, np.where(behind, -inner, inner))
        out = (value, dist, c, ~outside, behind)
        return out + (normal_part,) if with_normal else out

    def _local_plane_offset(self, p: np.ndarray) -> np.ndarray:
        """Signed offset (mm) of each point from the least-squares plane of its MLS_NEIGHBOURS nearest cloud
        points, along that plane's normal turned to their mean normal. A scan's points scatter by its noise
        (some 4-5 sigma out among 60,000) and its normals, estimated from neighbourhoods too, blend across an
        edge: the offset from one nearest point, along its normal, reads a pose on a face beside an edge as
        behind it by up to a point spacing. One step of moving least squares reads the plane instead."""
        k = min(MLS_NEIGHBOURS, len(self.points_mm))
        _, nb = self._tree.query(p, k=k, workers=-1)
        Q = self.points_mm[nb]
        mid, n, _, lam = _plane(Q, _stray_free(Q, nb, self._isolated), eigenvalues=True)
        mean = _unit(self.normals[nb].sum(axis=1))
        along = np.einsum("ij,ij->i", n, mean)
        n = np.where((along < 0)[:, None], -n, n)
        # along a cloud's edge the nearest points are a strip one or two points wide, and on a noisy scan a few
        # points scatter off their plane as far as across it: that plane turns freely (the shell scan's rim read a
        # lead 3 mm beyond it as 3.5 mm behind it, its plane 57 deg off the points' normals); there the points'
        # own normals (estimated over a wider neighbourhood) decide
        free = (lam[:, 0] > MLS_PLANE_DEFINED * lam[:, 1]) | (np.abs(along) < MLS_PLANE_AGREE_COS)
        n = np.where(free[:, None], mean, n)
        return np.einsum("ij,ij->i", p - mid, n)

    def _isolated(self, idx: np.ndarray) -> np.ndarray:
        """Per cloud point ``idx``: far off the plane of its own MLS_NEIGHBOURS nearest points (a stray scan
        point), not a point of a surface beside them (a chamfer or an edge, whose own neighbours lie round it)."""
        k = min(MLS_NEIGHBOURS + 1, len(self.points_mm))
        if len(idx) == 0 or k < 5:
            return np.zeros(len(idx), bool)
        _, nb = self._tree.query(self.points_mm[idx], k=k, workers=-1)
        R = self.points_mm[nb[:, 1:]]
        mid, n, spread = _plane(R, np.ones(R.shape[:2]))
        rms = np.sqrt(np.mean(np.einsum("mki,mi->mk", R - mid[:, None, :], n) ** 2, axis=1))
        off = np.abs(np.einsum("mi,mi->m", self.points_mm[idx] - mid, n))
        return (off > np.maximum(MLS_OUTLIER_SIGMAS * rms, MLS_OUTLIER_FLOOR_MM)) & (spread > MLS_MIN_SPREAD)

    def _feature(self, c: np.ndarray, prim: np.ndarray):
        """(pseudo-normal, on the patch's edge) of the corner or edge of each triangle nearest ``c``."""
        f = self.faces[prim]
        tri = self.verts_mm[f]  # (R, 3, 3)
        dv = np.linalg.norm(c[:, None, :] - tri, axis=2)
        a, b = tri, np.roll(tri, -1, axis=1)
        ab = b - a
        t = np.clip(np.einsum("rkj,rkj->rk", c[:, None, :] - a, ab)
                    / np.maximum(np.einsum("rkj,rkj->rk", ab, ab), 1e-300), 0.0, 1.0)
        de = np.linalg.norm(c[:, None, :] - (a + t[:, :, None] * ab), axis=2)
        rows = np.arange(len(c))
        kv, ke = np.argmin(dv, axis=1), np.argmin(de, axis=1)
        corner = dv[rows, kv] <= self._pos_tol
        pn = np.where(corner[:, None], self.vertex_normals[f[rows, kv]], self.edge_normals[prim, ke])
        pn = np.where(self.needle[prim][:, None], self.needle_normals[prim], pn)
        on_edge = np.where(corner, self.vertex_boundary[prim, kv], self.edge_boundary[prim, ke])
        return pn, on_edge

    def _side_of_the_faces(self, p: np.ndarray, c: np.ndarray, prim: np.ndarray) -> np.ndarray:
        """Per row: a normal offset that tells point ``p``'s side from the faces (no needles) that pass within the
        closest point's precision of its closest point ``c`` (on triangle ``prim``; ``_faces_near``), measured again
        in float64; NaN where they cannot tell.

        - The point lies square over its nearest face (its offset within ``FACE_SQUARE_SIN`` of the normal; past
          the face's edge, that edge is convex if the point is in front and concave if behind, and the edge's
          side is the face's): that face's normal offset. Right at a knife edge, where a point in front of one
          side is square to the edge's outward direction, the pseudo-normal's sign there is the few um's noise.
        - Else the closest point is an edge or a corner, and the point is in front of every face there (a ridge
          or a corner seen from outside) or behind every one (a valley or a hollow corner seen from inside). Where
          the faces are convex (each lies behind the others' planes: the material is behind all of them) a point
          in front of one, by more than twice the precision, is in front; elsewhere, where it is more in front of
          one than behind any (a point in a valley's material is behind the face it is nearest by its whole
          distance, more than in front of any other face there).

        The pseudo-normal (the faces' normals summed) tells this exactly, but where two sides meet at a knife edge
        (a blade's trailing edge, a fin's tip: normals 175-180 deg apart) the sum nearly cancels, and a ribbon of
        needles there takes it from corners a few um off: points 4-60 mm off the IEA 15 MW blade's trailing edge,
        and the wrist 300 mm beyond the 1:300 hull's bilge keel fin, read as behind them."""
        row, face = self._faces_near(c, prim)
        from trimesh.triangles import closest_point

        gap = p[row] - closest_point(self.verts_mm[self.faces[face]], p[row])   # exact (float64), unlike ``c``
        length = np.linalg.norm(gap, axis=1)
        along = np.einsum("ij,ij->i", gap, self.face_normals[face])
        front, back, least = (np.full(len(p), -np.inf) for _ in range(3))
        np.maximum.at(front, row, along)
        np.maximum.at(back, row, -along)
        np.maximum.at(least, row, -length)
        nearest = np.full(len(p), np.nan)   # the side of the nearest face where the point lies square over it
        over = (length == -least[row]) & (length**2 - along**2 <= (FACE_SQUARE_SIN * length) ** 2)
        nearest[row[over]] = along[over]
        convex = ~self._concave_rows(row, face, len(p))
        clear = (front > 2.0 * self._pos_tol) & (convex | (front > back))
        return np.where(np.isfinite(nearest), nearest, np.where(clear, front, np.nan))

    def _faces_near(self, c: np.ndarray, prim: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(row, face): the faces (no needles) within the closest point's precision of each row's ``c``: round the
        vertices of ``prim`` and those within ``FRONT_REACH`` precisions, and through the needles there (a ribbon
        between two sides) ``NEEDLE_RINGS`` times."""
        near_vertices = self._vertex_tree.query_ball_point(c, FRONT_REACH * self._pos_tol, workers=-1)
        counts = np.array([len(v) for v in near_vertices], dtype=np.int64)
        rows = np.arange(len(prim))
        row, face = self._faces_round(np.r_[np.repeat(rows, 3), np.repeat(rows, counts)],
                                      np.concatenate([self.faces[prim].ravel(), *[np.asarray(v, np.int64)
                                                                                  for v in near_vertices]]))
        for ring in range(NEEDLE_RINGS + 1):
            near = self._within_precision(row, face, c)
            if ring == NEEDLE_RINGS:
                break
            through = near & self.needle[face]
            more = self._faces_round(np.repeat(row[through], 3), self.faces[face[through]].ravel())
            row, face = np.unique(np.concatenate([np.stack([row, face]), np.stack(more)], axis=1), axis=1)
        keep = near & ~self.needle[face]
        return row[keep], face[keep]

    def _concave_rows(self, row: np.ndarray, face: np.ndarray, n_rows: int) -> np.ndarray:
        """Per row: whether a corner of one of its faces lies in front of another's plane (by more than the
        sheet's thickness): the faces there are not convex. ``row`` ascending, as ``_faces_near`` gives it."""
        start = np.searchsorted(row, np.arange(n_rows))
        count = np.bincount(row, minlength=n_rows)
        k = count[row]                                          # each (row, face) pairs with its row's faces
        i = np.repeat(np.arange(len(row)), k)
        j = np.repeat(start[row] - np.cumsum(k) + k, k) + np.arange(k.sum())
        tri, base = self.verts_mm[self.faces[face[j]]], self.verts_mm[self.faces[face[i], 0]]
        height = np.einsum("pkj,pj->pk", tri - base[:, None, :], self.face_normals[face[i]]).max(axis=1)
        out = np.zeros(n_rows, bool)
        np.logical_or.at(out, row[i], height > self._sheet)
        return out

    def _faces_round(self, row: np.ndarray, vertex: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(row, face) once each for every face round each ``vertex`` (of query ``row``)."""
        ring = self._vertex_faces
        start, count = ring.indptr[vertex], np.diff(ring.indptr)[vertex]
        face = ring.indices[np.repeat(start - np.cumsum(count) + count, count) + np.arange(count.sum())]
        return np.unique(np.stack([np.repeat(row, count), face.astype(np.int64)]), axis=1)

    def _within_precision(self, row: np.ndarray, face: np.ndarray, c: np.ndarray) -> np.ndarray:
        """Whether each ``face`` passes within the closest point's precision of its row's point ``c``."""
        from trimesh.triangles import closest_point

        return np.linalg.norm(closest_point(self.verts_mm[self.faces[face]], c[row]) - c[row], axis=1) \
            <= self._pos_tol

    # ------------------------------------------------------------------ bounds (grid)
    def _grid_setup(self, max_nodes: int):
        G = self.horizon_mm
        lo, hi = self._lo - G, self._hi + G
        span = hi - lo
        cell = max(float(np.cbrt(np.prod(span) / max(max_nodes, 8))), 1e-3 * float(span.max()), 0.5)
        self._g_shape = np.ceil(span / cell).astype(int) + 1
        self._g_lo, self._g_cell = lo, cell
        self._box_lo, self._box_hi = lo, lo + (self._g_shape - 1) * cell

    def _build_grid(self):
        """Per grid node: distance bounds and the clean radius rho (see module doc).

        Distances come from a Euclidean distance transform of the cells holding
        surface samples (bounds within half a cell diagonal), made exact near the
        surface; the side (front / behind) of the far nodes from one exact query
        per connected group of nodes that touch neither the surface nor the wall.
        """
        from scipy import ndimage

        G, cell, shape = self.horizon_mm, self._g_cell, self._g_shape
        ii = np.stack(np.meshgrid(*[np.arange(s) for s in shape], indexing="ij"), axis=-1).reshape(-1, 3)
        nodes = self._g_lo + ii * cell
        n = len(nodes)
        half_diag = cell * np.sqrt(3.0) / 2.0
        e = self._edt(self._surface_samples, shape)
        d_lb = np.maximum(e - half_diag - self._surface_gap, 0.0)
        d_ub = e + half_diag
        wall = (self._edt(self._wall_points, shape) - half_diag if len(self._wall_points)
                else np.full(n, np.inf))
        value, inside, behind = np.full(n, np.inf), np.zeros(n, bool), np.zeros(n, bool)
        known = e <= 4.0 * cell  # near the surface: exact (near queries are cheap)
        if known.any():
            v, d, _, i, b = self._query_local(nodes[known])
            value[known], d_lb[known], d_ub[known], inside[known], behind[known] = v, d, d, i, b
        near = np.minimum.reduce([d_lb - self._sheet, wall - self._wall_tol, np.full(n, G / 2.0)])
        # Nodes whose ball of radius cell/2 touches neither the surface nor the wall: each
        # 6-connected group of them lies on one side; one exact query per group tells which.
        free = (near >= cell / 2.0).reshape(tuple(shape))
        labels, count = ndimage.label(free)
        labels = labels.ravel()
        todo = np.nonzero(~known & (labels > 0))[0]
        if len(todo):
            lab = labels[todo]
            order = np.argsort(lab, kind="stable")
            first = todo[order[np.r_[0, np.nonzero(np.diff(lab[order]))[0] + 1]]]
            _, _, _, i, b = self._query_local(nodes[first])
            side_behind = np.zeros(count + 1, bool)
            side_behind[labels[first]] = b & i
            inside[todo], behind[todo] = True, side_behind[labels[todo]]
            value[todo] = np.where(behind[todo], -1.0, 1.0)
            known[todo] = True
        front = value >= 0
        deep = behind & inside  # behind the surface (farther than G it reads unsigned)
        rho = np.where(known & front & ~deep, np.maximum(d_lb - G, near), d_lb - G)
        self._g_dist = d_lb
        self._g_dist_ub = d_ub
        self._g_rho = rho
        self.grid_cell_mm = cell
        self.grid_nodes = n

    def _edt(self, points: np.ndarray, shape) -> np.ndarray:
        """Distance (mm) from each node to the nearest node whose cell holds a point (points
        outside the box are moved onto it: distances only shrink)."""
        from scipy import ndimage

        idx = np.clip(np.rint((points - self._g_lo) / self._g_cell).astype(np.int64), 0, shape - 1)
        empty = np.ones(tuple(shape), bool)
        empty[idx[:, 0], idx[:, 1], idx[:, 2]] = False
        return ndimage.distance_transform_edt(empty, sampling=self._g_cell).ravel()

    def _nearest_node(self, p):
        from .grid_bounds import nearest_nodes

        return nearest_nodes(np.ascontiguousarray(p, dtype=float), self._g_lo, float(self._g_cell),
                             self._g_shape.astype(np.int64))

    def lower_bound(self, points_mm: np.ndarray, half_length_mm) -> np.ndarray:
        """A lower bound of ``value`` over the ball of radius ``half_length_mm`` round each point.

        ``-inf`` where the grid cannot tell (near the surface, near its edge or
        behind it); the exact query decides there.
        """
        from .grid_bounds import lower_bounds

        p = np.asarray(points_mm, dtype=float).reshape(-1, 3) - self.origin_mm
        h = np.ascontiguousarray(np.broadcast_to(np.asarray(half_length_mm, float), (len(p),)))
        return lower_bounds(p, h, self._g_lo, float(self._g_cell), self._g_shape.astype(np.int64), self._g_rho,
                            self._g_dist, self._box_lo, self._box_hi, float(self._slack), float(self.horizon_mm))

    def above(self, points_mm: np.ndarray, half_length_mm, level_mm) -> np.ndarray:
        """True where ``value`` is provably above ``level_mm`` over the ball of radius
        ``half_length_mm`` round each point; tighter than ``lower_bound`` and dearer.

        The ball lies in a grid node's clean ball (so it is not behind the surface and
        ``value >= distance - slack``), and no point of a cover of the surface (every
        surface point within the cover's gap of one) is within the distance that would
        allow the level: a KD query capped at that distance, so far points cost little.
        """
        p = np.asarray(points_mm, dtype=float).reshape(-1, 3) - self.origin_mm
        h = np.broadcast_to(np.asarray(half_length_mm, float), (len(p),))
        need = np.broadcast_to(np.asarray(level_mm, float), (len(p),)) + h + self._slack + self._cover_gap
        out = np.zeros(len(p), bool)
        if not len(p):
            return out
        flat, a = self._nearest_node(p)
        inside = np.all((p >= self._box_lo) & (p <= self._box_hi), axis=1)
        cand = np.nonzero(inside & (self._g_rho[flat] >= a + h) & np.isfinite(need))[0]
        if len(cand):  # in groups of about equal caps: a query slows with its cap
            group = np.floor(np.log(np.maximum(need[cand], 1e-3)) / np.log(ABOVE_CAP_RATIO)).astype(np.int64)
            for g in np.unique(group):
                sel = cand[group == g]
                d = self._cover_tree.query(p[sel], workers=-1, distance_upper_bound=float(need[sel].max()))[0]
                out[sel] = d > need[sel]
        return out

    def upper_bound_distance(self, points_mm: np.ndarray) -> np.ndarray:
        """An upper bound of the distance (hence of ``value``) at each point; ``inf`` when unknown."""
        p = np.asarray(points_mm, dtype=float).reshape(-1, 3) - self.origin_mm
        flat, a = self._nearest_node(p)
        return self._g_dist_ub[flat] + a

    def describe(self) -> dict:
        d = {"kind": self.kind, "horizon_mm": self.horizon_mm, "grid_nodes": int(self.grid_nodes),
             "grid_cell_mm": round(float(self.grid_cell_mm), 3), "edge_elements": self.boundary_edges}
        if self.kind == "cloud":
            d.update(points=int(len(self.points_mm)), spacing_mm=round(self.spacing_mm, 4),
                     lateral_tol_mm=round(self.lateral_tol_mm, 4))
        else:
            d.update(faces=int(len(self.faces)))
        return d


def needle_triangles(tri: np.ndarray, width_mm: float) -> np.ndarray:
    """Which triangles (F, 3, 3) are needles: narrower (their least altitude) than ``width_mm`` and
    ``NEEDLE_ASPECT`` times longer than wide. A needle's three corners lie nearly on one line, so its normal
    turns any way about it (the IEA 15 MW blade's tessellated trailing-edge strip holds one 37 mm long and
    3 um wide, its normal 140 deg from both its neighbours'): it cannot tell a point's side, and being narrower
    than a closest point is exact along the surface, a point's closest point on it may as well be on its edges."""
    e = np.linalg.norm(np.roll(tri, -1, axis=1) - tri, axis=2)
    longest = e.max(axis=1)
    width = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1) / np.maximum(longest, 1e-300)
    return (width < width_mm) & (longest > NEEDLE_ASPECT * width)


def _pseudo_normals(verts, faces, normals, inv, edges: int, needle) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(edge pseudo-normals (F, 3, 3), angle-weighted vertex pseudo-normals (V, 3), the needles' (F, 3))
    (Baerentzen & Aanaes: the sign where the closest point is an edge or a corner, where a single face normal
    can give the wrong one); edge k of a face joins corners k and k+1, ``inv`` numbers the edges. A needle's
    normal takes no part (it would turn them any way, and at its obtuse corner its angle of nearly 180 deg would
    outweigh the rest) but where only needles meet; a needle's own is ``_needle_normals``."""
    tri = verts[faces]
    u, v = np.roll(tri, -1, axis=1) - tri, np.roll(tri, 1, axis=1) - tri
    angle = np.arccos(np.clip(np.einsum("fkj,fkj->fk", _unit(u), _unit(v)), -1.0, 1.0))

    def sums(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(per edge, per vertex) sums of the face normals ``n`` (the vertices' angle-weighted)."""
        edge, vertex = np.zeros((edges, 3)), np.zeros_like(verts)
        np.add.at(edge, inv.ravel(), np.repeat(n, 3, axis=0))
        np.add.at(vertex, faces.ravel(), (angle[:, :, None] * n[:, None, :]).reshape(-1, 3))
        return edge, vertex

    summed, vn = sums(np.where(needle[:, None], 0.0, normals))
    own, square = _needle_normals(faces, normals, needle, inv, vn)
    if square.any():   # a knife edge's square ribbon takes part with its own normal, the edge's outward direction
        summed, vn = sums(np.where((needle & ~square)[:, None], 0.0, normals))
    if needle.any():   # where only needles meet, their own normals
        alone, vn_all = sums(normals)
        summed = np.where((np.linalg.norm(summed, axis=1) > 1e-9)[:, None], summed, alone)
        vn = np.where((np.linalg.norm(vn, axis=1) > 1e-9)[:, None], vn, vn_all)
    return _unit(summed[inv.ravel()]).reshape(-1, 3, 3), _unit(vn), own


def _needle_normals(faces, normals, needle, inv, vn) -> tuple[np.ndarray, np.ndarray]:
    """Per triangle (F, 3): a needle's pseudo-normal, read as the edge it nearly is (a ribbon of needles, a blade's
    trailing edge narrower than a closest point is exact, is the edge where its two sides meet): the sum, with
    equal weights as at an edge, of the two most opposed of the vertex pseudo-normals (``vn``, needles left out)
    at its corners and those of the needles within ``NEEDLE_RINGS`` shared edges of it (a cap on one side's edge
    reaches the other side's through the ribbon): ``u`` the one least along their mean, then the one least along
    ``u``. Another triangle, or a needle with no such corner, keeps its own normal; so does a needle square to
    the two sides of a knife edge (their normals nearly opposed: a fin's tip), whose sum is a few um's noise (the
    second array marks those: their normal is the edge's outward direction)."""
    square = np.zeros(len(faces), bool)
    if not needle.any():
        return normals.copy(), square
    from scipy.sparse import coo_matrix, identity

    e = inv.ravel()
    order = np.argsort(e, kind="stable")
    e, f = e[order], np.repeat(np.arange(len(faces)), 3)[order]
    pair = np.flatnonzero(e[1:] == e[:-1])
    a, b = f[pair], f[pair + 1]
    both = needle[a] & needle[b]
    n = len(faces)
    step = coo_matrix((np.ones(2 * both.sum()), (np.r_[a[both], b[both]], np.r_[b[both], a[both]])), shape=(n, n))
    reach = identity(n, format="csr")
    for _ in range(NEEDLE_RINGS):
        reach = reach + reach @ step
    reach = reach[np.flatnonzero(needle)].tocoo()          # (needle, triangle within reach)
    i = np.repeat(reach.row, 3)
    v = faces[reach.col].ravel()
    length = np.linalg.norm(vn[v], axis=1)
    keep = length > 1e-9
    i, U = i[keep], vn[v][keep] / length[keep, None]
    out = normals.copy()
    if not len(i):
        return out, square
    mean = np.stack([np.bincount(i, U[:, c], minlength=reach.shape[0]) for c in range(3)], axis=1)
    first = _least_along(i, U, mean[i])
    second = _least_along(i, U, U[first][np.searchsorted(np.unique(i), i)])
    rows = np.unique(i)
    pn = U[first] + U[second]
    at = np.flatnonzero(needle)[rows]
    knife = (np.linalg.norm(pn, axis=1) < KNIFE_SUM) & (np.abs(np.einsum("ij,ij->i", normals[at], U[first]))
                                                         < KNIFE_SQUARE_COS)
    ok = (np.linalg.norm(pn, axis=1) > 1e-9) & ~knife
    out[at[ok]] = _unit(pn[ok])
    square[at[knife]] = True
    return out, square


def _least_along(group: np.ndarray, U: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Per group (in increasing order): the index into ``U`` of its row least along ``d`` (its row's direction)."""
    order = np.lexsort((np.einsum("ij,ij->i", U, d), group))
    starts = np.r_[0, np.flatnonzero(np.diff(group[order])) + 1]
    return order[starts]


def _hint(points, dirs):
    if points is None and dirs is None:
        return None, None
    if points is None or dirs is None:
        raise BadInput("outward hint: give both outward_points_mm and outward_dirs, or neither")
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    d = np.asarray(dirs, dtype=float).reshape(-1, 3)
    if len(p) != len(d) or len(p) == 0:
        raise BadInput(f"outward hint: {len(p)} points and {len(d)} directions; expected the same number > 0")
    n = np.linalg.norm(d, axis=1)
    ok = np.isfinite(p).all(axis=1) & np.isfinite(d).all(axis=1) & (n > 1e-9)
    if not ok.any():
        raise BadInput("outward hint: no finite point with a non-zero direction")
    p, d = p[ok], d[ok] / n[ok, None]
    if len(p) > 20000:  # plenty to orient a surface
        sel = np.linspace(0, len(p) - 1, 20000).astype(int)
        p, d = p[sel], d[sel]
    return p, d


def _sample_ruled(a0, a1, d0, d1, depth, step):
    """Points (spacing <= step along both directions) of the ruled patches
    (1 - w)(a0 - s depth d0) + w (a1 - s depth d1), s, w in [0, 1]."""
    m_d = max(1, int(np.ceil(depth / step)))
    width = np.maximum(np.linalg.norm(a1 - a0, axis=1), np.linalg.norm(a1 - a0 - depth * (d1 - d0), axis=1))
    m_w = np.maximum(1, np.ceil(width / step).astype(int))
    s = np.linspace(0.0, 1.0, m_d + 1)[None, :, None]
    out = []
    for m in np.unique(m_w):
        k = m_w == m
        w = np.linspace(0.0, 1.0, m + 1)[None, None, :, None]
        p0 = a0[k][:, None, :] - s * depth * d0[k][:, None, :]  # (P, S, 3)
        p1 = a1[k][:, None, :] - s * depth * d1[k][:, None, :]
        out.append(((1 - w) * p0[:, :, None] + w * p1[:, :, None]).reshape(-1, 3))
    return np.concatenate(out)


def _sample_triangles(tri, step):
    """Points such that every point of the triangles (T, 3, 3) lies within ``step`` of one."""
    edge = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
    m_all = np.maximum(1, np.ceil(edge / step).astype(int))
    out = []
    for m in np.unique(m_all):
        t = tri[m_all == m]
        i, j = np.nonzero(np.add.outer(np.arange(m + 1), np.arange(m + 1)) <= m)
        a, b = (i / m)[None, :, None], (j / m)[None, :, None]
        out.append((t[:, :1] + a * (t[:, 1:2] - t[:, :1]) + b * (t[:, 2:3] - t[:, :1])).reshape(-1, 3))
    return np.concatenate(out)


def _covering_tree(verts, faces, gap):
    """(KD-tree, covering radius <= ``gap``) of points with every point of the triangles within
    the radius of one: the vertices alone where the triangles are small enough (a triangle
    lies within its longest edge / sqrt(3) of its corners), else a lattice on each triangle."""
    tri = verts[faces]
    radius = float(np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max()) / np.sqrt(3.0)
    if radius <= gap:
        return cKDTree(verts[np.unique(faces)]), radius
    return cKDTree(_sample_triangles(tri, gap * np.sqrt(3.0))), float(gap)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)


def _spacing(points: np.ndarray) -> float:
    d, _ = cKDTree(points).query(points, k=2, workers=-1)
    return float(np.median(d[:, 1]))


def part_from_path(workpiece, path, **kwargs) -> PartGeometry:
    """PartGeometry oriented by a ``camtool.path.toolpath.Path``: outward = -tool z at its work poses."""
    from ..path.toolpath import WORK

    poses = np.asarray(path.poses_mm, dtype=float)
    sel = np.asarray(path.zone) == WORK
    if not sel.any():
        sel = np.ones(len(poses), bool)
    return PartGeometry.from_workpiece(workpiece, poses[sel, :3, 3], -poses[sel, :3, 2], **kwargs)


def import_part_libraries() -> None:
    """Import open3d, which the mesh query needs, and load the grid bounds' compiled loops (seconds): a
    process made ready ahead of the check (``camtool.alongside.Standby``) does it while the run still plans."""
    from ..part.open3d_import import import_open3d

    import_open3d()

    from .grid_bounds import load_compiled

    load_compiled()


def _cloud_edges(P: np.ndarray, N: np.ndarray, nb: np.ndarray, dist: np.ndarray, s90: float, is_edge=None):
    """(on the edge, in the edge band, outward direction) of each cloud point: the angular-gap test in its tangent
    plane (neighbours ``nb`` at ``dist``, ``s90`` the spacing's 90th percentile); ``is_edge`` given: kept, only
    the outward directions made in the tangent planes of ``N``."""
    off = P[nb[:, 1:]] - P[:, None, :]
    e1 = np.cross(N, np.where(np.abs(N[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]]))
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    e2 = np.cross(N, e1)
    x, y = np.einsum("ikj,ij->ik", off, e1), np.einsum("ikj,ij->ik", off, e2)
    if is_edge is None:
        ang = np.sort(np.arctan2(y, x), axis=1)
        gaps = np.diff(np.concatenate([ang, ang[:, :1] + 2 * np.pi], axis=1), axis=1)
        is_edge = gaps.max(axis=1) > EDGE_GAP_RAD
    # outward in the tangent plane: away from the neighbours' centroid
    out = -(x.mean(axis=1)[:, None] * e1 + y.mean(axis=1)[:, None] * e2)
    out_dir = out / np.maximum(np.linalg.norm(out, axis=1), 1e-12)[:, None]
    # The test misses some outermost points (random sampling): the edge band is every point
    # within EDGE_BAND spacings of a flagged one, facing out like its nearest flagged neighbour.
    band = is_edge[nb[:, 1:]] & (dist[:, 1:] <= EDGE_BAND * s90)
    first = np.argmax(band, axis=1)
    grow = ~is_edge & band.any(axis=1)
    out_dir[grow] = out_dir[nb[grow, 1 + first[grow]]]
    return is_edge, is_edge | grow, out_dir


def _checked_normals(P: np.ndarray, N: np.ndarray, nb: np.ndarray, edge: np.ndarray, hint=None) -> np.ndarray:
    """The cloud's normals, each replaced by the normal of the plane of its neighbours ``nb`` (turned to agree with
    it) on the cloud's ``edge`` and where the two lie more than NORMAL_AGREE_DEG apart. A file's normals were
    estimated on the whole scan, its outliers and its noise's tails among them, and at the edge of a noisy scan
    (its rim, a hole's) those tilt a one-sided neighbourhood: the shell scan's hole rims carry normals 35 deg off
    its surface, which read a lead over the hole, 6 mm beside the rim, as 5 mm behind the part, and flipped a
    lead's value from +4.7 to -4.0 mm within 0.5 mm of its way. The plane of the checked points' own neighbours
    is the surface's within a few degrees there; inside the edge, normals that agree with it (a clean scan's, a
    plane's, a chamfer's blended ones) are kept as they are. A replaced normal takes the side of the outward
    ``hint`` (per point) where given, else of the normal it replaces (a normal across the surface has none)."""
    if nb.shape[1] < 4:
        return N
    _, n, _ = _plane(P[nb], np.ones(nb.shape))
    along = np.einsum("ij,ij->i", n, N)
    off = edge | (np.abs(along) < np.cos(np.radians(NORMAL_AGREE_DEG)))
    if not off.any():
        return N
    side = along if hint is None else np.einsum("ij,ij->i", n, hint)
    out = N.copy()
    out[off] = n[off] * np.where(side[off] < 0, -1.0, 1.0)[:, None]
    return out


def _plane(Q: np.ndarray, w: np.ndarray, eigenvalues: bool = False):
    """(centroid, unit normal, spread[, eigenvalues ascending]) of the weighted least-squares plane of each row
    of points ``Q`` (..., k, 3); spread: the middle over the largest eigenvalue (near 0: the points lie on a
    line)."""
    mid = np.einsum("...k,...ki->...i", w, Q) / w.sum(axis=-1)[..., None]
    D = Q - mid[..., None, :]
    lam, vec = np.linalg.eigh(np.einsum("...k,...ki,...kj->...ij", w, D, D))
    out = mid, vec[..., :, 0], lam[..., 1] / np.maximum(lam[..., 2], 1e-300)
    return out + (lam,) if eigenvalues else out


def _stray_free(Q: np.ndarray, nb: np.ndarray, isolated) -> np.ndarray:
    """Weights (1 keep, 0 drop) of each row's neighbours ``Q`` (m, k, 3), cloud indices ``nb`` (m, k): a
    neighbour farther off the plane of the other k - 1 than MLS_OUTLIER_SIGMAS times their RMS offset (and
    MLS_OUTLIER_FLOOR_MM), and off the plane of its own neighbours too (``isolated(indices)``: not a point of
    a face beside an edge), is a stray scan point (an outlier within the fit's band, issue #48: one 4 mm off
    the wall among points 0.1 mm off tilted the plane and read a pose on the wall as 1.8 mm behind it). At
    most k - 3 are dropped."""
    m, k = Q.shape[:2]
    if k < 4:
        return np.ones((m, k))
    others = ~np.eye(k, dtype=bool)  # row j: every neighbour but j
    R = np.broadcast_to(Q[:, None, :, :], (m, k, k, 3))[:, others].reshape(m, k, k - 1, 3)
    mid, n, spread = _plane(R, np.ones((m, k, k - 1)))
    rms = np.sqrt(np.mean(np.einsum("mjki,mji->mjk", R - mid[:, :, None, :], n) ** 2, axis=2))
    off = np.abs(np.einsum("mji,mji->mj", Q - mid, n))
    stray = (off > np.maximum(MLS_OUTLIER_SIGMAS * rms, MLS_OUTLIER_FLOOR_MM)) & (spread > MLS_MIN_SPREAD)
    if stray.any():
        cand = np.unique(nb[stray])
        stray &= np.isin(nb, cand[isolated(cand)])
    w = (~stray).astype(float)
    w[w.sum(axis=1) < 3] = 1.0
    return w
