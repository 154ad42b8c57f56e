"""The buffers a ``.gltf`` names beside it, read through ``safe_io`` like the file itself.

A ``.gltf`` is JSON that names its binary buffers and images by relative URI. trimesh asks a
resolver for each; its own resolver opens ``folder/name`` by name, following links and any ``..``.
This one hands back only a plain file inside the ``.gltf``'s own folder (no absolute path, no ``..``,
no link, a regular file under the workpiece cap, opened once), and refuses anything else in one line.
"""
from __future__ import annotations

from pathlib import Path, PurePosixPath
from urllib.parse import unquote

import trimesh.resolvers

from ..errors import BadInput


class CheckedBuffers(trimesh.resolvers.Resolver):
    """A read-only trimesh resolver over ``folder`` for the ``.gltf`` named ``source``."""

    def __init__(self, folder: Path, source: str):
        self.folder = Path(folder)
        self.source = source

    def _path(self, name: str) -> Path:
        rel = PurePosixPath(unquote(str(name)))
        if rel.is_absolute() or not rel.parts or any(part in ("..", "") for part in rel.parts) \
                or ":" in rel.parts[0]:
            raise BadInput(f"{self.folder / self.source}: names a buffer outside its own folder "
                           f"({len(str(name))} characters); keep buffers beside the .gltf or export a .glb")
        return self.folder.joinpath(*rel.parts)

    def get(self, key):
        """The bytes of buffer ``key`` (checked: see the module docstring)."""
        from ..safe_io import read_input_bytes

        path = self._path(key)
        for parent in [path, *path.parents]:
            if parent == self.folder:
                break
            if parent.is_symlink():
                raise BadInput(f"{self.folder / self.source}: a buffer's path holds a symlink; "
                               "camtool does not follow links beside a workpiece")
        return read_input_bytes(path, "workpiece")

    def write(self, name: str, data):
        raise BadInput("camtool never writes beside a workpiece")

    def namespaced(self, namespace: str):
        return CheckedBuffers(self._path(namespace), self.source)

    def keys(self):
        return []
