"""Yaskawa INFORM: the dialect's tables (axis groups, statement patterns, position levels),
names, number formats, pulses, the plugin's options and the check of a profile."""
from __future__ import annotations

import math
import re

import numpy as np

from camtool.errors import BadInput
from camtool.program.profiles import require_full_map
from camtool.program.convention import controller_axes, model_joints
from camtool.program.text import sanitise_name

GROUPS = {"RB1": "C", "BS1": "BC", "ST1": "EC"}  # axis group -> position line prefix
AXIS_RE = re.compile(r"^(RB1|BS1|ST1):([1-9][0-9]*)$")
DATE_RE = re.compile(r"^\d{4}/\d{2}/\d{2} \d{2}:\d{2}$")
POS_RE = re.compile(r"^(C|BC|EC)(\d{5})=(.*)$")
MOVE_RE = re.compile(r"^(MOVJ|MOVL|MOVC)((?: (?:C|BC|EC)\d{5})+) (?:VJ=(\d+\.\d{2})|V=(\d+(?:\.\d+)?)) PL=(\d+)"
                     r"( FPT)?$")
# --- text in jobs: every comment and ///COMM camtool writes goes through comment_text ----------
COMMENT_MAX = 32
_COMMENT_KEEP = re.compile(r"[^A-Za-z0-9 _.,/+=()-]")
_CODE_WORD_RE = re.compile(r"(?i)\b(MOVJ|MOVL|MOVC|SMOVJ|SMOVL|IMOV|CALL|JUMP|DOUT|END|NOP|PAUSE|TIMER)\b")
CODE_IN_COMMENT_RE = re.compile(r"(?i)\b(S?MOV[JLC]|IMOV)\s+(B|E)?C\d|\bCALL\s+JOB|\bJUMP\s|\bDOUT\s+OT|^'?\s*END\s*$")


def comment_text(raw, max_len: int = COMMENT_MAX) -> str:
    """Text that is safe in an INFORM comment (``'...``) or ``///COMM``: one line of printable
    ASCII (control characters become spaces, others ``_``), no instruction shapes (``:``,
    ``#``; instruction words get a trailing ``_``), at most ``max_len`` characters."""
    s = str(raw)[:max_len * 4]
    s = "".join(" " if (c < " " or c == "\x7f") else c for c in s)
    s = _COMMENT_KEEP.sub("_", s.encode("ascii", "replace").decode("ascii"))
    s = _CODE_WORD_RE.sub(lambda m: m.group(1) + "_", s)
    s = " ".join(s.split())
    return s[:max_len]


# Circular moves (MOVC): an arc runs through three consecutive MOVC points; the move to the
# first is a straight line, and FPT on an arc's last point starts the next arc there
# (unverified: camtool's reading of the INFORM manuals' circular interpolation). One arc
# covers less than ARC_LIMIT_DEG (unverified); camtool's checker holds every arc to it.
ARC_LIMIT_DEG = 180.0
MAX_ARC_DEG = 120.0  # camtool writes at most this much of a circle per arc
CIRCLE_POINT = "c"  # the kind of a parsed MOVC before its arc is assembled
CALL_RE = re.compile(r"^CALL JOB:([A-Za-z0-9_]+)$")
DOUT_RE = re.compile(r"^DOUT OT#\((\d+)\) (ON|OFF)$")
ROW_RE = re.compile(r"^'ROW (\d+)\b")
ROW_END_RE = re.compile(r"^'END ROW (\d+)\b")
INT_RE = re.compile(r"^-?[0-9]+$")
INTS_RE = re.compile(r"^-?[0-9]+(?:,-?[0-9]+)*$")
LONG_RE = re.compile(r"[0-9]{19}")  # 18 digits always fit an int64
FLOAT_RE = re.compile(r"^-?[0-9]+(?:\.[0-9]+)?$")
INT64 = (-(2 ** 63), 2 ** 63 - 1)
PL_MM = [12.5, 25.0, 50.0, 100.0, 150.0, 200.0, 250.0, 300.0]  # unverified: controller parameters
V_STEP = 0.1  # mm/s
MOTIONS = ("joint", "cartesian")


def job_name(raw: str, max_len: int = 8) -> tuple[str, str]:
    """A legal job name (uppercase, digits, ``_``, leading letter, <= max_len) and a note."""
    return sanitise_name(raw, max_len=max_len, upper=True, what="INFORM job name")


def vj_percent(dv: np.ndarray, dt_s: float, vmax: np.ndarray) -> float:
    """VJ (%) for one move: axis changes dv (deg / mm), duration dt (s), max speeds vmax (unit/s)."""
    need = 100.0 * float(np.max(np.abs(dv) / vmax)) / dt_s if dt_s > 0 else 100.0
    return min(100.0, max(0.01, math.floor(need * 100 + 1e-6) / 100))


def group_axes(profile) -> dict[str, list]:
    """Axis-map entries per group (RB1, BS1, ST1), in index order."""
    out: dict[str, list] = {}
    for a in profile.axes:
        m = AXIS_RE.match(a.axis)
        out.setdefault(m.group(1), []).append((int(m.group(2)), a))
    return {g: [a for _i, a in sorted(v, key=lambda x: x[0])] for g, v in sorted(out.items(), key=lambda x: list(GROUPS).index(x[0]))}


def euler_xyz_deg(R: np.ndarray) -> np.ndarray:
    """Fixed-axis x, y, z angles (deg) of rotations (S, 3, 3): R = Rz Ry Rx."""
    import warnings

    from scipy.spatial.transform import Rotation
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Rotation.from_matrix(R).as_euler("xyz", degrees=True)


def matrix_xyz_deg(angles) -> np.ndarray:
    from scipy.spatial.transform import Rotation
    return Rotation.from_euler("xyz", angles, degrees=True).as_matrix()



def _fmt_column(values: np.ndarray, decimals: int) -> list[str]:
    v = np.round(np.asarray(values, float), decimals)
    v[v == 0] = 0.0
    return [f"{x:.{decimals}f}" for x in v.tolist()]


def _ascii(text: str) -> str:
    return text.encode("ascii", "replace").decode("ascii").replace("?", "_")



OPTIONS = {
    "motion": (str, "joint", "Process moves: 'joint' (MOVJ in pulses) or 'cartesian' (MOVL to ///RECTAN "
                             "positions; robots whose kinematics the controller knows, RB1 only)."),
    "lines_per_job": (int, 2000, "Positions per job; longer programs are split, off the surface only, into "
                                 "jobs run by a main job."),
    "pl": (int, 0, "Smallest position level of a blended move, 0..8 (0 and 1 alike: the largest level "
                   "within the path tolerance is taken, at least 1); PL=0 only where an exact stop is meant."),
    "max_pl": (int, 4, "Largest position level of a blended move."),
    "pl_mm": (list, list(PL_MM), "Corner radius (mm) of PL=1..8, for choosing levels and for the "
                                  "simulator (controller parameters; unverified defaults)."),
    "approach_vj": (float, 10.0, "VJ (%) of the first move, from wherever the robot is to the start."),
    "process_output": (int, 0, "Universal output OT#(n) switching the process (ON before each row, OFF "
                               "after it); 0: none, the job says so."),
    "rconf_fields": (int, 8, "Number of ///RCONF values (6 on NX100, 8 as public generators write)."),
    "arcs": (bool, True, "With motion = 'cartesian': positions of a row on a circle (within post.path_tol_mm) "
                         "become MOVC arcs, at most 120 degrees each; false writes MOVL only."),
    "date": (str, "job", "///DATE: 'job' (the job file's time, UTC: reruns are byte-identical), 'now', "
                         "or a fixed 'yyyy/mm/dd hh:mm'."),
    "job_name_length": (int, 8, "Longest job name; 8 is safe, newer controllers take 32."),
}


def validate_profile(profile, robot) -> None:
    """BadInput unless the axis map fits INFORM (every joint on RB1/BS1/ST1 with pulses and
    max_speed) and the options are valid."""
    require_full_map(profile, robot)
    for a in profile.axes:
        where = f"{profile.source}: axes.{a.joint}"
        if not AXIS_RE.match(a.axis):
            raise BadInput(f"{where}.axis: expected RB1:n, BS1:n or ST1:n, found {a.axis!r}")
        if a.pulses is None and not a.axis.startswith("RB1:"):
            raise BadInput(f"{where}.pulses: missing (pulses per {a.unit} of this axis, from the controller's "
                           "parameters; a base or station axis has no Cartesian position)")
        if a.max_speed is None:
            raise BadInput(f"{where}.max_speed: missing (the axis's maximum speed in {a.unit}/s, needed for VJ)")
    groups = group_axes(profile)
    if "RB1" not in groups:
        raise BadInput(f"{profile.source}: axes: no joint is mapped to the robot group RB1")
    for g, axes in groups.items():
        idx = sorted(int(AXIS_RE.match(a.axis).group(2)) for a in axes)
        if idx != list(range(1, len(idx) + 1)):
            raise BadInput(f"{profile.source}: axes: {g} axes must be numbered 1..{len(idx)}, found {idx}")
    o = profile.options
    if not 0 <= o["pl"] <= 8:
        raise BadInput(f"{profile.source}: options.pl: expected 0..8, found {o['pl']}")
    if not max(1, o["pl"]) <= o["max_pl"] <= 8:
        raise BadInput(f"{profile.source}: options.max_pl: expected pl..8, found {o['max_pl']}")
    pl_mm = o["pl_mm"]
    if len(pl_mm) != 8 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0
                                  for v in pl_mm) or list(pl_mm) != sorted(pl_mm):
        raise BadInput(f"{profile.source}: options.pl_mm: expected 8 increasing radii in mm, found {pl_mm!r}")
    if not 0.01 <= o["approach_vj"] <= 100:
        raise BadInput(f"{profile.source}: options.approach_vj: expected 0.01..100, found {o['approach_vj']}")
    if o["date"] not in ("job", "now") and not DATE_RE.match(o["date"]):
        raise BadInput(f"{profile.source}: options.date: expected 'job', 'now' or 'yyyy/mm/dd hh:mm', "
                       f"found {o['date']!r}")
    if o["lines_per_job"] < 1:
        raise BadInput(f"{profile.source}: options.lines_per_job: expected an integer >= 1")
    if not 3 <= o["job_name_length"] <= 32:
        raise BadInput(f"{profile.source}: options.job_name_length: expected 3..32")
    if o["process_output"] < 0:
        raise BadInput(f"{profile.source}: options.process_output: expected 0 (none) or an output number")
    if not 6 <= o["rconf_fields"] <= 24:
        raise BadInput(f"{profile.source}: options.rconf_fields: expected 6..24")
    if o["motion"] not in MOTIONS:
        raise BadInput(f"{profile.source}: options.motion: expected 'joint' or 'cartesian', found {o['motion']!r}")
    if o["motion"] == "cartesian" and (set(groups) != {"RB1"} or len(groups["RB1"]) not in (6, 7)):
        raise BadInput(f"{profile.source}: options.motion = 'cartesian' needs the robot group RB1 alone with "
                       "6 or 7 axes (the controller's own kinematics); use 'joint'")
    # without the controller's pulse factors camtool writes no pulse position (never made-up
    # pulses): every robot position is Cartesian (///RECTAN, MOVJ and MOVL alike), which needs
    # the controller's kinematics for the robot group alone
    missing = [a for a in groups["RB1"] if a.pulses is None]
    if missing and (set(groups) != {"RB1"} or len(groups["RB1"]) not in (6, 7) or len(missing) != len(groups["RB1"])):
        raise BadInput(f"{profile.source}: axes.{missing[0].joint}.pulses: missing (pulses per {missing[0].unit} "
                       "from the controller's parameters); without pulse factors camtool writes Cartesian "
                       "positions only, which needs every RB1 axis without them and RB1 alone with 6 or 7 axes")


def to_pulses(profile, robot, q_native: np.ndarray) -> dict[str, np.ndarray]:
    """Pulses (int64, M x n) per group for joint values (rad / mm)."""
    axes = controller_axes(profile, robot, q_native)
    return {g: np.stack([np.round(axes[a.axis] * a.pulses).astype(np.int64) + a.zero_pulses for a in ax], axis=1)
            for g, ax in group_axes(profile).items() if all(a.pulses is not None for a in ax)}


def pulse_free(profile) -> bool:
    """True if the profile has no pulse factors for the robot group: every position is Cartesian."""
    return any(a.pulses is None for a in group_axes(profile).get("RB1", []))

def from_pulses(profile, robot, pulses: dict[str, np.ndarray]) -> np.ndarray:
    """Joint values (rad / mm) from pulses per group."""
    values = {}
    for g, ax in group_axes(profile).items():
        for k, a in enumerate(ax):  # in float: no int64 wrap-around for absurd pulse values
            values[a.axis] = (np.asarray(pulses[g][:, k], float) - float(a.zero_pulses)) / a.pulses
    return model_joints(profile, robot, values)

