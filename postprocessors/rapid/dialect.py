"""ABB RAPID: the dialect's tables (zones, speed data, reserved words, statement patterns),
number and identifier formats, the plugin's options and the check of a profile."""
from __future__ import annotations

import math
import re

import numpy as np

from camtool.errors import BadInput
from camtool.program.profiles import require_full_map
from camtool.program.process import DATE_FORMAT
from camtool.program.text import sanitise_name

RESERVED = frozenset("""ALIAS AND BACKWARD CASE CONNECT CONST DEFAULT DIV DO ELSE ELSEIF ENDFOR ENDFUNC ENDIF
ENDMODULE ENDPROC ENDRECORD ENDTEST ENDTRAP ENDWHILE ERROR EXIT FALSE FOR FROM FUNC GOTO IF INOUT LOCAL MOD
MODULE NOSTEPIN NOT NOVIEW OR PERS PROC RAISE READONLY RECORD RETRY RETURN STEP SYSMODULE TASK TEST THEN TO
TRAP TRUE TRYNEXT UNDO VAR VIEWONLY WHILE WITH XOR""".split())
# Data the controller's BASE module already declares: never redeclare them.
BUILTIN_DATA = frozenset({"tool0", "wobj0", "load0"})
RAX = tuple(f"rax_{i}" for i in range(1, 7))
EAX = tuple(f"eax_{c}" for c in "abcdef")
# zonedata: the TCP path zone (mm) of the predefined zones; fine is an exact stop
ZONE_MM = {"fine": 0.0, "z0": 0.3, "z1": 1.0, "z5": 5.0, "z10": 10.0, "z15": 15.0, "z20": 20.0, "z30": 30.0,
           "z40": 40.0, "z50": 50.0, "z60": 60.0, "z80": 80.0, "z100": 100.0, "z150": 150.0, "z200": 200.0}
ZONES = tuple(ZONE_MM)
BLEND_ZONES = ZONES[1:]
SPEEDS = ("v5", "v10", "v20", "v30", "v40", "v50", "v60", "v80", "v100", "v150", "v200", "v300", "v400",
          "v500", "v600", "v800", "v1000", "v1500", "v2000", "v2500", "v3000", "v4000", "v5000", "v6000",
          "v7000", "vmax")
NOT_CONNECTED = 9e9
T_RESOLUTION_S = 1e-4
V_RESOLUTION = 0.01   # mm/s of a linear move's v_tcp
MOTIONS = ("joint", "cartesian")

# possessive quantifiers (*+, ++): no ambiguity to backtrack through, so a line of 200,000 digits or spaces
# fails in linear time (``\d+\.?\d*`` split one run of digits every way: quadratic, minutes per line)
_NUM = r"[-+]?+(?:\d++(?:\.\d*+)?+|\.\d++)(?:[eE][-+]?+\d++)?+"
_TAIL = (r"\s*+,\s*+(?P<speed>\w++|\[[^\[\]]*+\])\s*+(?:\\T:=(?P<t>" + _NUM + r"))?+\s*+,\s*+(?P<zone>\w++)\s*+,"
         r"\s*+(?P<tool>\w++)\s*+(?:\\WObj:=(?P<wobj>\w++))?+\s*+;$")


def _robt(p: str) -> str:
    return (rf"\[\[(?P<{p}pos>[^\[\]]*+)\],\[(?P<{p}q>[^\[\]]*+)\],\[(?P<{p}cf>[^\[\]]*+)\],"
            rf"\[(?P<{p}ex>[^\[\]]*+)\]\]")


MOVE_RE = re.compile(
    r"^\s*MoveAbsJ\s+\[\[(?P<rax>[^\[\]]*)\],\[(?P<eax>[^\[\]]*)\]\](?:\\NoEOffs)?" + _TAIL)
MOVEL_RE = re.compile(r"^\s*MoveL\s+" + _robt("") + _TAIL)
MOVEC_RE = re.compile(r"^\s*MoveC\s+" + _robt("c") + r"\s*,\s*" + _robt("") + _TAIL)
SETDO_RE = re.compile(r"^\s*SetDO\s+(?P<sig>\w+)\s*,\s*(?P<val>[01])\s*;$")
CONF_RE = re.compile(r"^\s*Conf[LJ]\s*\\(On|Off)\s*;$")
ROW_RE = re.compile(r"^\s*!\s*Row (?P<n>\d+)\b(?P<rest>.*)$")
ROW_END_RE = re.compile(r"^\s*!\s*End of row (?P<n>\d+)\b")
LOAD_RE = re.compile(r'^\s*Load\s+\\Dynamic\s*,\s*"(?P<path>[^"]+)"\s*;$')
UNLOAD_RE = re.compile(r'^\s*UnLoad\s+"(?P<path>[^"]+)"\s*;$')
CALL_RE = re.compile(r'^\s*%"(?P<proc>[^"]+)"%\s*;$')
MODULE_RE = re.compile(r"^MODULE\s+(?P<name>\w+)\s*$")
PROC_RE = re.compile(r"^\s*PROC\s+(?P<name>\w+)\s*\(\s*\)\s*$")
PERS_RE = re.compile(r"^\s*(?:TASK\s+)?(?:PERS|CONST|VAR)\s+(?P<type>\w+)\s+(?P<name>\w+)\s*:=(?P<value>.*);$")


# --- text in programs: every comment camtool writes goes through comment_text ---------------
COMMENT_MAX = 80
_COMMENT_KEEP = re.compile(r"[^A-Za-z0-9 _.,:/+=#@()-]")
_CODE_WORDS = r"PROC|ENDPROC|FUNC|ENDFUNC|TRAP|ENDTRAP|MODULE|ENDMODULE|RETURN|EXIT"
_CODE_WORD_RE = re.compile(rf"(?i)\b({_CODE_WORDS})\b")
CODE_IN_COMMENT_RE = re.compile(rf"(?i)\b({_CODE_WORDS})\b|\bMove\w*\s*\[|:=|%\"|\bSetDO\s+\w+\s*,\s*[01]\s*;")
DIR_RE = re.compile(r"^[A-Za-z0-9_.:/-]{1,80}$")


def comment_text(raw, max_len: int = COMMENT_MAX) -> str:
    """Text that is safe inside a RAPID ``!`` comment: one line of printable ASCII (control
    characters become spaces, other characters ``_``), no statement shapes (``;``, ``[``,
    ``:=``, quotes; routine and module keywords get a trailing ``_``), at most ``max_len``
    characters (longer text ends in ``...``)."""
    s = str(raw)[:max_len * 4]
    s = "".join(" " if (c < " " or c == "\x7f") else c for c in s)
    s = s.replace(":=", "=")
    s = _COMMENT_KEEP.sub("_", s.encode("ascii", "replace").decode("ascii"))
    s = _CODE_WORD_RE.sub(lambda m: m.group(1) + "_", s)
    s = " ".join(s.split())
    return s if len(s) <= max_len else s[:max_len - 3].rstrip() + "..."


def rapid_identifier(raw: str, max_len: int = 32) -> tuple[str, str]:
    """A legal RAPID identifier (<= 32 chars, leading letter, not reserved) and a note if changed."""
    return sanitise_name(raw, max_len=max_len, reserved=RESERVED | BUILTIN_DATA, what="RAPID identifier")


def fmt_num(x: float, decimals: int) -> str:
    """Fixed-point number without a negative zero."""
    s = f"{x:.{decimals}f}"
    return s[1:] if s.startswith("-") and float(s) == 0 else s


def fmt_column(values: np.ndarray, decimals: int) -> list[str]:
    """``fmt_num`` of every value (vectorised)."""
    v = np.round(np.asarray(values, float), decimals)
    v[v == 0] = 0.0  # no negative zero
    return [f"{x:.{decimals}f}" for x in v.tolist()]


def fmt_t(dt_s: float) -> str:
    """A \\T duration rounded up to 0.1 ms (never faster than planned), at least 0.1 ms."""
    ticks = max(1, math.ceil(dt_s / T_RESOLUTION_S - 1e-6))
    return f"{ticks * T_RESOLUTION_S:.4f}"



def _quat_column(R: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    xyzw = Rotation.from_matrix(R).as_quat()
    q = xyzw[:, [3, 0, 1, 2]]
    return np.where(q[:, :1] < 0, -q, q)


# One MoveC covers less than 240 degrees of its circle, so a full circle takes at least two
# (ABB, Technical reference manual RAPID Instructions, MoveC; e.g. the summary at
# https://blog.csdn.net/weixin_46026089/article/details/118248669: "圆弧运动时的圆周角不能超过240°").
# camtool writes at most half of that per MoveC, and keeps start, circle point and target at
# least 0.1 mm apart (steps.FitArcs.min_chord_mm).
MAX_ARC_DEG = 120.0
ARC_LIMIT_DEG = 240.0

OPTIONS = {
    "motion": (str, "joint", "Process moves: 'joint' (MoveAbsJ \\T) or 'cartesian' (MoveL with robtargets in "
                             "the work object; only for robots whose kinematics the controller knows)."),
    "lines_per_module": (int, 5000, "Moves per module; longer programs are split, off the surface only, "
                                    "into modules run by a main module."),
    "zone": (str, "z0", "Smallest zone of a blended move (the largest within the path tolerance is taken)."),
    "max_zone": (str, "z50", "Largest zone of a blended move."),
    "speed": (str, "v1000", "Speed data of joint moves (their duration comes from \\T)."),
    "approach_speed": (str, "v100", "Speed data of the first move, from wherever the robot is to the start."),
    "module_dir": (str, "HOME:", "Controller folder the main module loads split modules from."),
    "process_signal": (str, "", "Digital output switching the process (SetDO 1 before each row, 0 after "
                                "it); empty: none, the header says so."),
    "arcs": (bool, True, "With motion = 'cartesian': targets of a row on a circle (within post.path_tol_mm) "
                         "become MoveC, at most 120 degrees each; false writes MoveL only."),
    "date": (str, "job", "Date in the header: 'job' (the job file's time, UTC: reruns are byte-identical), "
                         "'now', or a fixed 'yyyy/mm/dd hh:mm'."),
}


def validate_profile(profile, robot) -> None:
    """BadInput unless the axis map fits RAPID (rax_1..6, eax_a..f, every joint once) and the
    options are valid; ``motion = "cartesian"`` needs the six robot axes mapped."""
    require_full_map(profile, robot)
    for a in profile.axes:
        if a.axis not in RAX + EAX:
            raise BadInput(f"{profile.source}: axes.{a.joint}.axis: expected one of rax_1..rax_6, "
                           f"eax_a..eax_f, found {a.axis!r}")
    o = profile.options
    for k in ("zone", "max_zone"):
        if o[k] not in BLEND_ZONES:
            raise BadInput(f"{profile.source}: options.{k}: expected one of {', '.join(BLEND_ZONES)}, "
                           f"found {o[k]!r}")
    if ZONE_MM[o["zone"]] > ZONE_MM[o["max_zone"]]:
        raise BadInput(f"{profile.source}: options.zone: {o['zone']} is larger than max_zone {o['max_zone']}")
    for k in ("speed", "approach_speed"):
        if o[k] not in SPEEDS:
            raise BadInput(f"{profile.source}: options.{k}: expected one of v5 .. v7000, vmax, found {o[k]!r}")
    if o["lines_per_module"] < 1:
        raise BadInput(f"{profile.source}: options.lines_per_module: expected an integer >= 1")
    if o["motion"] not in MOTIONS:
        raise BadInput(f"{profile.source}: options.motion: expected 'joint' or 'cartesian', found {o['motion']!r}")
    if o["motion"] == "cartesian":
        mapped = {a.axis for a in profile.axes}
        if not set(RAX) <= mapped:
            raise BadInput(f"{profile.source}: options.motion = 'cartesian' needs robot joints on all of "
                           "rax_1..rax_6 (the controller's own kinematics); use 'joint'")
    if not DIR_RE.match(o["module_dir"]):
        raise BadInput(f"{profile.source}: options.module_dir: {o['module_dir'][:40]!r} is not a controller "
                       "folder (letters, digits and _ . : / - only)")
    if o["process_signal"] and rapid_identifier(o["process_signal"])[0] != o["process_signal"]:
        raise BadInput(f"{profile.source}: options.process_signal: {o['process_signal']!r} is not a RAPID "
                       "identifier")
    if o["date"] not in ("job", "now"):
        from datetime import datetime
        try:
            datetime.strptime(o["date"], DATE_FORMAT)
        except ValueError:
            raise BadInput(f"{profile.source}: options.date: expected 'job', 'now' or 'yyyy/mm/dd hh:mm', "
                           f"found {o['date']!r}") from None
