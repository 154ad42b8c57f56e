"""Built-in robots and the loaders for user robots (TOML DH or URDF).

Robot TOML format (the built-ins in ``robots/data/`` use it too)::

    name = "myarm"
    convention = "modified"      # or "standard"
    [params]                     # optional named lengths (mm), overridable from the job
    L1 = 480.0
    [[joint]]                    # one table per joint, base to flange
    name = "j1"
    type = "revolute"            # or "prismatic"; default revolute
    a_mm = 0                     # a number or a [params] name
    alpha_deg = -90
    d_mm = 0                     # offset (added to the variable of a prismatic joint)
    theta_deg = 0                # offset (added to the variable of a revolute joint)
    lower = -170                 # deg, or mm for a prismatic joint
    upper = 170
    velocity = 120               # deg/s or mm/s
    acceleration = 300           # deg/s^2 or mm/s^2
    jerk = 1500                  # deg/s^3 or mm/s^3
    [flange]                     # optional constant flange offset after the last joint
    xyz_mm = [0, 0, 0]
    rpy_deg = [0, 0, 0]
    [controller]                 # optional: how the robot's controller sees the joints
    source = "user"              # "paper" | "manufacturer" | "user"
    reference = "where the numbers come from"
    [[controller.axis]]          # one per controller axis, in the controller's order
    name = "rax_1"
    joint = "j1"                 # the joint driving it
    plus = []                    # coupled joints added to it (ABB parallel linkage: ["j2"] on axis 3)
    minus = []                   # coupled joints subtracted from it (FANUC's J3 = j3 - j2: ["j2"])
    direction = 1                # 1 or -1
    zero_offset = 0              # deg (mm for a prismatic joint)
    lower = -170                 # the controller's limits of this axis, deg or mm
    upper = 170
    [controller.tool0_in_flange]     # the controller's tool0 in the flange (xyz_mm, rpy_deg)
    [controller.robot_frame_in_base] # the controller's robot frame in the base (xyz_mm, rpy_deg)

    Without [controller] the controller's axes are the joints (``conventions.py``).

Every value is checked before Pinocchio sees it; each problem is one BadInput
line naming the file and the key: an unknown key (with the closest known key
suggested), a table where a number belongs, NaN or infinite numbers, duplicate
joint names, a flange vector without 3 numbers, and lengths beyond
``MAX_LENGTH_MM`` (1 km: a link, offset, track limit or [params] length that
long is a typo or a unit slip, never a robot).
"""
from __future__ import annotations

import difflib
import math
import os
import tomllib
from importlib import resources
from pathlib import Path

import numpy as np

from ..errors import BadInput
from ..transforms import matrix_from_xyz_rpy
from .conventions import conventions_from_table
from .dh import MAX_LENGTH_MM, DHRow, build_pinocchio_model
from .model import Limits, Robot
from .validate import validate_robot

BUILTIN_ROBOTS = ("seed8", "irb2400", "irb2400_paper", "sia20", "sia20_paper", "kr16", "m20ia")

_JOINT_KEYS = {"name", "type", "a_mm", "alpha_deg", "d_mm", "theta_deg", "lower", "upper",
               "velocity", "acceleration", "jerk"}
_TOP_KEYS = {"name", "convention", "notes", "params", "joint", "flange", "controller"}
_FLANGE_KEYS = {"xyz_mm", "rpy_deg"}
_LENGTH_KEYS = ("a_mm", "d_mm")
_LIMIT_KEYS = ("lower", "upper", "velocity", "acceleration", "jerk")


def _unknown_key(where: str, key: str, known) -> BadInput:
    """One line naming an unknown key and the closest known one."""
    close = difflib.get_close_matches(str(key), sorted(known), n=1)
    close = close or [k for k in sorted(known) if k.rsplit("_", 1)[0] == key]  # "a" for "a_mm": the unit left out
    hint = f"did you mean {close[0]}?" if close else f"expected one of {', '.join(sorted(known))}"
    return BadInput(f"{where}{key}: unknown key; {hint}")


def check_length_mm(value: float, where: str) -> float:
    """``value`` if it is a plausible length in mm (finite, |value| <= MAX_LENGTH_MM), else BadInput."""
    if not math.isfinite(value) or abs(value) > MAX_LENGTH_MM:
        raise BadInput(f"{where}: {value:g} mm is not a plausible length (more than {MAX_LENGTH_MM:g} mm = 1 km); "
                       "check the value and its unit")
    return value


def _check_params(params, source: str) -> dict:
    """The [params] table: names of finite, plausible lengths (mm)."""
    if params is None:
        return {}
    if not isinstance(params, dict):
        raise BadInput(f"{source}: params: expected a [params] table of lengths in mm, found {params!r}")
    for k, v in params.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise BadInput(f"{source}: [params] {k}: expected a length in mm, found {v!r}")
        check_length_mm(float(v), f"{source}: [params] {k}")
    return dict(params)


def _builtin_text(name: str) -> str:
    return resources.files("camtool.robots").joinpath("data", f"{name}.toml").read_text()


def robot_toml_data(spec: str, base_dir: Path | None = None) -> dict | None:
    """The parsed TOML description of a built-in or .toml robot (None for a URDF)."""
    if spec in BUILTIN_ROBOTS:
        return tomllib.loads(_builtin_text(spec))
    path = Path(spec)
    if base_dir is not None and not path.is_absolute():
        path = base_dir / path
    if path.suffix.lower() != ".toml":
        return None
    from ..safe_io import load_toml  # regular file under the cap: never a FIFO hang

    try:
        data = load_toml(path, "robot")
    except FileNotFoundError:
        raise BadInput(f"{path}: robot file not found") from None
    except IsADirectoryError:
        raise BadInput(f"{path}: is a folder; give a robot .toml file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise BadInput(f"{path}: cannot read the robot file ({type(exc).__name__}: {exc})") from None
    _check_params(data.get("params"), str(path))
    return data


def get_robot(spec: str, params: dict | None = None, base_dir: Path | None = None) -> Robot:
    """A robot from a built-in name, a ``.toml`` DH file or a ``.urdf`` file.

    ``params`` overrides named lengths (mm) of a parametric robot such as
    seed8 (L1..L4). Relative file names are taken from ``base_dir``.
    """
    path = Path(spec)
    if base_dir is not None and not path.is_absolute():
        path = base_dir / path
    if spec in BUILTIN_ROBOTS or path.suffix.lower() == ".toml":
        source = f"builtin:{spec}" if spec in BUILTIN_ROBOTS else str(path)
        robot = robot_from_toml(robot_toml_data(spec, base_dir), source, params)
        validate_robot(robot, source)
        return robot
    if path.suffix.lower() == ".urdf":
        if not os.path.lexists(path):
            raise BadInput(f"{path}: robot file not found")
        from .urdf import robot_from_urdf
        robot = robot_from_urdf(path)
        validate_robot(robot, str(path))
        return robot
    raise BadInput(f"unknown robot {spec!r}: use one of {', '.join(BUILTIN_ROBOTS)}, or a .toml/.urdf file")


def _number(value, where: str, params: dict) -> float:
    if isinstance(value, str):
        if value not in params:
            close = difflib.get_close_matches(value, sorted(params), n=1)
            hint = f" (did you mean {close[0]}?)" if close else ""
            raise BadInput(f"{where}: expected a number or a [params] name, found {value!r}{hint}")
        return float(params[value])
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise BadInput(f"{where}: expected a number, found {value!r}")
    if not math.isfinite(value):
        raise BadInput(f"{where}: expected a finite number, found {value!r}")
    return float(value)


def _vector3(value, where: str) -> list[float]:
    if not isinstance(value, list) or len(value) != 3:
        raise BadInput(f"{where}: expected 3 numbers [x, y, z], found {value!r}")
    for v in value:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise BadInput(f"{where}: expected 3 finite numbers [x, y, z], found {value!r}")
    return [float(v) for v in value]


def _flange_matrix(flange, source: str) -> np.ndarray:
    if not isinstance(flange, dict):
        raise BadInput(f"{source}: flange: expected a [flange] table with xyz_mm and rpy_deg, found {flange!r}")
    for key in flange:
        if key not in _FLANGE_KEYS:
            raise _unknown_key(f"{source}: [flange] ", key, _FLANGE_KEYS)
    xyz = _vector3(flange.get("xyz_mm", [0, 0, 0]), f"{source}: [flange] xyz_mm")
    rpy = _vector3(flange.get("rpy_deg", [0, 0, 0]), f"{source}: [flange] rpy_deg")
    check_length_mm(float(np.linalg.norm(xyz)), f"{source}: [flange] xyz_mm")
    return matrix_from_xyz_rpy(xyz, rpy)


def robot_from_toml(data: dict, source: str, params: dict | None = None) -> Robot:
    """Build a Robot from a parsed robot TOML (see module doc); errors name the key."""
    name, convention = _robot_header(data, source)
    all_params = _robot_params(data, source, name, params)
    if "notes" in data and not isinstance(data["notes"], str):
        raise BadInput(f"{source}: notes: expected text, found {data['notes']!r}")
    joints = data.get("joint")
    if not isinstance(joints, list) or not joints:
        raise BadInput(f"{source}: joint: expected at least one [[joint]] table")
    rows, names, prismatic = [], [], []
    lim = {k: [] for k in _LIMIT_KEYS}
    for i, j in enumerate(joints):
        row, jname, is_p, limit = _joint(j, f"{source}: joint[{i}]", i, all_params, names)
        rows.append(row)
        names.append(jname)
        prismatic.append(is_p)
        for k in lim:
            lim[k].append(limit[k])
    flange_T = _flange_matrix(data.get("flange", {}), source)
    model, fid = build_pinocchio_model(rows, convention, flange_T, names, name)
    limits = Limits(*(np.array(lim[k]) for k in ("lower", "upper", "velocity", "acceleration", "jerk")))
    conventions = conventions_from_table(data.get("controller"), name, names, prismatic, limits.lower, limits.upper,
                                         source, "paper" if source.startswith("builtin:") else "user")
    return Robot(
        name=name,
        joint_names=tuple(names),
        prismatic=np.array(prismatic),
        limits=limits,
        model=model,
        flange_frame_id=fid,
        convention=convention,
        dh=tuple(rows),
        source=source,
        notes=data.get("notes", ""),
        conventions=conventions,
    )


def _robot_header(data, source: str) -> tuple[str, str]:
    """(name, DH convention) of a robot TOML, its top-level keys checked."""
    if not isinstance(data, dict):
        raise BadInput(f"{source}: expected a robot description table, found {type(data).__name__}")
    unknown = sorted(set(data) - _TOP_KEYS)
    if unknown:
        raise _unknown_key(f"{source}: ", unknown[0], _TOP_KEYS)
    name = data.get("name")
    if not isinstance(name, str) or not name:
        raise BadInput(f"{source}: name: expected a robot name, found {name!r}")
    convention = data.get("convention", "modified")
    if convention not in ("modified", "standard"):
        raise BadInput(f"{source}: convention: expected 'modified' or 'standard', found {convention!r}")
    return name, convention


def _robot_params(data: dict, source: str, name: str, params: dict | None) -> dict:
    """The robot's ``[params]`` lengths (mm) with the job's ``robot.params`` over them."""
    all_params = _check_params(data.get("params"), source)
    for k, v in (params or {}).items():
        if k not in all_params:
            close = difflib.get_close_matches(str(k), sorted(all_params), n=1)
            hint = f"; did you mean {close[0]}?" if close else ""
            raise BadInput(f"{source}: robot.params.{k}: {name} has no parameter {k!r} "
                           f"(it has {', '.join(all_params) or 'none'}){hint}")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise BadInput(f"{source}: robot.params.{k}: expected a length > 0 mm, found {v!r}")
        all_params[k] = check_length_mm(float(v), f"{source}: robot.params.{k}")
    return all_params


def _joint(j, where: str, i: int, all_params: dict, names: list[str]):
    """(DH row, name, prismatic, limits by key in rad or mm) of the ``[[joint]]`` table ``i``; ``names`` the
    joints' before it."""
    if not isinstance(j, dict):
        raise BadInput(f"{where}: expected a [[joint]] table (name, a_mm, ..., jerk), found {j!r}")
    for key in j:
        if key not in _JOINT_KEYS:
            raise _unknown_key(f"{where} ", key, _JOINT_KEYS)
    kind = j.get("type", "revolute")
    if kind not in ("revolute", "prismatic"):
        raise BadInput(f"{where}.type: expected 'revolute' or 'prismatic', found {kind!r}")
    is_p = kind == "prismatic"
    num = {k: _number(j.get(k, 0.0), f"{where}.{k}", all_params)
           for k in ("a_mm", "alpha_deg", "d_mm", "theta_deg")}
    for k in _LENGTH_KEYS:
        check_length_mm(num[k], f"{where}.{k}")
    row = DHRow(num["a_mm"], np.radians(num["alpha_deg"]), num["d_mm"], np.radians(num["theta_deg"]), is_p)
    jname = j.get("name", f"j{i + 1}")
    if not isinstance(jname, str) or not jname:
        raise BadInput(f"{where}.name: expected a joint name, found {jname!r}")
    if jname in names:
        raise BadInput(f"{where}.name: {jname!r} is already the name of joint[{names.index(jname)}]; "
                       "joint names must be unique")
    limit = {}
    for k in _LIMIT_KEYS:
        if k not in j:
            raise BadInput(f"{where}.{k}: missing (every joint needs lower, upper, velocity, acceleration, jerk)")
        v = _number(j[k], f"{where}.{k}", all_params)
        if is_p and k in ("lower", "upper"):
            check_length_mm(v, f"{where}.{k}")
        limit[k] = v if is_p else np.radians(v)
    if limit["lower"] >= limit["upper"]:
        raise BadInput(f"{where}: lower limit must be below upper limit")
    for k in ("velocity", "acceleration", "jerk"):
        if limit[k] <= 0:
            raise BadInput(f"{where}.{k}: expected a value > 0, found {j[k]!r}")
    return row, jname, is_p, limit
