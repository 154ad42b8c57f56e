"""STEP parts through OCP (``cadquery-ocp-novtk``): the mesh, and every B-rep face with its exact surface.

Why OCP and not cascadio: cascadio converts STEP to a GLB mesh, so the faces
and their types are lost and would have to be found again by RANSAC; OCP (the
OpenCASCADE bindings CadQuery uses, on PyPI as a wheel) reads the B-rep, so a
plane, sphere or cylinder face is used exactly (type, parameters, material
side from the face's orientation) and only other faces (B-splines, cones,
tori) are tessellated and fitted. The ``-novtk`` build is the same OCP without
the VTK viewer.

Each face is tessellated by ``BRepMesh_IncrementalMesh`` (chordal deflection
``DEFLECTION_MM``); triangles are wound so their normals point out of the
material (the face's orientation says which way). A node coordinate below
``sampling.TINY_COORDINATE`` in magnitude (9.86e-31 from a cosine of 90
degrees) is zero. The last file's faces are kept: the loader and the
segmentation read the part once; ``camtool faces`` starts that read in a forked
child (``read_ahead``) while it imports the segmentation. A part of more than ``MAX_TRIANGLES``
triangles is refused in one line (issue 48: bounded memory).
"""
from __future__ import annotations

import logging
import os
import sys
import threading
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np

from ..errors import BadInput

log = logging.getLogger("camtool.step")
_fd_lock = threading.Lock()

DEFLECTION_MM = 0.05    # largest distance of the tessellation from the B-rep surface
ANGLE_RAD = 0.1         # largest angle between neighbouring triangles of one face
# (0.2 would tessellate a 2046-face assembly of small holes into 243 k triangles instead of 808 k, 2.2 s instead
# of 6.6 s, within the same deflection; but the edge pass then puts a boss's outline 2.6 mm past its top edge:
# tests/test_step.py::test_a_boss_all_round_keeps_its_outline_within_one_turn)
# The most triangles a part may tessellate into: the load and the segmentation take about 1 kB per triangle
# (a 2046-face SolidWorks assembly: 0.8 M triangles, 1.1 GB), so this keeps `camtool faces` within about 4 GB;
# a larger part is refused with one line instead of growing until the kernel kills the process.
MAX_TRIANGLES = 3_000_000


@dataclass(frozen=True)
class StepFace:
    """One B-rep face: its type ('plane', 'sphere', 'cylinder' or 'other'), exact parameters, triangles (mm).

    ``params``: plane (unit normal out of the material, offset_mm); sphere
    (centre, radius, concave); cylinder (axis point, unit axis, radius, concave); other: ().
    """

    model: str
    params: tuple
    vertices_mm: np.ndarray
    triangles: np.ndarray


@contextmanager
def _ocp_output_to_log() -> Iterator[None]:
    """OpenCASCADE prints its reader's messages on the process's stdout (file descriptor 1), which
    ``--json`` keeps for results: while it reads, fd 1 goes to a temporary file, logged at debug level."""
    from ..safe_io import anonymous_file

    with _fd_lock, anonymous_file() as sink:
        sys.stdout.flush()
        saved = os.dup(1)
        os.dup2(sink.fileno(), 1)
        try:
            yield
        finally:
            os.dup2(saved, 1)
            os.close(saved)
            sink.seek(0)
            text = sink.read().decode("utf-8", errors="replace").strip()
            if text:
                log.debug("OpenCASCADE: %s", text[:2000])


def _vec(p) -> np.ndarray:
    return np.array([p.X(), p.Y(), p.Z()], dtype=float)


# the last file read: (its path, size and modification time), its faces. The loader and the segmentation both
# read the part; OpenCASCADE's reading and tessellation are most of their time, so they are done once.
_LAST: dict = {}


def _nodes(tri, loc) -> np.ndarray:
    """The triangulation's nodes (n, 3) placed by the face's location, as ``gp_Pnt.Transformed`` places them
    (``gp_Trsf``: the matrix, the scale, then the translation), one array op per coordinate, not per node."""
    from OCP.gp import gp_Identity, gp_Translation

    xyz = np.array([(p.X(), p.Y(), p.Z()) for p in map(tri.Node, range(1, tri.NbNodes() + 1))], float).reshape(-1, 3)
    T = loc.Transformation()
    form = T.Form()
    if form == gp_Identity:
        return xyz
    t = _vec(T.TranslationPart())
    if form == gp_Translation:
        return xyz + t
    M = T.HVectorialPart()   # the rotation part; the scale apart
    m = np.array([[M.Value(r, c) for c in (1, 2, 3)] for r in (1, 2, 3)])
    x, y, z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    out = np.stack([m[r, 0] * x + m[r, 1] * y + m[r, 2] * z for r in range(3)], axis=1)
    s = T.ScaleFactor()
    if s != 1.0:
        out = out * s
    return out + t


def _file_key(path: Path) -> tuple | None:
    """What names one version of a file: its resolved path, device, inode, size and modification time."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return str(Path(path).resolve()), st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns


# a STEP file being read ahead in a forked child (``read_ahead``): its key and the child
_AHEAD: dict = {}


def read_ahead(path: Path) -> None:
    """Start reading and tessellating the STEP file ``path`` in a forked child (``alongside.Alongside``, where
    this process has a second CPU), while this process imports what comes after; ``read_step_faces`` of the
    same file (path, inode, size, modification time) takes the child's faces. OpenCASCADE is then imported in
    the child only; where this process has imported it already, the file is read here, when asked."""
    from ..alongside import Alongside
    from ..safe_io import held_input

    key = _file_key(path)
    if key is None or _LAST.get("key") == key or "OCP" in sys.modules:
        return   # (a child forked after OpenCASCADE meshed here would wait forever on its thread pool's threads)
    _drop_ahead()

    def read() -> list[StepFace]:
        with held_input(path, "workpiece"):   # (checked and read as load_workpiece does)
            return _read_step_faces(Path(path))

    child = Alongside(read)
    if child.forked:
        _AHEAD.update(key=key, child=child)


def _drop_ahead() -> None:
    child = _AHEAD.pop("child", None)
    _AHEAD.clear()
    if child is not None:
        child.cancel()


def read_step_faces(path: Path) -> list[StepFace]:
    """The faces of a STEP file, in the file's order; BadInput when it cannot be read.

    The last file's faces are kept (the same path, inode, size and modification time read again gives them),
    and a file read ahead (``read_ahead``) is taken from its child."""
    key = _file_key(path)
    if key is not None and _LAST.get("key") == key:
        return _LAST["faces"]
    if key is not None and _AHEAD.get("key") == key:
        child = _AHEAD.pop("child")
        _AHEAD.clear()
        try:
            faces = child.result()   # (what the child raised, raised here: a BadInput is the same one line)
        except RuntimeError:   # the child ended without a result: read here, as without it
            faces = _read_step_faces(path)
    else:
        _drop_ahead()
        faces = _read_step_faces(path)
    _LAST.clear()
    if key is not None:
        _LAST.update(key=key, faces=faces)
    return faces


def _read_step_faces(path: Path) -> list[StepFace]:
    try:
        from OCP.BRep import BRep_Tool
        from OCP.BRepAdaptor import BRepAdaptor_Surface
        from OCP.BRepMesh import BRepMesh_IncrementalMesh
        from OCP.GeomAbs import GeomAbs_Cylinder, GeomAbs_Plane, GeomAbs_Sphere
        from OCP.IFSelect import IFSelect_RetDone
        from OCP.STEPControl import STEPControl_Reader
        from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
        from OCP.TopExp import TopExp_Explorer
        from OCP.TopLoc import TopLoc_Location
        from OCP.TopoDS import TopoDS
    except ImportError:
        raise BadInput(f"{path}: STEP needs OCP: pip install cadquery-ocp-novtk (a camtool dependency; "
                       "reinstall camtool), or export the part as STL") from None
    from .sampling import TINY_COORDINATE

    reader = STEPControl_Reader()
    with _ocp_output_to_log():
        from ..safe_io import private_copy  # OCP reads a private copy of the checked descriptor, never the name

        with private_copy(path, "workpiece", ".step") as name:
            ok = reader.ReadFile(name) == IFSelect_RetDone
        ok = ok and reader.TransferRoots() > 0
        shape = reader.OneShape() if ok else None
        if ok:
            BRepMesh_IncrementalMesh(shape, DEFLECTION_MM, False, ANGLE_RAD, True)
    if not ok:
        raise BadInput(f"{path}: not a readable STEP file (OpenCASCADE could not transfer it); export it again")
    faces, total = [], 0
    explorer = TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        face = TopoDS.Face(explorer.Current())
        explorer.Next()
        loc = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(face, loc)
        if tri is None or tri.NbTriangles() == 0:
            continue
        total += tri.NbTriangles()
        if total > MAX_TRIANGLES:
            raise BadInput(f"{path}: the part tessellates into more than {MAX_TRIANGLES:,} triangles at "
                           f"{DEFLECTION_MM} mm (at face {len(faces) + 1}), more than camtool works in bounded "
                           "memory; export only the faces to work, or the part as STL at a coarser tolerance")
        verts = _nodes(tri, loc)
        # a coordinate below TINY_COORDINATE in magnitude is the tessellator's rounding of zero (e.g. 9.86e-31
        # from a cosine of 90 degrees): zero, not damage (NaN and infinity stay, and are refused by the loader)
        verts[np.abs(verts) < TINY_COORDINATE] = 0.0
        tris = np.array([tri.Triangle(i).Get() for i in range(1, tri.NbTriangles() + 1)], dtype=np.int64) - 1
        reversed_ = face.Orientation() == TopAbs_REVERSED
        if reversed_:
            tris = tris[:, ::-1]
        surf = BRepAdaptor_Surface(face)
        kind = surf.GetType()
        # the face's outward sense: the surface's own normal (flipped for a left-handed frame), then the orientation
        if kind == GeomAbs_Plane:
            pln = surf.Plane()
            n = _vec(pln.Axis().Direction()) * (1.0 if pln.Direct() else -1.0) * (-1.0 if reversed_ else 1.0)
            model, params = "plane", (n, float(n @ _vec(pln.Location())))
        elif kind == GeomAbs_Cylinder:
            cyl = surf.Cylinder()
            outward = cyl.Direct() != reversed_  # the surface normal of a direct cylinder points away from the axis
            a = _vec(cyl.Position().Direction())
            model, params = "cylinder", (_vec(cyl.Location()), a, float(cyl.Radius()), not outward)
        elif kind == GeomAbs_Sphere:
            sph = surf.Sphere()
            outward = sph.Direct() != reversed_
            model, params = "sphere", (_vec(sph.Location()), float(sph.Radius()), not outward)
        else:
            model, params = "other", ()
        faces.append(StepFace(model, params, verts, tris))
    if not faces:
        raise BadInput(f"{path}: the STEP file holds no faces; export the part as a solid or surfaces")
    return faces


def step_mesh(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertices mm, triangles, face index of each triangle) of the whole part."""
    faces = read_step_faces(path)
    verts, tris, owner, at = [], [], [], 0
    for k, f in enumerate(faces):
        verts.append(f.vertices_mm)
        tris.append(f.triangles + at)
        owner.append(np.full(len(f.triangles), k))
        at += len(f.vertices_mm)
    return np.vstack(verts), np.vstack(tris), np.concatenate(owner)
