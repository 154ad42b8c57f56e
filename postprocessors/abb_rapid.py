"""ABB RAPID post-processor: ``.mod`` modules plus a ``.pgf`` program file.

The moves come from ``postprocessors.moves.plan_moves``: waypoints merged while
the controller's interpolation stays within the path tolerance, corners blended
by zones, exact stops (``fine``) only at the first move, at the top of a
retract, at the end of a module that is followed by another, and at the end.

- Joint moves: ``MoveAbsJ jointtarget, speed \\T:=dt, zone, tool \\WObj:=wobj;``
  with the planned duration (0.1 ms grid, rounded so that the program's clock
  tracks the plan's and no move is faster than the robot's speed limits allow).
  Joint values: 1e-4 deg, 1e-3 mm; 9E9 for axes the profile leaves unconnected.
- Linear moves (profile option ``motion = "cartesian"``, for robots whose
  kinematics the controller knows): ``MoveL robtarget, [v_tcp,v_ori,5000,1000],
  zone, tool \\WObj:=wobj;`` with the robtarget (position 1e-3 mm, quaternion,
  confdata cf1, cf4, cf6, cfx from the planned joints, external axes) in the work
  object at the workpiece frame, and the TCP speed that gives the planned
  duration. Free motion stays joint moves.
- The first move goes from wherever the robot is to the start at
  ``approach_speed`` and stops (``fine``).
- Process I/O: ``SetDO signal, 1;`` before the move to each row's first work
  point and ``SetDO signal, 0;`` after the move to its last (option
  ``process_signal``; without one the header says the program switches nothing).
  Every row starts with a comment ``! Row n of N ...`` and ends with ``! End of
  row n``.
- Programs longer than ``lines_per_module`` moves are split into modules
  ``<NAME>_001 ...`` only after a target in free motion; each module holds one
  routine ``<NAME>_001_run`` and the main module ``<NAME>`` loads, runs (late
  binding ``%"<NAME>_001_run"%;``) and unloads them in turn.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from camtool import __version__
from camtool.errors import BadInput
from camtool.profiles import require_full_map
from camtool.transforms import invert, matrix_from_xyz_rpy, quaternion_wxyz_from_matrix

from .base import DATE_FORMAT, ProcessInfo, program_date, sanitise_name
from .check import check_motion, resolution_tol
from .moves import KIND_LINEAR, Kinematics, plan_moves, profile_tool, split_parts
from .program import CIRCULAR, JOINT, LINEAR, ProgramMoves, empty_moves

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

_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_TAIL = (r"\s*,\s*(?P<speed>\w+|\[[^\[\]]*\])\s*(?:\\T:=(?P<t>" + _NUM + r"))?\s*,\s*(?P<zone>\w+)\s*,"
         r"\s*(?P<tool>\w+)\s*(?:\\WObj:=(?P<wobj>\w+))?\s*;$")


def _robt(p: str) -> str:
    return (rf"\[\[(?P<{p}pos>[^\[\]]*)\],\[(?P<{p}q>[^\[\]]*)\],\[(?P<{p}cf>[^\[\]]*)\],"
            rf"\[(?P<{p}ex>[^\[\]]*)\]\]")


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


@dataclass
class Move:
    """One parsed motion instruction.

    ``kind`` J (MoveAbsJ: ``rax``/``eax`` the jointtarget), L (MoveL) or C (MoveC: ``to``
    and ``via`` robtargets, each ``(pos, quat, conf, eax)``); speed data (a name or the
    aggregate's text), duration (s or None), zone, tool, work object.
    """

    line: int
    rax: list[float]
    eax: list[float]
    speed: str
    t_s: float | None
    zone: str
    tool: str
    wobj: str | None
    kind: str = JOINT
    to: tuple | None = None
    via: tuple | None = None


@dataclass
class ModuleText:
    """What the reader finds in one .mod file; ``items`` the moves and process markers in
    order: ``("move", Move)``, ``("row", line, text)``, ``("end_row", line, n)``,
    ``("do", line, signal, value)``."""

    name: str = ""
    procs: list[str] = field(default_factory=list)
    data: dict[str, str] = field(default_factory=dict)  # name -> type
    values: dict[str, str] = field(default_factory=dict)  # name -> value text
    moves: list[Move] = field(default_factory=list)
    items: list[tuple] = field(default_factory=list)
    loads: list[tuple[int, str]] = field(default_factory=list)
    calls: list[tuple[int, str]] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)


def _all_finite(text: str) -> bool:
    """False when a data value holds nan / inf or a number too large for a float."""
    for tok in re.split(r"[\s,\[\]]+", text):
        try:
            if not math.isfinite(float(tok)):
                return False
        except ValueError:  # TRUE, "", a name: not a number
            pass
    return True


def _floats(text: str) -> list[float]:
    return [float(v) for v in text.split(",")] if text.strip() else []


def _robtarget(mv, p: str, where: str, problems: list[str]):
    """(pos, quat, conf, eax) of a matched robtarget, or None with a problem noted."""
    try:
        pos, quat = _floats(mv.group(p + "pos")), _floats(mv.group(p + "q"))
        conf, eax = _floats(mv.group(p + "cf")), _floats(mv.group(p + "ex"))
    except ValueError:
        problems.append(f"{where}: robtarget values must be numbers")
        return None
    if not all(math.isfinite(v) for v in pos + quat + conf + eax):
        problems.append(f"{where}: robtarget values must be finite numbers")
        return None
    if (len(pos), len(quat), len(conf), len(eax)) != (3, 4, 4, 6):
        problems.append(f"{where}: a robtarget needs 3 + 4 + 4 + 6 values, found {len(pos)}, {len(quat)}, "
                        f"{len(conf)} and {len(eax)}")
        return None
    if abs(math.sqrt(sum(v * v for v in quat)) - 1.0) > 1e-4:
        problems.append(f"{where}: the robtarget's quaternion is not normalised")
        return None
    if any(v != int(v) for v in conf):
        problems.append(f"{where}: confdata must be integers")
        return None
    return pos, quat, [int(v) for v in conf], eax


def _speed_ok(speed: str) -> bool:
    if speed in SPEEDS:
        return True
    if speed.startswith("["):
        try:
            v = _floats(speed.strip("[]"))
        except ValueError:
            return False
        return len(v) == 4 and all(math.isfinite(x) and x > 0 for x in v)
    return False


_PARSED: dict = {}  # (path, content digest) -> ModuleText: a check and a simulation read a file once
_READ: dict = {}    # the programs read last (read_program), by their parsed modules, profile and robot
_PARSED_MAX = 64


def parse_module(path: Path) -> ModuleText:
    """Parse a camtool-style RAPID module; structural problems are collected, not raised.
    The result is cached by the file's path and content (callers must not change it)."""
    import hashlib

    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        m = ModuleText()
        m.problems.append(f"{path}: cannot read ({exc})")
        return m
    key = (str(path), hashlib.blake2b(raw, digest_size=16).digest())
    if key in _PARSED:
        return _PARSED[key]
    m = _parse_module(path, raw.decode("latin-1"))
    if len(_PARSED) >= _PARSED_MAX:
        _PARSED.clear()
    _PARSED[key] = m
    return m


def _parse_module(path: Path, text: str) -> ModuleText:
    m = ModuleText()
    bulk: list = []  # well-formed jointtargets: (move, rax text, eax text, where)
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines = lines[:-1]
    else:
        m.problems.append(f"{path}:{len(lines)}: no newline at end of file")
    if "\r" in text:
        m.problems.append(f"{path}: CR characters found (RAPID modules use LF line ends here)")
    depth = 0
    ps = str(path)
    for n, line in enumerate(lines, 1):
        where = f"{ps}:{n}"
        if line != line.rstrip():
            m.problems.append(f"{where}: trailing white space")
        if "\t" in line:
            m.problems.append(f"{where}: tab character")
        s = line.strip()
        if not s:
            continue
        if s.startswith("!"):
            if depth and (rm := ROW_RE.match(s)):
                m.items.append(("row", n, s.lstrip("! ").strip()))
            elif depth and (em := ROW_END_RE.match(s)):
                m.items.append(("end_row", n, int(em.group("n"))))
            continue
        if s[:4] == "Move":
            first = s.split(None, 1)[0]
            kind = {"MoveAbsJ": JOINT, "MoveL": LINEAR, "MoveC": CIRCULAR}.get(first)
            regex = {JOINT: MOVE_RE, LINEAR: MOVEL_RE, CIRCULAR: MOVEC_RE}.get(kind)
            mv = regex.match(line) if regex else None
            word = first if kind else s[:8]
            if not mv or not depth:
                m.problems.append(f"{where}: malformed {word}" + ("" if mv else f": {s[:60]}"))
                continue
            t = mv.group("t")
            if t and not math.isfinite(float(t)):
                m.problems.append(f"{where}: \\T must be a finite number of seconds, found {t}")
                continue
            if mv.group("speed")[:1] == "[" and not _all_finite(mv.group("speed")):
                m.problems.append(f"{where}: speed data must be finite numbers")
                continue
            tail = (mv.group("speed"), float(t) if t else None, mv.group("zone"), mv.group("tool"), mv.group("wobj"))
            if kind == JOINT and mv.group("rax").count(",") == 5 and mv.group("eax").count(",") == 5:
                move = Move(n, None, None, *tail)  # values converted in bulk after the loop
                bulk.append((move, mv.group("rax"), mv.group("eax"), where))
            elif kind == JOINT:
                try:
                    rax, eax = _floats(mv.group("rax")), _floats(mv.group("eax"))
                except ValueError:
                    m.problems.append(f"{where}: jointtarget values must be numbers")
                    continue
                if not all(math.isfinite(v) for v in rax + eax):
                    m.problems.append(f"{where}: jointtarget values must be finite numbers")
                    continue
                if len(rax) != 6 or len(eax) != 6:
                    m.problems.append(f"{where}: jointtarget needs 6 robot and 6 external values, found "
                                      f"{len(rax)} and {len(eax)}")
                    continue
                move = Move(n, rax, eax, *tail)
            else:
                to = _robtarget(mv, "", where, m.problems)
                via = _robtarget(mv, "c", where, m.problems) if kind == CIRCULAR else None
                if to is None or (kind == CIRCULAR and via is None):
                    continue
                move = Move(n, [], to[3], *tail, kind=kind, to=to, via=via)
            m.moves.append(move)
            m.items.append(("move", move))
            continue
        if s.startswith("%%%"):
            m.problems.append(f"{where}: '%%%' header is not allowed in a .mod file")
        elif (mm := MODULE_RE.match(line)):
            if m.name:
                m.problems.append(f"{where}: second MODULE in one file")
            m.name = mm.group("name")
        elif s == "ENDMODULE":
            if depth:
                m.problems.append(f"{where}: ENDMODULE inside a PROC")
            if n != len(lines):
                m.problems.append(f"{where}: text after ENDMODULE")
        elif (pm := PROC_RE.match(line)):
            if depth:
                m.problems.append(f"{where}: PROC inside a PROC")
            depth += 1
            m.procs.append(pm.group("name"))
        elif s == "ENDPROC":
            if not depth:
                m.problems.append(f"{where}: ENDPROC without PROC")
            depth = max(0, depth - 1)
        elif (dm := PERS_RE.match(line)) and not depth:
            m.data[dm.group("name")] = dm.group("type")
            m.values[dm.group("name")] = dm.group("value")
            if not _all_finite(dm.group("value")):
                m.problems.append(f"{where}: {dm.group('name')} holds a value that is not a finite number")
        elif (dm := SETDO_RE.match(line)) and depth:
            m.items.append(("do", n, dm.group("sig"), int(dm.group("val"))))
        elif CONF_RE.match(line) and depth:
            pass
        elif (lm := LOAD_RE.match(line)) and depth:
            m.loads.append((n, lm.group("path")))
        elif UNLOAD_RE.match(line) and depth:
            pass
        elif (cm := CALL_RE.match(line)) and depth:
            m.calls.append((n, cm.group("proc")))
        else:
            m.problems.append(f"{where}: unrecognised statement: {s[:60]}")
    _bulk_values(bulk, m)
    if not m.name:
        m.problems.append(f"{path}: no MODULE line")
    if depth:
        m.problems.append(f"{path}: PROC without ENDPROC")
    if not lines or lines[-1].strip() != "ENDMODULE":
        m.problems.append(f"{path}: the module does not end with ENDMODULE")
    return m


def _bulk_values(bulk: list, m: ModuleText) -> None:
    """The jointtarget values of well-formed MoveAbsJ lines, converted at once; a move whose
    values are no finite numbers is a problem and leaves the module's moves."""
    if not bulk:
        return
    try:
        vals = np.array(",".join(f"{r},{e}" for _mv, r, e, _w in bulk).split(","), dtype=float).reshape(-1, 12)
        ok = np.isfinite(vals).all(axis=1)
    except ValueError:
        vals, ok = None, None
    drop = set()
    rows = vals.tolist() if vals is not None else None
    for i, (mv, r, e, where) in enumerate(bulk):
        if rows is not None and ok[i]:
            row = rows[i]
            mv.rax, mv.eax = row[:6], row[6:]
            continue
        try:
            rax, eax = _floats(r), _floats(e)
        except ValueError:
            m.problems.append(f"{where}: jointtarget values must be numbers")
            drop.add(id(mv))
            continue
        if not all(math.isfinite(v) for v in rax + eax):
            m.problems.append(f"{where}: jointtarget values must be finite numbers")
            drop.add(id(mv))
            continue
        mv.rax, mv.eax = rax, eax
    if drop:
        m.moves = [mv for mv in m.moves if id(mv) not in drop]
        m.items = [it for it in m.items if not (it[0] == "move" and id(it[1]) in drop)]


def read_pgf(path: Path) -> list[str]:
    """Module file names listed in a .pgf program file."""
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as exc:
        raise BadInput(f"{path}: not a readable program file ({exc})") from None
    if root.tag != "Program":
        raise BadInput(f"{path}: root element is <{root.tag}>, expected <Program>")
    return [(e.text or "").strip() for e in root.findall("Module")]


def program_modules(path: Path) -> list[tuple[Path, ModuleText]]:
    """The modules of a program in run order: a .pgf's modules, then each Load of a main
    module (resolved by file name in the same folder)."""
    path = Path(path)
    mods = [path.parent / Path(n).name for n in read_pgf(path)] if path.suffix.lower() == ".pgf" else [path]
    out = []
    for mp in mods:
        mt = parse_module(mp)
        out.append((mp, mt))
        for _n, load in mt.loads:
            part = mp.parent / re.split(r"[/\\:]", load)[-1]
            out.append((part, parse_module(part)))
    return out


def _aggregate_numbers(text: str) -> list[float]:
    out = []
    for tok in re.split(r"[\s,\[\]]+", text):
        try:
            out.append(float(tok))
        except ValueError:
            pass
    return out


def _pose(pos, quat) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    w, x, y, z = quat
    T[:3, :3] = Rotation.from_quat([x, y, z, w]).as_matrix()
    T[:3, 3] = pos
    return T


def _wobj_frame(values: dict[str, str], name: str | None) -> np.ndarray:
    """The work object's frame (uframe * oframe) in the robot base frame; wobj0 is the base."""
    if not name or name == "wobj0" or name not in values:
        return np.eye(4)
    v = _aggregate_numbers(values[name])
    if len(v) < 14:
        return np.eye(4)
    return _pose(v[0:3], v[3:7]) @ _pose(v[7:10], v[10:14])


def _tool_frame(values: dict[str, str], name: str | None) -> np.ndarray | None:
    if not name or name not in values:
        return None
    v = _aggregate_numbers(values[name])
    return _pose(v[0:3], v[3:7]) if len(v) >= 7 else None


def _quat_column(R: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    xyzw = Rotation.from_matrix(R).as_quat()
    q = xyzw[:, [3, 0, 1, 2]]
    return np.where(q[:, :1] < 0, -q, q)


class RapidPost:
    """ABB RAPID writer and reader (see module doc)."""

    name = "rapid"
    extension = ".mod"
    extensions = (".pgf", ".mod")  # every file type it writes; `camtool check` finds the format by these
    requires_profile = True
    check_covers_calls = True  # checking the entry file checks every module / job it runs
    options_schema = {
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
        "date": (str, "job", "Date in the header: 'job' (the job file's time, UTC: reruns are byte-identical), "
                             "'now', or a fixed 'yyyy/mm/dd hh:mm'."),
    }

    def validate_profile(self, profile, robot) -> None:
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

    # --- writing ---------------------------------------------------------------------------

    def write(self, trajectory, robot, profile, outdir: Path, process: ProcessInfo | None = None) -> list[Path]:
        """Write ``<NAME>.pgf`` and ``<NAME>.mod`` (plus ``<NAME>_NNN.mod`` parts when split)."""
        self.validate_profile(profile, robot)
        process = process if process is not None else ProcessInfo()
        outdir = Path(outdir)
        o = profile.options
        name, _ = rapid_identifier(profile.program_name, 24)
        tool, _ = rapid_identifier(profile.tool["name"])
        wobj, _ = rapid_identifier(profile.wobj["name"])
        robot = robot.with_placement(tool_T_mm=profile_tool(profile))  # the TCP the program declares
        cart = o["motion"] == "cartesian"
        lo, hi = BLEND_ZONES.index(o["zone"]), BLEND_ZONES.index(o["max_zone"])
        plan = plan_moves(trajectory, robot, process, linear=cart,
                          levels_mm=[ZONE_MM[z] for z in BLEND_ZONES[:hi + 1]], min_level_on_surface=lo)
        n = len(plan)
        kind = np.array(plan.kind)
        length = np.r_[0.0, np.linalg.norm(np.diff(plan.P, axis=0), axis=1)]
        kind[(kind == KIND_LINEAR) & (length < 1e-3)] = JOINT  # a linear move that goes nowhere
        parts = split_parts(n, o["lines_per_module"], plan.free, "moves", f"{profile.source}: options.lines_per_module")
        level = plan.level.copy()
        for r in parts[:-1]:
            level[r.stop - 1] = -1  # a module ends with a stop: the next one is loaded there
        zone_names = np.array(BLEND_ZONES + ("fine",))[level]  # level -1 -> fine
        # --- timing: \T for joint moves, a TCP speed for linear moves; the clock tracks the plan
        dt = np.diff(plan.t)
        fastest = np.max(np.abs(np.diff(plan.q, axis=0)) / robot.limits.velocity[None, :], axis=1) \
            if n > 1 else np.zeros(0)
        angle = np.r_[0.0, _angles(plan.R[:-1], plan.R[1:])] if n > 1 else np.zeros(n)
        speed_txt = [""] * n
        t_txt = [""] * n
        planned = written = 0.0
        for i in range(1, n):
            planned += dt[i - 1]
            want = max(planned - written, T_RESOLUTION_S)
            if kind[i] == KIND_LINEAR:
                v = max(V_RESOLUTION, round(length[i] / want / V_RESOLUTION) * V_RESOLUTION)
                dur = length[i] / v
                v_ori = max(0.1, math.ceil(math.degrees(angle[i]) / dur * 10 - 1e-9) / 10)
                speed_txt[i] = f"[{v:.2f},{v_ori:.1f},5000,1000]"
                written += dur
            else:
                lo_ticks = math.ceil(max(fastest[i - 1], T_RESOLUTION_S) / T_RESOLUTION_S - 1e-6)
                ticks = max(lo_ticks, round(want / T_RESOLUTION_S))
                t_txt[i] = f"{ticks * T_RESOLUTION_S:.4f}"
                written += ticks * T_RESOLUTION_S
        # --- targets
        axes = profile.to_axes(plan.q, robot)
        units = {a.axis: a.unit for a in profile.axes}
        cols = {ax: (fmt_column(axes[ax], 3 if units[ax] == "mm" else 4) if ax in axes else ["9E9"] * n)
                for ax in RAX + EAX}
        rax_txt = [",".join(v) for v in zip(*(cols[a] for a in RAX))]
        eax_txt = [",".join(v) for v in zip(*(cols[a] for a in EAX))]
        lin_idx = np.flatnonzero(kind == KIND_LINEAR)
        robt = {}
        if len(lin_idx):
            W = invert(matrix_from_xyz_rpy(profile.wobj["xyz_mm"], profile.wobj["rpy_deg"]))
            P = plan.P[lin_idx] @ W[:3, :3].T + W[:3, 3]
            Q = _quat_column(W[:3, :3][None] @ plan.R[lin_idx])
            rear, lower = Kinematics(robot).arm_configuration(plan.q[lin_idx])
            cf = np.stack([np.floor(axes[a][lin_idx] / 90.0) for a in ("rax_1", "rax_4", "rax_6")], axis=1)
            cfx = 4 * rear + 2 * lower + (axes["rax_5"][lin_idx] < 0)
            px = [fmt_column(P[:, j], 3) for j in range(3)]
            qx = [fmt_column(Q[:, j], 6) for j in range(4)]
            for j, i in enumerate(lin_idx):
                robt[i] = (f"[[{px[0][j]},{px[1][j]},{px[2][j]}],[{qx[0][j]},{qx[1][j]},{qx[2][j]},{qx[3][j]}],"
                           f"[{int(cf[j, 0])},{int(cf[j, 1])},{int(cf[j, 2])},{int(cfx[j])}],[{eax_txt[i]}]]")
        moves = []
        for i in range(n):
            if i == 0:
                moves.append(f"MoveAbsJ [[{rax_txt[0]}],[{eax_txt[0]}]], {o['approach_speed']}, fine, {tool} "
                             f"\\WObj:={wobj};")
            elif kind[i] == KIND_LINEAR:
                moves.append(f"MoveL {robt[i]}, {speed_txt[i]}, {zone_names[i]}, {tool} \\WObj:={wobj};")
            else:
                moves.append(f"MoveAbsJ [[{rax_txt[i]}],[{eax_txt[i]}]], {o['speed']} \\T:={t_txt[i]}, "
                             f"{zone_names[i]}, {tool} \\WObj:={wobj};")
        # --- process markers and I/O around the rows
        sig = o["process_signal"]
        labels = list(process.row_labels)
        before: dict[int, list[str]] = {}
        after: dict[int, list[str]] = {}
        row_no = 0
        for i in np.flatnonzero(plan.row_start | plan.row_end):
            if plan.row_start[i]:
                row_no = int(plan.row[i]) + 1
                label = f": {labels[row_no - 1]}" if row_no - 1 < len(labels) else ""
                before[i] = [f"! Row {row_no} of {plan.rows}{label}"] + ([f"SetDO {sig}, 1;"] if sig else [])
            if plan.row_end[i]:
                after[i] = ([f"SetDO {sig}, 0;"] if sig else []) + [f"! End of row {int(plan.row[i]) + 1}"]

        def body(r):
            out = []
            for i in r:
                out += before.get(i, [])
                out.append(moves[i])
                out += after.get(i, [])
            return out

        n_lin = int((kind == KIND_LINEAR).sum())
        stops = int((level < 0).sum())
        date = program_date(o["date"], process)
        header = [f"! Generated by camtool {__version__} for robot {robot.name}: {n} moves ({n_lin} MoveL, "
                  f"{n - n_lin} MoveAbsJ), {stops} exact stops, {plan.rows} rows, {trajectory.duration_s:.3f} s",
                  f"! Job: {process.job_name or 'unknown'}; date {date} UTC (options.date = {o['date']}).",
                  f"! Profile: {Path(profile.source).name}. Units: mm, deg, s; 9E9 = axis not connected.",
                  f"! Moves merged and corners blended within {process.path_tol_mm:g} mm of the planned path "
                  "(post.path_tol_mm).",
                  (f"! Process: SetDO {sig}, 1 before each row's first work point, 0 after its last one."
                   if sig else "! Process: no signal configured (profile options.process_signal); this program "
                               "switches nothing.")]
        decl = [self._tooldata(tool, profile.tool), self._wobjdata(wobj, profile.wobj)]
        files: dict[str, list[str]] = {}
        if len(parts) == 1:
            files[name] = self._module(name, header, decl, "main", body(parts[0]))
        else:
            main_body = []
            for i, r in enumerate(parts, 1):
                part = f"{name}_{i:03d}"
                where = f"{o['module_dir'].rstrip('/')}/{part}.mod"
                main_body += [f'Load \\Dynamic, "{where}";', f'%"{part}_run"%;', f'UnLoad "{where}";']
                files[part] = self._module(part, [f"! Part {i} of {len(parts)} of {name}: moves "
                                                  f"{r.start + 1}..{r.stop}; it starts and ends off the surface."],
                                           [], f"{part}_run", body(r))
            files = {name: self._module(name, header + [f"! Runs {len(parts)} modules in turn."], decl, "main",
                                        main_body), **files}
        written = [outdir / f"{name}.pgf"]
        written[0].write_bytes(("<?xml version=\"1.0\" encoding=\"ISO-8859-1\" ?>\n<Program>\n"
                                f"  <Module>{name}.mod</Module>\n</Program>\n").encode("ascii"))
        for mod, lines in files.items():
            p = outdir / f"{mod}.mod"
            p.write_bytes(("\n".join(lines) + "\n").encode("latin-1"))
            written.append(p)
        return written

    @staticmethod
    def _module(name, header, decl, proc, body) -> list[str]:
        return ([f"MODULE {name}"] + [f"  {h}" for h in header] + [f"  {d}" for d in decl]
                + [f"  PROC {proc}()"] + [f"    {b}" for b in body] + ["  ENDPROC", "ENDMODULE"])

    @staticmethod
    def _quat(rpy_deg) -> str:
        q = quaternion_wxyz_from_matrix(matrix_from_xyz_rpy([0, 0, 0], rpy_deg)[:3, :3])
        return ",".join(fmt_num(v, 6) for v in q)

    def _tooldata(self, name: str, tool: dict) -> str:
        xyz = ",".join(fmt_num(v, 3) for v in tool["tcp_xyz_mm"])
        cog = ",".join(fmt_num(v, 3) for v in tool["cog_mm"])
        mass = fmt_num(max(float(tool["mass_kg"]), 0.001), 3)  # the controller refuses a zero mass
        return f"PERS tooldata {name}:=[TRUE,[[{xyz}],[{self._quat(tool['tcp_rpy_deg'])}]],[{mass},[{cog}],[1,0,0,0],0,0,0]];"

    def _wobjdata(self, name: str, wobj: dict) -> str:
        xyz = ",".join(fmt_num(v, 3) for v in wobj["xyz_mm"])
        return f'PERS wobjdata {name}:=[FALSE,TRUE,"",[[{xyz}],[{self._quat(wobj["rpy_deg"])}]],[[0,0,0],[1,0,0,0]]];'

    # --- reading ---------------------------------------------------------------------------

    def read_program(self, path: Path, robot, profile) -> ProgramMoves:
        """Every motion instruction of a program (.pgf or .mod and the modules it loads) in
        run order, with the process markers (``! Row`` / ``SetDO``) and modules as parts;
        Cartesian targets as TCP poses in the robot base frame (the work object applied)."""
        modules = program_modules(Path(path))
        key = (str(path), tuple(id(mt) for _p, mt in modules), id(profile), robot.name, id(robot))
        hit = _READ.get(key)
        if hit is not None and hit[0] == [mt for _p, mt in modules] and hit[2] is profile and hit[3] is robot:
            return hit[1]
        prog = self._read_program(modules, robot, profile)
        if len(_READ) >= 16:  # a few programs: a check and the simulation of the same file share them
            _READ.clear()
        _READ[key] = ([mt for _p, mt in modules], prog, profile, robot)  # the objects kept: their ids stay theirs
        return prog

    def _read_program(self, modules, robot, profile) -> ProgramMoves:
        values = {k: v for _p, mt in modules for k, v in mt.values.items()}
        seq, where, part = [], [], []
        starts, ends, names = set(), set(), []
        part_no = -1
        for mp, mt in modules:
            if mt.moves:
                part_no += 1
            pending_start = None
            for it in mt.items:
                if it[0] == "move":
                    mv = it[1]
                    if pending_start is not None:
                        starts.add(len(seq))
                        names.append(pending_start)
                        pending_start = None
                    seq.append(mv)
                    where.append(f"{mp}:{mv.line}")
                    part.append(max(part_no, 0))
                elif it[0] == "row" or (it[0] == "do" and it[3] == 1):
                    if pending_start is None:
                        pending_start = it[2] if it[0] == "row" else f"{it[2]} on"
                elif (it[0] == "end_row" or (it[0] == "do" and it[3] == 0)) and seq:
                    ends.add(len(seq) - 1)
        M = len(seq)
        kw = empty_moves(M, robot.dof)
        kw["part"] = np.array(part, int)
        if M:
            kind = np.array([mv.kind for mv in seq])
            kw["kind"] = kind.astype(kw["kind"].dtype)
            AX = np.array([(mv.rax if mv.kind == JOINT else [np.nan] * 6) + mv.eax for mv in seq], float)
            AX[AX >= 8.9e9] = np.nan
            axis_names = RAX + EAX
            for a in profile.axes:
                jn = robot.joint_names.index(a.joint)
                x = (AX[:, axis_names.index(a.axis)] - a.offset) / a.sign
                kw["q"][:, jn] = x if robot.prismatic[jn] else np.radians(x)
            kw["duration_s"] = np.array([np.nan if mv.t_s is None else mv.t_s for mv in seq], float)
            kw["blend_mm"] = np.array([ZONE_MM.get(mv.zone, 0.0) for mv in seq], float)
            frames = {}
            for k in np.flatnonzero(kind != JOINT):
                mv = seq[k]
                if mv.wobj not in frames:
                    frames[mv.wobj] = _wobj_frame(values, mv.wobj)
                F = frames[mv.wobj]
                kw["pose"][k] = F @ _pose(mv.to[0], mv.to[1])
                kw["conf"][k] = mv.to[2]
                if mv.via is not None:
                    kw["via"][k] = F @ _pose(mv.via[0], mv.via[1])
                if mv.speed.startswith("["):
                    sp = _floats(mv.speed.strip("[]"))
                    kw["speed_mm_s"][k], kw["ori_speed_deg_s"][k] = sp[0], sp[1]
                else:
                    kw["speed_mm_s"][k] = float(mv.speed[1:]) if mv.speed[1:].isdigit() else np.nan
        kw["row_start"][sorted(starts)] = True
        kw["row_end"][sorted(ends)] = True
        tool = seq[0].tool if seq else None
        return ProgramMoves(**kw, where=where, row_names=names, tool_T_mm=_tool_frame(values, tool),
                            conf_convention="abb")

    def read(self, path: Path, robot, profile) -> tuple[np.ndarray, np.ndarray]:
        """(durations_s, q): each move's duration (\\T; for a MoveL its length over its TCP
        speed; NaN for the first) and its target in rad / mm (a Cartesian target's joints by
        the simulator's inverse kinematics), following a .pgf and the Loads of a main module."""
        from camtool.simulate import move_durations, target_joints

        prog = self.read_program(Path(path), robot, profile)
        q = target_joints(prog, robot, profile)
        return move_durations(prog, robot, q), q

    @staticmethod
    def moves_to_arrays(moves: list[Move], robot, profile) -> tuple[np.ndarray, np.ndarray]:
        """Durations (s, NaN when absent) and joint values (rad / mm) of parsed joint moves."""
        dur = np.array([np.nan if m.t_s is None else m.t_s for m in moves])
        if not moves:
            return dur, np.zeros((0, robot.dof))
        names = RAX + EAX
        AX = np.array([m.rax + m.eax for m in moves], float)
        values = {a.axis: AX[:, names.index(a.axis)] for a in profile.axes}
        return dur, profile.from_axes(values, robot)

    # --- checking --------------------------------------------------------------------------

    def check(self, path: Path, robot, profile) -> list[str]:
        """Findings for a program (.pgf) or module (.mod) and the modules it loads: module /
        proc nesting (a truncated module lacks ENDPROC / ENDMODULE), statements, identifiers,
        declared tool and work object, 6 + 6 finite jointtarget values, robtargets (3 + 4 + 4
        + 6 values, a unit quaternion, integer confdata), 9E9 exactly on the axes the profile
        leaves unconnected, zones, speed data, row markers in pairs, a ``fine`` last move;
        then every target against the robot's limits (a Cartesian target's joints by the
        simulator's inverse kinematics) and every step's speed against its speed limits
        (tolerance: the written 1e-4 deg / 1e-3 mm)."""
        path = Path(path)
        out: list[str] = []
        try:
            modules = program_modules(path)
        except BadInput as exc:
            return [str(exc)]
        if path.suffix.lower() == ".pgf" and not path.read_bytes().endswith(b"\n"):
            out.append(f"{path}: no newline at end of file")
        mapped = {a.axis for a in profile.axes}
        names = RAX + EAX
        procs = {p for _mp, mt in modules for p in mt.procs}
        declared = {n: t for _mp, mt in modules for n, t in mt.data.items()}
        entry = path.suffix.lower() == ".pgf" or "main" in modules[0][1].procs
        moves, where = [], []
        open_row = None
        for mp, mt in modules:
            out += mt.problems
            if mt.name:
                ident, _ = rapid_identifier(mt.name)
                if ident != mt.name or len(mt.name) > 32:
                    out.append(f"{mp}: module name {mt.name!r} is not a valid RAPID identifier")
                if mt.name != mp.stem:
                    out.append(f"{mp}: module {mt.name!r} is in a file named {mp.name!r}")
            for p in mt.procs + list(mt.data):
                if rapid_identifier(p)[0] != p and p not in BUILTIN_DATA:
                    out.append(f"{mp}: {p!r} is not a valid RAPID identifier")
            for n, proc in mt.calls:
                if proc not in procs:
                    out.append(f"{mp}:{n}: %\"{proc}\"% calls a routine no loaded module defines")
            for it in mt.items:
                if it[0] == "row":
                    if open_row is not None:
                        out.append(f"{mp}:{it[1]}: a row starts before the previous one ended")
                    open_row = it[1]
                elif it[0] == "end_row":
                    if open_row is None:
                        out.append(f"{mp}:{it[1]}: a row ends that never started")
                    open_row = None
            if not mt.moves:
                continue
            w_mod = [f"{mp}:{mv.line}" for mv in mt.moves]
            # axis values of every move: jointtargets in full, robtargets' external axes (NaN on rax)
            AX = np.array([(mv.rax if mv.kind == JOINT else [np.nan] * 6) + mv.eax for mv in mt.moves], float)
            for j, ax in enumerate(names):
                col = AX[:, j]
                bad = np.flatnonzero(col >= 8.9e9) if ax in mapped else \
                    np.flatnonzero(np.isfinite(col) & (col != NOT_CONNECTED))
                for i in bad[:20]:
                    out.append(f"{w_mod[i]}: {ax} is connected (profile) but written as 9E9" if ax in mapped else
                               f"{w_mod[i]}: {ax} is not connected (profile) and must be 9E9, found {col[i]}")
            for i, mv in enumerate(mt.moves):
                if mv.zone not in ZONE_MM:
                    out.append(f"{w_mod[i]}: unknown zone {mv.zone!r}")
            speeds = {mv.speed for mv in mt.moves}
            bad_speeds = {sp for sp in speeds if not _speed_ok(sp)}
            if bad_speeds:
                out += [f"{w_mod[i]}: unknown speed data {mv.speed!r}" for i, mv in enumerate(mt.moves)
                        if mv.speed in bad_speeds]
            if entry:  # a split module alone relies on the main module's declarations
                for kind, attr in (("tooldata", "tool"), ("wobjdata", "wobj")):
                    names_used = {getattr(mv, attr) for mv in mt.moves}
                    undeclared = {nm for nm in names_used if nm and nm not in BUILTIN_DATA and declared.get(nm) != kind}
                    out += [f"{w_mod[i]}: {kind} {getattr(mv, attr)!r} is not declared in the program"
                            for i, mv in enumerate(mt.moves) if getattr(mv, attr) in undeclared]
            moves += mt.moves
            where += w_mod
        if open_row is not None and entry:
            out.append(f"{path}: row started at line {open_row} never ends")
        if entry and "main" not in modules[0][1].procs:
            out.append(f"{modules[0][0]}: the main module has no PROC main()")
        if entry and moves and moves[-1].zone != "fine":
            out.append(f"{where[-1]}: the last move must be fine, found {moves[-1].zone}")
        if not moves or out:
            if not moves and not out:
                out.append(f"{path}: no MoveAbsJ found")
            if any("connected" in f for f in out) or not moves:
                return out
        if any(mv.kind != JOINT for mv in moves):
            if not entry:
                return out  # a part alone: its work object is declared in the main module
            try:
                from camtool.simulate import move_durations, target_joints
                prog = self.read_program(path, robot, profile)
                q = target_joints(prog, robot, profile)
                dur = move_durations(prog, robot, q)
            except BadInput as exc:
                return out + [str(exc)]
            bad = np.flatnonzero(~np.isfinite(q).all(axis=1))
            if len(bad):
                return out + [f"{prog.where[k]}: no joint values reach this target in its configuration"
                              for k in bad[:20]]
            return out + check_motion(q, dur, robot, prog.where, resolution_tol(robot, 1e-4, 1e-3) + 1e-6)
        dur, q = self.moves_to_arrays(moves, robot, profile)
        return out + check_motion(q, dur, robot, where, resolution_tol(robot, 1e-4, 1e-3))


def _angles(Ra: np.ndarray, Rb: np.ndarray) -> np.ndarray:
    """Rotation angles (rad) from each Ra to Rb."""
    R = np.transpose(Ra, (0, 2, 1)) @ Rb
    s = 0.5 * np.linalg.norm(np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0],
                                       R[:, 1, 0] - R[:, 0, 1]], axis=1), axis=1)
    c = (np.trace(R, axis1=1, axis2=2) - 1.0) / 2.0
    return np.arctan2(s, c)
