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
"""
from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path

import numpy as np

from ..errors import BadInput
from ..transforms import matrix_from_xyz_rpy
from .dh import DHRow, build_pinocchio_model
from .model import Limits, Robot

BUILTIN_ROBOTS = ("seed8", "irb2400", "irb2400_paper", "sia20")

_JOINT_KEYS = {"name", "type", "a_mm", "alpha_deg", "d_mm", "theta_deg", "lower", "upper",
               "velocity", "acceleration", "jerk"}
_TOP_KEYS = {"name", "convention", "notes", "params", "joint", "flange"}


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
    try:
        return tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise BadInput(f"{path}: robot file not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise BadInput(f"{path}: TOML syntax error: {exc}") from None


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
        return robot_from_toml(robot_toml_data(spec, base_dir), source, params)
    if path.suffix.lower() == ".urdf":
        if not path.is_file():
            raise BadInput(f"{path}: robot file not found")
        from .urdf import robot_from_urdf
        return robot_from_urdf(path)
    raise BadInput(f"unknown robot {spec!r}: use one of {', '.join(BUILTIN_ROBOTS)}, or a .toml/.urdf file")


def _number(value, where: str, params: dict) -> float:
    if isinstance(value, str):
        if value not in params:
            raise BadInput(f"{where}: expected a number or a [params] name, found {value!r}")
        return float(params[value])
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise BadInput(f"{where}: expected a number, found {value!r}")
    return float(value)


def robot_from_toml(data: dict, source: str, params: dict | None = None) -> Robot:
    """Build a Robot from a parsed robot TOML (see module doc); errors name the key."""
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise BadInput(f"{source}: unknown key {sorted(unknown)[0]!r} (expected one of {sorted(_TOP_KEYS)})")
    name = data.get("name")
    if not isinstance(name, str) or not name:
        raise BadInput(f"{source}: name: expected a robot name, found {name!r}")
    convention = data.get("convention", "modified")
    if convention not in ("modified", "standard"):
        raise BadInput(f"{source}: convention: expected 'modified' or 'standard', found {convention!r}")
    all_params = dict(data.get("params", {}))
    for k, v in (params or {}).items():
        if k not in all_params:
            raise BadInput(f"{source}: robot.params.{k}: {name} has no parameter {k!r} "
                           f"(it has {', '.join(all_params) or 'none'})")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or v <= 0:
            raise BadInput(f"{source}: robot.params.{k}: expected a length > 0 mm, found {v!r}")
        all_params[k] = v
    joints = data.get("joint")
    if not isinstance(joints, list) or not joints:
        raise BadInput(f"{source}: joint: expected at least one [[joint]] table")
    rows, names, prismatic = [], [], []
    lim = {k: [] for k in ("lower", "upper", "velocity", "acceleration", "jerk")}
    for i, j in enumerate(joints):
        where = f"{source}: joint[{i}]"
        bad = set(j) - _JOINT_KEYS
        if bad:
            raise BadInput(f"{where}: unknown key {sorted(bad)[0]!r}")
        kind = j.get("type", "revolute")
        if kind not in ("revolute", "prismatic"):
            raise BadInput(f"{where}.type: expected 'revolute' or 'prismatic', found {kind!r}")
        is_p = kind == "prismatic"
        num = {k: _number(j.get(k, 0.0), f"{where}.{k}", all_params)
               for k in ("a_mm", "alpha_deg", "d_mm", "theta_deg")}
        rows.append(DHRow(num["a_mm"], np.radians(num["alpha_deg"]), num["d_mm"], np.radians(num["theta_deg"]), is_p))
        names.append(str(j.get("name", f"j{i + 1}")))
        prismatic.append(is_p)
        for k in lim:
            if k not in j:
                raise BadInput(f"{where}.{k}: missing (every joint needs lower, upper, velocity, acceleration, jerk)")
            v = _number(j[k], f"{where}.{k}", all_params)
            lim[k].append(v if is_p else np.radians(v))
        if lim["lower"][-1] >= lim["upper"][-1]:
            raise BadInput(f"{where}: lower limit must be below upper limit")
        for k in ("velocity", "acceleration", "jerk"):
            if lim[k][-1] <= 0:
                raise BadInput(f"{where}.{k}: expected a value > 0, found {j[k]!r}")
    flange = data.get("flange", {})
    flange_T = matrix_from_xyz_rpy(flange.get("xyz_mm", [0, 0, 0]), flange.get("rpy_deg", [0, 0, 0]))
    model, fid = build_pinocchio_model(rows, convention, flange_T, names, name)
    return Robot(
        name=name,
        joint_names=tuple(names),
        prismatic=np.array(prismatic),
        limits=Limits(*(np.array(lim[k]) for k in ("lower", "upper", "velocity", "acceleration", "jerk"))),
        model=model,
        flange_frame_id=fid,
        convention=convention,
        dh=tuple(rows),
        source=source,
        notes=str(data.get("notes", "")),
    )
