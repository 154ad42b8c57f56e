"""Workpiece loading: meshes and point clouds, units, sampling and normals.

One call, :func:`load_workpiece`, dispatches on the file extension to a loader
registered in ``LOADERS`` (trimesh style), so a new format touches one place.

- Meshes (STL, OBJ, OFF, GLB/GLTF, PLY with faces; STEP when ``cascadio`` is
  installed) are read with trimesh and sampled area-weighted into points with
  the face normals (seeded, deterministic).
- Point clouds (PLY without faces, PCD, XYZ/CSV/TXT) are read with open3d or
  numpy; normals stored in the file are kept, missing ones are estimated with
  open3d from ``normal_neighbours`` neighbours and oriented towards the file's
  origin (the sensor viewpoint convention of PCD and open3d).

Everything is converted to mm. A model whose size is implausible for the
declared unit keeps loading but carries a warning naming the likely unit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from .errors import BadInput

UNIT_TO_MM = {"mm": 1.0, "m": 1000.0, "in": 25.4}

# Bounding-box diagonals (mm) that are plausible for a workpiece of a robot cell.
PLAUSIBLE_DIAGONAL_MM = (5.0, 20_000.0)
# Coordinates beyond this (mm, 1000 km) are treated as corrupt, not as a unit slip.
MAX_ABS_COORDINATE_MM = 1e9


@dataclass(frozen=True)
class Workpiece:
    """Points (N x 3, mm) with unit normals; optional mesh (vertices_mm, faces)."""

    points_mm: np.ndarray
    normals: np.ndarray
    faces: np.ndarray | None = None
    source: str = ""
    units: str = "mm"
    warnings: tuple[str, ...] = ()
    vertices_mm: np.ndarray | None = field(default=None, repr=False)

    @property
    def n_points(self) -> int:
        return int(len(self.points_mm))

    def transformed(self, T_mm: np.ndarray) -> "Workpiece":
        """The workpiece moved by a 4x4 pose (translation in mm); normals are rotated."""
        T = np.asarray(T_mm, dtype=float)
        R, t = T[:3, :3], T[:3, 3]
        verts = None if self.vertices_mm is None else self.vertices_mm @ R.T + t
        return Workpiece(self.points_mm @ R.T + t, self.normals @ R.T, self.faces, self.source,
                         self.units, self.warnings, verts)


@dataclass(frozen=True)
class _Raw:
    """What a loader returns, in file units: a cloud, or a mesh (vertices + faces)."""

    points: np.ndarray
    normals: np.ndarray | None = None
    faces: np.ndarray | None = None


Loader = Callable[[Path], _Raw]
LOADERS: dict[str, Loader] = {}


def register_loader(*extensions: str) -> Callable[[Loader], Loader]:
    """Decorator: register a loader for file extensions (lower case, with dot)."""

    def deco(fn: Loader) -> Loader:
        for ext in extensions:
            LOADERS[ext] = fn
        return fn

    return deco


def supported_extensions() -> list[str]:
    return sorted(LOADERS)


# --------------------------------------------------------------------------- loaders

def _mesh_from_trimesh(obj, path: Path) -> _Raw:
    import trimesh

    if isinstance(obj, trimesh.Scene):
        geoms = [g for g in obj.dump() if isinstance(g, trimesh.Trimesh)]
        if not geoms:
            clouds = [g for g in obj.dump() if isinstance(g, trimesh.PointCloud)]
            if clouds:
                return _Raw(np.vstack([np.asarray(c.vertices) for c in clouds]))
            raise BadInput(f"{path}: the file holds no triangles or points (truncated or corrupt?); export the part again")
        obj = trimesh.util.concatenate(geoms)
    if isinstance(obj, trimesh.PointCloud):
        return _Raw(np.asarray(obj.vertices, dtype=float))
    if not isinstance(obj, trimesh.Trimesh):
        raise BadInput(f"{path}: the file holds no triangle mesh ({type(obj).__name__}); export it as a mesh")
    return _Raw(np.asarray(obj.vertices, dtype=float), None, np.asarray(obj.faces, dtype=np.int64))


@register_loader(".stl", ".obj", ".off", ".glb", ".gltf")
def _load_mesh(path: Path) -> _Raw:
    import trimesh

    if path.suffix.lower() == ".stl":
        _check_binary_stl_length(path)
    return _mesh_from_trimesh(trimesh.load(str(path), file_type=path.suffix.lower()[1:]), path)


def _check_binary_stl_length(path: Path) -> None:
    """A binary STL's size must be 84 + 50 x its triangle count (trimesh would guess on)."""
    size = path.stat().st_size
    with path.open("rb") as f:
        head = f.read(84)
    if head[:5].lower() == b"solid" and b"facet" in path.read_bytes()[:1000]:
        return  # ASCII STL
    count = int.from_bytes(head[80:84], "little") if len(head) == 84 else -1
    if count < 0 or size != 84 + 50 * count:
        raise BadInput(f"{path}: binary STL is truncated or corrupt (header says {max(count, 0)} triangles, "
                       f"{size} bytes present, {84 + 50 * max(count, 0)} expected); export it again")


@register_loader(".step", ".stp")
def _load_step(path: Path) -> _Raw:
    try:
        import cascadio  # noqa: F401  (trimesh's STEP reader)
    except ImportError:
        raise BadInput(f"{path}: STEP needs the optional loader: pip install 'camtool[step]' "
                       "(cascadio), or export the part as STL") from None
    import trimesh

    return _mesh_from_trimesh(trimesh.load(str(path), file_type="step"), path)


@register_loader(".ply")
def _load_ply(path: Path) -> _Raw:
    """A PLY with faces is a mesh; without faces it is a point cloud."""
    import trimesh

    obj = trimesh.load(str(path), file_type="ply")
    if isinstance(obj, trimesh.Trimesh) and len(obj.faces) > 0:
        return _mesh_from_trimesh(obj, path)
    return _load_o3d_cloud(path)


@register_loader(".pcd")
def _load_o3d_cloud(path: Path) -> _Raw:
    import open3d as o3d

    pc = o3d.io.read_point_cloud(str(path), format="auto", remove_nan_points=False,
                                 remove_infinite_points=False)
    pts = np.asarray(pc.points, dtype=float)
    normals = np.asarray(pc.normals, dtype=float) if pc.has_normals() else None
    return _Raw(pts, normals)


@register_loader(".xyz", ".csv", ".txt", ".pts")
def _load_text_cloud(path: Path) -> _Raw:
    """Columns x y z [nx ny nz], separated by spaces, commas or semicolons; one header line allowed."""
    text = path.read_text(errors="replace")
    lines = [ln for ln in text.replace(",", " ").replace(";", " ").splitlines()
             if ln.strip() and not ln.lstrip().startswith(("#", "//"))]
    if lines and not _numeric(lines[0]):
        lines = lines[1:]  # header
    if not lines:
        return _Raw(np.zeros((0, 3)))
    try:
        data = np.loadtxt(lines, dtype=float, ndmin=2)
    except ValueError as exc:
        raise BadInput(f"{path}: not a table of numbers x y z [nx ny nz] ({exc})") from None
    if data.shape[1] < 3:
        raise BadInput(f"{path}: expected at least 3 columns (x y z), found {data.shape[1]}")
    normals = data[:, 3:6] if data.shape[1] >= 6 else None
    return _Raw(data[:, :3], normals)


def _numeric(line: str) -> bool:
    try:
        [float(x) for x in line.split()]
        return True
    except ValueError:
        return False


# --------------------------------------------------------------------------- entry

def load_workpiece(path: Path, units: str = "mm", sample_points: int = 100000,
                   normal_neighbours: int = 30, seed: int = 0) -> Workpiece:
    """Load a mesh or point cloud as a Workpiece in mm.

    Meshes are sampled area-weighted into ``sample_points`` points with face
    normals (``seed`` makes it deterministic); clouds keep their points and get
    normals estimated from ``normal_neighbours`` neighbours. ``units`` is the
    file's length unit (mm, m or in). Raises BadInput naming the file.
    """
    path = Path(path)
    if units not in UNIT_TO_MM:
        raise BadInput(f"{path}: units {units!r} is not one of {', '.join(UNIT_TO_MM)}")
    if path.is_dir():
        raise BadInput(f"{path}: is a folder; give a mesh or point-cloud file")
    ext = path.suffix.lower()
    loader = LOADERS.get(ext)
    if loader is None:
        raise BadInput(f"{path}: unsupported file type {ext or '(no extension)'!r}; "
                       f"use one of {' '.join(supported_extensions())}")
    if not path.exists():
        raise BadInput(f"{path}: workpiece file not found; check the name and the folder")
    if path.stat().st_size == 0:
        raise BadInput(f"{path}: the file is empty; export the workpiece again")
    try:
        raw = loader(path)
    except BadInput:
        raise
    except Exception as exc:  # parser errors of trimesh / open3d / numpy: one line for the user
        first = (str(exc).splitlines() or [""])[0][:200]
        raise BadInput(f"{path}: cannot read as {ext[1:].upper()} ({type(exc).__name__}: {first}); "
                       "the file may be truncated or corrupt, export it again") from None

    scale = UNIT_TO_MM[units]
    points = np.asarray(raw.points, dtype=float).reshape(-1, 3)
    _check_coordinates(points, path, units, scale)
    warnings = _unit_warnings(points, path, units)
    rng = np.random.default_rng(seed)
    if raw.faces is not None and len(raw.faces):
        verts_mm = points * scale
        pts_mm, normals = _sample_mesh(verts_mm, raw.faces, sample_points, rng, path)
        return Workpiece(pts_mm, normals, raw.faces, str(path), units, warnings, verts_mm)
    pts_mm = points * scale
    normals = _cloud_normals(pts_mm, raw.normals, normal_neighbours)
    return Workpiece(pts_mm, normals, None, str(path), units, warnings, None)


def _check_coordinates(points: np.ndarray, path: Path, units: str, scale: float) -> None:
    if len(points) == 0:
        raise BadInput(f"{path}: the file holds no points; export the workpiece again")
    finite = np.isfinite(points).all(axis=1)
    if not finite.all():
        bad = int((~finite).sum())
        raise BadInput(f"{path}: {bad} of {len(points)} points have NaN or infinite coordinates; "
                       "remove them or export the file again")
    biggest_mm = float(np.abs(points).max()) * scale
    if biggest_mm > MAX_ABS_COORDINATE_MM:
        raise BadInput(f"{path}: coordinates reach {biggest_mm:.3g} mm (units = {units}); "
                       "that is not a workpiece: check the file and its units")


def _unit_warnings(points: np.ndarray, path: Path, units: str) -> tuple[str, ...]:
    """A warning when the size in the declared unit is implausible, naming a likely unit."""
    diag = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    lo, hi = PLAUSIBLE_DIAGONAL_MM
    size_mm = diag * UNIT_TO_MM[units]
    if lo <= size_mm <= hi or diag == 0.0:
        return ()
    fits = [u for u in UNIT_TO_MM if u != units and lo <= diag * UNIT_TO_MM[u] <= hi]
    # Among plausible units, prefer the one giving a size nearest 1 m (a typical part).
    fits.sort(key=lambda u: abs(math.log10(diag * UNIT_TO_MM[u] / 1000.0)))
    hint = f"; the file is probably in {fits[0]} (set units = \"{fits[0]}\")" if fits else ""
    return (f"{path}: the workpiece is {size_mm:.4g} mm across with units = \"{units}\", "
            f"outside the plausible {lo:g}..{hi:g} mm{hint}",)


def _sample_mesh(verts_mm: np.ndarray, faces: np.ndarray, count: int, rng: np.random.Generator,
                 path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Area-weighted random points on the triangles, with the face normals."""
    import trimesh

    if faces.min() < 0 or faces.max() >= len(verts_mm):
        raise BadInput(f"{path}: faces refer to vertices that do not exist; export the mesh again")
    mesh = trimesh.Trimesh(verts_mm, faces, process=False, validate=False)
    area = mesh.area_faces
    if not np.isfinite(area).all() or area.sum() <= 0:
        raise BadInput(f"{path}: the mesh has no area (all triangles degenerate); export it again")
    pts, face_idx = trimesh.sample.sample_surface(mesh, int(count), seed=rng)
    normals = np.asarray(mesh.face_normals)[face_idx]
    return np.asarray(pts, dtype=float), np.asarray(normals, dtype=float)


def _cloud_normals(pts_mm: np.ndarray, normals: np.ndarray | None, k: int) -> np.ndarray:
    """Unit normals: the file's if it has valid ones, else estimated by open3d (k neighbours)."""
    if normals is not None:
        normals = np.asarray(normals, dtype=float)
        length = np.linalg.norm(normals, axis=1)
        if np.isfinite(normals).all() and (length > 1e-9).all():
            return normals / length[:, None]
    if len(pts_mm) < 3:
        return np.zeros_like(pts_mm)
    import open3d as o3d

    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts_mm))
    pc.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=int(min(k, len(pts_mm)))))
    n = np.asarray(pc.normals, dtype=float)
    # Orient towards the file origin (the sensor viewpoint convention); open3d's own
    # orient_* call does the same but is threaded; this is the one-line numpy form.
    flip = np.einsum("ij,ij->i", n, -pts_mm) < 0
    n[flip] *= -1
    return n
