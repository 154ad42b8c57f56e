"""KUKA KRL: the dialect's tables (axes, keywords, statement patterns, approximation), names,
number formats, frames, the plugin's options and the check of a profile.

Sources (docs/controllers.md, "KUKA KRL"): KUKA's KRL quick guide for KSS 8.x (names of
at most 24 characters: letters, digits, ``_`` and ``$``, not starting with a digit, not a
keyword; ``$`` starts the system variables), KUKA.PLC mxAutomation 1.0 (the approximation
parameters: ``C_DIS`` starts at ``$APO.CDIS`` mm before the end point, ``C_PTP`` at
``$APO.CPTP`` % of half the PTP motion, and a PTP approximated into a LIN / CIRC needs
``C_DIS`` as well), the ROS-Industrial KRL files (``ros_rsi.src``: ``PTP {A1 0, A2 -90,
A3 90, A4 0, A5 90, A6 0}``; ``kuka_eki_hw_interface.src``: ``ptp joint_pos_tgt c_ptp``).
"""
from __future__ import annotations

import math
import re

import numpy as np

from camtool.errors import BadInput
from camtool.program.profiles import require_full_map
from camtool.program.process import DATE_FORMAT
from camtool.program.text import sanitise_name

ROBOT_AXES = tuple(f"A{i}" for i in range(1, 7))
EXTERNAL_AXES = tuple(f"E{i}" for i in range(1, 7))
AXES = ROBOT_AXES + EXTERNAL_AXES
NAME_MAX = 24  # KRL names: at most 24 characters (KUKA, KRL quick guide KSS 8.x)
LINE_MAX = 250  # camtool keeps every line this short (the controller's own limit is not published)
# Keywords a name must not be (KRL is case-insensitive); the motion and data words first.
RESERVED = frozenset("""DEF END DEFDAT ENDDAT DEFFCT ENDFCT PUBLIC GLOBAL DECL CONST STRUC ENUM SIGNAL EXT EXTFCT
IMPORT IS PTP LIN CIRC PTP_REL LIN_REL CIRC_REL SPLINE ENDSPLINE SPL SLIN SCIRC SPTP C_PTP C_DIS C_ORI C_VEL CA
IF THEN ELSE ENDIF FOR TO STEP ENDFOR WHILE ENDWHILE REPEAT UNTIL LOOP ENDLOOP SWITCH CASE DEFAULT ENDSWITCH
GOTO HALT WAIT SEC DELAY RETURN EXIT INTERRUPT ON OFF WHEN DO TRIGGER DISTANCE PATH PRIO CONTINUE BRAKE RESUME
ANIN ANOUT INT REAL BOOL CHAR FRAME POS E6POS AXIS E6AXIS TRUE FALSE AND OR NOT EXOR B_AND B_OR B_NOT B_EXOR
IN OUT MAXIMUM MINIMUM BAS""".split())

NUM = r"[-+]?+(?:\d++(?:\.\d*+)?+|\.\d++)"  # possessive: linear on long digit runs
# statements of the .src files camtool writes (one a line; ``;`` starts a comment)
DEF_RE = re.compile(r"^DEF\s+(?P<name>[A-Za-z_][A-Za-z0-9_]*)\s*\(\s*\)$", re.I)
END_RE = re.compile(r"^END$", re.I)
DEFDAT_RE = re.compile(r"^DEFDAT\s+(?P<name>[A-Za-z_][A-Za-z0-9_]*)(?:\s+PUBLIC)?$", re.I)
ENDDAT_RE = re.compile(r"^ENDDAT$", re.I)
DECL_RE = re.compile(r"^DECL\s+(?P<type>E6AXIS|E6POS|FRAME)\s+(?P<name>[A-Za-z_][A-Za-z0-9_]*)\s*=\s*"
                     r"\{(?P<body>[^{}]*)\}$", re.I)
MOVE_RE = re.compile(r"^(?P<word>PTP|LIN|CIRC)\s+(?P<target>[A-Za-z_][A-Za-z0-9_]*)"
                     r"(?:\s*,\s*(?P<end>[A-Za-z_][A-Za-z0-9_]*))?(?P<apo>(?:\s+C_(?:PTP|DIS))*)$", re.I)
ASSIGN_RE = re.compile(r"^(?P<var>\$[A-Za-z_][A-Za-z0-9_]*(?:\[\d+\])?(?:\.[A-Za-z0-9_]+)?)\s*=\s*(?P<value>.+)$")
CALL_RE = re.compile(r"^(?P<name>[A-Za-z_][A-Za-z0-9_]*)\s*\(\s*\)$")
BAS_RE = re.compile(r"^BAS\s*\(\s*#INITMOV\s*,\s*0\s*\)$", re.I)
ROW_RE = re.compile(r"^;\s*Row (?P<n>\d+) of (?P<of>\d+)\b(?P<rest>.*)$")
ROW_END_RE = re.compile(r"^;\s*End of row (?P<n>\d+)\b")
FIELD_RE = re.compile(rf"^\s*(?P<key>[A-Za-z][A-Za-z0-9]*)\s+(?P<value>{NUM})\s*$")


# --- text in programs: every comment camtool writes goes through comment_text ---------------
COMMENT_MAX = 80
_COMMENT_KEEP = re.compile(r"[^A-Za-z0-9 _.,:/+=()-]")
_CODE_WORDS = (r"DEF|END|DEFDAT|ENDDAT|DEFFCT|ENDFCT|FOLD|ENDFOLD|DECL|GLOBAL|PTP|LIN|CIRC|SPLINE|HALT|GOTO|"
               r"INTERRUPT|TRIGGER|WAIT|RETURN|EXIT|BAS")
_CODE_WORD_RE = re.compile(rf"(?i)\b({_CODE_WORDS})\b")
# statement shapes a comment must never hold (a motion with its target, an assignment to a system
# variable, a routine, data list or declaration head, a fold marker, an aggregate's braces)
CODE_IN_COMMENT_RE = re.compile(r"(?i)\b(S?PTP|S?LIN|S?CIRC)\s*(\{|X[PA]\d|\$)|\$\w+(\[\d+\])?(\.\w+)?\s*="
                                r"|\bDEF(DAT|FCT)?\s+\w+|\bDECL\s+\w+|^\s*(END|ENDDAT|ENDFCT)\s*$|^\s*(END)?FOLD\b"
                                r"|[{}]|&ACCESS|%\{")


def comment_text(raw, max_len: int = COMMENT_MAX) -> str:
    """Text that is safe inside a KRL ``;`` comment: one line of printable ASCII (control
    characters become spaces, other characters ``_``), no statement shapes (no ``{ } $ & %``
    or quotes; statement and fold words get a trailing ``_``, so the editor never sees a
    ``;FOLD``), at most ``max_len`` characters (longer text ends in ``...``)."""
    s = str(raw)[:max_len * 4]
    s = "".join(" " if (c < " " or c == "\x7f") else c for c in s)
    s = _COMMENT_KEEP.sub("_", s.encode("ascii", "replace").decode("ascii"))
    s = _CODE_WORD_RE.sub(lambda m: m.group(1) + "_", s)
    s = " ".join(s.split())
    return s if len(s) <= max_len else s[:max_len - 3].rstrip() + "..."


def krl_name(raw: str, max_len: int = NAME_MAX) -> tuple[str, str]:
    """A legal KRL name (letters, digits, ``_``, a leading letter, <= 24 characters, not a
    keyword; upper case as the KUKA editor shows module names) and a note if changed."""
    return sanitise_name(raw, max_len=min(max_len, NAME_MAX), reserved=RESERVED, upper=True, what="KRL name")


# --- numbers and frames ---------------------------------------------------------------------
def fmt_column(values, decimals: int) -> list[str]:
    """Fixed-point numbers without a negative zero (vectorised)."""
    v = np.round(np.asarray(values, float), decimals)
    v[v == 0] = 0.0
    return [f"{x:.{decimals}f}" for x in v.tolist()]


def abc_deg(R: np.ndarray) -> np.ndarray:
    """KUKA's A, B, C (deg) of rotations (S, 3, 3): R = Rz(A) Ry(B) Rx(C), A about z, then B
    about the new y, then C about the newest x."""
    import warnings

    from scipy.spatial.transform import Rotation
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # gimbal lock: scipy picks one of the equal answers
        return Rotation.from_matrix(np.asarray(R, float).reshape(-1, 3, 3)).as_euler("ZYX", degrees=True)


def matrix_abc(abc_deg_values) -> np.ndarray:
    """Rotations (S, 3, 3) of KUKA A, B, C angles (deg)."""
    from scipy.spatial.transform import Rotation
    return Rotation.from_euler("ZYX", np.asarray(abc_deg_values, float).reshape(-1, 3), degrees=True).as_matrix()


def frame_text(T: np.ndarray, keys=("X", "Y", "Z", "A", "B", "C")) -> str:
    """A FRAME / E6POS aggregate body ``X x,Y y,Z z,A a,B b,C c`` of a pose (mm, deg)."""
    T = np.asarray(T, float)
    vals = [*fmt_column(T[:3, 3], 3), *fmt_column(abc_deg(T[:3, :3])[0], 4)]
    return ",".join(f"{k} {v}" for k, v in zip(keys, vals))


def frame_from_fields(fields: dict) -> np.ndarray:
    """A pose (4 x 4, mm) from an aggregate's X, Y, Z, A, B, C (missing ones are 0)."""
    T = np.eye(4)
    T[:3, 3] = [fields.get(k, 0.0) for k in "XYZ"]
    T[:3, :3] = matrix_abc([fields.get(k, 0.0) for k in "ABC"])[0]
    return T


def aggregate_fields(body: str) -> dict[str, float] | None:
    """``{key: value}`` of an aggregate body ``X 1.0,Y 2.0,...``; None if a field is malformed or
    not a finite number."""
    out = {}
    for part in body.split(","):
        m = FIELD_RE.match(part)
        if not m:
            return None
        v = float(m.group("value"))
        if not math.isfinite(v) or m.group("key").upper() in out:
            return None
        out[m.group("key").upper()] = v
    return out


# --- timing and approximation ------------------------------------------------------------------
# $VEL_AXIS[n] is an integer percentage of the axis's maximum speed; a PTP moves its axes
# synchronously, the one that needs longest at its $VEL_AXIS % (camtool's model, as INFORM VJ).
VEL_CP_DECIMALS = 5  # $VEL.CP in m/s: 0.01 mm/s
CDIS_MM = [0.3, 0.5, 1.0, 2.0, 3.0, 5.0, 10.0, 20.0, 50.0]


def cptp_percent(r_mm: float, move_length: float) -> int:
    """$APO.CPTP (1..100 %) whose approximation starts no earlier than ``r_mm`` before the
    end of a PTP of ``move_length`` (100 % = half the motion, KUKA mxAutomation manual);
    lengths in the blend model's TCP-equivalent mm (``camtool.program.moves.joint_travel``)."""
    if move_length <= 0:
        return 1
    return int(min(100, max(1, math.floor(100.0 * r_mm / (move_length / 2.0) + 1e-9))))


def cptp_radius(percent: float, move_length: float) -> float:
    """The approximation distance (TCP-equivalent mm) of ``$APO.CPTP`` % on a PTP of ``move_length``."""
    return percent / 100.0 * move_length / 2.0


# One CIRC of camtool covers at most 120 degrees of its circle (the controller takes more, up
# to a full circle with CA; camtool never writes CA).
MAX_ARC_DEG = 120.0
ARC_LIMIT_DEG = 360.0

OPTIONS = {
    "lines_per_file": (int, 5000, "Moves per .src file; longer programs are split, off the surface only, "
                                  "into modules a main module calls in turn."),
    "cdis_mm": (list, list(CDIS_MM), "The $APO.CDIS values (mm) camtool chooses from for C_DIS (and, through "
                                     "$APO.CPTP, for C_PTP); the largest within post.path_tol_mm is taken."),
    "approach_vel_axis": (int, 10, "$VEL_AXIS (%) of the first move, from wherever the robot is to the start."),
    "ori_vel_deg_s": (float, 200.0, "$VEL.ORI1 and $VEL.ORI2 (deg/s) at the start; a LIN or CIRC that needs "
                                    "more gets more before it."),
    "process_output": (int, 0, "Output $OUT[n] switching the process (TRUE before each row, FALSE after it); "
                               "0: none, the header says so."),
    "arcs": (bool, True, "Targets of a row on a circle (within post.path_tol_mm) become CIRC moves, at most 120 "
                         "degrees each; false writes LIN only."),
    "date": (str, "job", "Date in the header: 'job' (the job file's time, UTC: reruns are byte-identical), "
                         "'now', or a fixed 'yyyy/mm/dd hh:mm'."),
}


def validate_profile(profile, robot) -> None:
    """BadInput unless the axis map fits KRL (A1..A6 on the robot's six arm joints, E1..E6 for
    the others, each with its ``max_speed``) and the options are valid."""
    require_full_map(profile, robot)
    for a in profile.axes:
        where = f"{profile.source}: axes.{a.joint}"
        if a.axis not in AXES:
            raise BadInput(f"{where}.axis: expected one of A1..A6, E1..E6, found {a.axis!r}")
        if a.max_speed is None:
            raise BadInput(f"{where}.max_speed: missing (the axis's maximum speed in {a.unit}/s, which "
                           "$VEL_AXIS is a percentage of)")
    mapped = {a.axis for a in profile.axes}
    if not set(ROBOT_AXES) <= mapped:
        raise BadInput(f"{profile.source}: axes: KRL needs robot joints on all of A1..A6 (LIN and CIRC use the "
                       "controller's own kinematics)")
    o = profile.options
    levels = o["cdis_mm"]
    if not levels or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0
                             for v in levels) or list(levels) != sorted(levels):
        raise BadInput(f"{profile.source}: options.cdis_mm: expected ascending numbers > 0 (mm)")
    if o["lines_per_file"] < 1:
        raise BadInput(f"{profile.source}: options.lines_per_file: expected an integer >= 1")
    if not 1 <= o["approach_vel_axis"] <= 100:
        raise BadInput(f"{profile.source}: options.approach_vel_axis: expected 1..100 (%)")
    if not 0 < o["ori_vel_deg_s"] <= 10000:
        raise BadInput(f"{profile.source}: options.ori_vel_deg_s: expected a speed > 0 deg/s")
    if not 0 <= o["process_output"] <= 4096:
        raise BadInput(f"{profile.source}: options.process_output: expected an output number 1..4096, or 0")
    if o["date"] not in ("job", "now"):
        from datetime import datetime
        try:
            datetime.strptime(o["date"], DATE_FORMAT)
        except ValueError:
            raise BadInput(f"{profile.source}: options.date: expected 'job', 'now' or 'yyyy/mm/dd hh:mm', "
                           f"found {o['date']!r}") from None
