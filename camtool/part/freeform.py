"""Free-form surfaces: a face of any smooth shape, from a CAD mesh or a raw scan (docs/freeform.md).

``FreeformSurface`` gives the raster and everything downstream the interface of the
analytic surfaces (``point_mm(u, v)``, ``normal_at(u, v)``, ``uv_from_points``,
``metric_scale``, a ``Boundary`` in (u, v), ``to_dict``). Inside it is a height field
on a regular grid of the face's chart plane (``freeform_grid``), sampled exactly from a
mesh or smoothed from a scan (``freeform_sample``), with normals smoothed at
``normal_smoothing_mm``, and a row chart (``freeform_rows``): u is the chart coordinate
along the rows, v the geodesic distance on the surface from the face's middle row.
Rows of constant v are therefore ``step_over_mm`` apart along the surface, and the
raster's arc length along a row (``metric_scale``) is measured on the surface too.

``freeform_surface(workpiece, settings)`` builds one from a placed workpiece (all of it,
or the points ``indices`` of one face).
"""
from __future__ import annotations

import base64
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import BadInput
from .freeform_exact import ChartMesh
from .freeform_grid import Grid, fill, grid_over, normals_of
from .freeform_normals import point_normals, scan_normals
from .mesh_normals import mesh_normals
from .roughness import SCAN_SMOOTHING_MIN_MM, SCAN_SMOOTHING_SPACINGS, mesh_is_scan
from .freeform_rows import row_distance, row_table, seed_row
from .freeform_sample import chart_frame, cloud_heights, mesh_heights, to_chart
from .domain import Boundary, FitStats
from .surface_base import Surface

NORMAL_SMOOTHING_MM = 6.0   # Gaussian sigma of the normals (a tool's footprint of 10-15 mm averages about this)
FOOTPRINT_RADIUS_MM = 12.5  # a CAD mesh's normals: its triangles' mean over a disc of this radius (issue #46: the part's
                            # normal averaged over 10-15 mm; its middle), where they replace the chart's (mesh_normals)
MAX_NODES = 300_000         # the grid's nodes at most (the spacing grows for a large face)
MIN_CELL_MM = 1.0           # ... and at least this spacing
MAX_SLOPE_DEG = 80.0        # a node steeper than this from the chart plane is no material (a wall of a closed part)
KNOWN_WEIGHT_SHARE = 0.2    # a scan's node has a height where its window holds this share of the typical weight
NOISE_BAND_SIGMAS = 3.0     # a scan's noise band in RMS residuals (the motion check's scan tolerance, run/stages.py)
LEAD_LIFT_MIN_MM = 1.0      # a free-form face's leads rise at least this far (a scanned mesh's roughness)
MARGIN_CELLS = 4            # nodes of margin round the face's box (the leads start on the surface continued)
SCAN_NORMAL_NOISE_DEG = 0.1         # a scan's normals are smoothed until its noise tilts them by at most this (RMS)
SCAN_NORMAL_SMOOTHING_MAX_MM = 10.0  # ... but over a Gaussian of at most this sigma (a 40 mm disc: the part's shape)
GAP_BAND_MM = 5.0           # another face's triangle over the face within this of the height field is the part's
                            # surface in a gap of the face's own triangles (farther: a flange over it, another skin)


def _b64(a: np.ndarray) -> dict:
    a = np.ascontiguousarray(a)
    return {"dtype": str(a.dtype), "shape": list(a.shape), "data": base64.b64encode(a.tobytes()).decode("ascii")}


def _unb64(d: dict, dtype: str) -> np.ndarray:
    if d["dtype"] != dtype:
        raise ValueError(f"freeform array: expected {dtype}, found {d['dtype']!r}")
    shape = tuple(int(x) for x in d["shape"])
    raw = base64.b64decode(d["data"].encode("ascii"), validate=True)
    a = np.frombuffer(raw, dtype=dtype)
    if a.size != int(np.prod(shape)):
        raise ValueError("freeform array: its data does not match its shape")
    return a.reshape(shape).copy()


@dataclass(frozen=True, eq=False)
class FreeformSurface(Surface):
    """A free-form face: a height field over a chart plane with geodesic row coordinates.

    ``origin_mm``, ``frame`` (columns e1, e2, e3; e3 towards the tool): the chart plane. ``grid``: its nodes;
    ``height`` (ny, nx) mm along e3, ``normals`` (ny, nx, 3) unit (world, towards the tool), ``material``
    (ny, nx) the face's nodes, ``distance`` (ny, nx) the signed geodesic distance from the seed row.
    ``table_grid`` / ``table``: chart y per (u, v). (u, v) are (chart x, geodesic distance), both mm.
    ``mesh``: a CAD mesh face's own triangles; its points are then on them wherever one lies over the chart point
    (``freeform_exact``), the height field's elsewhere (holes, the margin the leads run on).
    ``gaps``: the part's other triangles in the face's gaps (``GAP_BAND_MM``): a CAD face whose own triangles leave
    slivers to a neighbouring face (the door's skin round its tight bends) is closed over them (``close_gaps_mm``);
    a point there is on the part's triangle, not on the height field's membrane (0.1-0.69 mm off the door).
    ``from_scan``: built from a scan (a cloud, or a mesh judged a scan: ``roughness.mesh_is_scan`` with the job's
    ``workpiece.scan``), not from a CAD mesh; decided once, as the face is made (``freeform_surface``), and read by
    every stage that treats a scan's face otherwise (its normals, ``_cad_normals``; the sag's midposes)."""

    origin_mm: np.ndarray
    frame: np.ndarray
    grid: Grid
    height: np.ndarray
    normals: np.ndarray
    material: np.ndarray
    distance: np.ndarray
    table_grid: Grid
    table: np.ndarray
    boundary: Boundary
    stats: FitStats | None = None
    source_kind: str = "mesh"            # "mesh" (positions exact) or "scan" (smoothed)
    smoothing_mm: float = 0.0            # the scan's smoothing sigma (0 for a mesh)
    normal_smoothing_mm: float = NORMAL_SMOOTHING_MM
    warnings: tuple[str, ...] = ()
    mesh: ChartMesh | None = None        # a CAD mesh face's triangles (chart coordinates): exact heights between nodes
    gaps: ChartMesh | None = None        # the part's other triangles in the face's gaps (chart coordinates)
    from_scan: bool = False              # built from a scan, not a CAD mesh (the class doc)
    model: str = field(default="freeform", init=False)
    uv_unit: str = field(default="mm", init=False)

    def __post_init__(self):
        for name in ("origin_mm", "frame", "height", "normals", "material", "distance", "table"):
            getattr(self, name).setflags(write=False)

    # ----------------------------------------------------------------- queries

    def chart_xy(self, u, v) -> tuple[np.ndarray, np.ndarray]:
        """Chart-plane (x, y) (mm) of parameters (u, v)."""
        u, v = np.broadcast_arrays(np.asarray(u, float), np.asarray(v, float))
        return u, self.table_grid.interp(self.table, u, v)

    def height_at(self, x, y) -> np.ndarray:
        """Heights (mm) at chart (x, y): a CAD mesh face's own triangle's where it has one, else the part's triangle
        in a gap of the face (``gaps``), else the height field's."""
        h = self.grid.interp(self.height, x, y)
        if self.mesh is None:
            return h
        exact = self.triangle_heights(x, y)
        return np.where(np.isfinite(exact), exact, h)

    def triangle_heights(self, x, y) -> np.ndarray:
        """Heights (mm) at chart (x, y) of a CAD mesh face's own triangle, else of the part's in a gap of the face;
        NaN where neither lies over the point (past the face's edge, over a hole) or the face is a scan's."""
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        if self.mesh is None:
            return np.full(x.shape, np.nan)
        exact = self.mesh.heights(x, y)
        miss = ~np.isfinite(exact)
        if self.gaps is not None and miss.any():
            exact[miss] = self.gaps.heights(x[miss], y[miss])
        return exact

    def point_mm(self, u, v) -> np.ndarray:
        """Points (..., 3) in mm at u (along the rows, mm) and v (geodesic distance across them, mm)."""
        x, y = self.chart_xy(u, v)
        h = self.height_at(x, y)
        e1, e2, e3 = self.frame[:, 0], self.frame[:, 1], self.frame[:, 2]
        return self.origin_mm + x[..., None] * e1 + y[..., None] * e2 + h[..., None] * e3

    def normal_at(self, u, v) -> np.ndarray:
        """Unit normals (..., 3) at u, v: the smoothed normals, towards the tool side. Past the grid the edge's
        normal (the heights there continue the edge cells' tangent plane, whose normal does not turn)."""
        x, y = self.chart_xy(u, v)
        n = self.grid.interp(self.normals, x, y, extrapolate=False)
        return n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)

    @property
    def scanned(self) -> bool:
        return self.source_kind == "scan"

    @property
    def on_mesh_facets(self) -> bool:
        return self.source_kind == "mesh"

    @property
    def lead_band_mm(self) -> float:
        """How far a scan's points scatter off the face (``NOISE_BAND_SIGMAS`` x the fit's RMS), at least
        ``LEAD_LIFT_MIN_MM`` (a scanned mesh's triangles are as rough, with no RMS to show it): the leads rise by it
        past the face's edge, so they do not run into the part's roughness beyond it."""
        if not self.scanned or self.stats is None:
            return LEAD_LIFT_MIN_MM
        return max(NOISE_BAND_SIGMAS * float(self.stats.rms_mm), LEAD_LIFT_MIN_MM)

    def project_mm(self, points_mm: np.ndarray, continued: bool = False, along: np.ndarray | None = None) -> np.ndarray:
        """Points (..., 3) mm taken onto the surface along the chart's normal e3: onto a CAD mesh face's triangles
        (``triangle_heights``), NaN where it has none under a point (past its edge the height field only continues
        the face; the part there may fall away or turn: issue #46, a Vito door lead's midpose went onto it and the
        joint spline through them looped 5.5 mm into the door); a scan's onto its height field. ``continued``: onto
        the surface continued (``height_at``) everywhere. ``along`` (..., 3) unit directions (a CAD mesh face, not
        continued): onto its triangles (then its gaps') along those lines instead (``ChartMesh.along``)."""
        if along is not None and self.mesh is not None and not continued:
            return self._along_mm(points_mm, along)
        c = (np.asarray(points_mm, float) - self.origin_mm) @ self.frame
        exact = self.mesh is not None and not continued
        h = self.triangle_heights(c[..., 0], c[..., 1]) if exact else self.height_at(c[..., 0], c[..., 1])
        return self.origin_mm + c[..., 0, None] * self.frame[:, 0] + c[..., 1, None] * self.frame[:, 1] \
            + h[..., None] * self.frame[:, 2]

    def onto_face_mm(self, points_mm: np.ndarray) -> np.ndarray:
        """Points (k, 3) mm of a CAD mesh face with no triangle under them along the chart normal (its own, or the
        part's in a gap of it) taken to the nearest point of its own triangles; the rest as they are (a scan's
        all). Where the face turns parallel to the chart normal (a blade's leading edge) the raster's boundary,
        drawn on a grid, passes a fraction of a mm past the triangles' outline, and the height field continued
        there leaves the part: the IEA 15 MW blade's one such work pose of 3449 was 0.12 mm in front of it, and
        the motion check refused the program."""
        P = np.asarray(points_mm, float).reshape(-1, 3)
        if self.mesh is None or not len(P):
            return P
        c = (P - self.origin_mm) @ self.frame
        off = ~np.isfinite(self.triangle_heights(c[:, 0], c[:, 1]))   # (over a gap of the face: the part's)
        if not off.any():
            return P
        out = P.copy()
        out[off] = self.origin_mm + self.mesh.nearest(c[off]) @ self.frame.T
        return out

    def _along_mm(self, points_mm: np.ndarray, along: np.ndarray) -> np.ndarray:
        """``project_mm`` along the lines ``along``: onto the face's own triangles, else its gaps'; NaN off both."""
        P = np.asarray(points_mm, float)
        c = ((P - self.origin_mm) @ self.frame).reshape(-1, 3)
        d = (np.broadcast_to(np.asarray(along, float), P.shape) @ self.frame).reshape(-1, 3)
        on = self.mesh.along(c, d)
        miss = ~np.isfinite(on).all(axis=1)
        if self.gaps is not None and miss.any():
            on[miss] = self.gaps.along(c[miss], d[miss])
        return (self.origin_mm + on @ self.frame.T).reshape(P.shape)

    def uv_from_points(self, points_mm: np.ndarray) -> np.ndarray:
        """(N, 2) parameters of points (projected along e3 onto the surface)."""
        c = (np.asarray(points_mm, float) - self.origin_mm) @ self.frame
        return np.stack([c[..., 0], self.grid.interp(self.distance, c[..., 0], c[..., 1])], axis=-1)

    def metric_scale(self, uv: np.ndarray) -> np.ndarray:
        """(N, 2) mm on the surface per mm of u (along the row, at constant v) and per mm of v (1: v is a
        geodesic distance)."""
        uv = np.atleast_2d(np.asarray(uv, float))
        eps = 0.25 * self.grid.g
        a = self.point_mm(uv[:, 0] - eps, uv[:, 1])
        b = self.point_mm(uv[:, 0] + eps, uv[:, 1])
        return np.stack([np.linalg.norm(b - a, axis=1) / (2 * eps), np.ones(len(uv))], axis=-1)

    # ----------------------------------------------------------------- figures

    def area_mm2(self) -> float:
        """Area of the material nodes' cells on the surface (mm^2)."""
        cosn = np.abs(self.normals[..., :] @ self.frame[:, 2])
        return float((self.grid.g ** 2 / np.maximum(cosn, 0.05))[self.material].sum())

    def mean_normal(self) -> np.ndarray:
        n = self.normals[self.material].mean(axis=0)
        return n / np.linalg.norm(n)

    def middle_mm(self) -> np.ndarray:
        """The surface point over the middle of the material nodes (world mm)."""
        xy = self.grid.node_xy()[self.material].mean(axis=0)
        h = float(self.grid.interp(self.height, xy[0], xy[1]))
        return self.origin_mm + self.frame @ np.array([xy[0], xy[1], h])

    def curvature_range(self) -> tuple[float, float]:
        """(min, max) mean curvature (1/mm; > 0 convex towards the tool) over the material, 1st..99th percentile."""
        g = self.grid.g
        hy, hx = np.gradient(self.height, g)
        hxx, hxy, hyy = np.gradient(hx, g, axis=1), np.gradient(hx, g, axis=0), np.gradient(hy, g, axis=0)
        w = 1 + hx ** 2 + hy ** 2
        H = -((1 + hy ** 2) * hxx - 2 * hx * hy * hxy + (1 + hx ** 2) * hyy) / (2 * w ** 1.5)
        vals = H[self.material]
        if len(vals) == 0:
            return 0.0, 0.0
        return float(np.percentile(vals, 1)), float(np.percentile(vals, 99))

    def summary(self) -> dict:
        """The face's figures: area (mm^2), mean normal, mean-curvature range (1/mm), holes, grid, source."""
        return {"area_mm2": round(self.area_mm2(), 1), "normal": [round(float(x), 6) for x in self.mean_normal()],
                "curvature_range": [round(x, 6) for x in self.curvature_range()],
                "holes": len(self.boundary.holes_uv), "grid_mm": self.grid.g, "source": self.source_kind,
                "smoothing_mm": self.smoothing_mm, "normal_smoothing_mm": self.normal_smoothing_mm}

    def rows_at(self, angle_rad: float) -> "FreeformSurface":
        """The same face with its rows turned by ``angle_rad`` about e3 (from e1 towards e2): the height field
        resampled onto a turned grid and its row chart made again."""
        if abs(math.remainder(angle_rad, 2 * math.pi)) < 1e-12:
            return self
        c, s = math.cos(angle_rad), math.sin(angle_rad)
        e1, e2, e3 = self.frame[:, 0], self.frame[:, 1], self.frame[:, 2]
        frame = np.column_stack([c * e1 + s * e2, -s * e1 + c * e2, e3])
        xy = self.grid.node_xy()[self.material]
        rot = np.array([[c, s], [-s, c]])
        new_xy = xy @ rot.T
        grid = grid_over(new_xy.min(axis=0), new_xy.max(axis=0), self.grid.g, MARGIN_CELLS)
        nxy = grid.node_xy()
        old = nxy @ rot                                      # back to the old chart
        h = self.grid.interp(self.height, old[..., 0], old[..., 1])
        n = self.grid.interp(self.normals, old[..., 0], old[..., 1])
        n = n / np.linalg.norm(n, axis=-1, keepdims=True)
        fi = np.rint((old[..., 0] - self.grid.x0) / self.grid.g).astype(int)
        fj = np.rint((old[..., 1] - self.grid.y0) / self.grid.g).astype(int)
        inside = (fi >= 0) & (fi < self.grid.nx) & (fj >= 0) & (fj < self.grid.ny)
        material = np.zeros(h.shape, bool)
        material[inside] = self.material[fj[inside], fi[inside]]
        return _assembled(self.origin_mm, frame, grid, h, n, material, self.stats, self.source_kind,
                          self.smoothing_mm, self.normal_smoothing_mm, self.warnings, close_px=0,
                          mesh=_turned(self.mesh, rot), gaps=_turned(self.gaps, rot), from_scan=self.from_scan)

    # ----------------------------------------------------------------- stage files

    def to_dict(self) -> dict:
        d = {
            "model": "freeform",
            "origin_mm": self.origin_mm.tolist(),
            "frame": self.frame.tolist(),
            "grid": self.grid.to_dict(),
            "table_grid": self.table_grid.to_dict(),
            "height": _b64(self.height.astype(np.float64)),
            "normals": _b64(self.normals.astype(np.float64)),
            "material": _b64(self.material.astype(np.uint8)),
            "distance": _b64(self.distance.astype(np.float64)),
            "table": _b64(self.table.astype(np.float64)),
            "source_kind": self.source_kind,
            "from_scan": bool(self.from_scan),
            "smoothing_mm": float(self.smoothing_mm),
            "normal_smoothing_mm": float(self.normal_smoothing_mm),
            "warnings": list(self.warnings),
            "uv_unit": "mm",
            "boundary": self.boundary.to_dict(),
        }
        for name, m in (("mesh", self.mesh), ("gap", self.gaps)):
            if m is not None:
                d.update({f"{name}_vertices": _b64(m.vertices), f"{name}_faces": _b64(m.faces.astype(np.int64))})
        if self.stats is not None:
            st = self.stats
            d.update(inlier_ratio=st.inlier_ratio, rms_mm=st.rms_mm, max_residual_mm=st.max_residual_mm,
                     n_points=st.n_points, n_inliers=st.n_inliers)
        return d

    @staticmethod
    def from_dict(d: dict) -> "FreeformSurface":
        frame = np.asarray(d["frame"], float)
        origin = np.asarray(d["origin_mm"], float)
        if frame.shape != (3, 3) or not np.allclose(frame.T @ frame, np.eye(3), atol=1e-6):
            raise ValueError("frame must be orthonormal")
        if origin.shape != (3,) or not np.all(np.isfinite(origin)) or np.abs(origin).max() > 1e6:
            raise ValueError("origin_mm must be 3 finite numbers within +-1e6")
        grid, tgrid = Grid.from_dict(d["grid"]), Grid.from_dict(d["table_grid"])
        height, normals = _unb64(d["height"], "float64"), _unb64(d["normals"], "float64")
        material = _unb64(d["material"], "uint8").astype(bool)
        distance, table = _unb64(d["distance"], "float64"), _unb64(d["table"], "float64")
        shape = (grid.ny, grid.nx)
        if height.shape != shape or normals.shape != shape + (3,) or material.shape != shape \
                or distance.shape != shape or table.shape != (tgrid.ny, tgrid.nx):
            raise ValueError("freeform arrays do not match their grids")
        for a in (height, normals, distance, table):
            if not np.all(np.isfinite(a)) or np.abs(a).max() > 1e7:
                raise ValueError("freeform arrays must be finite")
        stats = None
        if "inlier_ratio" in d:
            stats = FitStats(d["inlier_ratio"], d["rms_mm"], d["max_residual_mm"], d["n_points"], d["n_inliers"])
        return FreeformSurface(origin, frame, grid, height, normals, material, distance, tgrid, table,
                               Boundary.from_dict(d["boundary"]), stats, str(d.get("source_kind", "mesh")),
                               float(d.get("smoothing_mm", 0.0)),
                               float(d.get("normal_smoothing_mm", NORMAL_SMOOTHING_MM)),
                               tuple(str(w) for w in d.get("warnings", ())), _mesh_from_dict(d, "mesh"),
                               _mesh_from_dict(d, "gap"), _from_scan(d))


def _from_scan(d: dict) -> bool:
    """A saved face's scan verdict: ``from_scan`` (true or false); a file written before the face kept it: a cloud's
    face is a scan's, a mesh's is taken as CAD (its normals were made and saved with it)."""
    v = d.get("from_scan", str(d.get("source_kind", "mesh")) == "scan")
    if not isinstance(v, bool):
        raise ValueError("from_scan must be true or false")
    return v


def _turned(mesh: ChartMesh | None, rot: np.ndarray) -> ChartMesh | None:
    """The same triangles in a chart turned about e3 (``rot`` maps old chart (x, y) to new)."""
    if mesh is None:
        return None
    V = mesh.vertices.copy()
    V[:, :2] = V[:, :2] @ rot.T
    return ChartMesh(V, mesh.faces)


def _mesh_from_dict(d: dict, name: str) -> ChartMesh | None:
    """A stage file's chart mesh ``{name}_vertices`` / ``{name}_faces``, None when absent."""
    if f"{name}_vertices" not in d:
        return None
    V, F = _unb64(d[f"{name}_vertices"], "float64"), _unb64(d[f"{name}_faces"], "int64")
    if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3 or not np.all(np.isfinite(V)) \
            or (len(F) and (F.min() < 0 or F.max() >= len(V))):
        raise ValueError(f"freeform {name}: vertices (n, 3) finite and faces (m, 3) indexing them")
    return ChartMesh(V, F)


# --------------------------------------------------------------------------- building


def _material_mask(grid: Grid, xy: np.ndarray, spacing_mm: float, close_gaps_mm: float) -> np.ndarray:
    """The nodes of the face: nodes near its points (dilated by a point spacing), gaps up to ``close_gaps_mm``
    closed, the largest connected region."""
    import cv2
    from scipy import ndimage

    i = np.clip(np.rint((xy[:, 0] - grid.x0) / grid.g), 0, grid.nx - 1).astype(np.int64)
    j = np.clip(np.rint((xy[:, 1] - grid.y0) / grid.g), 0, grid.ny - 1).astype(np.int64)
    m = np.zeros((grid.ny, grid.nx), np.uint8)
    m[j, i] = 1
    r = int(math.ceil(0.75 * spacing_mm / grid.g))
    if r > 0:
        m = cv2.dilate(m, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1)))
    k = int(math.ceil(close_gaps_mm / grid.g))
    if k > 0:
        k = 2 * ((k + 1) // 2) + 1
        m = cv2.morphologyEx(m, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)))
    if r > 0:  # the dilation taken back: the outline lies at the points' extent, not a spacing past it
        m = cv2.erode(m, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1)))
    labels, n = ndimage.label(m > 0)
    if n == 0:
        return m > 0
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    return labels == int(np.argmax(sizes))


def _boundary(grid: Grid, material: np.ndarray, distance: np.ndarray, close_px: int) -> Boundary:
    """The material's outline and holes as polygons in (u, v) = (x, d): traced on the node mask (cv2), densified
    to the grid spacing and mapped through the distance field."""
    import cv2

    img = material.astype(np.uint8) * 255
    contours, hierarchy = cv2.findContours(img, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    if not contours:
        raise BadInput("free-form face: no material region found")
    hierarchy = hierarchy[0]
    outers = [k for k in range(len(contours)) if hierarchy[k][3] < 0]
    best = max(outers, key=lambda k: (cv2.contourArea(contours[k]), len(contours[k])))

    def to_uv(c: np.ndarray) -> np.ndarray:
        c = cv2.approxPolyDP(c, 0.5, True).reshape(-1, 2).astype(float)
        closed = np.vstack([c, c[:1]])
        seg = np.diff(closed, axis=0)
        n = np.maximum(np.ceil(np.linalg.norm(seg, axis=1)).astype(int), 1)
        px = np.concatenate([a + np.linspace(0, 1, k, endpoint=False)[:, None] * s
                             for a, s, k in zip(closed[:-1], seg, n)])
        x = grid.x0 + px[:, 0] * grid.g
        y = grid.y0 + px[:, 1] * grid.g
        return np.stack([x, grid.interp(distance, x, y)], axis=-1)

    def oriented(poly: np.ndarray, ccw: bool) -> np.ndarray:
        area = 0.5 * float(np.dot(poly[:, 0], np.roll(poly[:, 1], -1)) - np.dot(poly[:, 1], np.roll(poly[:, 0], -1)))
        return np.ascontiguousarray(poly if (area > 0) == ccw else poly[::-1])

    outer = oriented(to_uv(contours[best]), True)
    holes = []
    child = hierarchy[best][2]
    min_px = max(4.0, float(close_px) ** 2)
    while child >= 0:
        if cv2.contourArea(contours[child]) >= min_px and len(contours[child]) >= 3:
            holes.append(oriented(to_uv(contours[child]), False))
        child = hierarchy[child][0]
    holes.sort(key=lambda h: (round(float(h[:, 0].min()), 9), round(float(h[:, 1].min()), 9)))
    return Boundary(outer, tuple(holes))


def _flat_outside(height: np.ndarray, material: np.ndarray) -> np.ndarray:
    """``height`` with the margin outside the face (the non-material regions touching the grid's edge) made level
    with the face's nearest node: the rows' distance is measured on the face and runs on, flat, into the margin,
    so the leads' row chart cannot fold where the surface continued falls away steeply (a dome's corners)."""
    from scipy import ndimage

    labels, _ = ndimage.label(~material)
    border = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    outside = np.isin(labels, border[border > 0])
    if not outside.any():
        return height
    _, (jj, ii) = ndimage.distance_transform_edt(outside, return_indices=True)
    return np.where(outside, height[jj, ii], height)


def _assembled(origin, frame, grid, height, normals, material, stats, source_kind, smoothing_mm,
               normal_smoothing_mm, warnings, close_px, mesh: ChartMesh | None = None,
               gaps: ChartMesh | None = None, from_scan: bool = False) -> FreeformSurface:
    """The surface with its row chart (distance field, table) and boundary made from its height field."""
    if material.sum() < 9:
        raise BadInput("free-form face: fewer than 9 grid nodes of material; the face is too small for its grid")
    distance = row_distance(grid, _flat_outside(height, material), seed_row(material))
    tgrid, table = row_table(grid, distance)
    boundary = _boundary(grid, material, distance, close_px)
    return FreeformSurface(np.asarray(origin, float), np.asarray(frame, float), grid, height, normals, material,
                           distance, tgrid, table, boundary, stats, source_kind, smoothing_mm,
                           normal_smoothing_mm, tuple(warnings), mesh, gaps, bool(from_scan))


def _median_spacing(xy: np.ndarray, sample: int = 20000, queries: int = 2000) -> float:
    """Median nearest-neighbour distance (mm) of the chart points, from a strided subsample rescaled."""
    from scipy.spatial import cKDTree

    m = min(len(xy), sample)
    sub = xy[np.linspace(0, len(xy) - 1, m).astype(int)]
    q = sub[np.linspace(0, m - 1, min(m, queries)).astype(int)]
    dist, _ = cKDTree(sub).query(q, k=2)
    return max(float(np.median(dist[:, 1])) * math.sqrt(m / len(xy)), 1e-3)


def scan_normal_smoothing_mm(noise_rms_mm: float, points_per_mm2: float, smoothing_mm: float, floor_mm: float) -> float:
    """The Gaussian sigma (mm) of a scan's normals: at least ``floor_mm`` (the tool's footprint), and wide enough
    that the scan's noise tilts them by at most ``SCAN_NORMAL_NOISE_DEG`` RMS, up to ``SCAN_NORMAL_SMOOTHING_MAX_MM``.

    White noise of RMS r on points at density rho (``points_per_mm2``), smoothed by Gaussians of total sigma L (the
    heights' ``smoothing_mm``, then the normals'), has slopes of RMS r / (L^2 sqrt(8 pi rho)) along each axis. At
    6 mm the 1 mm-noise shell scan's tool axis wobbled 0.3 deg from one 5 mm pose to the next, and near-singular
    wrist joints turned that into jerk: its rows ran at 41-56 % of the feed."""
    tau = math.radians(SCAN_NORMAL_NOISE_DEG)
    L2 = float(noise_rms_mm) / (tau * math.sqrt(8.0 * math.pi * max(float(points_per_mm2), 1e-12)))
    wanted = math.sqrt(max(L2 - float(smoothing_mm) ** 2, 0.0))
    return max(float(floor_mm), min(wanted, SCAN_NORMAL_SMOOTHING_MAX_MM))


def _scan_normal_sigma(residuals_mm, n_points: int, area_mm2: float, smoothing_mm: float, floor_mm: float) -> float:
    """``scan_normal_smoothing_mm`` of a scan's residuals from its smoothed surface, its points over its area."""
    finite = residuals_mm[np.isfinite(residuals_mm)]
    noise = float(np.sqrt(np.mean(finite ** 2))) if finite.size else 0.0
    return scan_normal_smoothing_mm(noise, n_points / max(area_mm2, 1e-9), smoothing_mm, floor_mm)


def _scan_normals(height, grid: Grid, frame, xyh, res, n_points: int, material, reliable, sigma_mm: float,
                  footprint_mm: float) -> tuple[np.ndarray, float, np.ndarray]:
    """A scan's (normals, their smoothing sigma, material): normals averaged along its surface (``scan_normals``),
    its steep nodes' from its points (``point_normals``), the material cut where they pass ``MAX_SLOPE_DEG``."""
    g = grid.g
    smoothing = _scan_normal_sigma(res, n_points, float(material.sum()) * g * g, sigma_mm, footprint_mm)
    normals = point_normals(scan_normals(height, g, frame, smoothing, footprint_mm, reliable), height, grid, frame,
                            xyh, footprint_mm, material)
    return normals, smoothing, material & ((normals @ frame[:, 2]) >= math.cos(math.radians(MAX_SLOPE_DEG)))


def _fit_stats(residuals_mm, n_points: int, threshold_mm: float) -> FitStats:
    """The surface's fit figures: a point is an inlier within the threshold or 3 RMS residuals."""
    res_abs = np.abs(residuals_mm[np.isfinite(residuals_mm)]) if len(residuals_mm) else np.zeros(1)
    rms = float(np.sqrt(np.mean(res_abs ** 2)))
    n_in = int((res_abs <= max(threshold_mm, 3.0 * rms)).sum())
    return FitStats(n_in / n_points, rms, float(res_abs.max()), int(n_points), n_in)


def _gap_mesh(part, own_faces: np.ndarray, origin, frame, grid: Grid, height: np.ndarray,
              material: np.ndarray) -> ChartMesh | None:
    """The triangles of ``part`` (the whole workpiece mesh) that are not the face's own (``own_faces``, rows of the
    part's faces) and lie in the face's gaps: the middle over a node within the face's outline (its material or
    a hole in it), every corner within ``GAP_BAND_MM`` of the (filled) height field. None when there are none."""
    from scipy.ndimage import binary_fill_holes

    F = np.ascontiguousarray(np.asarray(part.faces, np.int64))
    own = np.ascontiguousarray(np.asarray(own_faces, np.int64))
    row = np.dtype([("a", np.int64), ("b", np.int64), ("c", np.int64)])
    other = F[~np.isin(F.view(row).ravel(), own.view(row).ravel())]
    if not len(other):
        return None
    V = to_chart(np.asarray(part.vertices_mm, float), origin, frame)
    T = V[other]
    mid = T.mean(axis=1)
    i = np.rint((mid[:, 0] - grid.x0) / grid.g).astype(np.int64)
    j = np.rint((mid[:, 1] - grid.y0) / grid.g).astype(np.int64)
    inside = (i >= 0) & (i < grid.nx) & (j >= 0) & (j < grid.ny)
    over = np.zeros(len(other), bool)
    over[inside] = binary_fill_holes(material)[j[inside], i[inside]]
    near = np.abs(T[..., 2] - grid.interp(height, T[..., 0], T[..., 1])).max(axis=1) <= GAP_BAND_MM
    keep = over & near
    return ChartMesh.of(V, other[keep]) if keep.any() else None


def _gaps_of(workpiece, part, origin, frame, grid: Grid, height: np.ndarray, material: np.ndarray) -> ChartMesh | None:
    """The part's triangles in a mesh face's gaps (``_gap_mesh``), None where ``part`` is no mesh."""
    if getattr(part, "faces", None) is None or getattr(part, "vertices_mm", None) is None:
        return None
    return _gap_mesh(part, workpiece.faces, origin, frame, grid, height, material)


def _cad_normals(height, grid: Grid, frame, V_chart, sigma_mm: float, reliable, workpiece,
                 from_scan: bool) -> tuple[ChartMesh, np.ndarray]:
    """(the face's own triangles (``workpiece.faces``) as a ``ChartMesh``, its normals): the triangles averaged on the surface at the tool's scale
    (``mesh_normals``), the height field's chart-window normals giving each node its side and holding far from them.
    A mesh judged a scan (``from_scan``: ``_scan_verdict``) keeps the chart-window normals: its triangles carry the
    sensor's noise, and averaging them on the surface turned the noether panel scan's wrist into the part at its
    placement (the tilt refused it); its flanks are the scan normals' (``freeform_normals``) to mend."""
    own = ChartMesh.of(V_chart, workpiece.faces)
    chart = normals_of(height, grid.g, frame, sigma_mm, reliable)
    if from_scan:
        return own, chart
    return own, mesh_normals(chart, height, grid, frame, own, FOOTPRINT_RADIUS_MM)


def _scan_verdict(workpiece, part, is_mesh: bool) -> bool:
    """Whether a face is built from a scan (``FreeformSurface.from_scan``): a cloud always; a mesh when the whole
    mesh it is of (``part``, else ``workpiece``) is judged one (``roughness.mesh_is_scan``, by the job's
    ``workpiece.scan``: "auto" by its roughness)."""
    if not is_mesh:
        return True
    whole = part if part is not None and getattr(part, "faces", None) is not None else workpiece
    return mesh_is_scan(whole.vertices_mm, whole.scan, whole.faces)


def freeform_surface(workpiece, settings, indices: np.ndarray | None = None,
                     normal_smoothing_mm: float = NORMAL_SMOOTHING_MM, part=None) -> FreeformSurface:
    """A free-form surface (world mm) of a placed workpiece, or of its points ``indices`` (one face).

    A mesh workpiece is sampled exactly from its triangles (z-buffer); a cloud is cleaned of outliers and
    smoothed at ``settings.smoothing_mm`` (0: ``SCAN_SMOOTHING_SPACINGS`` point spacings, at least
    ``SCAN_SMOOTHING_MIN_MM``). ``settings``: ``FitSettings`` (threshold, close_gaps_mm, smoothing_mm). ``part``: the
    whole mesh ``workpiece`` is a face of (``_gap_mesh``). BadInput with one line when the points hold no surface."""
    P, N = np.asarray(workpiece.points_mm, float), np.asarray(workpiece.normals, float)
    source = getattr(workpiece, "source", "") or "workpiece"
    if indices is not None:
        P, N = P[indices], N[indices]
    finite = np.isfinite(P).all(axis=1)
    if finite.sum() < 100:
        raise BadInput(f"{source}: too few points for a free-form surface: {int(finite.sum())}, need at least 100")
    P, N = P[finite], np.where(np.isfinite(N[finite]), N[finite], 0.0)
    D = P - P.mean(axis=0)
    s = np.sqrt(np.maximum(np.linalg.eigvalsh(D.T @ D), 0.0))[::-1]
    if s[1] < 1e-6 * max(s[0], 1e-300):
        raise BadInput(f"{source}: the points lie on a line (or coincide); no surface is defined")
    warnings = []
    origin, frame, consistent = chart_frame(P, N)
    if not consistent:
        warnings.append(f"{source}: the normals do not agree on a side (triangles wound both ways or a closed "
                        "part): the free-form face is worked from the side facing world up; normals are taken "
                        "from the surface itself")
    xyh = to_chart(P, origin, frame)
    lo, hi = xyh[:, :2].min(axis=0), xyh[:, :2].max(axis=0)
    spacing = _median_spacing(xyh[:, :2])
    is_mesh = workpiece.faces is not None and getattr(workpiece, "vertices_mm", None) is not None
    from_scan = _scan_verdict(workpiece, part, is_mesh)
    box = float(np.prod(hi - lo + 2 * MARGIN_CELLS))
    g = max(MIN_CELL_MM, math.sqrt(box / MAX_NODES))
    sigma = 0.0
    if not is_mesh:
        sigma = float(getattr(settings, "smoothing_mm", 0.0) or 0.0)
        if sigma <= 0:
            sigma = max(SCAN_SMOOTHING_SPACINGS * spacing, SCAN_SMOOTHING_MIN_MM)
        g = max(g, min(spacing, sigma / 2))
    grid = grid_over(lo, hi, g, MARGIN_CELLS)
    if grid.nx * grid.ny > 4 * MAX_NODES:
        raise BadInput(f"{source}: the free-form grid would have {grid.nx * grid.ny} nodes; the part is too large")
    if is_mesh:
        V = to_chart(np.asarray(workpiece.vertices_mm, float), origin, frame)
        height = mesh_heights(V, np.asarray(workpiece.faces), grid)
        known = np.isfinite(height)
        keep = np.ones(len(P), bool)
    else:
        height, weight, keep, res = cloud_heights(xyh, grid, sigma)
        # a node's height is known where its window holds a fifth of the typical weight (not extrapolated far)
        typical = float(np.median(weight[weight > 1e-6])) if (weight > 1e-6).any() else 0.0
        known = np.isfinite(height) & (weight >= KNOWN_WEIGHT_SHARE * typical)
        dropped = int((~keep).sum())
        if dropped:
            warnings.append(f"{source}: {dropped} of {len(P)} scan points lie off the surface (outliers) and "
                            "were left out of it")
    material = _material_mask(grid, xyh[keep, :2], spacing, float(settings.close_gaps_mm)) & known
    reliable = known
    if not is_mesh:
        # at a scan's edge the window is one-sided and the noise fuzzes the edge outwards: the face (and the
        # normals' average) keeps a sigma inside its last points
        from scipy.ndimage import binary_erosion

        material = binary_erosion(material, iterations=max(1, int(round(sigma / g))))
        # the normals average the nodes a further window inside (the edge's one-sided fits tilt their slope)
        inner = binary_erosion(material, iterations=max(1, int(round(2 * sigma / g))))
        reliable = inner if inner.sum() > 0.5 * material.sum() else material
    height = fill(height, known, g)
    if is_mesh:
        res = xyh[:, 2] - grid.interp(height, xyh[:, 0], xyh[:, 1])
        own, normals = _cad_normals(height, grid, frame, V, normal_smoothing_mm, reliable, workpiece, from_scan)
        material &= (normals @ frame[:, 2]) >= math.cos(math.radians(MAX_SLOPE_DEG))
    else:
        normals, normal_smoothing_mm, material = _scan_normals(height, grid, frame, xyh[keep], res, int(keep.sum()),
                                                               material, reliable, sigma, normal_smoothing_mm)
    stats = _fit_stats(res, len(P), float(settings.threshold_mm))
    close_px = int(math.ceil(float(settings.close_gaps_mm) / g))
    mesh, gaps = (own, _gaps_of(workpiece, part, origin, frame, grid, height, material)) if is_mesh else (None, None)
    return _assembled(origin, frame, grid, height, normals, material, stats, "mesh" if is_mesh else "scan", sigma,
                      normal_smoothing_mm, warnings, close_px, mesh, gaps, from_scan)
