"""Yaskawa INFORM post-processor: ``.JBI`` job files (ASCII, CRLF).

The moves come from ``postprocessors.moves.plan_moves`` (waypoints merged
within the path tolerance, corners blended by position levels, exact stops
``PL=0`` only at the first move, the top of a retract, the end of a job that
is followed by another, and the end). Each move has its own position:

- **Joint moves** ``MOVJ C… [BC…] VJ=xx.xx PL=n`` to positions in pulses
  (``///POSTYPE PULSE``; ``C`` line for the robot RB1, ``BC`` for a base axis
  BS1, ``EC`` for a station ST1, axis order from the profile). INFORM has no
  per-move duration, so the timing is approximated by VJ, a percentage of each
  axis's maximum speed ``max_speed`` from the profile::

      VJ = 100 * max_i |dv_i| / (dt * vmax_i)

  with dt the planned duration of the move; VJ is rounded to 0.01 so that the
  job's clock tracks the plan's, never above what the robot's speed limits
  allow, and clipped to 0.01..100.00. The first move (from wherever the robot
  is) uses ``approach_vj``.
- **Linear moves** (profile option ``motion = "cartesian"``, robots whose
  kinematics the controller knows, robot group RB1 only) ``MOVL C… V=v PL=n`` to
  Cartesian positions in the robot base frame (``///POSTYPE BASE``,
  ``///RECTAN``, ``///RCONF`` from the planned joints; ``C=X,Y,Z,Rx,Ry,Rz[,Re]``
  in mm and degrees, the rotation fixed-axis x, y, z, and Re the 7th axis value
  of a 7-axis arm) with the TCP speed V (mm/s, 0.1) that gives the planned
  duration. Free motion stays joint moves.
- **Process I/O**: ``DOUT OT#(n) ON`` before the move to each row's first work
  point and ``DOUT OT#(n) OFF`` after the move to its last (option
  ``process_output``; 0 = none, the job says so in a comment). Every row starts
  with a comment ``'ROW n/N`` and ends with ``'END ROW n``.
- ``///DATE`` from the ``date`` option (default ``job``: the job file's time, so
  reruns give byte-identical files), ``///COMM`` names the job.

Jobs longer than ``lines_per_job`` positions are split, only after a target in
free motion, into ``NAME_1``, ``NAME_2`` ... (each name <= ``job_name_length``
characters) and a main job ``NAME`` runs them with ``CALL JOB:...``.
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

from .base import ProcessInfo, program_date, sanitise_name
from .check import check_motion
from .moves import KIND_LINEAR, Kinematics, plan_moves, profile_tool, split_parts
from .program import JOINT, LINEAR, ProgramMoves, empty_moves

GROUPS = {"RB1": "C", "BS1": "BC", "ST1": "EC"}  # axis group -> position line prefix
AXIS_RE = re.compile(r"^(RB1|BS1|ST1):([1-9][0-9]*)$")
DATE_RE = re.compile(r"^\d{4}/\d{2}/\d{2} \d{2}:\d{2}$")
POS_RE = re.compile(r"^(C|BC|EC)(\d{5})=(.*)$")
MOVE_RE = re.compile(r"^(MOVJ|MOVL)((?: (?:C|BC|EC)\d{5})+) (?:VJ=(\d+\.\d{2})|V=(\d+(?:\.\d+)?)) PL=(\d+)$")
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


@dataclass
class JbiMove:
    """One parsed move: line number, kind (J / L), referenced positions by prefix, VJ (%) or
    V (mm/s), PL."""

    line: int
    refs: dict[str, int]
    vj: float
    pl: int
    kind: str = JOINT
    v: float = float("nan")


@dataclass
class JbiText:
    """What the reader finds in one .JBI file. Each position is ``(index, values, line,
    kind, rconf)`` with kind ``pulse`` (integers) or ``rectan`` (mm / deg)."""

    name: str = ""
    npos: list[int] = field(default_factory=list)
    tool: int | None = None
    group: list[str] = field(default_factory=list)
    attr: str = ""
    comm: str | None = None
    pos: dict[str, list[tuple]] = field(default_factory=lambda: {"C": [], "BC": [], "EC": []})
    moves: list[JbiMove] = field(default_factory=list)
    items: list[tuple] = field(default_factory=list)
    calls: list[tuple[int, str]] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    bad_values: list[str] = field(default_factory=list)  # position lines whose values cannot be read


def parse_jbi(path: Path) -> JbiText:
    """Parse a job file; every structural problem is collected (NPOS, indices, values per
    line, references, END, CRLF, ASCII), never raised; cached by path and content (callers
    must not change the result). ``items`` holds, in order, the moves
    and the process markers: ``("move", JbiMove)``, ``("row", line, text)``, ``("end_row",
    line)``, ``("dout", line, n, on)``."""
    import hashlib

    try:
        raw = Path(path).read_bytes()
    except OSError as exc:
        j = JbiText()
        j.problems.append(f"{path}: cannot read ({exc})")
        return j
    key = (str(path), hashlib.blake2b(raw, digest_size=16).digest())
    if key in _PARSED:
        return _PARSED[key]
    j = _parse_jbi(path, raw)
    if len(_PARSED) >= 64:
        _PARSED.clear()
    _PARSED[key] = j
    return j


_PARSED: dict = {}  # (path, content digest) -> JbiText: a check and a simulation read a job once
_READ: dict = {}    # the programs read last (read_program), by their parsed jobs, profile and robot


def _parse_jbi(path, raw: bytes) -> JbiText:
    j = JbiText()
    p = f"{path}"
    bulk: list = []  # short pulse lines: (position entry, its values' text)
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError as exc:
        j.problems.append(f"{p}: not ASCII (byte {exc.start})")
        text = raw.decode("latin-1")
    if not text.endswith("\r\n"):
        j.problems.append(f"{p}: the file must end with CRLF")
    lines = text.split("\r\n")
    if lines[-1] == "":
        lines = lines[:-1]
    section = ""
    postype, rconf = "pulse", None
    for n, line in enumerate(lines, 1):
        where = f"{p}:{n}"
        if "\n" in line or "\r" in line:
            j.problems.append(f"{where}: line ending is not CRLF")
            line = line.replace("\r", "").replace("\n", "")
        if n == 1:
            if line != "/JOB":
                j.problems.append(f"{where}: expected /JOB, found {line[:40]!r}")
            continue
        if section == "pos" and line[:1] in ("C", "B", "E") and (m := POS_RE.match(line)):
            pre, num, txt = m.groups()
            kind = postype if pre == "C" else "pulse"
            if kind == "pulse" and INTS_RE.match(txt) and not LONG_RE.search(txt):
                # no value can leave int64: converted in bulk below
                entry = [int(num), None, n, kind, rconf]
                j.pos[pre].append(entry)
                bulk.append((entry, txt))
                continue
            cells = txt.split(",")
            if kind == "pulse":
                if not INTS_RE.match(txt):
                    j.bad_values.append(f"{where}: pulse values must be integers")
                    j.problems.append(j.bad_values[-1])
                    continue
                big = next((c for c in cells if len(c.lstrip("-").lstrip("0")) > 19
                            or not INT64[0] <= int(c) <= INT64[1]), None)
                if big is not None:
                    shown = big if len(big) <= 30 else big[:27] + "..."
                    j.bad_values.append(f"{where}: pulse value {shown} is beyond the int64 range")
                    j.problems.append(j.bad_values[-1])
                    continue
                vals = [int(c) for c in cells]
            else:
                if not all(FLOAT_RE.match(c) for c in cells):
                    j.bad_values.append(f"{where}: Cartesian values must be finite decimal numbers")
                    j.problems.append(j.bad_values[-1])
                    continue
                vals = [float(c) for c in cells]
            j.pos[m.group(1)].append((int(m.group(2)), vals, n, kind, rconf))
        elif section == "inst" and line[:3] == "MOV" and (m := MOVE_RE.match(line)):
            refs = {}
            for tok in m.group(2).split():
                pre = tok.rstrip("0123456789")
                if pre in refs:
                    j.problems.append(f"{where}: {pre} given twice")
                refs[pre] = int(tok[len(pre):])
            kind = JOINT if m.group(1) == "MOVJ" else LINEAR
            if (kind == JOINT) != (m.group(3) is not None):
                j.problems.append(f"{where}: {m.group(1)} takes {'VJ' if kind == JOINT else 'V'}=")
                continue
            mv = JbiMove(n, refs, float(m.group(3)) if m.group(3) else float("nan"), int(m.group(5)), kind,
                         float(m.group(4)) if m.group(4) else float("nan"))
            j.moves.append(mv)
            j.items.append(("move", mv))
        elif line.startswith("//NAME "):
            j.name = line[7:]
        elif line == "//POS":
            section = "pos"
        elif line == "//INST":
            section = "inst"
        elif line.startswith("///NPOS "):
            try:
                j.npos = [int(x) for x in line[8:].split(",")]
            except ValueError:
                j.problems.append(f"{where}: NPOS must be 6 integers")
            if len(j.npos) != 6:
                j.problems.append(f"{where}: NPOS must be 6 integers")
        elif line.startswith("///TOOL "):
            j.tool = int(line[8:]) if line[8:].isdigit() else None
        elif line.startswith("///GROUP1 "):
            j.group = line[10:].split(",")
        elif line.startswith("///ATTR "):
            j.attr = line[8:]
            if line[8:] not in ("SC,RW", "SC,RW,RJ"):
                j.problems.append(f"{where}: unexpected ///ATTR {line[8:]}")
        elif line.startswith("///COMM"):
            j.comm = line[8:]
            if len(j.comm) > 32:
                j.problems.append(f"{where}: ///COMM is longer than 32 characters")
        elif section == "pos" and line.startswith("///POSTYPE "):
            kind = line[11:]
            if kind not in ("PULSE", "BASE"):
                j.problems.append(f"{where}: ///POSTYPE {kind} is not supported (PULSE or BASE)")
            postype = "pulse" if kind == "PULSE" else "rectan"
        elif section == "pos" and line.startswith("///RCONF "):
            try:
                rconf = [int(x) for x in line[9:].split(",")]
            except ValueError:
                j.problems.append(f"{where}: RCONF must be integers")
            else:
                if len(rconf) < 6 or any(v not in (0, 1) for v in rconf):
                    j.problems.append(f"{where}: RCONF needs at least 6 values of 0 or 1")
        elif line in ("///PULSE", "///RECTAN", "NOP") or line.startswith("///DATE "):
            if line.startswith("///DATE ") and not DATE_RE.match(line[8:]):
                j.problems.append(f"{where}: DATE must be yyyy/mm/dd hh:mm")
        elif line.startswith("'"):
            if section == "inst" and (m := ROW_RE.match(line)):
                j.items.append(("row", n, line[1:]))
            elif section == "inst" and ROW_END_RE.match(line):
                j.items.append(("end_row", n))
            continue
        elif section == "inst" and (m := DOUT_RE.match(line)):
            j.items.append(("dout", n, int(m.group(1)), m.group(2) == "ON"))
        elif section == "inst" and (m := CALL_RE.match(line)):
            j.calls.append((n, m.group(1)))
        elif line == "END":
            if n != len(lines):
                j.problems.append(f"{where}: text after END")
        else:
            j.problems.append(f"{where}: unrecognised line: {line[:60]}")
    if bulk:  # every short pulse line at once
        flat = np.array(",".join(txt for _e, txt in bulk).split(","), dtype=np.int64).tolist()
        i = 0
        for entry, txt in bulk:
            c = txt.count(",") + 1
            entry[1] = flat[i:i + c]
            i += c
    for pre in j.pos:
        j.pos[pre] = [tuple(e) for e in j.pos[pre]]
    if not lines or lines[-1] != "END":
        j.problems.append(f"{p}: the job does not end with END")
    if not j.name:
        j.problems.append(f"{p}: no //NAME line")
    if len(j.npos) == 6:
        for k, pre in enumerate(("C", "BC", "EC")):
            if j.npos[k] != len(j.pos[pre]):
                j.problems.append(f"{p}: NPOS says {j.npos[k]} {pre} positions, the file has {len(j.pos[pre])}")
        if any(j.npos[3:]):
            j.problems.append(f"{p}: NPOS counts P/BP/EX variables, which camtool never writes")
    elif not j.npos:
        j.problems.append(f"{p}: no ///NPOS line")
    order = [ln for pre in ("C", "BC", "EC") for (_i, _v, ln, _k, _r) in j.pos[pre]]
    if order != sorted(order):
        j.problems.append(f"{p}: positions must come as all C lines, then BC, then EC")
    for pre, items in j.pos.items():
        idx = [it[0] for it in items]
        if idx != list(range(len(idx))):
            bad = next(k for k, i in enumerate(idx) if i != k)
            j.problems.append(f"{p}:{items[bad][2]}: {pre} indices must be contiguous from 00000")
        for kind in ("pulse", "rectan"):
            counts = {len(it[1]) for it in items if it[3] == kind}
            if len(counts) > 1:
                j.problems.append(f"{p}: {pre} lines have different numbers of values ({sorted(counts)})")
    if any(it[3] == "rectan" for it in j.pos["C"]) and j.attr and "RJ" not in j.attr.split(","):
        j.problems.append(f"{p}: Cartesian positions need ///ATTR SC,RW,RJ")
    need = {"RB1": "C", "BS1": "BC", "ST1": "EC"}
    for mv in j.moves:
        for pre, i in mv.refs.items():
            if i >= len(j.pos[pre]):
                j.problems.append(f"{p}:{mv.line}: {pre}{i:05d} is not defined in //POS")
        for g in j.group:
            if g in need and need[g] not in mv.refs:
                j.problems.append(f"{p}:{mv.line}: group {g} needs a {need[g]} position on every move")
        if mv.kind == JOINT and not 0.01 <= mv.vj <= 100.0:
            j.problems.append(f"{p}:{mv.line}: VJ={mv.vj:.2f} outside 0.01..100.00")
        if mv.kind == LINEAR and not mv.v > 0:
            j.problems.append(f"{p}:{mv.line}: V={mv.v} must be above 0")
        if mv.kind == LINEAR and "C" in mv.refs and mv.refs["C"] < len(j.pos["C"]) \
                and j.pos["C"][mv.refs["C"]][3] != "rectan":
            j.problems.append(f"{p}:{mv.line}: MOVL to a pulse position (camtool writes Cartesian ones)")
        if not 0 <= mv.pl <= 8:
            j.problems.append(f"{p}:{mv.line}: PL={mv.pl} outside 0..8")
    return j


def job_files(path: Path) -> list[tuple[Path, JbiText]]:
    """A job and, in run order, the jobs it CALLs (found as NAME.JBI in the same folder)."""
    path = Path(path)
    j = parse_jbi(path)
    out = [(path, j)]
    for _n, name in j.calls:
        out.append((path.parent / f"{name}.JBI", parse_jbi(path.parent / f"{name}.JBI")))
    return out


def _rconf(kin: Kinematics, axes: dict, groups, q: np.ndarray, n_fields: int) -> list[str]:
    """``///RCONF`` values (flip, lower arm, rear, R>=180, T>=180, S>=180, 0...) per target."""
    rb = groups["RB1"]
    val = {i + 1: axes[a.axis] for i, a in enumerate(rb)}
    rear, lower = kin.arm_configuration(q)
    flip = (val[5] < 0).astype(int)  # unverified: 'flip' taken as B < 0
    big = [(np.abs(val[i]) >= 180).astype(int) for i in (4, 6, 1)]
    rows = np.stack([flip, lower.astype(int), rear.astype(int), *big], axis=1)
    return [",".join(str(int(v)) for v in r) + ",0" * (n_fields - 6) for r in rows]


class InformPost:
    """Yaskawa INFORM writer and reader (see module doc)."""

    name = "inform"
    extension = ".JBI"
    extensions = (".JBI",)
    requires_profile = True
    check_covers_calls = True  # checking the entry file checks every module / job it runs
    options_schema = {
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
        "date": (str, "job", "///DATE: 'job' (the job file's time, UTC: reruns are byte-identical), 'now', "
                             "or a fixed 'yyyy/mm/dd hh:mm'."),
        "job_name_length": (int, 8, "Longest job name; 8 is safe, newer controllers take 32."),
    }

    def validate_profile(self, profile, robot) -> None:
        """BadInput unless the axis map fits INFORM (every joint on RB1/BS1/ST1 with pulses and
        max_speed) and the options are valid."""
        require_full_map(profile, robot)
        for a in profile.axes:
            where = f"{profile.source}: axes.{a.joint}"
            if not AXIS_RE.match(a.axis):
                raise BadInput(f"{where}.axis: expected RB1:n, BS1:n or ST1:n, found {a.axis!r}")
            if a.pulses is None:
                raise BadInput(f"{where}.pulses: missing (pulses per {a.unit} of this axis, from the controller's parameters)")
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

    @staticmethod
    def to_pulses(profile, robot, q_native: np.ndarray) -> dict[str, np.ndarray]:
        """Pulses (int64, M x n) per group for joint values (rad / mm)."""
        axes = profile.to_axes(q_native, robot)
        return {g: np.stack([np.round(axes[a.axis] * a.pulses).astype(np.int64) + a.zero_pulses for a in ax], axis=1)
                for g, ax in group_axes(profile).items()}

    @staticmethod
    def from_pulses(profile, robot, pulses: dict[str, np.ndarray]) -> np.ndarray:
        """Joint values (rad / mm) from pulses per group."""
        values = {}
        for g, ax in group_axes(profile).items():
            for k, a in enumerate(ax):  # in float: no int64 wrap-around for absurd pulse values
                values[a.axis] = (np.asarray(pulses[g][:, k], float) - float(a.zero_pulses)) / a.pulses
        return profile.from_axes(values, robot)

    # --- writing ---------------------------------------------------------------------------

    def write(self, trajectory, robot, profile, outdir: Path, process: ProcessInfo | None = None) -> list[Path]:
        """Write ``NAME.JBI`` (plus ``NAME_1.JBI`` ... parts and a main job when split)."""
        self.validate_profile(profile, robot)
        process = process if process is not None else ProcessInfo()
        o = profile.options
        outdir = Path(outdir)
        name, _ = job_name(profile.program_name, o["job_name_length"])
        robot = robot.with_placement(tool_T_mm=profile_tool(profile))  # the TCP the program declares
        cart = o["motion"] == "cartesian"
        radii = [float(v) for v in o["pl_mm"]][:o["max_pl"]]
        plan = plan_moves(trajectory, robot, process, linear=cart, levels_mm=radii,
                          min_level_on_surface=max(1, o["pl"]) - 1)
        n = len(plan)
        kind = np.array(plan.kind)
        length = np.r_[0.0, np.linalg.norm(np.diff(plan.P, axis=0), axis=1)]
        kind[(kind == KIND_LINEAR) & (length < 1e-3)] = JOINT
        parts = split_parts(n, o["lines_per_job"], plan.free, "positions", f"{profile.source}: options.lines_per_job")
        pl = plan.level + 1  # level -1 (exact stop) -> PL=0
        for r in parts[:-1]:
            pl[r.stop - 1] = 0  # CALL JOB ends the motion: the job before ends with a stop
        groups = group_axes(profile)
        pulses = self.to_pulses(profile, robot, plan.q)
        axes = profile.to_axes(plan.q, robot)
        order = [a for ax in groups.values() for a in ax]
        vmax = np.array([a.max_speed for a in order])
        values = np.stack([axes[a.axis] for a in order], axis=1)
        # --- timing: VJ for joint moves, V for linear ones; the job's clock tracks the plan
        speed = [""] * n
        speed[0] = f"VJ={o['approach_vj']:.2f}"
        fastest = np.max(np.abs(np.diff(plan.q, axis=0)) / robot.limits.velocity[None, :], axis=1) \
            if n > 1 else np.zeros(0)
        governing = np.max(np.abs(np.diff(values, axis=0)) / vmax[None, :], axis=1) if n > 1 else np.zeros(0)
        dt = np.diff(plan.t)
        planned = written = 0.0
        for i in range(1, n):
            planned += dt[i - 1]
            want = max(planned - written, 1e-4)
            if kind[i] == KIND_LINEAR:
                v = max(V_STEP, round(length[i] / want / V_STEP) * V_STEP)
                speed[i] = f"V={v:.1f}"
                written += length[i] / v
            else:
                g = governing[i - 1]
                if g <= 0:
                    speed[i] = "VJ=0.01"
                    continue
                cap = 100.0 if fastest[i - 1] <= 0 else min(100.0, math.floor(100 * g / fastest[i - 1] * 100 + 1e-6) / 100)
                vj = min(cap, max(0.01, round(100 * g / want, 2)))
                speed[i] = f"VJ={vj:.2f}"
                written += 100 * g / vj
        # --- positions
        lin = kind == KIND_LINEAR
        pos_txt: dict[str, list[str]] = {}
        for g, pre in GROUPS.items():
            if g in pulses:
                pos_txt[pre] = [",".join(map(str, row)) for row in pulses[g].tolist()]
        rconf = [None] * n
        if lin.any():
            li = np.flatnonzero(lin)
            ang = euler_xyz_deg(plan.R[li])
            rb = groups["RB1"]
            extra = [axes[rb[6].axis][li]] if len(rb) == 7 else []
            cols = [plan.P[li, 0], plan.P[li, 1], plan.P[li, 2], ang[:, 0], ang[:, 1], ang[:, 2], *extra]
            dec = [3, 3, 3, 4, 4, 4, 4]
            txt = [_fmt_column(c, d) for c, d in zip(cols, dec)]
            rc = _rconf(Kinematics(robot), {a: v[li] for a, v in axes.items()}, groups, plan.q[li],
                        o["rconf_fields"])
            for j, i in enumerate(li):
                pos_txt["C"][i] = ",".join(t[j] for t in txt)
                rconf[i] = rc[j]
        # --- instructions
        out_no = o["process_output"]
        labels = list(process.row_labels)
        before: dict[int, list[str]] = {}
        after: dict[int, list[str]] = {}
        for i in np.flatnonzero(plan.row_start | plan.row_end):
            r = int(plan.row[i]) + 1
            if plan.row_start[i]:
                label = f" {labels[r - 1].upper()}" if r - 1 < len(labels) else ""
                before[i] = [f"'ROW {r}/{plan.rows}{label}"[:33]] + ([f"DOUT OT#({out_no}) ON"] if out_no else [])
            if plan.row_end[i]:
                after[i] = ([f"DOUT OT#({out_no}) OFF"] if out_no else []) + [f"'END ROW {r}"]
        date = program_date(o["date"], process)
        comm = _ascii(f"camtool {process.job_name or name}")[:32]
        n_lin = int(lin.sum())
        notes = [f"'camtool {__version__} {robot.name} {n} moves",
                 f"'{n_lin} MOVL {n - n_lin} MOVJ {int((pl == 0).sum())} STOPS",
                 f"'PATH TOL {process.path_tol_mm:g} MM",
                 (f"'PROCESS OUTPUT OT#({out_no})" if out_no else "'NO PROCESS OUTPUT CONFIGURED")]
        header = dict(tool=profile.tool["number"], date=date, group=",".join(groups), comm=comm,
                      attr="SC,RW,RJ" if n_lin else "SC,RW", notes=notes)
        files: dict[str, list[str]] = {}
        job = dict(kind=kind, pos_txt=pos_txt, rconf=rconf, speed=speed, pl=pl, before=before, after=after,
                   rconf_fields=o["rconf_fields"])
        if len(parts) == 1:
            files[name] = self._job(name, parts[0], header, job)
        else:
            names = []
            for i, r in enumerate(parts, 1):
                s = f"_{i}"
                part = name[:o["job_name_length"] - len(s)] + s
                names.append(part)
                files[part] = self._job(part, r, header, job)
            main = ["/JOB", f"//NAME {name}", "//POS", "///NPOS 0,0,0,0,0,0", "//INST", f"///DATE {date}",
                    f"///COMM {comm}", "///ATTR SC,RW", f"///GROUP1 {header['group']}", "NOP"] + notes \
                + [f"CALL JOB:{n_}" for n_ in names] + ["END"]
            files = {name: main, **files}
        written_files = []
        for job_, lines in files.items():
            p = outdir / f"{job_}.JBI"
            p.write_bytes(("\r\n".join(lines) + "\r\n").encode("ascii"))
            written_files.append(p)
        return written_files

    @staticmethod
    def _job(name, r: range, header, job) -> list[str]:
        lines = ["/JOB", f"//NAME {name}", "//POS"]
        pos_txt, kind, rconf = job["pos_txt"], job["kind"], job["rconf"]
        counts = [len(r) if pre in pos_txt else 0 for pre in GROUPS.values()]
        lines += [f"///NPOS {counts[0]},{counts[1]},{counts[2]},0,0,0", f"///TOOL {header['tool']}"]
        state = None
        for i, k in enumerate(r):
            want = ("rectan", rconf[k]) if kind[k] == KIND_LINEAR else ("pulse", None)
            if want != state:
                if want[0] == "pulse":
                    lines += ["///POSTYPE PULSE", "///PULSE"]
                else:
                    if state is None or state[0] != "rectan":
                        lines += ["///POSTYPE BASE", "///RECTAN"]
                    lines.append(f"///RCONF {want[1]}")
                state = want
            lines.append(f"C{i:05d}={pos_txt['C'][k]}")
        for pre in ("BC", "EC"):
            if pre in pos_txt:
                if state is None or state[0] != "pulse":
                    lines += ["///POSTYPE PULSE", "///PULSE"]
                    state = ("pulse", None)
                lines += [f"{pre}{i:05d}={pos_txt[pre][k]}" for i, k in enumerate(r)]
        lines += ["//INST", f"///DATE {header['date']}", f"///COMM {header['comm']}", f"///ATTR {header['attr']}",
                  f"///GROUP1 {header['group']}", "NOP"] + header["notes"]
        for i, k in enumerate(r):
            lines += job["before"].get(k, [])
            refs = " ".join(f"{pre}{i:05d}" for pre in pos_txt)
            word = "MOVL" if kind[k] == KIND_LINEAR else "MOVJ"
            lines.append(f"{word} {refs} {job['speed'][k]} PL={job['pl'][k]}")
            lines += job["after"].get(k, [])
        return lines + ["END"]

    # --- reading ---------------------------------------------------------------------------

    def _collect(self, path: Path, profile):
        """Moves, their positions per prefix, file:line labels, parts and markers of a job and
        the jobs it calls."""
        moves, posns, where, part, starts, ends, names = [], [], [], [], set(), set(), []
        files = job_files(Path(path))
        part_no = -1
        for jp, j in files:
            if j.moves:
                part_no += 1
            pending = None
            for it in j.items:
                if it[0] == "move":
                    mv = it[1]
                    if pending is not None:
                        starts.add(len(moves))
                        names.append(pending)
                        pending = None
                    refs = {pre: j.pos[pre][i] for pre, i in mv.refs.items() if i < len(j.pos[pre])}
                    moves.append(mv)
                    posns.append(refs)
                    where.append(f"{jp}:{mv.line}")
                    part.append(max(part_no, 0))
                elif it[0] == "row" or (it[0] == "dout" and it[3]):
                    if pending is None:
                        pending = it[2] if it[0] == "row" else f"OT#({it[2]}) ON"
                elif (it[0] == "end_row" or (it[0] == "dout" and not it[3])) and moves:
                    ends.add(len(moves) - 1)
        return files, moves, posns, where, part, starts, ends, names

    def read_program(self, path: Path, robot, profile) -> ProgramMoves:
        """Every MOVJ / MOVL of a job and the jobs it calls, in run order, with the process
        markers (``'ROW`` / ``DOUT``) and the jobs as parts; Cartesian positions as TCP poses
        in the robot base frame (the Re value, if any, fixes the 7th axis)."""
        files = job_files(Path(path))
        key = (str(path), tuple(id(j) for _jp, j in files), id(profile), robot.name, id(robot))
        hit = _READ.get(key)
        if hit is not None and hit[0] == [j for _jp, j in files] and hit[2] is profile and hit[3] is robot:
            return hit[1]
        prog = self._read_program(path, robot, profile)
        if len(_READ) >= 16:  # a few programs: a check and the simulation of the same file share them
            _READ.clear()
        _READ[key] = ([j for _jp, j in files], prog, profile, robot)  # the objects kept: their ids stay theirs
        return prog

    def _read_program(self, path: Path, robot, profile) -> ProgramMoves:
        files, moves, posns, where, part, starts, ends, names = self._collect(path, profile)
        for _jp, j in files:
            if j.bad_values:
                raise BadInput(j.bad_values[0])
        groups = group_axes(profile)
        M = len(moves)
        kw = empty_moves(M, robot.dof)
        kw["part"] = np.array(part, int)
        o = profile.options
        radii = np.array([0.0] + [float(v) for v in o.get("pl_mm", PL_MM)])
        order = [a for ax in groups.values() for a in ax]
        vmax = np.array([a.max_speed for a in order])
        kind = np.array([mv.kind for mv in moves]) if M else np.zeros(0, str)
        pl = np.array([mv.pl for mv in moves], int) if M else np.zeros(0, int)
        kw["kind"] = kind.astype(kw["kind"].dtype) if M else kw["kind"]
        kw["blend_mm"] = np.where((pl >= 0) & (pl <= 8), radii[np.clip(pl, 0, 8)], 0.0)
        values = {a.axis: np.full(M, np.nan) for a in order}  # controller axis values (deg / mm)
        for g, pre in GROUPS.items():
            if g not in groups:
                continue
            ax = groups[g]
            refs = [r.get(pre) for r in posns]
            pulse = [k for k, r in enumerate(refs) if r is not None and r[3] == "pulse"]
            if pulse:
                try:
                    arr = np.array([refs[k][1] for k in pulse], dtype=float)
                except ValueError:
                    arr = None
                if arr is None or arr.ndim != 2 or arr.shape[1] != len(ax):
                    k = next(k for k in pulse if len(refs[k][1]) != len(ax))
                    raise BadInput(f"{where[k]}: {pre} position has {len(refs[k][1])} values, group {g} has "
                                   f"{len(ax)} axes")
                for i, a in enumerate(ax):
                    values[a.axis][pulse] = (arr[:, i] - float(a.zero_pulses)) / a.pulses
            rect = [k for k, r in enumerate(refs) if r is not None and r[3] == "rectan"]
            if rect:
                want = 6 + (len(ax) == 7)
                bad = next((k for k in rect if len(refs[k][1]) != want), None)
                if bad is not None:
                    raise BadInput(f"{where[bad]}: a Cartesian C position needs {want} values")
                arr = np.array([refs[k][1] for k in rect], dtype=float)
                T = np.broadcast_to(np.eye(4), (len(rect), 4, 4)).copy()
                T[:, :3, :3] = matrix_xyz_deg(arr[:, 3:6])
                T[:, :3, 3] = arr[:, :3]
                kw["pose"][rect] = T
                if len(ax) == 7:
                    values[ax[6].axis][rect] = arr[:, 6]
                for k in rect:
                    rc = refs[k][4]
                    if rc:
                        kw["conf"][k, :] = [rc[0], rc[1], rc[2], rc[3] * 4 + rc[4] * 2 + rc[5]]
        for a in profile.axes:
            jn = robot.joint_names.index(a.joint)
            x = (values[a.axis] - a.offset) / a.sign
            kw["q"][:, jn] = x if robot.prismatic[jn] else np.radians(x)
        if M > 1:
            V = np.stack([values[a.axis] for a in order], axis=1)
            vj = np.array([mv.vj for mv in moves])
            step = np.max(np.abs(np.diff(V, axis=0)) / vmax[None, :], axis=1)  # NaN next to a Cartesian target
            ok = (kind[1:] == JOINT) & (vj[1:] > 0) & np.isfinite(step)
            kw["duration_s"][1:][ok] = step[ok] * 100.0 / vj[1:][ok]
        lin = kind == LINEAR
        kw["speed_mm_s"][lin] = np.array([mv.v for mv in moves])[lin] if M else kw["speed_mm_s"][lin]
        kw["row_start"][sorted(starts)] = True
        kw["row_end"][sorted(ends)] = True
        prog = ProgramMoves(**kw, where=where, row_names=names, conf_convention="yaskawa")
        # a joint move after a Cartesian one: VJ needs the axis values of the Cartesian target
        need = np.flatnonzero((prog.kind == JOINT) & np.isnan(prog.duration_s))
        need = need[(need > 0)]
        if len(need) and (prog.kind != JOINT).any():
            from camtool.simulate import target_joints
            q = target_joints(prog, robot, profile)
            ax = profile.to_axes(np.nan_to_num(q), robot)
            vals = np.stack([ax[a.axis] for a2 in groups.values() for a in a2], axis=1)
            for k in need:
                mv = moves[k]
                if mv.vj > 0 and np.isfinite(q[k - 1]).all():
                    prog.duration_s[k] = float(np.max(np.abs(vals[k] - vals[k - 1]) / vmax)) * 100.0 / mv.vj
        return prog

    def read(self, path: Path, robot, profile) -> tuple[np.ndarray, np.ndarray]:
        """(durations_s, q): per move the duration implied by VJ and the profile's max speeds
        (MOVL: its length over V; NaN for the first move) and the target in rad / mm (a
        Cartesian target's joints by the simulator's inverse kinematics); follows CALL JOB."""
        from camtool.simulate import move_durations, target_joints

        prog = self.read_program(Path(path), robot, profile)
        if not (prog.kind != JOINT).any():
            return prog.duration_s, prog.q
        q = target_joints(prog, robot, profile)
        return move_durations(prog, robot, q), q

    # --- checking --------------------------------------------------------------------------

    def check(self, path: Path, robot, profile) -> list[str]:
        """Findings for a job and the jobs it CALLs: NPOS counts against the positions (a
        truncated job has fewer, and no END), contiguous indices, integer pulses within
        int64, values per line, references, END, CRLF, ASCII, group, names and row markers;
        then every target against the robot's limits and every move's speed against the
        robot's speed limits (tolerance: one pulse). A joint move's duration is the
        controller's: the governing axis at VJ % of the profile's ``max_speed``
        (docs/controllers.md); the resulting axis speeds must stay within
        ``robot.limits.velocity``, whatever the profile says."""
        path = Path(path)
        out: list[str] = []
        groups = group_axes(profile)
        want_group = list(groups)
        max_len = profile.options.get("job_name_length", 8)
        consistent = True
        n_moves = 0
        open_row = None
        for jp, j in job_files(path):
            out += j.problems
            consistent &= not j.problems
            n_moves += len(j.moves)
            if j.name:
                if job_name(j.name, 32)[0] != j.name or len(j.name) > max_len:
                    out.append(f"{jp}: job name {j.name!r} is not valid (uppercase, digits, _, leading letter, "
                               f"<= {max_len} characters)")
                if j.name != jp.stem:
                    out.append(f"{jp}: job {j.name!r} is in a file named {jp.name!r}")
            if j.group and j.group != want_group:
                out.append(f"{jp}: ///GROUP1 {','.join(j.group)} does not match the profile ({','.join(want_group)})")
                consistent = False
            for g, ax in groups.items():
                pre = GROUPS[g]
                for _i, vals, ln, kind, _rc in j.pos[pre]:
                    want = len(ax) if kind == "pulse" else 6 + (len(ax) == 7)
                    if len(vals) != want:
                        out.append(f"{jp}:{ln}: {pre} line has {len(vals)} values, expected {want} for group {g}")
                        consistent = False
            for it in j.items:
                if it[0] == "row":
                    if open_row is not None:
                        out.append(f"{jp}:{it[1]}: a row starts before the previous one ended")
                    open_row = it[1]
                elif it[0] == "end_row":
                    if open_row is None:
                        out.append(f"{jp}:{it[1]}: a row ends that never started")
                    open_row = None
        if not consistent or not n_moves:
            if not n_moves and not out:
                out.append(f"{path}: no MOVJ found")
            return out
        try:
            prog = self.read_program(path, robot, profile)
        except BadInput as exc:
            return out + [f"{path}: {exc}"]
        if (prog.kind != JOINT).any():
            from camtool.simulate import move_durations, target_joints
            q = target_joints(prog, robot, profile)
            bad = np.flatnonzero(~np.isfinite(q).all(axis=1))
            if len(bad):
                return out + [f"{prog.where[k]}: no joint values reach this position" for k in bad[:20]]
            dur = move_durations(prog, robot, q)
        else:
            q, dur = prog.q, prog.duration_s
        tol = np.zeros(robot.dof)
        for a in (a for ax in groups.values() for a in ax):
            i = robot.joint_names.index(a.joint)
            step = 1.0 / a.pulses
            tol[i] = step if robot.prismatic[i] else np.radians(step)
        if (prog.kind != JOINT).any():
            tol = tol + np.where(robot.prismatic, 1e-3, np.radians(1e-4))  # Cartesian positions: 0.001 mm / deg
        return out + check_motion(q, dur, robot, prog.where, tol + 1e-9)


def _fmt_column(values: np.ndarray, decimals: int) -> list[str]:
    v = np.round(np.asarray(values, float), decimals)
    v[v == 0] = 0.0
    return [f"{x:.{decimals}f}" for x in v.tolist()]


def _ascii(text: str) -> str:
    return text.encode("ascii", "replace").decode("ascii").replace("?", "_")

