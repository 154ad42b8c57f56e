"""Controller profiles: how a robot's joints appear on one controller (TOML).

A profile says which robot joint drives which controller axis (with sign,
offset, unit, pulses per unit and maximum speed), the program name, tool and
work-object data, and the plugin's options (zones, split thresholds, ...).
Defaults for the built-in robots ship beside this module, in ``profile_data/``, as
``<robot>_<format>.toml``; docs/controllers.md describes every key. This one module
parses a profile, holds its defaults and loads it for a plugin (``load_profile``: the
plugin's options schema and ``validate_profile``). Layout::

    format = "rapid"                  # the post-processor this profile is for
    robot = "seed8"                   # optional: refuse other robots
    program_name = "CAMTOOL"          # optional; the job's post.program_name wins
    [axes]                            # one entry per robot joint
    j2 = { axis = "rax_1", sign = 1, offset = 0.0, unit = "deg", pulses = 1341.38, zero_pulses = 0, max_speed = 120.0 }
    [tool]                            # name, tcp_xyz_mm, tcp_rpy_deg, mass_kg, cog_mm, number
    [wobj]                            # name, xyz_mm, rpy_deg
    [options]                         # the plugin's options_schema

Controller axis value = sign * (joint in deg or mm) + offset; for pulse
formats, pulses = round(value * pulses) + zero_pulses.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import BadInput
from .plugin import PostProcessor

_TOP = {"format", "robot", "program_name", "axes", "tool", "wobj", "options", "notes"}
_AXIS = {"axis", "sign", "offset", "unit", "pulses", "zero_pulses", "max_speed"}
_TOOL = {"name": "tool0", "tcp_xyz_mm": [0.0, 0.0, 0.0], "tcp_rpy_deg": [0.0, 0.0, 0.0],
         "mass_kg": 1.0, "cog_mm": [0.0, 0.0, 0.0], "number": 0}
_WOBJ = {"name": "wobj0", "xyz_mm": [0.0, 0.0, 0.0], "rpy_deg": [0.0, 0.0, 0.0]}


@dataclass(frozen=True)
class AxisMap:
    """One robot joint on one controller axis.

    ``value = sign * joint + offset`` in ``unit`` (deg or mm); ``pulses`` per
    deg or mm and ``zero_pulses`` for pulse formats; ``max_speed`` in unit/s.
    """

    joint: str
    axis: str
    sign: int = 1
    offset: float = 0.0
    unit: str = "deg"
    pulses: float | None = None
    zero_pulses: int = 0
    max_speed: float | None = None


@dataclass(frozen=True)
class Profile:
    """A validated controller profile (see module doc)."""

    source: str
    format: str
    robot: str = ""
    program_name: str = "CAMTOOL"
    axes: tuple[AxisMap, ...] = ()
    tool: dict = field(default_factory=lambda: dict(_TOOL))
    wobj: dict = field(default_factory=lambda: dict(_WOBJ))
    options: dict = field(default_factory=dict)

    def axis_for(self, joint: str) -> AxisMap | None:
        """The axis map entry of a joint, or None."""
        return next((a for a in self.axes if a.joint == joint), None)

    def with_changes(self, **changes) -> "Profile":
        """A copy with some fields replaced (tool/options/wobj are merged, not replaced)."""
        merged = {"tool": self.tool, "wobj": self.wobj, "options": self.options}
        for k, current in merged.items():
            if k in changes:
                changes[k] = {**current, **changes[k]}
        return replace(self, **changes)

    def to_axes(self, q_native: np.ndarray, robot) -> dict[str, np.ndarray]:
        """Controller axis values (deg / mm) per axis name for M x dof joint values."""
        out = {}
        for a in self.axes:
            i = robot.joint_names.index(a.joint)
            v = q_native[:, i] if robot.prismatic[i] else np.degrees(q_native[:, i])
            out[a.axis] = a.sign * v + a.offset
        return out

    def from_axes(self, values: dict[str, np.ndarray], robot) -> np.ndarray:
        """Inverse of ``to_axes``: M x dof joint values (rad / mm) from axis values."""
        n = len(next(iter(values.values()))) if values else 0
        q = np.zeros((n, robot.dof))
        for a in self.axes:
            i = robot.joint_names.index(a.joint)
            v = (np.asarray(values[a.axis], float) - a.offset) / a.sign
            q[:, i] = v if robot.prismatic[i] else np.radians(v)
        return q


def default_profile_path(robot_name: str, fmt: str) -> Path | None:
    """The shipped default profile for a robot and format, or None."""
    p = resources.files("camtool.program").joinpath("profile_data", f"{robot_name}_{fmt}.toml")
    return Path(str(p)) if p.is_file() else None


def _num(v) -> bool:
    return not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)


def _check_options(raw: dict, schema: dict, where: str) -> dict:
    out = {k: default for k, (_typ, default, _doc) in schema.items()}
    for k, v in raw.items():
        if k not in schema:
            raise BadInput(f"{where}.{k}: unknown option (expected one of {', '.join(schema) or 'none'})")
        typ = schema[k][0]
        ok = (_num(v) if typ is float else
              isinstance(v, int) and not isinstance(v, bool) if typ is int else isinstance(v, typ))
        if not ok:
            raise BadInput(f"{where}.{k}: expected {typ.__name__}, found {v!r}")
        out[k] = float(v) if typ is float else v
    return out


def parse_profile(data: dict, source: str, fmt: str, robot=None, options_schema: dict | None = None) -> Profile:
    """Validate parsed profile TOML; errors name the file and key."""
    bad = set(data) - _TOP
    if bad:
        raise BadInput(f"{source}: {sorted(bad)[0]}: unknown key (expected one of {', '.join(sorted(_TOP))})")
    if data.get("format", fmt) != fmt:
        raise BadInput(f"{source}: format: this profile is for {data['format']!r}, not {fmt!r}")
    rname = data.get("robot", "")
    if not isinstance(rname, str):
        raise BadInput(f"{source}: robot: expected a robot name, found {rname!r}")
    if robot is not None and rname and rname != robot.name:
        raise BadInput(f"{source}: robot: this profile is for robot {rname!r}, not {robot.name!r}")
    pname = data.get("program_name", "CAMTOOL")
    if not isinstance(pname, str) or not pname:
        raise BadInput(f"{source}: program_name: expected a non-empty string, found {pname!r}")
    axes_raw = data.get("axes", {})
    if not isinstance(axes_raw, dict):
        raise BadInput(f"{source}: axes: expected a table of joint = {{axis = ...}}")
    axes, used = [], {}
    for joint, spec in axes_raw.items():
        where = f"{source}: axes.{joint}"
        if robot is not None and joint not in robot.joint_names:
            raise BadInput(f"{where}: robot {robot.name} has no joint {joint!r} "
                           f"(its joints: {', '.join(robot.joint_names)})")
        if not isinstance(spec, dict):
            raise BadInput(f"{where}: expected a table {{axis = ..., unit = ...}}, found {spec!r}")
        bad = set(spec) - _AXIS
        if bad:
            raise BadInput(f"{where}.{sorted(bad)[0]}: unknown key (expected {', '.join(sorted(_AXIS))})")
        axis = spec.get("axis")
        if not isinstance(axis, str) or not axis:
            raise BadInput(f"{where}.axis: expected a controller axis name, found {axis!r}")
        if axis in used:
            raise BadInput(f"{where}.axis: {axis!r} is already used by joint {used[axis]!r}")
        used[axis] = joint
        sign = spec.get("sign", 1)
        if sign not in (1, -1) or isinstance(sign, bool):
            raise BadInput(f"{where}.sign: expected 1 or -1, found {sign!r}")
        unit = spec.get("unit", "deg")
        if unit not in ("deg", "mm"):
            raise BadInput(f"{where}.unit: expected 'deg' or 'mm', found {unit!r}")
        if robot is not None:
            want = "mm" if robot.prismatic[robot.joint_names.index(joint)] else "deg"
            if unit != want:
                raise BadInput(f"{where}.unit: joint {joint} is {'prismatic' if want == 'mm' else 'revolute'}, "
                               f"so its unit is {want!r}, found {unit!r}")
        for k in ("offset", "pulses", "max_speed"):
            if k in spec and not _num(spec[k]):
                raise BadInput(f"{where}.{k}: expected a number, found {spec[k]!r}")
        for k in ("pulses", "max_speed"):
            if k in spec and spec[k] <= 0:
                raise BadInput(f"{where}.{k}: expected a number > 0, found {spec[k]!r}")
        zp = spec.get("zero_pulses", 0)
        if isinstance(zp, bool) or not isinstance(zp, int):
            raise BadInput(f"{where}.zero_pulses: expected an integer, found {zp!r}")
        axes.append(AxisMap(joint, axis, int(sign), float(spec.get("offset", 0.0)), unit,
                            float(spec["pulses"]) if "pulses" in spec else None, zp,
                            float(spec["max_speed"]) if "max_speed" in spec else None))
    tool = _table(data.get("tool", {}), _TOOL, f"{source}: tool")
    wobj = _table(data.get("wobj", {}), _WOBJ, f"{source}: wobj")
    opts = data.get("options", {})
    if not isinstance(opts, dict):
        raise BadInput(f"{source}: options: expected a table")
    options = _check_options(opts, options_schema or {}, f"{source}: options") if options_schema is not None else dict(opts)
    return Profile(source, fmt, rname, pname, tuple(axes), tool, wobj, options)


def _table(raw, defaults: dict, where: str) -> dict:
    if not isinstance(raw, dict):
        raise BadInput(f"{where}: expected a table")
    out = dict(defaults)
    for k, v in raw.items():
        if k not in defaults:
            raise BadInput(f"{where}.{k}: unknown key (expected one of {', '.join(defaults)})")
        d = defaults[k]
        if isinstance(d, list):
            if not (isinstance(v, list) and len(v) == len(d) and all(_num(x) for x in v)):
                raise BadInput(f"{where}.{k}: expected a list of {len(d)} numbers, found {v!r}")
            v = [float(x) for x in v]
        elif isinstance(d, str):
            if not isinstance(v, str) or not v:
                raise BadInput(f"{where}.{k}: expected a non-empty string, found {v!r}")
        elif isinstance(d, int) and not isinstance(d, bool) and not isinstance(d, float) and k == "number":
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise BadInput(f"{where}.{k}: expected an integer >= 0, found {v!r}")
        elif not _num(v) or v < 0:
            raise BadInput(f"{where}.{k}: expected a number >= 0, found {v!r}")
        out[k] = v
    return out


def read_profile_file(path: str | Path) -> dict:
    """The parsed TOML of a profile file; BadInput naming the file when it cannot be read."""
    path = Path(path)
    from ..safe_io import load_toml  # one checked read: a FIFO or /dev/zero is one line, never a hang

    try:
        return load_toml(path, "profile")
    except FileNotFoundError:
        raise BadInput(f"{path}: profile file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise BadInput(f"{path}: cannot read profile ({exc})") from None


def require_full_map(profile: Profile, robot) -> None:
    """BadInput unless every robot joint is mapped to exactly one axis."""
    missing = [j for j in robot.joint_names if profile.axis_for(j) is None]
    if missing:
        raise BadInput(f"{profile.source}: axes: joint(s) {', '.join(missing)} of robot {robot.name} "
                       "have no controller axis")
    for a in profile.axes:
        if a.joint not in robot.joint_names:
            raise BadInput(f"{profile.source}: axes.{a.joint}: robot {robot.name} has no joint {a.joint!r} "
                           f"(its joints: {', '.join(robot.joint_names)})")


# ---------------------------------------------------------------- loading for a plugin

def _plugin(fmt: str, plugin: PostProcessor | None) -> PostProcessor:
    if plugin is not None:
        return plugin
    from .registry import get_plugin

    return get_plugin(fmt)


def load_profile(path: str | Path | None, robot_name: str, fmt: str, robot=None,
                 plugin: PostProcessor | None = None) -> Profile:
    """Load and validate a controller profile.

    ``path`` None takes the shipped default ``<robot_name>_<fmt>.toml`` (BadInput when there
    is none). Options are checked against the plugin's schema (``plugin``, else the
    registered plugin of ``fmt``); with ``robot`` given, the axis map is checked against
    its joints and by the plugin's ``validate_profile``.
    """
    if path is None:
        path = default_profile_path(robot_name, fmt)
        if path is None:
            raise BadInput(f"no default {fmt} profile for robot {robot_name!r}: write one (docs/controllers.md) "
                           f"and name it in the job's post.profiles.{fmt}")
    path = Path(path)
    data = read_profile_file(path)
    plugin = _plugin(fmt, plugin)
    profile = parse_profile(data, str(path), fmt, robot, plugin.options_schema)
    if robot is not None:
        plugin.validate_profile(profile, robot)
    return profile


def default_options(fmt_or_plugin: str | PostProcessor) -> dict[str, Any]:
    """The options of a format's plugin at their defaults."""
    plugin = fmt_or_plugin if isinstance(fmt_or_plugin, PostProcessor) else _plugin(fmt_or_plugin, None)
    return {k: d for k, (_t, d, _doc) in plugin.options_schema.items()}


def defaults_profile(fmt: str, robot_name: str, plugin: PostProcessor) -> Profile:
    """A profile of option defaults only, for a plugin that needs no axis map."""
    return Profile("<defaults>", fmt, robot_name, options=default_options(plugin))
