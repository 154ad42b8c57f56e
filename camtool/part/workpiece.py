"""Workpiece loading: meshes and point clouds, units, sampling and normals.

One call, :func:`load_workpiece`, dispatches on the file extension to a loader
registered in ``LOADERS`` (trimesh style), so a new format touches one place.

- Meshes (STL, OBJ, OFF, GLB/GLTF, PLY with faces) are read with trimesh, STEP
  with OCP (``camtool.part.step``: its B-rep faces tessellated); all are sampled
  area-weighted into points with the face normals (seeded, deterministic).
- Point clouds (PLY without faces, PCD, XYZ/CSV/TXT/PTS) are read with
  trimesh, open3d or numpy; normals stored in the file are kept, missing ones
  are estimated with open3d from ``normal_neighbours`` neighbours (on voxels for
  a dense cloud: ``camtool.part.cloud_normals``) and oriented
  towards the file's origin (the sensor viewpoint convention of PCD and open3d).

Everything is converted to mm. A model whose size is implausible for the
declared unit keeps loading but carries a warning naming the likely unit.

Damaged files never become a workpiece
--------------------------------------
The library readers are lenient: open3d zero-fills (or leaves stale memory in)
the rest of a cloud when an ASCII PLY or PCD is cut short or holds a token its
parser gives up on (RPly stops at ``-inf``), and says so only on stdout;
trimesh returns fewer faces for a cut ASCII PLY and its default processing
drops triangles with NaN vertices without a word. So the reading stays with the
libraries, and every loader checks what they read against the file:

- counts: PLY ``element`` counts (and, in binary PLY, every face's list
  length), PCD ``POINTS`` = ``WIDTH`` x ``HEIGHT``, OFF's counts, a binary
  STL's triangle count against the file length, a leading point count in an
  XYZ/PTS file; the data present must match (no missing lines or bytes; for
  PLY, PCD and binary STL no undeclared data after the last element either),
  and the reader must return exactly that many points, vertices and faces;
- text bodies (ASCII PLY and PCD, STL ``vertex`` lines, OBJ ``v`` lines, OFF)
  are checked line by line with a strict parse (numpy or ``float``), which must
  also agree with the library's values: a reader that gave up on a token and
  filled in zeros, or dropped a byte that is not UTF-8, is caught because the
  text at that place does not say what it read;
- values: NaN or infinite coordinates, and non-zero coordinates below 1e-30 in
  magnitude (``TINY_COORDINATE``: no length a workpiece file holds is that
  small in any unit; such numbers come from flipped exponent bits or garbled
  text, e.g. ``1e-300``), are an error naming the file and the first bad
  element (numbered from 0, with its line in text files). Exact zeros are fine. With ``drop_nonfinite=True`` (job key
  ``workpiece.drop_nonfinite``) those points, or those vertices and the
  triangles using them, are dropped instead, with a warning giving the count.

Library messages never reach stdout (which ``--json`` keeps for results):
open3d runs at Error verbosity during reads, and trimesh's log records and the
Python warnings raised while reading go to the ``camtool.part.workpiece`` logger at
debug level; the checks above produce the one message the user sees.
"""
from __future__ import annotations

import logging
import math
import re
import threading
import warnings as pywarnings
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from ..errors import BadInput
from .sampling import TINY_COORDINATE

log = logging.getLogger("camtool.workpiece")

UNIT_TO_MM = {"mm": 1.0, "m": 1000.0, "in": 25.4}

# Bounding-box diagonals (mm) that are plausible for a workpiece of a robot cell.
PLAUSIBLE_DIAGONAL_MM = (5.0, 20_000.0)
# Coordinates beyond this (mm, 1000 km) are treated as corrupt, not as a unit slip.
MAX_ABS_COORDINATE_MM = 1e9
# Non-zero coordinates smaller than this (in the file's unit) are damaged numbers.

INDEXED = (".obj", ".off", ".ply", ".glb", ".gltf")   # mesh formats whose duplicate vertices are a defect
DROP_HINT = "fix the file or set workpiece.drop_nonfinite = true to drop them"


@dataclass(frozen=True)
class Workpiece:
    """Points (N x 3, mm) with unit normals; optional mesh (vertices_mm, faces). ``scan``: whether the job calls
    the mesh a scan (``workpiece.scan``: "auto" judges it by its roughness, ``part.roughness.mesh_is_scan``)."""

    points_mm: np.ndarray
    normals: np.ndarray
    faces: np.ndarray | None = None
    source: str = ""
    units: str = "mm"
    warnings: tuple[str, ...] = ()
    vertices_mm: np.ndarray | None = field(default=None, repr=False)
    scan: str = "auto"

    @property
    def n_points(self) -> int:
        return int(len(self.points_mm))

    def transformed(self, T_mm: np.ndarray) -> "Workpiece":
        """The workpiece moved by a 4x4 pose (translation in mm); normals are rotated."""
        T = np.asarray(T_mm, dtype=float)
        R, t = T[:3, :3], T[:3, 3]
        verts = None if self.vertices_mm is None else self.vertices_mm @ R.T + t
        return Workpiece(self.points_mm @ R.T + t, self.normals @ R.T, self.faces, self.source,
                         self.units, self.warnings, verts, self.scan)


@dataclass(frozen=True)
class _Raw:
    """What a loader returns, in file units: a cloud, or a mesh (vertices + faces).

    ``element`` names what a row of ``points`` belongs to in messages ("point",
    "vertex", or "triangle" when every ``per_element`` rows are one triangle's
    corners, as in STL); ``lines`` holds the file line of each element when the
    format is text and the rows are in file order.
    """

    points: np.ndarray
    normals: np.ndarray | None = None
    faces: np.ndarray | None = None
    element: str = "point"
    per_element: int = 1
    lines: np.ndarray | None = None


Loader = Callable[[Path], _Raw]
LOADERS: dict[str, Loader] = {}

_PLURAL = {"point": "points", "vertex": "vertices", "triangle": "triangles"}


def register_loader(*extensions: str) -> Callable[[Loader], Loader]:
    """Decorator: register a loader for file extensions (lower case, with dot)."""

    def deco(fn: Loader) -> Loader:
        for ext in extensions:
            LOADERS[ext] = fn
        return fn

    return deco


def supported_extensions() -> list[str]:
    return sorted(LOADERS)


# --------------------------------------------------------------------------- library output

_trimesh_quiet_lock = threading.Lock()
_trimesh_quiet_depth = 0
_trimesh_propagate = True


class _ToDebugLog(logging.Handler):
    """On the 'trimesh' logger while reading: each record (its modules log through child
    loggers) goes to camtool's log at debug level instead of the root logger's stderr."""

    def emit(self, record: logging.LogRecord) -> None:
        log.debug("%s: %s", record.name, record.getMessage())


_TO_DEBUG = _ToDebugLog()


@contextmanager
def _library_output_to_log() -> Iterator[None]:
    """While reading: trimesh's log records and Python warnings go to camtool's debug log."""
    global _trimesh_quiet_depth, _trimesh_propagate
    tlog = logging.getLogger("trimesh")
    with _trimesh_quiet_lock:
        if _trimesh_quiet_depth == 0:
            _trimesh_propagate = tlog.propagate
            tlog.addHandler(_TO_DEBUG)
            tlog.propagate = False
        _trimesh_quiet_depth += 1
    try:
        with pywarnings.catch_warnings(record=True) as caught:
            pywarnings.simplefilter("always")
            try:
                yield
            finally:
                for w in caught:
                    log.debug("%s: %s", w.category.__name__, w.message)
    finally:
        with _trimesh_quiet_lock:
            _trimesh_quiet_depth -= 1
            if _trimesh_quiet_depth == 0:
                tlog.removeHandler(_TO_DEBUG)
                tlog.propagate = _trimesh_propagate


# --------------------------------------------------------------------------- checks shared by loaders

_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f]")  # never in a header line of a sound text header
_INT_TOKEN = re.compile(r"[+-]?\d+")


def _strict_table(rows: list[str], ncols: int, path: Path, first_line: int, what: str) -> np.ndarray:
    """Rows of exactly ``ncols`` numbers each, parsed by numpy; else BadInput naming the line."""
    if not rows:
        return np.zeros((0, ncols))
    try:
        with pywarnings.catch_warnings():
            pywarnings.simplefilter("ignore")
            table = np.loadtxt(rows, dtype=float, ndmin=2, comments=None)
        if table.shape == (len(rows), ncols):
            return table
        problem = f"{table.shape[0]} rows of {table.shape[1]} numbers"
    except ValueError:  # numpy's message quotes the file's text: never passed on (it may be a secret)
        problem = "a value that is not a number"
    for i, row in enumerate(rows):
        tokens = row.split()
        if len(tokens) != ncols:
            raise BadInput(f"{path}: line {first_line + i}: expected {ncols} numbers for {what}, "
                           f"found {len(tokens)}; the file is truncated or corrupt, export it again")
        for k, tok in enumerate(tokens):
            try:
                float(tok)
            except ValueError:
                raise BadInput(f"{path}: line {first_line + i}: value {k + 1} is not a number; "
                               "the file is corrupt, export it again") from None
    raise BadInput(f"{path}: lines {first_line}..{first_line + len(rows) - 1} are not a table of "
                   f"{ncols} numbers per {what} ({problem}); the file is corrupt, export it again")


def _same_values(read: np.ndarray, text: np.ndarray) -> bool:
    """The library's values equal the strict parse of the text (NaN where NaN)."""
    read, text = np.asarray(read, dtype=float), np.asarray(text, dtype=float)
    return read.shape == text.shape and bool(np.allclose(read, text, rtol=1e-6, atol=0.0, equal_nan=True))


def _disagree(path: Path, what: str) -> BadInput:
    return BadInput(f"{path}: the reader's {what} disagree with the file's text (a value it could not "
                    "parse?); the file is corrupt, export it again")


def _is_int_token(tok: str) -> bool:
    try:
        v = float(tok)
    except ValueError:
        return False
    return math.isfinite(v) and v >= 0 and v == int(v)


# --------------------------------------------------------------------------- meshes (trimesh)

def _mesh_from_trimesh(obj, path: Path) -> _Raw:
    import trimesh

    if isinstance(obj, trimesh.Scene):
        geoms = [g for g in obj.dump() if isinstance(g, trimesh.Trimesh)]
        if not geoms:
            clouds = [g for g in obj.dump() if isinstance(g, trimesh.PointCloud)]
            if clouds:
                return _Raw(np.vstack([np.asarray(c.vertices) for c in clouds]))
            raise BadInput(f"{path}: the file holds no triangles or points (truncated or corrupt?); export the part again")
        obj = geoms[0] if len(geoms) == 1 else trimesh.util.concatenate(geoms)
    if isinstance(obj, trimesh.PointCloud):
        return _Raw(np.asarray(obj.vertices, dtype=float))
    if not isinstance(obj, trimesh.Trimesh):
        raise BadInput(f"{path}: the file holds no triangle mesh ({type(obj).__name__}); export it as a mesh")
    return _Raw(np.asarray(obj.vertices, dtype=float), None, np.asarray(obj.faces, dtype=np.int64), "vertex")


def _read_checked(path: Path) -> bytes:
    """The workpiece's bytes through ``safe_io``: a regular file under the workpiece cap, never a FIFO or device."""
    from ..safe_io import read_input_bytes

    return read_input_bytes(path, "workpiece")


def _trimesh_load(path: Path, file_type: str):
    """trimesh's reader without its processing: processing would drop NaN triangles unseen;
    load_workpiece checks the values first and merges vertices afterwards."""
    import trimesh

    from ..safe_io import opened_input

    if file_type == "gltf":  # a .gltf names its buffers beside it: each read through safe_io (gltf_buffers.py)
        import io

        from .gltf_buffers import CheckedBuffers

        data = _read_checked(path)
        return trimesh.load(io.BytesIO(data), file_type=file_type, process=False,
                            resolver=CheckedBuffers(path.parent, path.name))
    with opened_input(path, "workpiece") as name:  # the checked file itself (regular, capped), opened once
        return trimesh.load(name, file_type=file_type, process=False)


@register_loader(".stl")
def _load_stl(path: Path) -> _Raw:
    data = _read_checked(path)
    binary_count = _binary_stl_count(path, data)
    if binary_count is None:  # ASCII: trimesh reads it when the length does not fit binary
        facets, text_vertices = _check_ascii_stl(path, data)
    raw = _mesh_from_trimesh(_trimesh_load(path, "stl"), path)
    expected = binary_count if binary_count is not None else facets
    got = 0 if raw.faces is None else len(raw.faces)
    if got != expected:
        raise BadInput(f"{path}: the STL holds {expected} triangles, the reader got {got}; "
                       "the file is corrupt, export it again")
    if binary_count is None and not _same_values(raw.points, text_vertices):
        raise _disagree(path, "vertices")
    return replace(raw, element="triangle", per_element=3)


def _binary_stl_count(path: Path, data: bytes) -> int | None:
    """The triangle count of a binary STL, None for ASCII; BadInput for a damaged binary file.

    trimesh reads a file as binary exactly when its size is 84 + 50 x the
    header's triangle count, and as ASCII otherwise: the same rule here, so the
    check and the reader agree on what the file is.
    """
    size = len(data)
    count = int.from_bytes(data[80:84], "little") if size >= 84 else -1
    if count >= 0 and size == 84 + 50 * count:
        return count
    if data.lstrip()[:5].lower() == b"solid" and b"facet" in data[:1000].lower():
        return None
    raise BadInput(f"{path}: binary STL is truncated or corrupt (header says {max(count, 0)} triangles, "
                   f"{size} bytes present, {84 + 50 * max(count, 0)} expected); export it again")


_STL_FACET = re.compile(r"(?<!end)facet\b")
_STL_VERTEX = re.compile(r"vertex([^\n]*)")


def _check_ascii_stl(path: Path, data: bytes) -> tuple[int, np.ndarray]:
    """Facet count and vertices of an ASCII STL, each ``vertex`` line exactly 3 numbers.

    ASCII STL has no count: a cut file shows as a missing ``endsolid`` or a
    facet with fewer than 3 vertices (trimesh would drop or shift them).
    """
    text = data.decode("utf-8", errors="replace").lower()
    last_end = text.rfind("endsolid")
    if last_end < 0 or _STL_FACET.search(text, last_end):
        raise BadInput(f"{path}: ASCII STL does not end with 'endsolid': the file is truncated; export it again")
    facets = len(_STL_FACET.findall(text))
    rows = [m.group(1) for m in _STL_VERTEX.finditer(text)]
    if len(rows) != 3 * facets:
        raise BadInput(f"{path}: ASCII STL has {facets} facets but {len(rows)} vertex lines (3 per facet "
                       "expected); the file is truncated or corrupt, export it again")
    if not rows:
        return 0, np.zeros((0, 3))
    try:
        with pywarnings.catch_warnings():
            pywarnings.simplefilter("ignore")
            verts = np.loadtxt(rows, dtype=float, ndmin=2, comments=None)
        if verts.shape == (len(rows), 3):
            return facets, verts
    except ValueError:
        pass
    for i, row in enumerate(rows):
        tokens = row.split()
        if len(tokens) != 3 or not all(_is_float(t) for t in tokens):
            raise BadInput(f"{path}: ASCII STL vertex {i} (triangle {i // 3}) is not 3 numbers; "
                           "the file is corrupt, export it again")
    raise BadInput(f"{path}: ASCII STL vertex lines are not numbers; the file is corrupt, export it again")


def _is_float(tok: str) -> bool:
    try:
        float(tok)
        return True
    except ValueError:
        return False


@register_loader(".obj")
def _load_obj(path: Path) -> _Raw:
    """OBJ has no counts; its ``v`` lines must each be x y z [w] or x y z r g b [a] numbers
    (trimesh reshapes a short line into a wrong table instead of failing)."""
    text = _read_checked(path).decode("utf-8", errors="replace")
    v_lines = []
    for no, line in enumerate(text.splitlines(), 1):
        tokens = line.split()
        if tokens and tokens[0] == "f":  # indices count from 1 (or from the end when negative): 0 is none
            if any(t.split("/")[0] in ("0", "-0", "+0") for t in tokens[1:]):
                raise BadInput(f"{path}: line {no}: a face refers to vertex 0, but OBJ counts vertices from 1; "
                               "the file is corrupt, export it again")
            continue
        if not tokens or tokens[0] != "v":
            continue
        if len(tokens) - 1 not in (3, 4, 6, 7) or not all(_is_float(t) for t in tokens[1:]):
            raise BadInput(f"{path}: line {no}: a vertex needs x y z numbers; "
                           "the file is truncated or corrupt, export it again")
        v_lines.append(no)
    raw = _mesh_from_trimesh(_trimesh_load(path, "obj"), path)
    # trimesh keeps the file's vertex order unless texture or normal indices split vertices
    lines = np.array(v_lines) if len(v_lines) == len(raw.points) else None
    return replace(raw, lines=lines)


@register_loader(".off")
def _load_off(path: Path) -> _Raw:
    """OFF states its vertex and face counts; trimesh reads fewer faces from a cut file unseen."""
    text = _read_checked(path).decode("utf-8", errors="replace")
    lines = [ln.split("#", 1)[0].strip() for ln in text.splitlines()]
    lines = [ln for ln in lines if ln]
    head = lines[0].split() if lines else []
    counts = head[1:] if head and head[0].upper() in ("OFF", "COFF") else []
    rest = lines[1:]
    if not counts and rest:
        counts, rest = rest[0].split(), rest[1:]
    if len(counts) != 3 or not all(t.isdigit() for t in counts):
        raise BadInput(f"{path}: not an OFF file (no 'OFF' header with vertex, face and edge counts); "
                       "export it again")
    nv, nf = int(counts[0]), int(counts[1])
    if len(rest) != nv + nf:
        raise BadInput(f"{path}: OFF header says {nv} vertices and {nf} faces, the file holds "
                       f"{len(rest)} data lines; the file is truncated or corrupt, export it again")
    # x y z [colour]: trimesh drops bytes that are not UTF-8 (a damaged '600' may read as '00')
    verts = [_floats3(line) for line in rest[:nv]]
    bad = next((i for i, v in enumerate(verts) if v is None), None)
    if bad is not None:
        raise BadInput(f"{path}: OFF vertex {bad} is not x y z numbers; "
                       "the file is corrupt, export it again")
    triangles = 0
    for i, line in enumerate(rest[nv:nv + nf]):  # n i1 .. in [colour]: trimesh skips a short one
        tokens = line.split()
        n = int(tokens[0]) if tokens[0].isdigit() else 0
        if n < 3 or len(tokens) < 1 + n or not all(_INT_TOKEN.fullmatch(t) for t in tokens[1:1 + n]):
            raise BadInput(f"{path}: OFF face {i} is not a vertex count >= 3 and that many indices; "
                           "the file is truncated or corrupt, export it again")
        triangles += n - 2
    raw = _mesh_from_trimesh(_trimesh_load(path, "off"), path)
    got = 0 if raw.faces is None else len(raw.faces)
    if len(raw.points) != nv or got != triangles:
        raise BadInput(f"{path}: OFF header says {nv} vertices and {nf} faces ({triangles} triangles), the reader "
                       f"got {len(raw.points)} and {got}; the file is corrupt, export it again")
    if not _same_values(raw.points, np.array(verts, dtype=float).reshape(-1, 3)):
        raise _disagree(path, "vertices")
    return raw


def _floats3(line: str) -> list[float] | None:
    """The first 3 numbers of a text line, or None if it does not start with 3 numbers."""
    tokens = line.split()[:3]
    if len(tokens) < 3 or not all(_is_float(t) for t in tokens):
        return None
    return [float(t) for t in tokens]


@register_loader(".glb", ".gltf")
def _load_gltf(path: Path) -> _Raw:
    return _mesh_from_trimesh(_trimesh_load(path, path.suffix.lower()[1:]), path)


@register_loader(".step", ".stp")
def _load_step(path: Path) -> _Raw:
    """STEP through OCP (``camtool.part.step``): every B-rep face tessellated, triangles facing out of the material."""
    from .step import step_mesh

    verts, tris, _ = step_mesh(path)
    return _Raw(verts, None, tris, "vertex")


# --------------------------------------------------------------------------- PLY

_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
_PLY_FORMATS = ("ascii", "binary_little_endian", "binary_big_endian")


@dataclass(frozen=True)
class _PlyElement:
    name: str
    count: int
    props: tuple[tuple[str, str, str | None], ...]  # (name, numpy type, list count type or None)

    @property
    def has_lists(self) -> bool:
        return any(p[2] is not None for p in self.props)


def _ply_header(path: Path, data: bytes) -> tuple[str, list[_PlyElement], int, int]:
    """(format, elements, byte offset of the body, header line count) from a PLY header.

    Parsed here only to know the counts and layout the body must match.
    """
    end = data.find(b"end_header", 0, 1 << 20)
    if not data.startswith(b"ply") or end < 0:
        raise BadInput(f"{path}: not a PLY file (no 'ply' ... 'end_header' header); export it again")
    nl = data.find(b"\n", end)
    body_at = len(data) if nl < 0 else nl + 1
    try:
        lines = data[:end].decode("ascii").splitlines()
    except UnicodeDecodeError:
        raise BadInput(f"{path}: the PLY header holds bytes that are not text; the file is corrupt") from None
    fmt, elements = None, []
    for no, line in enumerate(lines[1:], 2):
        tok = line.split()
        if not tok or tok[0] in ("comment", "obj_info"):
            continue
        bad = BadInput(f"{path}: PLY header line {no} is malformed; the file is corrupt")
        if _CONTROL.search(line.rstrip("\r")):
            raise bad
        if tok[0] == "format":
            if len(tok) != 3 or tok[1] not in _PLY_FORMATS or fmt is not None:
                raise bad
            fmt = tok[1]
        elif tok[0] == "element":
            if len(tok) != 3 or not tok[2].isdigit() or any(e.name == tok[1] for e in elements):
                raise bad
            elements.append(_PlyElement(tok[1], int(tok[2]), ()))
        elif tok[0] == "property":
            if not elements:
                raise bad
            if len(tok) == 5 and tok[1] == "list" and tok[2] in _PLY_TYPES and tok[3] in _PLY_TYPES:
                prop = (tok[4], _PLY_TYPES[tok[3]], _PLY_TYPES[tok[2]])
            elif len(tok) == 3 and tok[1] in _PLY_TYPES:
                prop = (tok[2], _PLY_TYPES[tok[1]], None)
            else:
                raise bad
            el = elements[-1]
            if any(q[0] == prop[0] for q in el.props):
                raise bad
            elements[-1] = _PlyElement(el.name, el.count, el.props + (prop,))
        else:
            raise bad
    if fmt is None:
        raise BadInput(f"{path}: PLY header has no 'format' line; the file is corrupt")
    return fmt, elements, body_at, len(lines) + 1


_PLY_PLURAL = {"vertex": "vertices", "face": "faces", "edge": "edges"}


def _ply_count(e: _PlyElement) -> str:
    if e.count == 1:
        return f"1 {e.name}"
    return f"{e.count} {_PLY_PLURAL.get(e.name, e.name + ' elements')}"


def _ply_summary(elements: list[_PlyElement]) -> str:
    return " and ".join(_ply_count(e) for e in elements)


def _check_binary_ply(path: Path, fmt: str, elements: list[_PlyElement], body: memoryview) -> None:
    """The body must hold exactly what the header declares.

    trimesh reads list properties (faces) assuming every list has the length of
    the first one and never looks at the other counts, so a damaged count byte
    would go unseen: here every count must equal the first (mixed polygon sizes
    are not readable by trimesh either).
    """
    order = "<" if fmt == "binary_little_endian" else ">"
    truncated = BadInput(f"{path}: binary PLY is truncated or corrupt (the header says {_ply_summary(elements)}, "
                         f"{len(body)} bytes of data present); export it again")
    at = 0
    for e in elements:
        fields, row_at = [], at
        for k, (name, t, c) in enumerate(e.props):
            if c is None:
                fields.append((f"p{k}", order + t))
                row_at += np.dtype(t).itemsize
                continue
            if not e.count:
                break
            if row_at + np.dtype(c).itemsize > len(body):
                raise truncated
            n0 = int(np.frombuffer(body, dtype=order + c, count=1, offset=row_at)[0])
            fields += [(f"n{k}", order + c), (f"p{k}", order + t, (n0,))]
            row_at += np.dtype(c).itemsize + n0 * np.dtype(t).itemsize
        if not e.count:
            continue
        dtype = np.dtype(fields)
        if at + e.count * dtype.itemsize > len(body):
            raise truncated
        rec = np.frombuffer(body, dtype=dtype, count=e.count, offset=at)
        for k, (name, _, c) in enumerate(e.props):
            if c is not None:
                n = rec[f"n{k}"]
                odd = np.flatnonzero(n != n[0])
                if len(odd):
                    raise BadInput(f"{path}: binary PLY {e.name} {odd[0]} has {n[odd[0]]} {name} where the "
                                   f"first has {n[0]}: a corrupt count (or mixed polygon sizes, which cannot be "
                                   "read); export the mesh again")
        at += e.count * dtype.itemsize
    if at != len(body):
        raise BadInput(f"{path}: binary PLY is truncated or corrupt (the header says {_ply_summary(elements)}, "
                       f"{at} bytes of data; {len(body)} present); export it again")


def _check_ascii_ply(path: Path, data: bytes, body_at: int, header_lines: int,
                     elements: list[_PlyElement]) -> tuple[dict[str, np.ndarray], dict[str, int], dict[str, bool]]:
    """Every element's rows present and well formed; (tables of scalar elements, first line
    of each element, whether a list element holds only triangles).

    Lines are split as trimesh splits them (str.splitlines), one element per line.
    """
    lines = data[body_at:].decode("utf-8", errors="replace").splitlines()
    tables, first, triangles = {}, {}, {}
    pos = 0
    for e in elements:
        rows = lines[pos:pos + e.count]
        line0 = header_lines + 1 + pos
        first[e.name] = line0
        if len(rows) < e.count:
            raise BadInput(f"{path}: ASCII PLY is truncated: the header says {_ply_count(e)}, "
                           f"the file holds {len(rows)}; export it again")
        if not e.has_lists:
            tables[e.name] = _strict_table(rows, len(e.props), path, line0, f"a {e.name}")
        else:
            triangles[e.name] = _check_ply_list_rows(rows, e, path, line0)
        pos += e.count
    for i, line in enumerate(lines[pos:]):
        if line.strip():
            raise BadInput(f"{path}: line {header_lines + 1 + pos + i}: data after the {_ply_summary(elements)} "
                           "the header declares; the header or the file is corrupt, export it again")
    return tables, first, triangles


def _ply_token_ok(tok: str, numpy_type: str) -> bool:
    return _is_float(tok) if numpy_type.startswith("f") else _INT_TOKEN.fullmatch(tok) is not None


def _check_ply_list_rows(rows: list[str], e: _PlyElement, path: Path, line0: int) -> bool:
    """Each row: a number of each property's type, list lengths matching their items
    (face indices whole numbers); True if every list has 3 items."""
    all_three = True
    for i, row in enumerate(rows):
        tokens, at, ok = row.split(), 0, True
        for _, item_type, count_type in e.props:
            if count_type is None:
                ok = at < len(tokens) and _ply_token_ok(tokens[at], item_type)
                at += 1
            else:
                ok = at < len(tokens) and tokens[at].isdigit()
                n = int(tokens[at]) if ok else 0
                all_three = all_three and n == 3
                items = tokens[at + 1:at + 1 + n]
                ok = ok and len(items) == n and all(_ply_token_ok(t, item_type) for t in items)
                at += 1 + n
            if not ok:
                break
        if not ok or at != len(tokens):
            raise BadInput(f"{path}: line {line0 + i}: {e.name} {i} does not match the header's properties; "
                           "the file is truncated or corrupt, export it again")
    return all_three


@register_loader(".ply")
def _load_ply(path: Path) -> _Raw:
    """A PLY with faces is a mesh; without faces it is a point cloud. trimesh reads both
    (open3d's RPly zero-fills after a token it cannot parse and prints to the terminal)."""
    import trimesh

    data = _read_checked(path)
    fmt, elements, body_at, header_lines = _ply_header(path, data)
    vertex = next((e for e in elements if e.name == "vertex"), None)
    if vertex is None:
        raise BadInput(f"{path}: the PLY declares no vertex element; export the part again")
    names = [p[0] for p in vertex.props]
    if not {"x", "y", "z"} <= set(names):
        raise BadInput(f"{path}: the PLY vertices have no x y z properties ({' '.join(names)}); export it again")
    if fmt == "ascii":
        tables, first, triangles = _check_ascii_ply(path, data, body_at, header_lines, elements)
    else:
        _check_binary_ply(path, fmt, elements, memoryview(data)[body_at:])
        tables, first, triangles = {}, {}, {}
    obj = _trimesh_load(path, "ply")
    faces = np.asarray(obj.faces, dtype=np.int64) if isinstance(obj, trimesh.Trimesh) else None
    if isinstance(obj, (trimesh.Trimesh, trimesh.PointCloud)):
        pts = np.asarray(obj.vertices, dtype=float)
    else:
        pts = np.zeros((0, 3))
    if len(pts) != vertex.count:
        raise BadInput(f"{path}: the PLY header says {vertex.count} vertices, the reader got {len(pts)}; "
                       "the file is corrupt, export it again")
    if "vertex" in tables:
        text = tables["vertex"][:, [names.index(c) for c in "xyz"]]
        dtypes = [vertex.props[names.index(c)][1] for c in "xyz"]
        text = np.column_stack([text[:, k].astype(dtypes[k]) for k in range(3)]) if len(text) else text
        if not _same_values(pts, text):
            raise _disagree(path, "vertices")
    n_faces = 0 if faces is None else len(faces)
    face_el = next((e for e in elements if e.name == "face"), None)
    if face_el is not None and face_el.count:
        if n_faces < face_el.count or (triangles.get("face") and n_faces != face_el.count):
            raise BadInput(f"{path}: the PLY header says {face_el.count} faces, the reader got {n_faces}; "
                           "the file is corrupt, export it again")
    lists = [e.name for e in elements if e.has_lists and e.count and e.name != "face"]
    if lists and not n_faces:  # e.g. triangle strips, or a damaged 'face' name: not a cloud either
        raise BadInput(f"{path}: the PLY holds {lists[0]!r} elements camtool cannot read (triangles go in "
                       "'face' elements); export the mesh again")
    lines = None if "vertex" not in first else first["vertex"] + np.arange(vertex.count)
    if faces is not None and len(faces):
        return _Raw(pts, None, faces, "vertex", 1, lines)
    return _Raw(pts, _ply_normals(obj, names), None, "vertex", 1, lines)


def _ply_normals(obj, names: list[str]) -> np.ndarray | None:
    """The nx ny nz vertex properties as trimesh read them, if the file has them."""
    if not {"nx", "ny", "nz"} <= set(names):
        return None
    raw = getattr(obj, "metadata", {}).get("_ply_raw", {}).get("vertex", {}).get("data")
    try:
        return np.column_stack([np.asarray(raw[c], dtype=float).reshape(-1) for c in ("nx", "ny", "nz")])
    except (KeyError, TypeError, ValueError, IndexError):
        return None


# --------------------------------------------------------------------------- PCD (open3d)

_PCD_SIZES = {"F": (4, 8), "I": (1, 2, 4, 8), "U": (1, 2, 4, 8)}
_PCD_KEYS = {"VERSION", "FIELDS", "SIZE", "TYPE", "COUNT", "WIDTH", "HEIGHT", "VIEWPOINT", "POINTS", "DATA"}


def _pcd_header(path: Path, data: bytes) -> dict:
    """The PCD header fields the body must match (parsed here only for the counts and layout)."""
    h: dict = {}
    pos, no = 0, 0
    while "DATA" not in h:
        nl = data.find(b"\n", pos)
        if nl < 0 or no > 200:
            raise BadInput(f"{path}: not a PCD file (no 'DATA' header line); export it again")
        line = data[pos:nl].decode("ascii", errors="replace").strip()
        pos, no = nl + 1, no + 1
        tok = line.split()
        if not tok or tok[0].startswith("#"):
            continue
        if _CONTROL.search(line):
            raise BadInput(f"{path}: PCD header line {no} holds control characters; the file is corrupt, "
                           "export it again")
        key = tok[0]
        if key not in _PCD_KEYS or key in h:
            raise BadInput(f"{path}: PCD header line {no} is not a PCD header field or repeats one; "
                           "the file is corrupt, export it again")
        h[key] = tok[1:]
    h["_body_at"], h["_header_lines"] = pos, no
    return h


def _pcd_layout(path: Path, h: dict) -> tuple[list[str], list[int], int, str]:
    """(fields, values per field, point count, data kind), checked against each other."""
    bad = lambda what: BadInput(f"{path}: PCD header {what}; the file is corrupt, export it again")  # noqa: E731
    fields = h.get("FIELDS", [])
    if not {"x", "y", "z"} <= set(fields):
        raise bad(f"has no x y z fields (FIELDS {' '.join(fields)})")
    sizes, types = h.get("SIZE", []), h.get("TYPE", [])
    counts = h.get("COUNT", ["1"] * len(fields))
    if not (len(sizes) == len(types) == len(counts) == len(fields)):
        raise bad("SIZE, TYPE, COUNT and FIELDS disagree in length")
    if not all(s.isdigit() for s in sizes + counts):
        raise bad("SIZE or COUNT is not a whole number")
    for s, t in zip(sizes, types):
        if int(s) not in _PCD_SIZES.get(t.upper(), ()):
            raise bad(f"has a field of TYPE {t} and SIZE {s}")
    try:
        width = int(h["WIDTH"][0])
        height = int(h.get("HEIGHT", ["1"])[0])
        points = int(h["POINTS"][0])
    except (KeyError, ValueError, IndexError):
        raise bad("WIDTH, HEIGHT or POINTS is missing or not a whole number") from None
    if min(width, height, points) < 0 or points != width * height:
        raise bad(f"says POINTS {points} but WIDTH x HEIGHT = {width} x {height}")
    kind = (h["DATA"] or [""])[0]
    if kind not in ("ascii", "binary", "binary_compressed"):
        raise bad(f"has DATA {kind!r} (expected ascii, binary or binary_compressed)")
    h["_point_bytes"] = sum(int(s) * int(c) for s, c in zip(sizes, counts))
    return fields, [int(c) for c in counts], points, kind


@register_loader(".pcd")
def _load_pcd(path: Path) -> _Raw:
    from .open3d_import import import_open3d, open3d_quiet
    o3d = import_open3d()

    data = _read_checked(path)
    h = _pcd_header(path, data)
    fields, counts, n, kind = _pcd_layout(path, h)
    body = data[h["_body_at"]:]
    text = None
    if kind == "ascii":
        # open3d skips short lines and leaves the points it did not get as zeros or stale memory
        rows = [ln for ln in body.decode("utf-8", errors="replace").splitlines() if ln.strip()]
        if len(rows) != n:
            raise BadInput(f"{path}: the PCD header says {n} points, the file holds {len(rows)} data lines; "
                           "the file is truncated or corrupt, export it again")
        table = _strict_table(rows, sum(counts), path, h["_header_lines"] + 1, "a point")
        starts = np.cumsum([0] + counts[:-1])
        text = table[:, [starts[fields.index(c)] for c in "xyz"]]
    elif kind == "binary":
        need = n * h["_point_bytes"]
        if len(body) != need:
            raise BadInput(f"{path}: binary PCD is truncated or corrupt (the header says {n} points, {need} bytes "
                           f"of data; {len(body)} present); export it again")
    else:
        packed, unpacked = (int.from_bytes(body[k:k + 4], "little") for k in (0, 4)) if len(body) >= 8 else (-1, -1)
        if unpacked != n * h["_point_bytes"] or len(body) < 8 + packed:
            raise BadInput(f"{path}: compressed PCD is truncated or corrupt (the header says {n} points); "
                           "export it again")
    from ..safe_io import opened_input

    with open3d_quiet(), opened_input(path, "workpiece") as name:
        pc = o3d.io.read_point_cloud(name, format="pcd", remove_nan_points=False,
                                     remove_infinite_points=False)
    pts = np.asarray(pc.points, dtype=float)
    if len(pts) != n:
        raise BadInput(f"{path}: the PCD header says {n} points, the reader got {len(pts)}; "
                       "the file is corrupt, export it again")
    if text is not None and not _same_values(pts, text):
        raise _disagree(path, "points")
    normals = np.asarray(pc.normals, dtype=float) if pc.has_normals() else None
    lines = None if text is None else _ascii_pcd_lines(body, h["_header_lines"])
    return _Raw(pts, normals, None, "point", 1, lines)


def _ascii_pcd_lines(body: bytes, header_lines: int) -> np.ndarray:
    rows = body.decode("utf-8", errors="replace").splitlines()
    return np.array([header_lines + 1 + i for i, ln in enumerate(rows) if ln.strip()], dtype=np.int64)


# --------------------------------------------------------------------------- text tables (numpy)

@register_loader(".xyz", ".csv", ".txt", ".pts")
def _load_text_cloud(path: Path) -> _Raw:
    """Columns x y z [nx ny nz], separated by spaces, commas or semicolons; one header line
    allowed; a first line holding only a whole number is the point count (PTS) and is checked."""
    text = _read_checked(path).decode("utf-8", errors="replace")
    numbered = [(no, ln) for no, ln in enumerate(text.replace(",", " ").replace(";", " ").splitlines(), 1)
                if ln.strip() and not ln.lstrip().startswith(("#", "//"))]
    if numbered and not any(_is_float(t) for t in numbered[0][1].split()):
        numbered = numbered[1:]  # a header: words only (a row with a damaged number is no header)
    declared = None
    if numbered and len(numbered[0][1].split()) == 1 and _is_int_token(numbered[0][1].split()[0]):
        declared = int(float(numbered[0][1].split()[0]))
        numbered = numbered[1:]
    if declared is not None and declared != len(numbered):
        raise BadInput(f"{path}: the first line says {declared} points, the file holds {len(numbered)}; "
                       "the file is truncated or corrupt, export it again")
    if not numbered:
        return _Raw(np.zeros((0, 3)))
    lines = np.array([no for no, _ in numbered], dtype=np.int64)
    rows = [ln for _, ln in numbered]
    ncols = len(rows[0].split())
    try:
        with pywarnings.catch_warnings():
            pywarnings.simplefilter("ignore")
            data = np.loadtxt(rows, dtype=float, ndmin=2, comments=None)
        ok = data.shape == (len(rows), ncols)
    except ValueError:
        ok = False
    if not ok:
        for no, ln in numbered:
            tokens = ln.split()
            if len(tokens) != ncols or not all(_is_float(t) for t in tokens):
                raise BadInput(f"{path}: line {no}: not a row of {ncols} numbers x y z [nx ny nz] like the first; "
                               "the file is truncated or corrupt")
        raise BadInput(f"{path}: not a table of numbers x y z [nx ny nz]")
    if data.shape[1] < 3:
        raise BadInput(f"{path}: expected at least 3 columns (x y z), found {data.shape[1]}")
    normals = data[:, 3:6] if data.shape[1] >= 6 else None
    return _Raw(data[:, :3], normals, None, "point", 1, lines)


# --------------------------------------------------------------------------- entry

def load_workpiece(path: Path, units: str = "mm", sample_points: int = 100000,
                   normal_neighbours: int = 30, seed: int = 0, drop_nonfinite: bool = False) -> Workpiece:
    """Load a mesh or point cloud as a Workpiece in mm.

    Meshes are sampled area-weighted into ``sample_points`` points with face
    normals (``seed`` makes it deterministic); clouds keep their points and get
    normals estimated from ``normal_neighbours`` neighbours. ``units`` is the
    file's length unit (mm, m or in). Raises BadInput naming the file, also when
    the file does not hold what its header declares or holds NaN, infinite or
    damaged coordinates; with ``drop_nonfinite`` those points (or vertices and
    their triangles) are dropped instead, with a warning in ``Workpiece.warnings``.
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
    from ..safe_io import held_input

    # opened and checked once (regular file under the cap, O_NONBLOCK, fstat); every loader below reads that
    # descriptor (safe_io's held inputs), never the name again
    with held_input(path, "workpiece") as st, _library_output_to_log():
        if st.st_size == 0:
            raise BadInput(f"{path}: the file is empty; export the workpiece again")
        try:
            raw = loader(path)
        except BadInput:
            raise
        except Exception as exc:  # parser errors of trimesh / open3d / numpy: one line for the user
            # the library's own message may quote the file's text (a secret, if the file is one): never passed on
            raise BadInput(f"{path}: cannot read as {ext[1:].upper()} ({type(exc).__name__}); "
                           "the file may be truncated or corrupt, export it again") from None
        return _workpiece_from_raw(raw, path, units, sample_points, normal_neighbours, seed, drop_nonfinite)


def _workpiece_from_raw(raw: _Raw, path: Path, units: str, sample_points: int, normal_neighbours: int,
                        seed: int, drop_nonfinite: bool) -> Workpiece:
    points = np.asarray(raw.points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3:
        raise BadInput(f"{path}: the reader got points of shape {points.shape}, not x y z rows; "
                       "the file is corrupt, export it again")
    faces = None if raw.faces is None or not len(raw.faces) else _checked_faces(raw.faces, len(points), path)
    normals = raw.normals
    if normals is not None:
        normals = np.asarray(normals, dtype=float)
        if normals.shape != points.shape:
            normals = None
    points, normals, faces, dropped = _screen_values(raw, points, normals, faces, path, drop_nonfinite)
    scale = UNIT_TO_MM[units]
    _check_coordinates(points, path, units, scale)
    warnings = dropped + _unit_warnings(points, path, units)
    rng = np.random.default_rng(seed)
    if faces is not None:
        from .mesh_repair import repaired_mesh

        verts_mm, faces, repairs = repaired_mesh(points * scale, faces, str(path), path.suffix.lower() in INDEXED)
        if path.suffix.lower() not in (".step", ".stp"):  # camtool's own tessellation: its slivers are no damage
            warnings = tuple(warnings) + repairs
        warnings = tuple(warnings) + _fold_warning(verts_mm, faces, path)
        pts_mm, face_normals = _sample_mesh(verts_mm, faces, sample_points, rng, path)
        return Workpiece(pts_mm, face_normals, faces, str(path), units, warnings, verts_mm)
    pts_mm = points * scale
    normals = _cloud_normals(pts_mm, normals, normal_neighbours)
    return Workpiece(pts_mm, normals, None, str(path), units, warnings, None)


def _fold_warning(verts_mm: np.ndarray, faces: np.ndarray, path: Path) -> tuple[str, ...]:
    """One warning line where the mesh's surface folds back onto itself (``part.folds``: a CAD surface folded over
    itself, kept as it is; the motion check reads those triangles as the surface they lie on), else none."""
    from .folds import folded_triangles

    folds = folded_triangles(verts_mm, faces)
    if not folds.count:
        return ()
    them = "them" if folds.count > 1 else "it"
    return (f"{path}: the surface folds back onto itself at {folds.count} triangle{'s' * (folds.count > 1)} (the "
            f"largest {folds.largest_mm2:.2g} mm2; a CAD surface folded over itself): the checks take {them} as the "
            f"surface {'they lie' if folds.count > 1 else 'it lies'} on",)


def _checked_faces(faces, n_vertices: int, path: Path) -> np.ndarray:
    faces = np.asarray(faces)
    if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
        raise BadInput(f"{path}: the reader got faces of shape {faces.shape}, not triangles; "
                       "the file is corrupt, export it again")
    if faces.min() < 0 or faces.max() >= n_vertices:
        raise BadInput(f"{path}: faces refer to vertices that do not exist; export the mesh again")
    return faces.astype(np.int64)


def _bad_rows(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row: any non-finite coordinate; any damaged (0 < |x| < TINY_COORDINATE) coordinate."""
    nonfinite = ~np.isfinite(points)
    with np.errstate(invalid="ignore"):
        mag = np.abs(points)
        tiny = (mag > 0) & (mag < TINY_COORDINATE)
    return nonfinite.any(axis=1), tiny.any(axis=1)


def _screen_values(raw: _Raw, points: np.ndarray, normals: np.ndarray | None, faces: np.ndarray | None,
                   path: Path, drop: bool):
    """Reject (or with ``drop`` remove) rows with NaN, infinite or damaged coordinates."""
    nonfinite, tiny = _bad_rows(points)
    bad = nonfinite | tiny
    if not bad.any():
        return points, normals, faces, ()
    per = max(1, raw.per_element)
    bad_rows = np.flatnonzero(bad)
    n_elements = len(points) // per
    k = len(np.unique(bad_rows // per))
    plural = _PLURAL.get(raw.element, raw.element + "s")
    kind = ("NaN or infinite" if not tiny.any() else "damaged" if not nonfinite.any()
            else "NaN, infinite or damaged")
    if not drop:
        row = int(bad_rows[0])
        e = row // per
        where = f"{raw.element} {e}"
        if raw.lines is not None and e < len(raw.lines):
            where += f" (line {int(raw.lines[e])})"
        v = points[row]
        if not np.isfinite(v).all():
            what = f"a non-finite coordinate ({v[~np.isfinite(v)][0]})"
        else:
            what = f"a damaged coordinate ({v[(v != 0) & (np.abs(v) < TINY_COORDINATE)][0]:.3g}: non-zero " \
                   f"but below {TINY_COORDINATE:g}, no real length)"
        raise BadInput(f"{path}: {where} has {what}; {k} of {n_elements} {plural} have {kind} coordinates: "
                       f"{DROP_HINT}")
    keep = ~bad
    if faces is None:
        if not keep.any():
            raise BadInput(f"{path}: all {n_elements} {plural} have {kind} coordinates; nothing is left to use")
        msg = f"{path}: dropped {k} of {n_elements} {plural} with {kind} coordinates (workpiece.drop_nonfinite)"
        return points[keep], None if normals is None else normals[keep], None, (msg,)
    face_bad = bad[faces].any(axis=1)
    if face_bad.all():
        raise BadInput(f"{path}: all {len(faces)} triangles have a vertex with {kind} coordinates; "
                       "nothing is left to use")
    new_index = np.cumsum(keep) - 1
    kept_faces = new_index[faces[~face_bad]]
    n_bad = int(bad.sum())
    msg = (f"{path}: dropped {n_bad} {'vertex' if n_bad == 1 else 'vertices'} with {kind} coordinates and the "
           f"{int(face_bad.sum())} of {len(faces)} triangles using them (workpiece.drop_nonfinite)")
    return points[keep], None, kept_faces, (msg,)


def _check_coordinates(points: np.ndarray, path: Path, units: str, scale: float) -> None:
    if len(points) == 0:
        raise BadInput(f"{path}: the file holds no points; export the workpiece again")
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
    """Unit normals: the file's if it has valid ones, else estimated (``cloud_normals``: k neighbours, per voxel
    for a dense cloud), towards the file's origin."""
    if normals is not None:
        normals = np.asarray(normals, dtype=float)
        length = np.linalg.norm(normals, axis=1)
        if np.isfinite(normals).all() and (length > 1e-9).all():
            return normals / length[:, None]
    from .cloud_normals import cloud_normals

    return cloud_normals(pts_mm, k)
