"""FANUC LS (the ASCII listing FANUC's tools compile into a TP program): the dialect's
tables, statement patterns, number formats, names, the plugin's options and the check of
a profile.

Sources (docs/controllers.md, "FANUC LS"): the LS files in ROS-Industrial's fanuc_driver
(``tpe/ros.ls``, ``tpe/ros_movesm.ls``: ``/PROG``, ``/ATTR``, ``/MN`` with numbered lines,
``J PR[2] R[1]% CNT R[2]``, ``/POS``, ``/END``), LS files exported by controllers and
ROBOGUIDE in public repositories (the ``/POS`` layouts of joint and Cartesian positions,
``C P[n]`` with its continuation line ``:  P[m] ...``, ``UFRAME_NUM`` / ``UTOOL_NUM``,
``PR[i]=P[j]`` and ``UTOOL[i]=PR[j]``), and public generators (RoboDK's Fanuc_R30iA post).
"""
from __future__ import annotations

import math
import re

import numpy as np

from camtool.errors import BadInput
from camtool.program.profiles import require_full_map
from camtool.program.process import DATE_FORMAT
from camtool.program.text import sanitise_name

ROBOT_AXES = tuple(f"J{i}" for i in range(1, 7))
EXTERNAL_AXES = tuple(f"E{i}" for i in range(1, 4))
AXES = ROBOT_AXES + EXTERNAL_AXES
NAME_MAX = 36            # newer controllers; the option program_name_length defaults to 8 (older ones)
COMMENT_MAX = 32         # a remark line (``!...``); unverified, camtool keeps remarks this short
ATTR_COMMENT_MAX = 16    # /ATTR COMMENT (exported padded to 16 characters)
RESERVED = frozenset("""END CALL JMP LBL IF THEN ELSE ENDIF SELECT FOR ENDFOR WAIT PAUSE ABORT RUN MESSAGE
REMARK OFFSET TOOL_OFFSET UFRAME UTOOL UFRAME_NUM UTOOL_NUM PR P R AR SR DI DO RI RO GI GO AI AO UI UO SI SO
F M TIMER OVERRIDE PAYLOAD MAIN""".split())

# /MN instruction lines camtool writes: "  12:  text ;" or a motion "  12:J P[3] 50% CNT10    ;"
LINE_RE = re.compile(r"^\s*(?P<n>\d+):(?P<body>.*)$")
CONT_RE = re.compile(r"^\s*:\s*(?P<body>.*)$")
MOTION_RE = re.compile(r"^(?P<word>[JLC])\s+P\[(?P<p>\d+)\]\s*(?P<rest>.*)$")
SPEED_TERM_RE = re.compile(r"^(?P<v>\d+(?:\.\d+)?)(?P<unit>%|mm/sec)\s+(?P<term>FINE|CNT\s*(?P<cnt>\d+))\s*;?\s*$")
REMARK_RE = re.compile(r"^!(?P<text>.*?)\s*;\s*$")
FRAME_NUM_RE = re.compile(r"^(?P<what>UFRAME_NUM|UTOOL_NUM)\s*=\s*(?P<n>\d+)\s*;\s*$")
PR_FROM_P_RE = re.compile(r"^PR\[(?P<pr>\d+)\]\s*=\s*P\[(?P<p>\d+)\]\s*;\s*$")
FRAME_FROM_PR_RE = re.compile(r"^(?P<what>UFRAME|UTOOL)\[(?P<n>\d+)\]\s*=\s*PR\[(?P<pr>\d+)\]\s*;\s*$")
DO_RE = re.compile(r"^DO\[(?P<n>\d+)\]\s*=\s*(?P<v>ON|OFF)\s*;\s*$")
CALL_RE = re.compile(r"^CALL\s+(?P<name>[A-Za-z][A-Za-z0-9_]*)\s*;\s*$")
ROW_RE = re.compile(r"^ROW (?P<n>\d+)/(?P<of>\d+)\b(?P<rest>.*)$")
ROW_END_RE = re.compile(r"^END ROW (?P<n>\d+)\b")
PROG_RE = re.compile(r"^/PROG\s+(?P<name>[A-Za-z][A-Za-z0-9_]*)\s*$")
POS_HEAD_RE = re.compile(r"^P\[(?P<p>\d+)(?::\"[^\"]*\")?\]\s*\{\s*$")
NUM = r"-?+(?:\d++(?:\.\d*+)?+|\.\d++)"  # possessive: linear on long digit runs
POS_FIELD_RE = re.compile(rf"(?P<key>J\d|E\d|X|Y|Z|W|P|R)\s*=\s*(?P<v>{NUM})\s*(?P<unit>deg|mm)")
UFUT_RE = re.compile(r"UF\s*:\s*(?P<uf>\d+)\s*,\s*UT\s*:\s*(?P<ut>\d+)")
CONFIG_RE = re.compile(r"CONFIG\s*:\s*'(?P<conf>[^']*)'")


# --- text in programs: every remark and /ATTR comment camtool writes goes through comment_text -----
_COMMENT_KEEP = re.compile(r"[^A-Za-z0-9 _.,+=()-]")
_CODE_WORD_RE = re.compile(r"(?i)\b(CALL|JMP|LBL|END|PAUSE|ABORT|RUN|WAIT|IF|SELECT|UFRAME|UTOOL|UFRAME_NUM|"
                           r"UTOOL_NUM|PR|DO|DI|MESSAGE)\b")
CODE_IN_COMMENT_RE = re.compile(r"(?i)\b[JLC]\s+P\s*\[|\bCALL\s+\w|\bJMP\s+LBL|\b(UFRAME|UTOOL)(_NUM)?\s*[\[=]"
                                r"|\bD[IO]\s*\[|\bPR\s*\[|/(PROG|ATTR|MN|POS|END)\b|[\[\];:'\"]")


def comment_text(raw, max_len: int = COMMENT_MAX) -> str:
    """Text that is safe in a remark (``!...``) or the /ATTR COMMENT: one line of printable ASCII
    (control characters become spaces, other characters ``_``), no statement shapes (no
    brackets, ``;``, ``:``, ``/`` or quotes; instruction words get a trailing ``_``), at most
    ``max_len`` characters."""
    s = str(raw)[:max_len * 4]
    s = "".join(" " if (c < " " or c == "\x7f") else c for c in s)
    s = _COMMENT_KEEP.sub("_", s.encode("ascii", "replace").decode("ascii"))
    s = _CODE_WORD_RE.sub(lambda m: m.group(1) + "_", s)
    s = " ".join(s.split())
    return s[:max_len].rstrip()


def program_name(raw: str, max_len: int = 8) -> tuple[str, str]:
    """A legal TP program name (upper-case letters, digits, ``_``, a leading letter, at most
    ``max_len`` characters, no instruction word) and a note if changed."""
    return sanitise_name(raw, max_len=min(max_len, NAME_MAX), reserved=RESERVED, upper=True,
                         what="FANUC program name")


# --- numbers ----------------------------------------------------------------------------------
def ls_number(v: float, width: int = 10) -> str:
    """A /POS value as the controller lists it: 3 decimals, no leading zero below 1 (``.500``,
    ``-.350``), an exact ``0.000`` for zero (never ``-0.000``), right-aligned in ``width``."""
    s = f"{v:.3f}"
    if float(s) == 0.0:
        s = "0.000"
    elif s.startswith("0."):
        s = s[1:]
    elif s.startswith("-0."):
        s = "-" + s[2:]
    return s.rjust(width)


def wpr_deg(R: np.ndarray) -> np.ndarray:
    """FANUC's W, P, R (deg) of rotations (S, 3, 3): fixed-axis x, y, z (R = Rz(R) Ry(P) Rx(W))."""
    import warnings

    from scipy.spatial.transform import Rotation
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Rotation.from_matrix(np.asarray(R, float).reshape(-1, 3, 3)).as_euler("xyz", degrees=True)


def matrix_wpr(wpr) -> np.ndarray:
    """Rotations (S, 3, 3) of W, P, R (deg)."""
    from scipy.spatial.transform import Rotation
    return Rotation.from_euler("xyz", np.asarray(wpr, float).reshape(-1, 3), degrees=True).as_matrix()


# --- timing and corners ---------------------------------------------------------------------------
# J speeds are integer % of each axis's maximum speed (the axis that needs longest governs, as
# INFORM's VJ); L / C speeds are integer mm/sec. CNT n rounds a corner by a radius that depends on
# the controller's speed and acceleration: cnt_mm is camtool's model of it (unverified defaults).
CNT = [1, 2, 5, 10, 20, 50, 100]
CNT_MM = [0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0]
MAX_ARC_DEG = 120.0
ARC_LIMIT_DEG = 180.0    # camtool holds every C move below this (unverified: the controller's limit)


def cnt_radius(cnt: float, levels, radii) -> float:
    """The corner radius (mm) camtool models for CNT ``cnt``: the profile's ``cnt_mm`` at its
    ``cnt`` values, linear between them and from CNT0 (0 mm: the robot reaches the point)."""
    xs = [0.0] + [float(v) for v in levels]
    ys = [0.0] + [float(v) for v in radii]
    return float(np.interp(cnt, xs, ys))


OPTIONS = {
    "program_name_length": (int, 8, "Longest program name; 8 is safe on older controllers, newer ones take "
                                    "36."),
    "lines_per_program": (int, 2000, "Moves per program; longer programs are split, off the surface only, "
                                     "into programs a main program calls in turn."),
    "cnt": (list, list(CNT), "CNT values camtool chooses from for blended moves (the largest within "
                             "post.path_tol_mm by cnt_mm is taken)."),
    "cnt_mm": (list, list(CNT_MM), "Corner radius (mm) camtool models for each CNT value, for choosing and for "
                                   "the simulator (the controller's depends on speed: unverified defaults)."),
    "approach_percent": (int, 10, "J speed (%) of the first move, from wherever the robot is to the start."),
    "uframe": (int, 1, "User frame number (UFRAME_NUM) the program selects and its positions record."),
    "utool": (int, 1, "Tool frame number (UTOOL_NUM) the program selects and its positions record."),
    "set_frames": (bool, True, "Write UTOOL[utool] (the job's tool) and UFRAME[uframe] (the work object) from "
                               "the program, through position register frame_register; false: the header "
                               "states the values to set by hand."),
    "frame_register": (int, 100, "Position register PR[n] the frames are copied through (set_frames)."),
    "process_output": (int, 0, "Digital output DO[n] switching the process (ON before each row, OFF after it); "
                               "0: none, the header says so."),
    "arcs": (bool, True, "Targets of a row on a circle (within post.path_tol_mm) become C moves, at most 120 "
                         "degrees each; false writes L only."),
    "date": (str, "job", "CREATE / MODIFIED date: 'job' (the job file's time, UTC: reruns are byte-identical), "
                         "'now', or a fixed 'yyyy/mm/dd hh:mm'."),
}


def validate_profile(profile, robot) -> None:
    """BadInput unless the axis map fits LS (J1..J6 on the arm, E1..E3 extended axes, each with
    its ``max_speed``) and the options are valid."""
    require_full_map(profile, robot)
    for a in profile.axes:
        where = f"{profile.source}: axes.{a.joint}"
        if a.axis not in AXES:
            raise BadInput(f"{where}.axis: expected one of J1..J6, E1..E3, found {a.axis!r}")
        if a.max_speed is None:
            raise BadInput(f"{where}.max_speed: missing (the axis's maximum speed in {a.unit}/s, which a J "
                           "move's % is of)")
    if not set(ROBOT_AXES) <= {a.axis for a in profile.axes}:
        raise BadInput(f"{profile.source}: axes: LS needs robot joints on all of J1..J6")
    o = profile.options
    cnt, mm = o["cnt"], o["cnt_mm"]
    if (not cnt or len(cnt) != len(mm) or not all(isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= 100
                                                    for v in cnt) or list(cnt) != sorted(set(cnt))):
        raise BadInput(f"{profile.source}: options.cnt: expected ascending whole CNT values 1..100, one per cnt_mm")
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0 for v in mm) \
            or list(mm) != sorted(mm):
        raise BadInput(f"{profile.source}: options.cnt_mm: expected ascending radii > 0 (mm)")
    if not 1 <= o["program_name_length"] <= NAME_MAX:
        raise BadInput(f"{profile.source}: options.program_name_length: expected 1..{NAME_MAX}")
    if o["lines_per_program"] < 1:
        raise BadInput(f"{profile.source}: options.lines_per_program: expected an integer >= 1")
    if not 1 <= o["approach_percent"] <= 100:
        raise BadInput(f"{profile.source}: options.approach_percent: expected 1..100 (%)")
    for k, hi in (("uframe", 9), ("utool", 10)):
        if not 1 <= o[k] <= hi:
            raise BadInput(f"{profile.source}: options.{k}: expected 1..{hi} (0 is the controller's own frame, "
                           "which camtool does not change)")
    if not 1 <= o["frame_register"] <= 1000:
        raise BadInput(f"{profile.source}: options.frame_register: expected a position register number 1..1000")
    if not 0 <= o["process_output"] <= 4096:
        raise BadInput(f"{profile.source}: options.process_output: expected an output number 1..4096, or 0")
    if o["date"] not in ("job", "now"):
        from datetime import datetime
        try:
            datetime.strptime(o["date"], DATE_FORMAT)
        except ValueError:
            raise BadInput(f"{profile.source}: options.date: expected 'job', 'now' or 'yyyy/mm/dd hh:mm', "
                           f"found {o['date']!r}") from None
