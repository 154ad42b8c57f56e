"""Fitted surfaces with a 2-D parameter domain (u, v) and a material boundary.

Two kinds:
- ``PlaneSurface``: u, v are in-plane coordinates in mm along ``u_axis`` and
  ``v_axis`` from ``origin_mm``; the normal points out of the material, towards
  the tool side.
- ``SpherePatch``: u is the azimuth and v the elevation in **radians** in the
  patch frame ``frame`` (columns e1, e2, e3; e1 is the patch's mean direction
  from the centre, e3 is "up"):
  ``p(u, v) = c + R (cos v cos u e1 + cos v sin u e2 + sin v e3)``.
  The normal is the outward radial direction (worked from outside).

- ``Cylinder``: u is the angle in **radians** about the axis from the frame's
  e1 (the patch's mean radial direction), v the axial position in **mm** from
  ``center_mm`` along the axis e3:
  ``p(u, v) = c + R (cos u e1 + sin u e2) + v e3``. The normal is radial,
  outward (worked from outside) or to the axis when ``concave`` (a bore,
  worked from inside). The (R u, v) chart is an isometry, so rows of the chart
  are geodesics of the cylinder (helices, circles and lines).

The boundary is a set of polygons in (u, v): one outer contour and any number
of holes; material is inside the outer polygon and outside every hole.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path as FsPath

import numpy as np

from ..errors import BadInput
from ..files import output_file
from .. import safe_io
from .domain import Boundary, FitStats  # noqa: F401  (the surfaces' parameter domain; re-exported)
from .surface_base import Surface


@dataclass(frozen=True)
class PlaneSurface(Surface):
    """A plane n.x = offset_mm with an in-plane (u, v) frame in mm."""

    origin_mm: np.ndarray
    normal: np.ndarray
    u_axis: np.ndarray
    v_axis: np.ndarray
    boundary: Boundary
    stats: FitStats | None = None
    model: str = field(default="plane", init=False)
    uv_unit: str = field(default="mm", init=False)

    @property
    def offset_mm(self) -> float:
        return float(self.normal @ self.origin_mm)

    def point_mm(self, u, v) -> np.ndarray:
        """Points (..., 3) in mm at parameters u, v (mm)."""
        u = np.asarray(u, dtype=float)[..., None]
        v = np.asarray(v, dtype=float)[..., None]
        return self.origin_mm + u * self.u_axis + v * self.v_axis

    def normal_at(self, u, v) -> np.ndarray:
        """Outward unit normals (..., 3) at u, v."""
        shape = np.broadcast(np.asarray(u), np.asarray(v)).shape
        return np.broadcast_to(self.normal, shape + (3,)).copy()

    def uv_from_points(self, points_mm: np.ndarray) -> np.ndarray:
        """(N, 2) parameters of points projected onto the plane."""
        d = np.asarray(points_mm) - self.origin_mm
        return np.stack([d @ self.u_axis, d @ self.v_axis], axis=-1)

    def metric_scale(self, uv: np.ndarray) -> np.ndarray:
        """(N, 2) mm per unit of u and of v at uv (1 for a plane)."""
        return np.ones_like(np.atleast_2d(uv), dtype=float)

    def summary_rows(self) -> list[tuple[str, str]]:
        return [("surface.normal", ", ".join(f"{v:.4f}" for v in self.normal))]

    def to_dict(self) -> dict:
        d = {
            "model": "plane",
            "normal": self.normal.tolist(),
            "offset_mm": self.offset_mm,
            "origin_mm": self.origin_mm.tolist(),
            "u_axis": self.u_axis.tolist(),
            "v_axis": self.v_axis.tolist(),
            "uv_unit": "mm",
            "boundary": self.boundary.to_dict(),
        }
        return _with_stats(d, self.stats)


@dataclass(frozen=True)
class SpherePatch(Surface):
    """A patch of a sphere, parameterised by azimuth u and elevation v (rad).

    ``concave``: the material is outside the sphere (a bowl, worked from inside);
    the normal then points to the centre.
    """

    center_mm: np.ndarray
    radius_mm: float
    frame: np.ndarray  # 3x3, columns e1 (mean direction), e2, e3
    boundary: Boundary
    stats: FitStats | None = None
    concave: bool = False
    model: str = field(default="sphere", init=False)
    uv_unit: str = field(default="rad", init=False)

    def _direction(self, u, v) -> np.ndarray:
        u = np.asarray(u, dtype=float)
        v = np.asarray(v, dtype=float)
        cos_v = np.cos(v)
        local = np.stack([cos_v * np.cos(u), cos_v * np.sin(u), np.sin(v) * np.ones_like(u)], axis=-1)
        return local @ self.frame.T

    def point_mm(self, u, v) -> np.ndarray:
        """Points (..., 3) in mm at azimuth u and elevation v (rad)."""
        return self.center_mm + self.radius_mm * self._direction(u, v)

    def normal_at(self, u, v) -> np.ndarray:
        """Unit normals (..., 3) at u, v, out of the material (radial; to the centre when concave)."""
        return -self._direction(u, v) if self.concave else self._direction(u, v)

    def uv_from_points(self, points_mm: np.ndarray) -> np.ndarray:
        """(N, 2) azimuth and elevation (rad) of points seen from the centre."""
        local = (np.asarray(points_mm) - self.center_mm) @ self.frame
        r = np.linalg.norm(local, axis=-1)
        u = np.arctan2(local[..., 1], local[..., 0])
        v = np.arcsin(np.clip(local[..., 2] / np.maximum(r, 1e-12), -1, 1))
        return np.stack([u, v], axis=-1)

    def metric_scale(self, uv: np.ndarray) -> np.ndarray:
        """(N, 2) mm per rad of u (R cos v) and of v (R) at uv."""
        uv = np.atleast_2d(uv)
        return np.stack([self.radius_mm * np.cos(uv[:, 1]), np.full(len(uv), self.radius_mm)], axis=-1)

    def summary_rows(self) -> list[tuple[str, str]]:
        return [("surface.radius_mm", f"{self.radius_mm:.6g}"),
                ("surface.center_mm", ", ".join(f"{v:.1f}" for v in self.center_mm))]

    def to_dict(self) -> dict:
        d = {
            "model": "sphere",
            "center_mm": self.center_mm.tolist(),
            "radius_mm": float(self.radius_mm),
            "frame": self.frame.tolist(),
            "concave": bool(self.concave),
            "uv_unit": "rad",
            "boundary": self.boundary.to_dict(),
        }
        return _with_stats(d, self.stats)


@dataclass(frozen=True)
class Cylinder(Surface):
    """A patch of a circular cylinder, parameterised by angle u (rad) about the axis and axial v (mm).

    ``frame``: columns e1 (u = 0, the patch's mean radial direction), e2, e3 (the axis);
    ``center_mm`` is the point of the axis at v = 0. ``concave``: the material
    is outside the cylinder (a bore or the inside of a pipe, worked from
    inside); the normal then points to the axis.
    """

    center_mm: np.ndarray
    radius_mm: float
    frame: np.ndarray  # 3x3, columns e1, e2, e3 = axis
    boundary: Boundary
    stats: FitStats | None = None
    concave: bool = False
    model: str = field(default="cylinder", init=False)
    uv_unit: str = field(default="rad,mm", init=False)

    @property
    def axis(self) -> np.ndarray:
        return self.frame[:, 2]

    def _radial(self, u) -> np.ndarray:
        u = np.asarray(u, dtype=float)
        return np.cos(u)[..., None] * self.frame[:, 0] + np.sin(u)[..., None] * self.frame[:, 1]

    def point_mm(self, u, v) -> np.ndarray:
        """Points (..., 3) in mm at angle u (rad) and axial position v (mm)."""
        u, v = np.broadcast_arrays(np.asarray(u, dtype=float), np.asarray(v, dtype=float))
        return self.center_mm + self.radius_mm * self._radial(u) + v[..., None] * self.axis

    def normal_at(self, u, v) -> np.ndarray:
        """Unit normals (..., 3) at u, v out of the material (radial; to the axis when concave)."""
        u, _ = np.broadcast_arrays(np.asarray(u, dtype=float), np.asarray(v, dtype=float))
        return -self._radial(u) if self.concave else self._radial(u)

    def uv_from_points(self, points_mm: np.ndarray) -> np.ndarray:
        """(N, 2) angle (rad) and axial position (mm) of points."""
        local = (np.asarray(points_mm) - self.center_mm) @ self.frame
        return np.stack([np.arctan2(local[..., 1], local[..., 0]), local[..., 2]], axis=-1)

    def metric_scale(self, uv: np.ndarray) -> np.ndarray:
        """(N, 2) mm per rad of u (R) and per mm of v (1)."""
        uv = np.atleast_2d(uv)
        return np.stack([np.full(len(uv), self.radius_mm), np.ones(len(uv))], axis=-1)

    def summary_rows(self) -> list[tuple[str, str]]:
        return [("surface.radius_mm", f"{self.radius_mm:.6g}"),
                ("surface.axis", ", ".join(f"{v:.4f}" for v in self.axis)),
                ("surface.center_mm", ", ".join(f"{v:.1f}" for v in self.center_mm)),
                ("surface.side", "inside (concave)" if self.concave else "outside")]

    def to_dict(self) -> dict:
        d = {
            "model": "cylinder",
            "center_mm": self.center_mm.tolist(),
            "axis": self.axis.tolist(),
            "radius_mm": float(self.radius_mm),
            "frame": self.frame.tolist(),
            "concave": bool(self.concave),
            "uv_unit": "rad,mm",
            "boundary": self.boundary.to_dict(),
        }
        return _with_stats(d, self.stats)



@dataclass(frozen=True)
class FaceSet:
    """The faces a job works in one program (``camtool.path.face_set``), as surfaces (world frame), with their
    segmentation numbers and raster changes.

    ``raster_changes[k]``: the ``RasterSettings`` fields face k's ``faces.raster`` keys set
    (internal units), applied over whatever settings the path is rastered with."""

    surfaces: tuple
    indices: tuple[int, ...]
    raster_changes: tuple[dict, ...]
    model: str = field(default="faces", init=False)

    def __post_init__(self):
        if not (len(self.surfaces) == len(self.indices) == len(self.raster_changes)) or len(self.surfaces) < 2:
            raise ValueError("a FaceSet holds two or more faces, each with its index and raster changes")

    def settings_for(self, k: int, base):
        """Face k's raster settings: ``base`` (``settings.RasterSettings``) with the face's own keys."""
        return replace(base, **self.raster_changes[k])

    def to_dict(self) -> dict:
        return {"model": "faces", "indices": list(self.indices),
                "raster_changes": [dict(c) for c in self.raster_changes],
                "faces": [s.to_dict() for s in self.surfaces]}

    @staticmethod
    def from_dict(d: dict) -> "FaceSet":
        from ..settings import RasterSettings

        names = {f for f in RasterSettings.__dataclass_fields__}
        changes = tuple(dict(c) for c in d["raster_changes"])
        if any(not set(c) <= names for c in changes):
            raise ValueError("raster_changes names a key RasterSettings does not have")
        return FaceSet(tuple(surface_from_dict(f) for f in d["faces"]), tuple(int(i) for i in d["indices"]),
                       changes)



def _with_stats(d: dict, stats: FitStats | None) -> dict:
    if stats is not None:
        d.update(
            inlier_ratio=stats.inlier_ratio,
            rms_mm=stats.rms_mm,
            max_residual_mm=stats.max_residual_mm,
            n_points=stats.n_points,
            n_inliers=stats.n_inliers,
        )
    return d


def _finite(d: dict, keys, limit_mm: float = 1e6) -> None:
    for k in keys:
        a = np.asarray(d[k], dtype=float)
        if not np.all(np.isfinite(a)) or np.any(np.abs(a) > limit_mm):
            raise ValueError(f"{k} must be finite numbers within +-{limit_mm:g}")


def _unit_vectors(d: dict, keys) -> None:
    for k in keys:
        a = np.asarray(d[k], dtype=float).reshape(-1, 3)
        if not np.allclose(np.linalg.norm(a, axis=1), 1.0, atol=1e-6):
            raise ValueError(f"{k} must be unit vectors")


def surface_from_dict(d: dict) -> Surface:
    """Rebuild a surface from ``to_dict`` output (checked: finite, unit axes, a positive radius); a job's
    several faces (model "faces") come back as a ``FaceSet``."""
    if d.get("model") == "faces":
        return FaceSet.from_dict(d)
    if d.get("model") == "freeform":
        from .freeform import FreeformSurface

        return FreeformSurface.from_dict(d)
    b = d["boundary"]
    for poly in [b["outer_uv"], *b.get("holes_uv", [])]:
        a = np.asarray(poly, dtype=float)
        if a.ndim != 2 or a.shape[1] != 2 or len(a) < 3 or not np.all(np.isfinite(a)) or np.abs(a).max() > 1e6:
            raise ValueError("boundary polygons must be 3 or more finite (u, v) vertices")
    if d["model"] == "plane":
        _finite(d, ("origin_mm", "normal", "u_axis", "v_axis"))
        _unit_vectors(d, ("normal", "u_axis", "v_axis"))
    elif d["model"] in ("sphere", "cylinder"):
        _finite(d, ("center_mm", "radius_mm", "frame"))
        _unit_vectors(d, ("frame",))
        if not 0 < float(d["radius_mm"]) <= 1e6:
            raise ValueError("radius_mm must be > 0")
    stats = None
    if "inlier_ratio" in d:
        stats = FitStats(d["inlier_ratio"], d["rms_mm"], d["max_residual_mm"], d["n_points"], d["n_inliers"])
    boundary = Boundary.from_dict(d["boundary"])
    if d["model"] == "plane":
        return PlaneSurface(
            np.asarray(d["origin_mm"], float), np.asarray(d["normal"], float),
            np.asarray(d["u_axis"], float), np.asarray(d["v_axis"], float), boundary, stats,
        )
    if d["model"] == "sphere":
        return SpherePatch(
            np.asarray(d["center_mm"], float), float(d["radius_mm"]),
            np.asarray(d["frame"], float), boundary, stats, bool(d.get("concave", False)),
        )
    if d["model"] == "cylinder":
        frame = np.asarray(d["frame"], float)
        if not np.allclose(frame.T @ frame, np.eye(3), atol=1e-6):
            raise ValueError("frame must be orthonormal")
        return Cylinder(np.asarray(d["center_mm"], float), float(d["radius_mm"]), frame, boundary, stats,
                        bool(d.get("concave", False)))
    raise BadInput(f"surface model {d['model']!r} is not 'plane', 'sphere', 'cylinder' or 'freeform'")


SURFACE_FORMAT, SURFACE_VERSION = "camtool-surface", 1


def save_surface(surface: Surface, path: str | FsPath) -> None:
    """Write a surface as JSON (``format`` and ``version`` keys, then the surface's fields)."""
    d = {"format": SURFACE_FORMAT, "version": SURFACE_VERSION, **surface.to_dict()}
    safe_io.write_file(output_file(path).parent, FsPath(path).name, json.dumps(d, indent=1) + "\n")


MAX_BOUNDARY_VERTICES = 50_000  # a fitted boundary has hundreds to a few thousand (simplified at 0.5 mm)


def _check_boundary_size(p, b) -> None:
    """BadInput for a boundary no fit writes: more than ``MAX_BOUNDARY_VERTICES`` vertices in all (each
    point-in-polygon test of the run would scan them all: 400k vertices ran past 90 s)."""
    if not isinstance(b, dict):
        return
    polys = [b.get("outer_uv"), *(b.get("holes_uv") or [])] if isinstance(b.get("holes_uv", []), list) else []
    total = sum(len(x) for x in polys if isinstance(x, list))
    if total > MAX_BOUNDARY_VERTICES:
        raise BadInput(f"{p}: the boundary has {total} vertices, more than the {MAX_BOUNDARY_VERTICES} camtool reads; "
                       "rerun camtool fit")


def load_surface(path: str | FsPath) -> Surface:
    """Read a surface saved by ``save_surface``."""
    p = FsPath(path)
    try:
        # a regular file under the cap, read once (no FIFO hang); nesting bounded (no RecursionError)
        d = safe_io.load_json(safe_io.read_input_bytes(p, "stage"), f"{p}: not a camtool surface file:")
        if not isinstance(d, dict):
            raise BadInput(f"{p}: not a camtool surface file (not a JSON object)")
        _check_boundary_size(p, d.get("boundary"))
        if d.get("version", SURFACE_VERSION) != SURFACE_VERSION:
            raise BadInput(f"{p}: surface file version {d['version']} is not supported "
                           f"(this camtool reads version {SURFACE_VERSION}); rerun camtool fit")
        return surface_from_dict(d)
    except FileNotFoundError:
        raise BadInput(f"{p}: surface file not found") from None
    except (json.JSONDecodeError, KeyError, TypeError, ValueError, AttributeError, IndexError, OverflowError,
            RecursionError) as exc:
        raise BadInput(f"{p}: not a camtool surface file ({type(exc).__name__})") from None
    except (IsADirectoryError, PermissionError, UnicodeDecodeError) as exc:
        raise BadInput(f"{p}: cannot read the surface file ({type(exc).__name__})") from None
