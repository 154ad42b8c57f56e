"""``[[cell.obstacles]]`` of a job: validation of each entry (docs/job-file.md, "Obstacles").

Each entry is a table with ``name``, exactly one shape (``mesh`` with
``units``, ``box_mm``, ``cylinder_mm`` or ``sphere_mm``), ``xyz_mm``,
``rpy_deg`` and ``frame`` ("world" or "workpiece"). Errors name the entry and
the key, like every other job key.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

from ..errors import BadInput, closest

SHAPE_KEYS = ("mesh", "box_mm", "cylinder_mm", "sphere_mm")
OBSTACLE_KEYS = ("name",) + SHAPE_KEYS + ("units", "xyz_mm", "rpy_deg", "frame")
FRAMES = ("world", "workpiece")
UNITS = ("mm", "m", "in")
MAX_SIZE_MM = 1e5          # no obstacle is larger than 100 m
MAX_OBSTACLES = 1000
NAME_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_ .-]{0,63}$")


@dataclass(frozen=True)
class ObstacleSpec:
    """One obstacle as the job states it (lengths mm, angles deg)."""

    name: str
    shape: str                      # "mesh" | "box" | "cylinder" | "sphere"
    size_mm: tuple[float, ...]      # box (x, y, z); cylinder (radius, length); sphere (radius,); mesh ()
    mesh: str = ""
    units: str = "mm"
    xyz_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    frame: str = "world"


def _number(x) -> bool:
    return not isinstance(x, bool) and isinstance(x, (int, float)) and math.isfinite(x)


def _sizes(value, n: int, where: str, what: str) -> tuple[float, ...]:
    vals = [value] if n == 1 and not isinstance(value, (list, tuple)) else value
    if not (isinstance(vals, (list, tuple)) and len(vals) == n and all(_number(x) for x in vals)
            and all(0 < x <= MAX_SIZE_MM for x in vals)):
        raise BadInput(f"{where}: expected {what}, each in (0, {MAX_SIZE_MM:g}] mm, found {value!r}")
    return tuple(float(x) for x in vals)


def _vec3(value, where: str, bound: float, unit: str) -> tuple[float, float, float]:
    if not (isinstance(value, (list, tuple)) and len(value) == 3 and all(_number(x) for x in value)
            and all(abs(x) <= bound for x in value)):
        raise BadInput(f"{where}: expected a list of 3 numbers within +-{bound:g} {unit}, found {value!r}")
    return tuple(float(x) for x in value)


def parse_obstacles(value, where: str) -> list[dict]:
    """Validate ``cell.obstacles`` (a list of tables); returns the entries with defaults filled."""
    if not isinstance(value, list) or not all(isinstance(e, dict) for e in value):
        raise BadInput(f"{where}: expected [[cell.obstacles]] tables, found {value!r}")
    if len(value) > MAX_OBSTACLES:
        raise BadInput(f"{where}: at most {MAX_OBSTACLES} obstacles, found {len(value)}")
    out, names = [], set()
    for i, entry in enumerate(value):
        w = f"{where}[{i}]"
        for k in entry:
            if k not in OBSTACLE_KEYS:
                raise BadInput(f"{w}.{k}: unknown key{closest(k, OBSTACLE_KEYS)} (expected one of "
                               f"{', '.join(OBSTACLE_KEYS)})")
        name = entry.get("name")
        if not isinstance(name, str) or not NAME_RE.match(name):
            raise BadInput(f"{w}.name: expected a name of 1-64 letters, digits, spaces, '_', '-' or '.', "
                           f"found {name!r}")
        if name in names:
            raise BadInput(f"{w}.name: {name!r} names two obstacles; names must be distinct")
        names.add(name)
        w = f"{where}[{i}] ({name})"
        shapes = [k for k in SHAPE_KEYS if k in entry]
        if len(shapes) != 1:
            raise BadInput(f"{w}: expected exactly one shape key of {', '.join(SHAPE_KEYS)}, found "
                           f"{', '.join(shapes) or 'none'}")
        kind = shapes[0]
        units = entry.get("units", "mm")
        if "units" in entry and kind != "mesh":
            raise BadInput(f"{w}.units: only a mesh obstacle has units ({kind} is in mm)")
        if units not in UNITS:
            raise BadInput(f"{w}.units: expected one of {', '.join(map(repr, UNITS))}, found {units!r}")
        mesh = ""
        if kind == "mesh":
            mesh = entry["mesh"]
            if not isinstance(mesh, str) or not mesh.strip():
                raise BadInput(f"{w}.mesh: expected a mesh file name (STL, OBJ, PLY, OFF), found {mesh!r}")
            size = ()
        elif kind == "box_mm":
            size = _sizes(entry[kind], 3, f"{w}.box_mm", "a list of 3 edge lengths [x, y, z]")
        elif kind == "cylinder_mm":
            size = _sizes(entry[kind], 2, f"{w}.cylinder_mm", "[radius, length]")
        else:
            size = _sizes(entry[kind], 1, f"{w}.sphere_mm", "a radius")
        xyz = _vec3(entry.get("xyz_mm", [0.0, 0.0, 0.0]), f"{w}.xyz_mm", 1e6, "mm")
        rpy = _vec3(entry.get("rpy_deg", [0.0, 0.0, 0.0]), f"{w}.rpy_deg", 3600.0, "deg")
        frame = entry.get("frame", "world")
        if frame not in FRAMES:
            raise BadInput(f"{w}.frame: expected one of {', '.join(map(repr, FRAMES))}, found {frame!r}")
        out.append({"name": name, kind: (list(size) if kind in ("box_mm", "cylinder_mm") else
                                          size[0] if kind == "sphere_mm" else mesh),
                    "units": units, "xyz_mm": list(xyz), "rpy_deg": list(rpy), "frame": frame})
    return out


def obstacle_specs(entries: list[dict]) -> tuple[ObstacleSpec, ...]:
    """ObstacleSpec of each validated entry (``parse_obstacles``)."""
    specs = []
    for e in entries:
        kind = next(k for k in SHAPE_KEYS if k in e)
        size = (() if kind == "mesh" else tuple(e[kind]) if isinstance(e[kind], list) else (float(e[kind]),))
        specs.append(ObstacleSpec(e["name"], kind.removesuffix("_mm"), size, e.get("mesh", "") if kind == "mesh"
                                  else "", e["units"], tuple(e["xyz_mm"]), tuple(e["rpy_deg"]), e["frame"]))
    return tuple(specs)


def parse_pairs(value, where: str) -> list[list[str]]:
    """Validate a list of body-name pairs (``cell.allow_collision`` / ``cell.check_collision``)."""
    ok = isinstance(value, list) and all(isinstance(p, list) and len(p) == 2 and all(isinstance(x, str) and x
                                                                                      for x in p) for p in value)
    if not ok:
        raise BadInput(f"{where}: expected a list of [body, body] name pairs, found {value!r}")
    return [list(p) for p in value]
