"""Is a mesh a scan? Its vertices' roughness, and a scan's noise band (docs/freeform.md, "Scanned meshes").

A CAD mesh's vertices lie on the smooth surface it tessellates; a scanned mesh's vertices carry the
scanner's noise. Each vertex's residual is its offset, along the local normal, from the quadric fitted
(least squares) to its ``ROUGH_NEIGHBOURS`` nearest other vertices in their own principal frame. On a
CAD mesh that is the quadric's third-order error (the car hood: median 7e-7 mm, the dac CAD 3e-4 mm);
on a scan it is the noise (the dac scan 0.009 mm, the panel scan 0.014 mm, the dome scan 0.086 mm). A
mesh is rough -- judged as a scan -- when the median |residual| exceeds ``SCAN_ROUGHNESS_MM``. A
tessellation too coarse for its curvature (noether's wavy sheet, 9 mm facets on a wave: 0.2 mm) counts
as rough too: its facets' creases are the bumps the tool meets between poses, as a scan's noise is.

The noise band is measured at the scale the tool meets the scan: each vertex's residual from the quadric
through its neighbours within two smoothing sigmas (``fit.smoothing_mm``; 0: the free-form surface's own
default, ``SCAN_SMOOTHING_SPACINGS`` point spacings, at least ``SCAN_SMOOTHING_MIN_MM``), the surface a
scan's rows follow. A laser scan's roughness is correlated over a few mm (the dac scan's p99.9 grows from
0.07 mm over 12 neighbours to 0.27 mm over 2 sigmas, and its bumps between poses 5 mm apart reach
0.23 mm). The band is the ``BAND_QUANTILE`` quantile of those |residual|s, capped at ``BAND_MAX_MM``; the
motion check's TCP tolerances on the part grow by it (run/stages.py), so they are never below the CAD one.
The quantile is that high because the rows pass over the whole face and so meet its worst bumps: p99.9
leaves 34 of the dac scan's 33 600 vertices above the band (0.26 mm), and its rows met one 0.38 mm deep;
p99.99 (0.35 mm) leaves 3.

Written by hand: neither trimesh nor open3d gives a per-vertex quadric residual (open3d's normals fit a
plane, which reads curvature as noise; trimesh's curvature measures are ball integrals, not residuals).
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree


SCAN_SMOOTHING_SPACINGS = 2.5  # a scan's positions are smoothed over this many point spacings (at least 2 mm) ...
SCAN_SMOOTHING_MIN_MM = 2.0    # ... (part.freeform's smoothing of a scan; its noise band is measured over two of it)
COPLANAR_REL = 1e-5         # two triangles are coplanar when the fourth corner is this share of their edge off the plane
CAD_COPLANAR_SHARE = 0.005  # a rough mesh with this share of its triangle pairs coplanar is CAD (scans <= 0.16 %, a CAD door 1.62 %)
ROUGH_NEIGHBOURS = 12       # a vertex's quadric is fitted to this many nearest other vertices
SCAN_ROUGHNESS_MM = 0.003   # a mesh whose median |residual| exceeds this is rough: judged as a scan
BAND_QUANTILE = 99.99       # a scan's noise band: this percentile of |residual| (the rows pass over all of them) ...
BAND_MAX_MM = 0.5           # ... at most this (a few wild vertices, or a coarse mesh's facets, loosen no more)
MAX_BAND_NEIGHBOURS = 128   # the band's neighbourhood (two smoothing sigmas) holds at most this many vertices
MAX_QUERIES = 100_000       # residuals of at most this many vertices (every k-th) on a large mesh
CHUNK = 10_000              # vertices fitted at a time (bounded memory)


@dataclass(frozen=True)
class Roughness:
    """A mesh's roughness: median and banded |residual| (mm), and whether it is judged as a scan."""

    median_mm: float
    band_mm: float
    is_scan: bool
    coplanar_share: float | None = None   # of a rough mesh's triangle pairs (None: not measured)


def vertex_residuals(vertices_mm: np.ndarray, queries: np.ndarray | None = None,
                     neighbours: int = ROUGH_NEIGHBOURS, tree: cKDTree | None = None) -> np.ndarray:
    """Each queried vertex's offset (mm, signed) from the quadric through its ``neighbours`` nearest others."""
    V = np.asarray(vertices_mm, float)
    q = np.arange(len(V)) if queries is None else np.asarray(queries)
    k = min(int(neighbours), len(V) - 1)
    if k < 6:   # a quadric has six coefficients
        return np.zeros(len(q))
    tree = cKDTree(V) if tree is None else tree
    return np.concatenate([_residuals(V, q[i:i + CHUNK], k, tree) for i in range(0, len(q), CHUNK)]) \
        if len(q) else np.zeros(0)


def _residuals(V, q, k, tree):
    _, nb = tree.query(V[q], k=k + 1, workers=-1)
    R = V[nb[:, 1:]]
    mid = R.mean(axis=1)
    R = R - mid[:, None, :]
    vec = np.linalg.eigh(np.einsum("nki,nkj->nij", R, R))[1]   # ascending: the normal first
    local = np.einsum("nki,nij->nkj", R, vec[:, :, ::-1])        # (x, y, height) in the principal frame
    p = np.einsum("ni,nij->nj", V[q] - mid, vec[:, :, ::-1])

    def design(x, y):
        return np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=-1)

    A = design(local[..., 0], local[..., 1])
    scale = np.einsum("nki,nki->n", R, R)[:, None, None] / k + 1e-12
    AtA = np.einsum("nki,nkj->nij", A, A) + 1e-9 * scale * np.eye(6)
    coef = np.linalg.solve(AtA, np.einsum("nki,nk->ni", A, local[..., 2])[..., None])[..., 0]
    return p[:, 2] - np.einsum("ni,ni->n", design(p[:, 0], p[:, 1]), coef)


def coplanar_share(vertices_mm: np.ndarray, faces: np.ndarray) -> float:
    """Share of a mesh's pairs of triangles sharing an edge that are coplanar (module doc); degenerate triangles
    (no plane) are left out. trimesh gives the pairs (``face_adjacency``)."""
    import trimesh

    m = trimesh.Trimesh(np.asarray(vertices_mm, float), np.asarray(faces, np.int64), process=False)
    n = m.face_normals
    adj = m.face_adjacency
    if not len(adj):
        return 0.0
    ok = (np.linalg.norm(n[adj[:, 0]], axis=1) > 0.5) & (np.linalg.norm(n[adj[:, 1]], axis=1) > 0.5)
    edge, other = m.face_adjacency_edges[ok], m.face_adjacency_unshared[ok, 1]
    V = m.vertices
    h = np.abs(np.einsum("ij,ij->i", V[other] - V[edge[:, 0]], n[adj[ok, 0]]))
    length = np.linalg.norm(V[edge[:, 1]] - V[edge[:, 0]], axis=1)
    return float(np.mean(h <= COPLANAR_REL * length)) if ok.any() else 0.0


_VERDICTS: dict = {}   # the last few meshes' verdicts by their bytes: a run asks once per plan (lead sizing: 4+ times)


def _verdict_key(vertices_mm, scan: str, faces) -> tuple:
    V = np.ascontiguousarray(vertices_mm, float)
    F = np.ascontiguousarray(faces if faces is not None else np.zeros((0, 3), np.int64))
    return hashlib.sha256(V.tobytes() + F.tobytes()).hexdigest(), V.shape, F.shape, str(F.dtype), scan


def judged_before(vertices_mm: np.ndarray, scan: str = "auto", faces: np.ndarray | None = None) -> bool | None:
    """``mesh_is_scan``'s verdict when this process has judged the mesh already, else None (nothing judged now)."""
    return _VERDICTS.get(_verdict_key(vertices_mm, scan, faces))


def mesh_is_scan(vertices_mm: np.ndarray, scan: str = "auto", faces: np.ndarray | None = None) -> bool:
    """Whether a mesh is judged as a scan (``mesh_roughness``'s verdict, without its noise band); remembered for
    the same vertices, faces and ``scan`` (the judgement costs a second on a 200 k-vertex scan)."""
    key = _verdict_key(vertices_mm, scan, faces)
    if key not in _VERDICTS:
        if len(_VERDICTS) >= 4:
            _VERDICTS.clear()
        _VERDICTS[key] = _judged(vertices_mm, scan, faces)[0]
    return _VERDICTS[key]


def _judged(vertices_mm, scan, faces):
    """(is a scan, median |residual| mm, coplanar share or None, merged vertices, their tree, queried indices)."""
    V, inverse = np.unique(np.round(np.asarray(vertices_mm, float), 6), axis=0, return_inverse=True)
    if len(V) < 7 or scan == "no":
        return False, 0.0, None, V, None, None
    tree = cKDTree(V)
    q = np.arange(0, len(V), max(1, -(-len(V) // MAX_QUERIES)))
    median = float(np.median(np.abs(vertex_residuals(V, q, ROUGH_NEIGHBOURS, tree))))
    if scan == "auto" and median <= SCAN_ROUGHNESS_MM:
        return False, median, None, V, tree, q
    share = None
    if faces is not None and scan == "auto":   # the faces renumbered to the merged vertices
        share = coplanar_share(V, np.asarray(inverse).ravel()[np.asarray(faces)])
    return not (scan == "auto" and share is not None and share >= CAD_COPLANAR_SHARE), median, share, V, tree, q


def mesh_roughness(vertices_mm: np.ndarray, smoothing_mm: float = 0.0, scan: str = "auto",
                   faces: np.ndarray | None = None) -> Roughness:
    """The roughness of a mesh's vertices (every k-th of a large mesh, deterministic), its noise band measured
    over two ``smoothing_mm`` sigmas (0: the free-form default). Coincident vertices (an STL's or a triangle
    soup's corners) count once: a vertex's copy would pin its quadric. ``scan``: "auto" judges by the
    roughness and, for a rough mesh with its ``faces``, by its coplanar triangles (module doc), "yes" / "no" as
    the workpiece says (``workpiece.scan``); the band is 0 unless a scan."""
    is_scan, median, share, V, tree, q = _judged(vertices_mm, scan, faces)
    if not is_scan:
        return Roughness(median, 0.0, False, share)
    spacing = float(np.median(tree.query(V[q], k=2, workers=-1)[0][:, 1]))
    sigma = smoothing_mm if smoothing_mm > 0 else max(SCAN_SMOOTHING_SPACINGS * spacing, SCAN_SMOOTHING_MIN_MM)
    k = int(np.clip(np.ceil(np.pi * (2.0 * sigma / max(spacing, 1e-9)) ** 2), ROUGH_NEIGHBOURS, MAX_BAND_NEIGHBOURS))
    wide = np.abs(vertex_residuals(V, q, k, tree))
    return Roughness(median, min(float(np.percentile(wide, BAND_QUANTILE)), BAND_MAX_MM), True, share)
