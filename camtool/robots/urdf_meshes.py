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
- Pinocchio then parses the same text with each filename replaced by the
  absolute path that was checked (``buildGeomFromUrdfString``), so it opens
  only those files.
"""
from __future__ import annotations

import os
import stat
import xml.etree.ElementTree as ET
from pathlib import Path

from ..errors import BadInput

PACKAGE = "package://"
FILE = "file://"


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


def checked_collision_urdf(urdf_path: Path, package_dirs, data: bytes | None = None) -> str:
    """The URDF's text (``data``, the checked bytes, or read through safe_io) with every collision mesh
    filename replaced by the absolute path of its checked file; BadInput naming the link and the mesh
    when one is missing or refused."""
    from ..safe_io import read_input_bytes

    urdf_path = Path(urdf_path)
    try:
        root = ET.fromstring(read_input_bytes(urdf_path, "robot") if data is None else data)
    except ET.ParseError as exc:
        raise BadInput(f"{urdf_path}: not a URDF: XML error ({exc})") from None
    for link in root.findall("link"):
        for mesh in link.findall("collision/geometry/mesh"):
            filename = mesh.get("filename") or ""
            where = f"{urdf_path}: link {link.get('name')!r} collision mesh {filename!r}"
            path = resolve_mesh(filename, urdf_path, package_dirs)
            if path is None:
                raise BadInput(f"{where}: file not found (package folders searched: "
                               f"{', '.join(str(d) for d in package_dirs) or 'none'})")
            why = _refusal(path)
            if why is not None:
                raise BadInput(f"{where}: {path} {why}")
            mesh.set("filename", str(Path(os.path.abspath(path))))
    return ET.tostring(root, encoding="unicode")


def collision_geometry(model, urdf_path: Path, package_dirs, data: bytes | None = None):
    """Pinocchio's collision GeometryModel of a URDF whose meshes were checked first (``data``: the
    URDF's checked bytes, when the caller already read them)."""
    import pinocchio as pin

    text = checked_collision_urdf(urdf_path, package_dirs, data)
    try:
        return pin.buildGeomFromUrdfString(model, text, pin.GeometryType.COLLISION,
                                           package_dirs=[str(d) for d in package_dirs])
    except Exception as exc:  # a mesh assimp cannot parse: one line for the user
        raise BadInput(f"{urdf_path}: cannot read its collision meshes "
                       f"({(str(exc).splitlines() or [''])[0]})") from None
