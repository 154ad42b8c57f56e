"""Save and load stage boxes, so a user can stop after any stage, inspect, edit and resume.

One format for every box (``Path``, ``JointPath``, ``Trajectory`` and
``TimedTrajectory``): a NumPy ``.npz`` archive holding

- ``header``: a JSON document (as a 0-d unicode array) with
  ``{"format": "camtool-stage", "version": 1, "kind": "<class name>",
  "fields": {name: JSON value}}`` for every field that is not an array;
- one entry per array field, under the field's name, bit for bit.

Arrays round-trip exactly and JSON floats are written with ``repr``, so a
resumed stage reproduces the run's programs byte for byte. Fields marked
``metadata={"transient": True}`` (caches) are not saved. Surfaces keep their
JSON format (``camtool.part.surface.save_surface``, versioned the same way). See
docs/stage-files.md.
"""
from __future__ import annotations

import dataclasses
import io
import json
import os
from pathlib import Path as FsPath

import numpy as np

from .. import safe_io
from ..errors import BadInput
from ..files import output_file
from ..timing import TimedTrajectory
from ..path.toolpath import ZONES, Path
from ..trajectory import JointPath, Trajectory

FORMAT = "camtool-stage"
VERSION = 1
KINDS = {cls.__name__: cls for cls in (Path, JointPath, Trajectory, TimedTrajectory)}
STAGE_OF_KIND = {"Path": "raster", "JointPath": "plan", "Trajectory": "time", "TimedTrajectory": "time"}


def _jsonable(x):
    if isinstance(x, np.ndarray):
        return {"__array__": x.tolist(), "dtype": str(x.dtype)}
    if isinstance(x, (np.bool_,)):
        return bool(x)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.floating):
        return float(x)
    if isinstance(x, tuple):
        return {"__tuple__": [_jsonable(v) for v in x]}
    if isinstance(x, list):
        return [_jsonable(v) for v in x]
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    return x


def _restore(x):
    if isinstance(x, dict):
        if "__array__" in x:
            dtype = np.dtype(str(x.get("dtype")))
            if dtype.kind not in "biuf" or dtype.itemsize > 16:  # real numbers only: no objects, no huge voids
                raise TypeError("array dtype")
            return np.asarray(x["__array__"], dtype=dtype)
        if "__tuple__" in x:
            return tuple(_restore(v) for v in x["__tuple__"])
        return {k: _restore(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_restore(v) for v in x]
    return x


def save_stage(box, file: str | FsPath) -> FsPath:
    """Write a stage box (Path, JointPath, Trajectory, TimedTrajectory) to ``.npz``; returns the file."""
    kind = type(box).__name__
    if kind not in KINDS:
        raise TypeError(f"cannot save a {kind}")
    arrays, values = {}, {}
    for f in dataclasses.fields(box):
        if f.metadata.get("transient"):
            continue
        v = getattr(box, f.name)
        if isinstance(v, np.ndarray) and v.dtype != object:
            arrays[f.name] = v
        else:
            values[f.name] = _jsonable(v)
    header = {"format": FORMAT, "version": VERSION, "kind": kind, "fields": values}
    if kind == "Path":
        header["zones"] = list(ZONES)
    file = output_file(file)
    buf = io.BytesIO()
    np.savez_compressed(buf, header=np.array(json.dumps(header, allow_nan=True)), **arrays)
    # created O_EXCL|O_NOFOLLOW in a private folder, then renamed: never half-written, never through a link
    return safe_io.write_file(file.parent, file.name, buf.getvalue())


def load_stage(file: str | FsPath, expect: tuple[str, ...] = ()):
    """Read a stage box saved by ``save_stage``; BadInput naming the file when it is not one (of ``expect``)."""
    file = FsPath(file)
    if not os.path.lexists(file):
        raise BadInput(f"{file}: stage file not found")
    # a regular file under the cap, read once (no FIFO hang); inflated size capped before any allocation
    arrays = safe_io.load_npz(safe_io.read_input_bytes(file, "stage"), f"{file}: not a camtool stage file:",
                              safe_io.size_cap_bytes("stage"))
    head = arrays.pop("header", None)
    if head is None or head.ndim != 0 or head.dtype.kind != "U":
        raise BadInput(f"{file}: not a camtool stage file (no JSON header)")
    header = safe_io.load_json(str(head), f"{file}: the stage file's header")
    if not isinstance(header, dict) or header.get("format") != FORMAT or not isinstance(header.get("kind"), str) \
            or header["kind"] not in KINDS:
        raise BadInput(f"{file}: not a camtool stage file")
    version = header.get("version")
    if version != VERSION or isinstance(version, bool):
        shown = version if isinstance(version, int) and abs(version) < 10**9 else f"({type(version).__name__})"
        raise BadInput(f"{file}: stage file version {shown} is not supported "
                       f"(this camtool reads version {VERSION}); rerun the stage")
    kind = header["kind"]
    if expect and kind not in expect:
        raise BadInput(f"{file}: holds a {kind} (the {STAGE_OF_KIND[kind]} stage's output), "
                       f"expected {' or '.join(expect)}")
    zones = header.get("zones", ())
    if kind == "Path" and (not isinstance(zones, list) or tuple(zones) != ZONES):
        raise BadInput(f"{file}: path file's zone labels are not {list(ZONES)}")
    if not isinstance(header.get("fields"), dict):
        raise BadInput(f"{file}: the stage file's header has no fields table; the file is damaged")
    cls = KINDS[kind]
    try:
        values = {k: _restore(v) for k, v in header["fields"].items()}
    except (TypeError, ValueError, KeyError, OverflowError, MemoryError, RecursionError) as exc:
        raise BadInput(f"{file}: a field of the {kind} in it is damaged ({type(exc).__name__})") from None
    names = {f.name for f in dataclasses.fields(cls) if f.init}
    missing = [n for n in names if n not in values and n not in arrays
               and next(f for f in dataclasses.fields(cls) if f.name == n).default is dataclasses.MISSING
               and next(f for f in dataclasses.fields(cls) if f.name == n).default_factory is dataclasses.MISSING]
    if missing:
        raise BadInput(f"{file}: {kind} file lacks {', '.join(sorted(missing))}")
    kwargs = {k: v for k, v in {**values, **arrays}.items() if k in names}
    _check_rows(file, kind, kwargs)
    try:
        return cls(**kwargs)
    except (TypeError, ValueError, KeyError, IndexError, AttributeError, OverflowError) as exc:
        raise BadInput(f"{file}: the {kind} in it is damaged ({type(exc).__name__})") from None


# per-row arrays of each box: the same length, and their shapes past the first axis
ROWS = {"Path": {"poses_mm": (4, 4), "segment": (), "point": (), "zone": ()},
        "JointPath": {"q": None, "path_index": (), "zone": (), "position_error_mm": (), "orientation_error_rad": (),
                      "jump": (), "reverse_planned": (), "retract": (), "singular": (), "reached": ()},
        "Trajectory": {"t_s": (), "q": None, "qd": None, "qdd": None, "zone": (), "path_index": ()}}
ROWS["TimedTrajectory"] = ROWS["Trajectory"]


def _check_rows(file, kind: str, fields: dict) -> None:
    """BadInput unless the box's per-row arrays agree in length and shape and hold finite numbers."""
    n = None
    for name, tail in ROWS[kind].items():
        a = fields.get(name)
        if not isinstance(a, np.ndarray) or a.dtype.kind not in "biuf":
            what = type(a).__name__ if not isinstance(a, np.ndarray) else f"{a.dtype.kind!r}-kind values"
            raise BadInput(f"{file}: {kind}.{name} holds {what}, not real numbers; the file is damaged")
        if a.ndim == 0 or (tail is not None and a.shape[1:] != tail) or (tail is None and a.ndim != 2):
            raise BadInput(f"{file}: {kind}.{name} has shape {a.shape}; the file is damaged")
        if n is None:
            n = len(a)
        elif len(a) != n:
            raise BadInput(f"{file}: {kind}.{name} has {len(a)} rows, {n} expected; the file is damaged")
        if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
            raise BadInput(f"{file}: {kind}.{name} holds NaN or infinite values; the file is damaged")
    if n == 0:
        raise BadInput(f"{file}: the {kind} in it is empty")
