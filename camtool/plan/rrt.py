"""Free joint-space moves by RRT-Connect (seed 001) for approach and depart moves.

- ``CapsuleChecker(robot, mesh)``: the default validity check. A configuration
  is valid when it is inside the joint limits and every link, modelled as a
  capsule of ``radius_mm`` round the segment between consecutive joint-frame
  origins (from FK, plus flange and TCP), keeps ``clearance_mm`` from the
  workpiece mesh (world frame). Distances come from coal's BVH
  (``collision.mesh_query``; or trimesh's proximity query, ``backend="trimesh"``;
  the same closest-point query)
  (signed for watertight meshes, so a link inside the part counts too;
  unsigned for open surface patches, pre-filtered by a KD-tree of the
  vertices); link points farther than the capsule radius plus
  ``EXACT_BAND_MM`` are not queried exactly (their distance is a lower bound);
  on an open patch signed by its work (``outward``), such a point is screened at
  a near vertex for being behind the patch, and tested exactly only if it may be.
- ``rrt_connect(q_start, q_goal, valid, lower, upper, ...)``: bidirectional
  RRT with a seeded RNG (deterministic), edges checked every ``resolution_rad``.
- ``shortcut(path, ...)``: random shortcut smoothing (seeded).
- ``CloudChecker(robot, points)``: the same capsules against a point cloud
  (KD-tree distance; no inside test).
- ``free_move`` / ``insert_home_moves``: the approach and depart moves of
  raster jobs with ``robot.home_deg`` (``camtool.run.stages.add_home_moves``).
- ``plan_free_move(robot, q_start, q_goal, valid=None, mesh=None, ...)``: all
  of it, then timed by the common timing stage (rest-to-rest ruckig moves
  between waypoints); timed samples that break validity get their move split
  and retimed.

Any callable ``valid(q) -> bool`` can replace the default check.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..collision.validity import Validity, reason_of, valid_rows
from ..errors import BadInput, PlanInfeasible
from ..robots.ik_common import Chain
from ..path.toolpath import ZONE_CODE, Path
from ..trajectory import JointPath


EDGE_BATCH = 32       # edge samples checked in one batch (one distance query)
EXACT_BAND_MM = 50.0  # clearances below this are exact; larger ones may be reported as this lower bound


_FRACTIONS: dict = {}   # n -> linspace(0, 1, n + 1): the link sampling fractions, made once a process


class _LinkCapsules(Validity):
    """Link capsules of a robot (segments between joint-frame origins, flange and TCP) and their clearance.

    ``exempt``: balls ((x, y, z) mm world, radius mm) whose link points are not
    checked: the planned tool contact at the end of an approach, where the tool
    is meant to touch the part.
    """

    def __init__(self, robot, radius_mm: float, clearance_mm: float, skip_links: int, spacing_mm, exempt,
                 tip_exempt_mm: float = 0.0):
        if radius_mm <= 0:
            raise BadInput(f"capsule radius must be > 0 mm, found {radius_mm}")
        self.robot = robot
        self.chain = Chain(robot)
        self.radius, self.clearance = float(radius_mm), float(clearance_mm)
        self.skip = int(skip_links)   # links from the base not checked (the base stands on its own floor)
        self.spacing = spacing_mm or self.radius / 2.0
        self.exempt = [(np.asarray(c, float), float(r)) for c, r in exempt]
        # as the motion check measures: the last ``tip_exempt_mm`` of the chain before the TCP is no capsule
        # (the tool touches the part by design), the TCP itself keeps the clearance as a point
        self.tip_exempt = float(tip_exempt_mm)
        self.calls = 0

    def _points_many(self, Q) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """For every row of Q at once: the link points (M, 3) world frame (exempt balls and the exempt
        tip removed) with the row of each (M,), and the TCPs (K', 3) outside the exempt balls with theirs.

        A segment's points are ``a + f (b - a)`` at ``ceil(length / spacing)`` equal steps, and the
        rows whose segment has the same count are computed together."""
        F = self.chain.frames_many(Q)
        K = len(F)
        tool, base = self.robot.tool_T_mm, self.robot.base_T_mm
        pts = np.concatenate([np.zeros((K, 1, 3)), F[:, :, :3, 3], (F[:, -1] @ tool)[:, None, :3, 3]], axis=1)
        d = pts[:, 1:] - pts[:, :-1]
        L = np.sqrt(np.einsum("ksi,ksi->ks", d, d))
        after = np.cumsum(L[:, ::-1], axis=1)[:, ::-1] - L   # chain length from each segment's end to the TCP
        out, rows, to_tip = [], [], []
        for j in range(self.skip, L.shape[1]):
            counts = np.maximum(np.ceil(L[:, j] / self.spacing).astype(int), 1)
            for n in np.unique(counts):
                r = np.flatnonzero(counts == n)
                f = _FRACTIONS.get(int(n))
                if f is None:
                    f = _FRACTIONS[int(n)] = np.linspace(0.0, 1.0, n + 1)
                out.append((pts[r, j, None] + f[None, :, None] * d[r, j, None]).reshape(-1, 3))
                rows.append(np.repeat(r, n + 1))
                to_tip.append((after[r, j, None] + (1.0 - f)[None] * L[r, j, None]).ravel())
        P = np.concatenate(out) @ base[:3, :3].T + base[:3, 3]
        row, keep = np.concatenate(rows), np.ones(len(P), bool)
        if self.tip_exempt > 0:
            keep &= np.concatenate(to_tip) > self.tip_exempt
        tcp = (base @ F[:, -1] @ tool)[:, :3, 3]
        tcp_row, tcp_keep = np.arange(K), np.ones(K, bool)
        for c, r in self.exempt:
            keep &= np.linalg.norm(P - c, axis=1) > r
            tcp_keep &= np.linalg.norm(tcp - c, axis=1) > r
        return P[keep], row[keep], tcp[tcp_keep], tcp_row[tcp_keep]

    def link_points(self, q) -> np.ndarray:
        """Points (M, 3) along the link segments at q, world frame (exempt balls and the exempt tip removed)."""
        return self._points_many(np.asarray(q, float)[None])[0]

    def distances(self, P) -> np.ndarray:
        raise NotImplementedError

    def clearance_mm(self, q) -> float:
        """Smallest distance from a link capsule's surface (or, with a tip exemption, the TCP) to the part."""
        return float(self.clearances_mm(np.asarray(q, float)[None])[0])

    def __call__(self, q) -> bool:
        self.calls += 1
        if not self.robot.within_limits(q):
            return False
        return self.clearance_mm(q) >= self.clearance

    def valid_many(self, Q) -> np.ndarray:
        """``__call__`` for every row of Q, with one distance query for all their link points."""
        Q = np.asarray(Q, float)
        self.calls += len(Q)
        ok = np.array([self.robot.within_limits(q) for q in Q], bool)
        rows = np.flatnonzero(ok)
        if len(rows):
            ok[rows] = self.clearances_mm(Q[rows]) >= self.clearance
        return ok

    def clearances_mm(self, Q) -> np.ndarray:
        """``clearance_mm`` of every row of Q, with one distance query for all their link points."""
        Q = np.asarray(Q, float).reshape(-1, self.robot.dof)
        clear = np.full(len(Q), np.inf)
        if not len(Q):
            return clear
        P, row, tcp, tcp_row = self._points_many(Q)
        if self.tip_exempt > 0 and len(tcp):   # the TCP keeps the clearance as a point
            P, row = np.concatenate([P, tcp]), np.concatenate([row, tcp_row])
            shift = np.r_[np.full(len(P) - len(tcp), -self.radius), np.zeros(len(tcp))]
        else:
            shift = np.full(len(P), -self.radius)
        if len(P):
            np.minimum.at(clear, row, self.distances(P) + shift)
        return clear


HINT_COS = 0.5  # a work pose's tool axis orients a mesh face within 60 deg of it (open patches)
FAR_VERTEX_EPS = 0.5   # a far link point is screened at a vertex within 1.5 x its nearest vertex distance ...
FAR_BEHIND_COS = 0.25  # ... in a cone 15 deg wider than the behind test's (cos 60 deg); those inside it are
                       # tested exactly


class CapsuleChecker(_LinkCapsules):
    """Joint limits plus link-capsule clearance from a workpiece mesh (world frame, mm).

    Watertight meshes use the signed distance (a link inside the part counts as
    overlap); open meshes (a surface patch) the unsigned distance. ``backend``:
    "coal" (BVH, ``collision.mesh_query``, default, fast) or "trimesh" (ProximityQuery);
    a test checks they agree.
    """

    def __init__(self, robot, mesh, radius_mm: float = 60.0, clearance_mm: float = 0.0,
                 skip_links: int = 1, spacing_mm: float | None = None, exempt=(), backend: str = "coal",
                 outward=None, tip_exempt_mm: float = 0.0):
        import trimesh

        super().__init__(robot, radius_mm, clearance_mm, skip_links, spacing_mm, exempt, tip_exempt_mm)
        # an open surface patch is not a solid: with ``outward`` = (points_mm, unit directions towards the
        # tool side), a point behind the surface (closest-point offset against the oriented face normal)
        # counts as inside the part, however far it is from the surface
        self.outward = None
        if backend not in ("coal", "trimesh"):
            raise BadInput(f"collision backend must be 'coal' or 'trimesh', found {backend!r}")
        if outward is not None and backend == "coal":
            from scipy.spatial import cKDTree

            self.outward = (cKDTree(np.asarray(outward[0], float)), np.asarray(outward[1], float))
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            raise BadInput("the collision check needs a triangle mesh of the workpiece")
        self.mesh = mesh
        self.signed = bool(mesh.is_watertight)
        self.lo, self.hi = mesh.bounds
        self.backend = backend
        if backend == "coal":
            from ..collision.mesh_query import MeshQuery

            self.query = MeshQuery(mesh)
        else:
            self.query = trimesh.proximity.ProximityQuery(mesh)
        if not self.signed:
            from scipy.spatial import cKDTree

            # every surface point lies within the longest edge of a vertex: a cheap lower bound
            self.vertex_tree = cKDTree(np.asarray(mesh.vertices))
            self.edge_mm = float(mesh.edges_unique_length.max())
        self._vertex_normal = self._vertices = None   # ``_far_behind_setup``, on the first far point

    def _far_behind_setup(self):
        """Per vertex, its normal oriented by the nearest work pose's tool axis (``_behind``'s screen).

        Each face normal is oriented by the hint at its centre before the area-weighted mean, so a
        mesh wound either way gives the same normals."""
        tree, dirs = self.outward
        F, N = np.asarray(self.mesh.faces), np.asarray(self.mesh.face_normals, float)
        hint = dirs[tree.query(np.asarray(self.mesh.triangles_center))[1]]
        N = N * (np.where(np.sum(N * hint, axis=1) < 0, -1.0, 1.0) * np.asarray(self.mesh.area_faces))[:, None]
        acc = np.zeros((len(self.mesh.vertices), 3))
        for k in range(3):
            np.add.at(acc, F[:, k], N)
        self._vertex_normal = acc / np.maximum(np.linalg.norm(acc, axis=1), 1e-300)[:, None]
        self._vertices = np.array(self.mesh.vertices, float)   # plain array: no cache hashing per query

    def _behind(self, P) -> np.ndarray:
        """Distance of points from an open mesh, negative for points behind it (``outward`` given).

        A point within the capsule radius plus ``EXACT_BAND_MM`` of a vertex (plus the longest
        edge) is measured exactly: coal's closest point, 10-25 us a point. A point farther out is
        clear unless it is behind the patch, so it gets that band as its distance (a lower bound,
        as ``distances`` says). It is first screened at a near vertex (within ``FAR_VERTEX_EPS``
        of the nearest distance) against that vertex's normal, in a cone wider than the behind
        test's (``FAR_BEHIND_COS``), about 2 us a point; only the few inside the screen are tested
        exactly. Most link points of a free move are far, and a robot inside a concave patch sees
        every vertex at nearly the same distance, where an exact nearest query visits the whole
        tree. The screen could miss a point only where the vertex's direction is 15 deg off the
        closest point's, beside the patch's rim; the motion check, measured independently of
        this planner's check, is the judge of every move.
        """
        P = np.asarray(P, float)
        reach = self.radius + max(self.clearance, 0.0) + EXACT_BAND_MM
        near = np.isfinite(self.vertex_tree.query(P, distance_upper_bound=reach + self.edge_mm)[0])
        out = np.empty(len(P))
        if near.any():
            out[near] = self._behind_exact(P[near])
        far = ~near
        if far.any():
            if self._vertex_normal is None:
                self._far_behind_setup()
            idx = np.flatnonzero(far)
            dv, v = self.vertex_tree.query(P[idx], eps=FAR_VERTEX_EPS)
            off = P[idx] - self._vertices[v]
            maybe = np.sum(off * self._vertex_normal[v], axis=1) < -FAR_BEHIND_COS * dv
            out[idx] = reach
            if maybe.any():   # the few that may be behind: the exact test decides
                out[idx[maybe]] = np.minimum(self._behind_exact(P[idx[maybe]]), reach)
        return out

    def _behind_exact(self, P) -> np.ndarray:
        """``_behind`` with the exact closest point of every point."""
        c, triangle = self.query.closest(P)
        n = self.mesh.face_normals[triangle]   # fancy indexing: a copy, flipped in place below
        tree, dirs = self.outward
        hint = dirs[tree.query(c)[1]]
        along = np.sum(n * hint, axis=1)
        n *= np.where(along < 0, -1.0, 1.0)[:, None]
        off = P - c
        dist = np.linalg.norm(off, axis=1)
        # behind the face, not beside the patch's edge; and only where the nearest work pose's axis is the
        # face's (a part of several faces: the work on one face does not orient the face next to it)
        behind = (np.sum(off * n, axis=1) < -0.5 * dist) & (np.abs(along) > HINT_COS)
        return np.where(behind, -dist, dist)

    def _exact(self, P) -> np.ndarray:
        """Exact distance of points from the mesh: signed (negative inside) for watertight meshes."""
        if self.backend == "coal":
            if self.outward is not None and not self.signed:
                return self._behind(P)
            return self.query.signed_distance(P) if self.signed else self.query.distance(P)
        if self.signed:
            return -self.query.signed_distance(P)  # trimesh: positive inside
        return self.query.on_surface(P)[1]

    def distances(self, P) -> np.ndarray:
        """Distance of each point from the mesh (signed: negative inside), or a lower bound where clear."""
        if self.outward is not None and not self.signed:
            return self._behind(P)  # every point: one far behind the patch is inside the part
        gap = np.linalg.norm(np.maximum(0.0, np.maximum(self.lo - P, P - self.hi)), axis=1)
        reach = self.radius + max(self.clearance, 0.0) + EXACT_BAND_MM
        near = gap < reach
        d = gap.copy()
        if near.any():
            if self.signed:
                d[near] = self._exact(P[near])
            else:
                idx = np.flatnonzero(near)
                dv = self.vertex_tree.query(P[idx], distance_upper_bound=reach + self.edge_mm)[0]
                lower = np.minimum(dv, reach + self.edge_mm) - self.edge_mm
                d[idx] = np.maximum(gap[idx], lower)
                close = idx[lower < reach]
                if len(close):
                    d[close] = self._exact(P[close])
        return d


class CloudChecker(_LinkCapsules):
    """Joint limits plus link-capsule clearance from a point cloud (KD-tree; no inside test)."""

    def __init__(self, robot, points_mm, radius_mm: float = 60.0, clearance_mm: float = 0.0,
                 skip_links: int = 1, spacing_mm: float | None = None, exempt=(), tip_exempt_mm: float = 0.0):
        from scipy.spatial import cKDTree

        super().__init__(robot, radius_mm, clearance_mm, skip_links, spacing_mm, exempt, tip_exempt_mm)
        pts = np.asarray(points_mm, float)
        if pts.ndim != 2 or len(pts) == 0:
            raise BadInput("the collision check needs the workpiece points")
        self.tree = cKDTree(pts)

    def distances(self, P) -> np.ndarray:
        """Distance of each point from the nearest cloud point (capped at radius + clearance + EXACT_BAND_MM)."""
        cap = self.radius + max(self.clearance, 0.0) + EXACT_BAND_MM
        return np.minimum(self.tree.query(P, distance_upper_bound=cap)[0], cap)


@dataclass
class _Tree:
    nodes: list
    parent: list

    def nearest(self, q, w) -> int:
        X = np.asarray(self.nodes)
        return int(np.argmin(np.sum(((X - q) * w) ** 2, axis=1)))

    def path_to_root(self, i) -> list:
        out = []
        while i >= 0:
            out.append(self.nodes[i])
            i = self.parent[i]
        return out


def edge_valid(qa, qb, valid, resolution_rad: float, w) -> bool:
    """Every point of the straight joint-space edge, at ``resolution_rad`` steps, is valid."""
    n = max(int(np.ceil(np.linalg.norm((qb - qa) * w) / resolution_rad)), 1)
    s = np.linspace(0.0, 1.0, n + 1)[1:]
    for k in range(0, n, EDGE_BATCH):   # in order, a batch at a time: the first invalid batch ends it
        part = s[k:k + EDGE_BATCH]
        if not valid_rows(valid, qa[None] + part[:, None] * (qb - qa)[None]).all():
            return False
    return True


def rrt_connect(q_start, q_goal, valid, lower, upper, step_rad: float = 0.3, resolution_rad: float = 0.03,
                max_iterations: int = 5000, seed: int = 0, weights=None, stats: dict | None = None) -> list[np.ndarray]:
    """Joint waypoints from q_start to q_goal, every edge valid; PlanInfeasible if none is found.

    ``stats``, if given, receives ``nodes``: the size of both trees (2 for a direct edge).
    """
    stats = {} if stats is None else stats
    stats["nodes"] = 2
    q_start, q_goal = np.asarray(q_start, float), np.asarray(q_goal, float)
    w = np.ones_like(q_start) if weights is None else np.asarray(weights, float)
    if not valid(q_start):
        raise PlanInfeasible("free move: the start configuration is not valid (limits or collision)")
    if not valid(q_goal):
        raise PlanInfeasible("free move: the goal configuration is not valid (limits or collision)")
    if edge_valid(q_start, q_goal, valid, resolution_rad, w):
        return [q_start, q_goal]
    rng = np.random.default_rng(seed)
    ta, tb = _Tree([q_start], [-1]), _Tree([q_goal], [-1])
    a_is_start = True

    def extend(tree, target):
        i = tree.nearest(target, w)
        q = tree.nodes[i]
        d = (target - q) * w
        dist = np.linalg.norm(d)
        reached = dist <= step_rad
        q_new = target if reached else q + (target - q) * (step_rad / dist)
        if not edge_valid(q, q_new, valid, resolution_rad, w):
            return None, False
        tree.nodes.append(q_new)
        tree.parent.append(i)
        return len(tree.nodes) - 1, reached

    for _ in range(max_iterations):
        q_rand = rng.uniform(lower, upper)
        i_new, _r = extend(ta, q_rand)
        if i_new is not None:
            q_new = ta.nodes[i_new]
            while True:  # connect: grow the other tree towards q_new until reached or trapped
                j, reached = extend(tb, q_new)
                if j is None:
                    break
                if reached:
                    stats["nodes"] = len(ta.nodes) + len(tb.nodes)
                    pa, pb = ta.path_to_root(i_new)[::-1], tb.path_to_root(j)
                    path = pa + pb[1:]
                    return path if a_is_start else path[::-1]
        ta, tb = tb, ta
        a_is_start = not a_is_start
    raise PlanInfeasible(f"free move: RRT-Connect found no path in {max_iterations} iterations")


def shortcut(path: list, valid, resolution_rad: float = 0.03, iterations: int = 100, seed: int = 0,
             weights=None) -> list[np.ndarray]:
    """Random shortcut smoothing: join two waypoints directly where the edge is valid."""
    rng = np.random.default_rng(seed)
    p = [np.asarray(x, float) for x in path]
    w = np.ones_like(p[0]) if weights is None else np.asarray(weights, float)
    for _ in range(iterations):
        if len(p) <= 2:
            break
        i, j = sorted(rng.choice(len(p), 2, replace=False))
        if j - i < 2:
            continue
        if edge_valid(p[i], p[j], valid, resolution_rad, w):
            p = p[:i + 1] + p[j:]
    return p


def _joint_path(robot, q: np.ndarray) -> tuple[JointPath, Path]:
    n = len(q)
    poses = np.array([robot.base_T_mm @ robot.fk_tcp(x) for x in q])
    zone = np.full(n, ZONE_CODE["approach"])
    path = Path(poses, np.zeros(n, int), np.zeros(n, int), zone)
    f = np.zeros(n, bool)
    return JointPath(q, np.arange(n), zone.copy(), np.zeros(n), np.zeros(n), f, f.copy(), f.copy(), f.copy(),
                     ~f, {}), path


REROUTE_RESOLUTION_SHARE = 0.25   # a move re-routed after its timed samples broke validity is searched
                                  # with edges checked this much finer
MIN_REROUTE_RESOLUTION_RAD = 1e-3  # ... but never finer than this (about 1 mm at 1 m): each round made it
                                   # 4x finer, so a move grazing a body at the clearance took 4^k x the checks
                                   # (minutes); the timed 4 ms samples stay the judge either way


def time_and_verify(robot, waypoints: list, valid, dt_s: float = 0.004, max_splits: int = 6,
                    resolution_rad: float = 0.03, weights=None, seed: int = 0, **timing):
    """Time waypoints with the timing stage; mend moves whose timed samples are invalid. (trajectory, q).

    Each move between waypoints is a straight joint-space line (phase-synchronised ruckig), so
    splitting it keeps its path: a move whose timed samples break validity although its edge
    passed at ``resolution_rad`` grazes something between the checked points. It is re-routed
    by RRT-Connect with edges checked ``REROUTE_RESOLUTION_SHARE`` as finely; a move whose
    line is valid at that resolution too is split at its middle (a rest there).
    """
    from ..settings import TimingSettings
    from ..timing import time_trajectory

    q = np.array(waypoints)
    w = np.ones(q.shape[1]) if weights is None else np.asarray(weights, float)
    fine = max(resolution_rad * REROUTE_RESOLUTION_SHARE, MIN_REROUTE_RESOLUTION_RAD)
    for attempt in range(max_splits + 1):
        jp, path = _joint_path(robot, q)
        tr = time_trajectory(jp, path, robot, TimingSettings.make(**{"method": "ruckig", **timing}))
        t, qs, *_ = tr.sample(dt_s)
        bad = np.flatnonzero(~valid_rows(valid, qs))
        if not len(bad):
            return tr, q
        # the move each bad sample lies on: the last waypoint (path_index >= 0) at or before it; the
        # timing inserts its own samples (path_index -1) inside every move
        at = np.flatnonzero(np.asarray(tr.path_index) >= 0)
        start = np.clip(np.searchsorted(tr.t_s[at], t[bad], side="right") - 1, 0, len(at) - 1)
        rows = {int(tr.path_index[at[i]]) for i in start}
        new = [q[0]]
        for k in range(1, len(q)):
            if (k - 1) in rows:
                if edge_valid(q[k - 1], q[k], valid, fine, w):
                    new.append(0.5 * (q[k - 1] + q[k]))
                else:   # the line itself grazes: another route, checked finely
                    detour = rrt_connect(q[k - 1], q[k], valid, robot.limits.lower, robot.limits.upper,
                                         resolution_rad=fine, seed=seed + attempt, weights=w)
                    new.extend(shortcut(detour, valid, fine, 50, seed + attempt, w)[1:-1])
            new.append(q[k])
        q = np.array(new)
        fine = max(fine * REROUTE_RESOLUTION_SHARE, MIN_REROUTE_RESOLUTION_RAD)
    k = int(bad[0])
    raise PlanInfeasible(f"free move: the timed trajectory keeps breaking the validity check: at t = "
                         f"{float(t[k]):.3f} s of the move {reason_of(valid, qs[k])}")


def plan_free_move(robot, q_start, q_goal, valid=None, mesh=None, radius_mm: float = 60.0,
                   clearance_mm: float = 0.0, seed: int = 0, step_rad: float = 0.3, resolution_rad: float = 0.03,
                   max_iterations: int = 5000, shortcut_iterations: int = 100, **timing):
    """RRT-Connect + shortcut + timing for one free move; returns (trajectory, waypoints, info)."""
    if valid is None:
        if mesh is None:
            raise BadInput("free move: give a workpiece mesh or a validity check")
        valid = CapsuleChecker(robot, mesh, radius_mm, clearance_mm)
    lo, hi = robot.limits.lower, robot.limits.upper
    raw = rrt_connect(q_start, q_goal, valid, lo, hi, step_rad, resolution_rad, max_iterations, seed)
    smooth = shortcut(raw, valid, resolution_rad, shortcut_iterations, seed)
    tr, q = time_and_verify(robot, smooth, valid, **timing)
    return tr, q, {"rrt_waypoints": len(raw), "smoothed_waypoints": len(smooth), "timed_waypoints": len(q)}


def path_length(q, weights) -> float:
    """Length of a joint-space polyline in the weighted metric (rad; the track counts per ``weights``)."""
    q = np.asarray(q, float)
    return float(np.linalg.norm(np.diff(q, axis=0) * weights, axis=1).sum()) if len(q) > 1 else 0.0


def free_move(robot, q_start, q_goal, valid, seed: int = 0, track_scale_mm: float = 500.0,
              step_rad: float = 0.3, resolution_rad: float = 0.03, max_iterations: int = 5000,
              shortcut_iterations: int = 100) -> tuple[np.ndarray, dict]:
    """Waypoints (K, dof) of one collision-free move and its figures (nodes, length, clearance).

    RRT-Connect, shortcut smoothing, then ``time_and_verify``: the waypoints
    returned give rest-to-rest ruckig moves whose 4 ms samples are all valid.
    A track joint counts ``track_scale_mm`` mm per rad in the metric.
    """
    w = np.where(robot.prismatic, 1.0 / track_scale_mm, 1.0)
    calls0 = getattr(valid, "calls", 0)
    stats = {}
    raw = rrt_connect(q_start, q_goal, valid, robot.limits.lower, robot.limits.upper, step_rad, resolution_rad,
                      max_iterations, seed, w, stats)
    smooth = shortcut(raw, valid, resolution_rad, shortcut_iterations, seed, w)
    tr, q = time_and_verify(robot, smooth, valid, resolution_rad=resolution_rad, weights=w, seed=seed)
    info = {"rrt_nodes": stats["nodes"], "rrt_waypoints": len(raw), "smoothed_waypoints": len(smooth), "timed_waypoints": len(q),
            "path_length_rad": round(path_length(q, w), 6), "duration_s": round(float(tr.t_s[-1] - tr.t_s[0]), 4),
            "validity_checks": getattr(valid, "calls", 0) - calls0}
    if hasattr(valid, "clearance_mm"):
        _t, qs, *_ = tr.sample(0.004)
        info["min_clearance_mm"] = round(float(np.min(valid.clearances_mm(qs))), 3)
    return q, info


def insert_home_moves(joint_path: JointPath, approach: np.ndarray, depart: np.ndarray,
                      events: dict | None = None) -> JointPath:
    """``joint_path`` with approach rows (home ... , before row 0) and depart rows (after the last row ... home).

    ``approach`` runs from home to the first row's q (that last one is not repeated),
    ``depart`` from the last row's q (not repeated) to home; inserted rows have
    path_index -1 and zones 'approach' / 'depart'. ``events`` are added to the
    joint path's events (a new dict; the input is not changed).
    """
    jp = joint_path
    a, d = np.asarray(approach)[:-1], np.asarray(depart)[1:]
    na, nd = len(a), len(d)

    def pad(x, fill):
        x = np.asarray(x)
        return np.concatenate([np.full(na, fill, x.dtype), x, np.full(nd, fill, x.dtype)])

    zone = np.concatenate([np.full(na, ZONE_CODE["approach"]), jp.zone, np.full(nd, ZONE_CODE["depart"])])
    return JointPath(
        q=np.concatenate([a.reshape(na, -1), jp.q, d.reshape(nd, -1)]), path_index=pad(jp.path_index, -1),
        zone=zone.astype(jp.zone.dtype), position_error_mm=pad(jp.position_error_mm, 0.0),
        orientation_error_rad=pad(jp.orientation_error_rad, 0.0), jump=pad(jp.jump, False),
        reverse_planned=pad(jp.reverse_planned, False), retract=pad(jp.retract, False),
        singular=pad(jp.singular, False), reached=pad(jp.reached, True), events={**jp.events, **(events or {})})
