"""A URDF's collision meshes, checked before Pinocchio opens them.

Pinocchio's ``buildGeomFromUrdf`` opens every ``<collision>`` mesh itself
(assimp), before camtool's loaders see it: a mesh named in a hostile or
broken description could be a symlink, a FIFO that blocks the run, a device
or a file of any size, and a missing one gives assimp's message, which does
not name the link. So the description is read here first:

- each ``<collision><geometry><mesh filename>`` is resolved the way ROS does:
  ``package://<pkg>/<rest>`` in the first package folder that holds
  ``<pkg>/<rest>``, ``file://<path>`` and plain paths as they are, relative
  ones against the URDF's folder;
- the file must exist, not be a symlink, be a regular file (opened without
  blocking) and be under the mesh size cap; otherwise one line names the
  link, the mesh and what is wrong;
- Pinocchio then parses the same text with each mesh replaced by a point-sized
  sphere (``buildGeomFromUrdfString``), so it opens no file at all: it gives
  the placements and parent joints, and camtool reads each checked mesh itself
  (through the workpiece loader's descriptor checks). ``CollisionGeometry``
  keeps, per geometry object, the checked file and its scale.
"""
from __future__ import annotations

import os
import stat
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from ..errors import BadInput

PACKAGE = "package://"
FILE = "file://"
PLACEHOLDER = '<sphere radius="1e-9"/>'  # what Pinocchio parses in a mesh's place: no file to open


@dataclass(frozen=True)
class CollisionMesh:
    """A checked collision mesh file and the URDF's scale for it (unitless, per axis)."""

    path: Path
    scale: tuple[float, float, float]


@dataclass(frozen=True)
class CollisionGeometry:
    """Pinocchio's collision GeometryModel (each mesh a point-sized sphere) and, per geometry object
    in its order, the mesh it stands for (None: a box, cylinder or sphere of the URDF itself)."""

    model: object
    meshes: tuple[CollisionMesh | None, ...]


def resolve_mesh(filename: str, urdf_path: Path, package_dirs) -> Path | None:
    """The file a URDF mesh filename names (module docstring); None when no candidate exists."""
    if filename.startswith(PACKAGE):
        rest = filename[len(PACKAGE):]
        for folder in package_dirs:
            candidate = Path(folder) / rest
            if os.path.lexists(candidate):
                return candidate
        return None
    name = filename[len(FILE):] if filename.startswith(FILE) else filename
    path = Path(name)
    path = path if path.is_absolute() else Path(urdf_path).parent / path
    return path if os.path.lexists(path) else None


def _refusal(path: Path) -> str | None:
    """Why camtool will not let a library open ``path`` (None: a regular file under the cap)."""
    from ..safe_io import check_input

    if stat.S_ISLNK(os.lstat(path).st_mode):
        return "is a symlink; camtool does not follow links in a robot description"
    try:
        check_input(path, "workpiece")   # O_NONBLOCK open: regular file, size cap
    except BadInput as exc:
        return str(exc).split(": ", 1)[-1]
    return None


def _scale(mesh, where: str) -> tuple[float, float, float]:
    text = (mesh.get("scale") or "1 1 1").split()
    try:
        values = tuple(float(v) for v in text)
    except ValueError:
        values = ()
    if len(values) != 3 or not all(0.0 < abs(v) < 1e6 for v in values):
        raise BadInput(f"{where}: scale must be three finite non-zero numbers")
    return values


def checked_collision_urdf(urdf_path: Path, package_dirs, data: bytes | None = None
                           ) -> tuple[str, dict[str, list[CollisionMesh | None]]]:
    """The URDF's text (``data``, the checked bytes, or read through safe_io) with every collision mesh
    replaced by ``PLACEHOLDER``, and per link its collision elements' checked meshes in order (None for
    a primitive); BadInput naming the link and the mesh when one is missing or refused."""
    from ..safe_io import read_input_bytes

    urdf_path = Path(urdf_path)
    try:
        root = ET.fromstring(read_input_bytes(urdf_path, "robot") if data is None else data)
    except ET.ParseError as exc:
        raise BadInput(f"{urdf_path}: not a URDF: XML error ({exc})") from None
    meshes: dict[str, list[CollisionMesh | None]] = {}
    for link in root.findall("link"):
        found = meshes.setdefault(link.get("name") or "", [])
        for collision in link.findall("collision"):
            geometry = collision.find("geometry")
            mesh = geometry.find("mesh") if geometry is not None else None
            if mesh is None:
                found.append(None)
                continue
            filename = mesh.get("filename") or ""
            where = f"{urdf_path}: link {link.get('name')!r} collision mesh {filename!r}"
            path = resolve_mesh(filename, urdf_path, package_dirs)
            if path is None:
                raise BadInput(f"{where}: file not found (package folders searched: "
                               f"{', '.join(str(d) for d in package_dirs) or 'none'})")
            why = _refusal(path)
            if why is not None:
                raise BadInput(f"{where}: {path} {why}")
            found.append(CollisionMesh(Path(os.path.abspath(path)), _scale(mesh, where)))
            geometry.remove(mesh)
            geometry.append(ET.fromstring(PLACEHOLDER))
    return ET.tostring(root, encoding="unicode"), meshes


def collision_geometry(model, urdf_path: Path, package_dirs, data: bytes | None = None) -> CollisionGeometry:
    """The collision geometry of a URDF whose meshes were checked first (``data``: the URDF's checked
    bytes, when the caller already read them); Pinocchio opens no file."""
    import pinocchio as pin

    text, meshes = checked_collision_urdf(urdf_path, package_dirs, data)
    try:
        gm = pin.buildGeomFromUrdfString(model, text, pin.GeometryType.COLLISION)
    except Exception as exc:  # a description Pinocchio cannot place: one line for the user
        raise BadInput(f"{urdf_path}: cannot read its collision elements "
                       f"({(str(exc).splitlines() or [''])[0]})") from None
    # Pinocchio adds each link's collision elements together, in the URDF's order
    taken: dict[str, int] = {}
    per_object = []
    for go in gm.geometryObjects:
        link = model.frames[go.parentFrame].name if go.parentFrame < len(model.frames) else ""
        k = taken.get(link, 0)
        taken[link] = k + 1
        found = meshes.get(link, [])
        per_object.append(found[k] if k < len(found) else None)
    return CollisionGeometry(gm, tuple(per_object))
