"""The controller's joint conventions: how a robot's controller sees camtool's joint values.

camtool plans in its model's joints (``Robot.joint_names``, rad / mm, model order). A
controller has its own axes: in its own order, with its own directions and zeros, and
on some arms coupled (ABB's parallel linkage: the controller's axis 3 is the forearm
angle j2 + j3). It also has its own flange frame (``tool0``) and robot frame. This
module holds those conventions as data, read from the robot TOML's ``[controller]``
table (``camtool/robots/data/*.toml``; docs/robots.md), and applies them:

- controller value of axis k: ``q_ctrl[k] = direction_k * (q[joint_k] + sum(q[plus_k]) - sum(q[minus_k])) + zero_offset_k``
  (a linear map ``q_ctrl = M @ q + b``, vectorised over leading axes; FANUC's J3 is
  j3 - j2, fanuc_driver's J23 linkage);
- controller-axis limits are checked on the controller's axes (the coupled J3);
- ``tool0_in_flange`` places the controller's tool0 in the model's flange frame, and
  ``robot_frame_in_base`` the controller's robot (base) frame in the model's base frame;
- for a robot with a vendored ROS-Industrial description, ``urdf_from_model`` gives the
  URDF's joint vector (the URDF's joint order), and the model's base frame is the URDF's
  ``base_link``.

Robots without a ``[controller]`` table get identity conventions (``identity``): the
controller's axes are the model's joints. The built-in paper robots declare theirs as
``source = "paper"``; user robots are ``"user"``.
"""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from ..errors import BadInput
from ..transforms import matrix_from_xyz_rpy, rpy_deg_from_matrix

SOURCES = ("paper", "manufacturer", "user")
_TOP_KEYS = {"name", "source", "reference", "axis", "tool0_in_flange", "robot_frame_in_base", "urdf", "driver"}
_AXIS_KEYS = {"name", "joint", "plus", "minus", "direction", "zero_offset", "lower", "upper"}
_FRAME_KEYS = {"xyz_mm", "rpy_deg"}
_URDF_KEYS = {"file", "joints", "reference"}
LIMIT_TOL = 1e-9  # rad / mm: a value this close to a limit is on it


def _inverse(T: np.ndarray) -> np.ndarray:
    R, p = T[:3, :3], T[:3, 3]
    out = np.eye(4)
    out[:3, :3] = R.T
    out[:3, 3] = -R.T @ p
    return out


@dataclass(frozen=True)
class ControllerConventions:
    """How one robot's controller sees the model's joint values (see module doc).

    Arrays are in controller axis order unless named otherwise; angles rad, lengths mm.
    ``matrix`` (n_ctrl x n_model) and ``offset`` (n_ctrl) give ``q_ctrl = matrix @ q + offset``.
    """

    name: str
    source: str
    reference: str
    controller_axis_names: tuple[str, ...]
    model_joint_names: tuple[str, ...]
    matrix: np.ndarray = field(repr=False)
    offset: np.ndarray = field(repr=False)
    prismatic: np.ndarray = field(repr=False)
    lower: np.ndarray = field(repr=False)
    upper: np.ndarray = field(repr=False)
    tool0_in_flange: np.ndarray = field(repr=False, default_factory=lambda: np.eye(4))
    robot_frame_in_base: np.ndarray = field(repr=False, default_factory=lambda: np.eye(4))
    driver: str = ""
    urdf_path: Path | None = None
    urdf_joint_names: tuple[str, ...] = ()
    urdf_matrix: np.ndarray | None = field(repr=False, default=None)
    urdf_reference: str = ""
    axis_joints: tuple[int, ...] = ()   # the model joint driving each controller axis (its ``joint`` key)

    def __post_init__(self):
        if not self.axis_joints:
            object.__setattr__(self, "axis_joints", tuple(int(np.argmax(np.abs(r))) for r in self.matrix))

    # -- joint values ------------------------------------------------------------------
    @property
    def identity(self) -> bool:
        """True if the controller's axes are the model's joints, unchanged, and the frames agree."""
        n = len(self.model_joint_names)
        return (self.matrix.shape == (n, n) and np.array_equal(self.matrix, np.eye(n))
                and not np.any(self.offset) and np.array_equal(self.tool0_in_flange, np.eye(4))
                and np.array_equal(self.robot_frame_in_base, np.eye(4)))

    @property
    def coupled_axes(self) -> np.ndarray:
        """Indices of the controller axes that are sums of model joints (ABB's parallel linkage)."""
        return np.flatnonzero(np.count_nonzero(self.matrix, axis=1) > 1)

    @property
    def coupled(self) -> bool:
        """True if a controller axis is a sum of model joints: its limits are then not a box in the
        model's joints, and a solver clamping the joint box can leave them."""
        return bool(len(self.coupled_axes))

    def controller_from_model(self, q_rad) -> np.ndarray:
        """Controller axis values (rad / mm, controller order) from model joint values (..., n_model)."""
        q = np.asarray(q_rad, float)
        return q @ self.matrix.T + self.offset

    def model_from_controller(self, q_ctrl_rad) -> np.ndarray:
        """Model joint values (rad / mm, model order) from controller axis values (..., n_ctrl)."""
        q = np.asarray(q_ctrl_rad, float)
        return (q - self.offset) @ np.linalg.inv(self.matrix).T

    def controller_limit_violations(self, q_ctrl_rad, tol: float = LIMIT_TOL) -> np.ndarray:
        """Boolean (..., n_ctrl): True where a controller axis value is beyond its limits."""
        q = np.asarray(q_ctrl_rad, float)
        return (q < self.lower - tol) | (q > self.upper + tol)

    def within_limits(self, q_rad, tol: float = LIMIT_TOL):
        """True (per configuration) if the model joint values are inside every controller-axis limit."""
        bad = self.controller_limit_violations(self.controller_from_model(q_rad), tol)
        return ~np.any(bad, axis=-1) if bad.ndim > 1 else not bool(np.any(bad))

    def check_controller_limits(self, q_ctrl_rad, where: str = "", tol: float = LIMIT_TOL) -> list[str]:
        """One line per controller axis value beyond its limits (deg / mm), for (..., n_ctrl) values."""
        q = np.asarray(q_ctrl_rad, float).reshape(-1, len(self.controller_axis_names))
        bad = self.controller_limit_violations(q, tol)
        out = []
        for i, k in zip(*np.nonzero(bad)):
            conv = (lambda v: v) if self.prismatic[k] else math.degrees
            unit = "mm" if self.prismatic[k] else "deg"
            at = f"{where}target {i}: " if len(q) > 1 or where else ""
            out.append(f"{at}{self.name} controller axis {self.controller_axis_names[k]} = {conv(q[i, k]):.4f} "
                       f"{unit} is beyond its limits [{conv(self.lower[k]):.4f}, {conv(self.upper[k]):.4f}] {unit}")
        return out

    # -- frames ------------------------------------------------------------------------
    def tool_in_tool0(self, tool_in_flange_mm: np.ndarray) -> np.ndarray:
        """The TCP in the controller's tool0 frame (what tooldata holds) from the TCP in the model's flange."""
        return _inverse(self.tool0_in_flange) @ np.asarray(tool_in_flange_mm, float)

    def pose_in_robot_frame(self, pose_in_base_mm: np.ndarray) -> np.ndarray:
        """Poses (..., 4, 4) from the model's base frame into the controller's robot frame."""
        return _inverse(self.robot_frame_in_base) @ np.asarray(pose_in_base_mm, float)

    # -- the ROS-Industrial description -----------------------------------------------
    def urdf_from_model(self, q_rad) -> np.ndarray:
        """The vendored URDF's joint vector (rad, the URDF's joint order) from model joint values."""
        if self.urdf_matrix is None:
            raise BadInput(f"robot {self.name}: no ROS-Industrial description is vendored for it")
        return np.asarray(q_rad, float) @ self.urdf_matrix.T

    # -- for the user ----------------------------------------------------------------
    def axis_formulas(self) -> list[str]:
        """Each controller axis as a formula of the model joints, e.g. ``rax_3 = j3 + j2``."""
        out = []
        for k, name in enumerate(self.controller_axis_names):
            terms = []
            for i, c in enumerate(self.matrix[k]):
                if c:
                    j = self.model_joint_names[i]
                    terms.append(j if c == 1 else f"-{j}" if c == -1 else f"{c:g}*{j}")
            terms.sort(key=lambda t: t.startswith("-"))   # positive terms first: J3 = j3 - j2
            text = " + ".join(terms).replace("+ -", "- ")
            off = self.offset[k] if self.prismatic[k] else math.degrees(self.offset[k])
            if off:
                text += f" {'+' if off > 0 else '-'} {abs(off):g} {'mm' if self.prismatic[k] else 'deg'}"
            out.append(f"{name} = {text}")
        return out

    def describe(self) -> dict:
        """Source, reference, axis formulas, controller limits (deg / mm) and frames (for ``camtool robots``)."""
        def edge(v, k):
            return float(v) if self.prismatic[k] else float(math.degrees(v))

        def frame(T):
            return {"xyz_mm": [round(float(x), 9) for x in T[:3, 3]],
                    "rpy_deg": [round(float(x), 9) for x in rpy_deg_from_matrix(T)]}
        return {
            "source": self.source,
            "reference": self.reference,
            "identity": self.identity,
            "axes": [{"name": n, "formula": f, "lower": edge(self.lower[k], k), "upper": edge(self.upper[k], k),
                      "unit": "mm" if self.prismatic[k] else "deg"}
                     for k, (n, f) in enumerate(zip(self.controller_axis_names, self.axis_formulas()))],
            "tool0_in_flange": frame(self.tool0_in_flange),
            "robot_frame_in_base": frame(self.robot_frame_in_base),
            "driver": self.driver,
            "urdf": None if self.urdf_path is None else {
                "file": self.urdf_path.relative_to(_data_dir()).as_posix() if self.urdf_path.is_relative_to(_data_dir())
                else str(self.urdf_path),
                "joints": list(self.urdf_joint_names), "reference": self.urdf_reference},
        }

    def summary(self) -> str:
        """One line for program headers and report.json: source, the axis formulas that differ, the frames."""
        parts = [f"{self.name}: {self.source} robot"]
        if np.array_equal(self.matrix, np.eye(len(self.model_joint_names))) and not np.any(self.offset):
            parts.append("controller axes = camtool joints")
        else:
            parts.append("controller axes " + ", ".join(self.axis_formulas()))
        for label, T in (("tool0", self.tool0_in_flange), ("robot frame", self.robot_frame_in_base)):
            parts.append(f"{label} = {'flange' if label == 'tool0' else 'base'}" if np.array_equal(T, np.eye(4))
                         else f"{label} at {_frame_text(T)} in the {'flange' if label == 'tool0' else 'base'}")
        return " / ".join(parts)


def _frame_text(T: np.ndarray) -> str:
    xyz = ", ".join(f"{v:g}" for v in np.round(T[:3, 3], 6))
    rpy = ", ".join(f"{v:g}" for v in np.round(rpy_deg_from_matrix(T), 6))
    return f"xyz ({xyz}) mm, rpy ({rpy}) deg"


def _data_dir() -> Path:
    return Path(str(resources.files("camtool.robots").joinpath("data")))


def identity(name: str, joint_names, prismatic, lower, upper, source: str, reference: str) -> ControllerConventions:
    """Conventions for a robot whose controller axes are its model joints (no controller data given)."""
    n = len(joint_names)
    return ControllerConventions(
        name=name, source=source, reference=reference, controller_axis_names=tuple(joint_names),
        model_joint_names=tuple(joint_names), matrix=np.eye(n), offset=np.zeros(n),
        prismatic=np.asarray(prismatic, bool).copy(), lower=np.asarray(lower, float).copy(),
        upper=np.asarray(upper, float).copy())


# -- reading the [controller] table ---------------------------------------------------
def _unknown(where: str, key, known) -> BadInput:
    close = difflib.get_close_matches(str(key), sorted(known), n=1)
    hint = f"did you mean {close[0]}?" if close else f"expected one of {', '.join(sorted(known))}"
    return BadInput(f"{where}{key}: unknown key; {hint}")


def _num(v, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise BadInput(f"{where}: expected a finite number, found {v!r}")
    return float(v)


def _frame(value, where: str) -> np.ndarray:
    if not isinstance(value, dict):
        raise BadInput(f"{where}: expected a table with xyz_mm and rpy_deg, found {value!r}")
    for k in value:
        if k not in _FRAME_KEYS:
            raise _unknown(f"{where} ", k, _FRAME_KEYS)
    vec = {}
    for k in _FRAME_KEYS:
        v = value.get(k, [0.0, 0.0, 0.0])
        if not isinstance(v, list) or len(v) != 3:
            raise BadInput(f"{where} {k}: expected 3 numbers, found {v!r}")
        vec[k] = [_num(x, f"{where} {k}") for x in v]
    return matrix_from_xyz_rpy(vec["xyz_mm"], vec["rpy_deg"])


def _joint_index(name, names: tuple[str, ...], where: str) -> int:
    if name not in names:
        close = difflib.get_close_matches(str(name), names, n=1)
        hint = f"; did you mean {close[0]}?" if close else f" (joints: {', '.join(names)})"
        raise BadInput(f"{where}: the robot has no joint {name!r}{hint}")
    return names.index(name)


def conventions_from_table(table, robot_name: str, joint_names, prismatic, lower, upper, source_file: str,
                           default_source: str) -> ControllerConventions:
    """The conventions of a robot TOML's ``[controller]`` table (None: identity); errors name the key."""
    names = tuple(joint_names)
    prismatic = np.asarray(prismatic, bool)
    if table is None:
        reference = ("no controller data: the controller's axes are camtool's joints, unchanged"
                     if default_source != "user" else "none given: the controller's axes are the robot's joints, unchanged")
        return identity(robot_name, names, prismatic, lower, upper, default_source, reference)
    w = f"{source_file}: [controller] "
    src, reference, driver = _table_header(table, w, default_source)
    axes = table.get("axis")
    if axes is None:
        base = identity(robot_name, names, prismatic, lower, upper, src, reference)
        ax = _Axes(base.matrix, base.offset, base.lower, base.upper, names, prismatic, list(range(len(names))))
    else:
        ax = _controller_axes(axes, names, prismatic, w)
    urdf_path, urdf_names, urdf_M, urdf_ref = _urdf(table.get("urdf"), names, w, source_file, default_source)
    return ControllerConventions(
        name=robot_name, source=src, reference=reference, controller_axis_names=tuple(ax.names),
        model_joint_names=names, matrix=ax.matrix, offset=ax.offset, prismatic=np.asarray(ax.prismatic, bool),
        lower=np.asarray(ax.lower, float), upper=np.asarray(ax.upper, float),
        tool0_in_flange=_frame(table.get("tool0_in_flange", {}), f"{w}tool0_in_flange"),
        robot_frame_in_base=_frame(table.get("robot_frame_in_base", {}), f"{w}robot_frame_in_base"),
        driver=driver, urdf_path=urdf_path, urdf_joint_names=urdf_names, urdf_matrix=urdf_M, urdf_reference=urdf_ref,
        axis_joints=tuple(ax.joints))


@dataclass(frozen=True)
class _Axes:
    """The controller's axes as read: the coupling matrix and zero offsets (axis = matrix @ joints + offset),
    the limits (rad or mm), the names, which are prismatic, and the joint each drives."""

    matrix: np.ndarray
    offset: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    names: object
    prismatic: object
    joints: list


def _table_header(table, w: str, default_source: str) -> tuple[str, str, str]:
    """(source, reference, driver) of a ``[controller]`` table, its keys checked (``w``: where, for errors)."""
    if not isinstance(table, dict):
        raise BadInput(f"{w}: expected a table, found {table!r}")
    for k in table:
        if k not in _TOP_KEYS:
            raise _unknown(w, k, _TOP_KEYS)
    src = table.get("source", default_source)
    if src not in SOURCES:
        raise BadInput(f"{w}source: expected one of {', '.join(SOURCES)}, found {src!r}")
    reference = table.get("reference", "")
    driver = table.get("driver", "")
    for key, val in (("reference", reference), ("driver", driver)):
        if not isinstance(val, str):
            raise BadInput(f"{w}{key}: expected text, found {val!r}")
    return src, reference, driver


def _controller_axes(axes, names: tuple[str, ...], prismatic: np.ndarray, w: str) -> _Axes:
    """The ``[[controller.axis]]`` tables, one per joint; BadInput unless they determine the joints."""
    if not isinstance(axes, list) or not axes:
        raise BadInput(f"{w}axis: expected [[controller.axis]] tables, one per controller axis")
    if len(axes) != len(names):
        raise BadInput(f"{w}axis: {len(axes)} controller axes for {len(names)} joints; give one per joint")
    n = len(names)
    M, b = np.zeros((n, n)), np.zeros(n)
    lo, hi = np.zeros(n), np.zeros(n)
    ax_names, ax_prism, used, ax_joints = [], [], set(), []
    for k, a in enumerate(axes):
        nm, j, M[k], b[k], lo[k], hi[k] = _controller_axis(a, f"{w}axis[{k}]", names, prismatic, ax_names, used)
        used.add(j)
        ax_joints.append(j)
        ax_names.append(nm)
        ax_prism.append(bool(prismatic[j]))
    if abs(np.linalg.det(M)) < 1e-9:
        raise BadInput(f"{w}axis: the controller axes do not determine the joints (singular coupling)")
    return _Axes(M, b, lo, hi, ax_names, ax_prism, ax_joints)


def _controller_axis(a, wa: str, names: tuple[str, ...], prismatic: np.ndarray, taken: list, used: set):
    """(name, joint, coupling row, zero offset, lower, upper limit) of one ``[[controller.axis]]`` table (rad or
    mm); ``taken`` the names and ``used`` the joints of the axes before it."""
    if not isinstance(a, dict):
        raise BadInput(f"{wa}: expected a table (name, joint, ...), found {a!r}")
    for key in a:
        if key not in _AXIS_KEYS:
            raise _unknown(f"{wa} ", key, _AXIS_KEYS)
    nm = a.get("name")
    if not isinstance(nm, str) or not nm or nm in taken:
        raise BadInput(f"{wa}.name: expected a unique axis name, found {nm!r}")
    j = _joint_index(a.get("joint"), names, f"{wa}.joint")
    if j in used:
        raise BadInput(f"{wa}.joint: joint {names[j]!r} already drives another controller axis")
    d = a.get("direction", 1)
    if d not in (1, -1) or isinstance(d, bool):
        raise BadInput(f"{wa}.direction: expected 1 or -1, found {d!r}")
    row = np.zeros(len(names))
    row[j] = 1.0
    plus = a.get("plus", [])
    if not isinstance(plus, list):
        raise BadInput(f"{wa}.plus: expected a list of joint names, found {plus!r}")
    minus = a.get("minus", [])
    if not isinstance(minus, list):
        raise BadInput(f"{wa}.minus: expected a list of joint names, found {minus!r}")
    for key, coupled, c in (("plus", plus, 1.0), ("minus", minus, -1.0)):
        for p in coupled:
            i = _joint_index(p, names, f"{wa}.{key}")
            if i == j or prismatic[i] != prismatic[j]:
                raise BadInput(f"{wa}.{key}: {p!r} cannot be coupled to {names[j]!r}")
            row[i] += c
    row *= d
    scale = (lambda v: v) if prismatic[j] else math.radians
    offset = scale(_num(a.get("zero_offset", 0.0), f"{wa}.zero_offset"))
    limit = {}
    for key in ("lower", "upper"):
        if key not in a:
            raise BadInput(f"{wa}.{key}: missing (the controller's limit of this axis, deg or mm)")
        limit[key] = scale(_num(a[key], f"{wa}.{key}"))
    if limit["lower"] >= limit["upper"]:
        raise BadInput(f"{wa}: lower limit must be below upper limit")
    return nm, j, row, offset, limit["lower"], limit["upper"]


def _urdf(urdf, names: tuple[str, ...], w: str, source_file: str, default_source: str):
    """(file, URDF joint names, URDF-to-model matrix, reference) of a ``[controller.urdf]`` table; (None, (), None,
    "") without one."""
    if urdf is None:
        return None, (), None, ""
    if not isinstance(urdf, dict):
        raise BadInput(f"{w}urdf: expected a table (file, joints), found {urdf!r}")
    for key in urdf:
        if key not in _URDF_KEYS:
            raise _unknown(f"{w}urdf ", key, _URDF_KEYS)
    f, js = urdf.get("file"), urdf.get("joints")
    if not isinstance(f, str) or not isinstance(js, list) or len(js) != len(names) \
            or not all(isinstance(x, str) for x in js):
        raise BadInput(f"{w}urdf: expected file = \"...urdf\" and joints = one URDF joint name per robot joint")
    urdf_path = (_data_dir() / f) if default_source != "user" else Path(source_file).parent / f
    # URDF joint i is model joint i (the built-ins are built so)
    return urdf_path, tuple(js), np.eye(len(names)), str(urdf.get("reference", ""))
