"""KUKA KRL reader: ``.src`` modules and their ``.dat`` data lists parsed into statements, and
the program read back move by move (``ProgramMoves``)."""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from camtool.errors import BadInput
from camtool.program.calls import called_programs
from camtool.program.convention import base_pose, controller_axes, model_joints
from camtool.program.durations import move_durations
from camtool.program.moves import CIRCULAR, JOINT, LINEAR, ProgramMoves, empty_moves, joint_travel
from camtool.program.targets import _Chain, _robot_for, cartesian_targets, target_joints

from .dialect import (AXES, ASSIGN_RE, BAS_RE, CALL_RE, CODE_IN_COMMENT_RE, DECL_RE, DEF_RE, DEFDAT_RE, END_RE,
                      ENDDAT_RE, LINE_MAX, MOVE_RE, ROBOT_AXES, ROW_END_RE, ROW_RE, aggregate_fields, cptp_radius,
                      frame_from_fields)


def read_bytes(path: Path) -> bytes:
    """The bytes of one program file (the reader's only file access)."""
    from camtool.safe_io import read_program_bytes  # regular files under the cap: a FIFO never blocks

    return read_program_bytes(path)


@dataclass
class Move:
    """One parsed motion statement: ``kind`` J (PTP), L (LIN) or C (CIRC); its target's name (and
    a CIRC's auxiliary point's); the approximation it asks for; the settings in force."""

    line: int
    kind: str
    target: str
    aux: str | None
    c_ptp: bool
    c_dis: bool
    vel_axis: dict          # controller axis -> % ($VEL_AXIS / $VEL_EXTAX)
    vel_cp: float | None    # m/s
    ori: tuple              # ($VEL.ORI1, $VEL.ORI2) deg/s
    cdis: float | None      # mm
    cptp: float | None      # %
    base: str | None        # the $BASE and $TOOL aggregate texts in force
    tool: str | None


@dataclass
class Module:
    """What the reader finds in one .src file and its .dat: ``items`` the moves, row markers,
    outputs and calls in order: ``("move", Move)``, ``("row", line, text)``, ``("end_row", line,
    n)``, ``("out", line, n, value)``, ``("call", line, name)``."""

    name: str = ""
    data_name: str = ""
    items: list = field(default_factory=list)
    moves: list = field(default_factory=list)
    data: dict = field(default_factory=dict)    # name -> (type, fields, line)
    calls: list = field(default_factory=list)
    problems: list = field(default_factory=list)
    settings: dict = field(default_factory=dict)   # the system variables assigned, last value


_PARSED: dict = {}
_PARSED_MAX = 64


def forget() -> None:
    """Drop the files parsed (``PostProcessor.forget``)."""
    _PARSED.clear()


def _lines(path: Path, raw: bytes, problems: list[str]) -> list[str]:
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError:
        problems.append(f"{path}: not ASCII text")
        text = raw.decode("latin-1")
    if not text.endswith("\n"):
        problems.append(f"{path}: no line end at the end of the file (a truncated file)")
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines = lines[:-1]
    crlf = [ln.endswith("\r") for ln in lines]
    if any(crlf) and not all(crlf):
        problems.append(f"{path}: mixed line ends (CRLF and LF)")
    return [ln[:-1] if ln.endswith("\r") else ln for ln in lines]


def parse_module(src: Path) -> Module:
    """Parse a camtool-style .src file and the .dat of the same name; problems are collected,
    not raised. Cached by path and content (callers must not change the result)."""
    import hashlib

    src = Path(src)
    dat = src.with_suffix(".dat")
    try:
        raw_src = read_bytes(src)
    except OSError as exc:
        m = Module()
        m.problems.append(f"{src}: cannot read ({exc})")
        return m
    try:
        raw_dat = read_bytes(dat) if dat.exists() else None
    except OSError as exc:
        raw_dat, dat_problem = None, f"{dat}: cannot read ({exc})"
    else:
        dat_problem = None if raw_dat is not None else f"{dat}: missing (every .src needs its data list)"
    key = (str(src), hashlib.blake2b(raw_src + b"\0" + (raw_dat or b""), digest_size=16).digest())
    if key in _PARSED:
        return _PARSED[key]
    m = Module()
    if dat_problem:
        m.problems.append(dat_problem)
    else:
        _parse_dat(dat, raw_dat, m)
    _parse_src(src, raw_src, m)
    if len(_PARSED) >= _PARSED_MAX:
        _PARSED.clear()
    _PARSED[key] = m
    return m


def _parse_dat(path: Path, raw: bytes, m: Module) -> None:
    lines = _lines(path, raw, m.problems)
    opened = closed = False
    for n, line in enumerate(lines, 1):
        where = f"{path}:{n}"
        s = line.strip()
        if len(line) > LINE_MAX:
            m.problems.append(f"{where}: line longer than {LINE_MAX} characters")
        if not s or s.startswith(";"):
            if s.startswith(";") and CODE_IN_COMMENT_RE.search(s[1:]):
                m.problems.append(f"{where}: code in a comment: {s[:60]!r}")
            continue
        if closed:
            m.problems.append(f"{where}: text after ENDDAT")
        elif (dm := DEFDAT_RE.match(s)):
            if opened:
                m.problems.append(f"{where}: second DEFDAT")
            opened = True
            m.data_name = dm.group("name")
        elif ENDDAT_RE.match(s):
            closed = True
        elif (dm := DECL_RE.match(s)) and opened:
            fields = aggregate_fields(dm.group("body"))
            if fields is None:
                m.problems.append(f"{where}: {dm.group('name')}: every field must be a name and a finite number")
                continue
            nm = dm.group("name").upper()
            if nm in m.data:
                m.problems.append(f"{where}: {nm} is declared twice")
            m.data[nm] = (dm.group("type").upper(), fields, n)
        else:
            m.problems.append(f"{where}: unrecognised data declaration: {s[:60]}")
    if not opened:
        m.problems.append(f"{path}: no DEFDAT line")
    if not closed:
        m.problems.append(f"{path}: the data list does not end with ENDDAT")


def _parse_src(path: Path, raw: bytes, m: Module) -> None:
    lines = _lines(path, raw, m.problems)
    st = {"vel_axis": {}, "vel_cp": None, "ori1": None, "ori2": None, "cdis": None, "cptp": None,
          "base": None, "tool": None}
    depth = 0
    ended = False
    for n, line in enumerate(lines, 1):
        where = f"{path}:{n}"
        if len(line) > LINE_MAX:
            m.problems.append(f"{where}: line longer than {LINE_MAX} characters")
        s = line.strip()
        if not s:
            continue
        if s.startswith(";"):
            if CODE_IN_COMMENT_RE.search(s[1:]):
                m.problems.append(f"{where}: code in a comment (a name or text that could become a statement): "
                                  f"{s[:60]!r}")
            if depth and (rm := ROW_RE.match(s)):
                m.items.append(("row", n, s.lstrip("; ").strip()))
            elif depth and (em := ROW_END_RE.match(s)):
                m.items.append(("end_row", n, int(em.group("n"))))
            continue
        if ";" in s:
            s = s.split(";", 1)[0].rstrip()
        if ended:
            m.problems.append(f"{where}: text after END")
            continue
        if (dm := DEF_RE.match(s)):
            if depth:
                m.problems.append(f"{where}: DEF inside a DEF")
            if m.name:
                m.problems.append(f"{where}: a second DEF (camtool writes one routine per module)")
            depth = 1
            m.name = dm.group("name")
            continue
        if END_RE.match(s):
            if not depth:
                m.problems.append(f"{where}: END without DEF")
            depth = 0
            ended = True
            continue
        if not depth:
            m.problems.append(f"{where}: statement outside DEF ... END: {s[:60]}")
            continue
        if (mv := MOVE_RE.match(s)):
            word = mv.group("word").upper()
            apo = mv.group("apo").upper().split()
            if len(apo) != len(set(apo)):
                m.problems.append(f"{where}: an approximation parameter given twice")
            kind = {"PTP": JOINT, "LIN": LINEAR, "CIRC": CIRCULAR}[word]
            if (kind == CIRCULAR) != (mv.group("end") is not None):
                m.problems.append(f"{where}: malformed {word}: {s[:60]}")
                continue
            if kind != JOINT and "C_PTP" in apo:
                m.problems.append(f"{where}: C_PTP on a {word} (C_DIS approximates CP motions)")
            target = (mv.group("end") or mv.group("target")).upper()
            aux = mv.group("target").upper() if kind == CIRCULAR else None
            move = Move(n, kind, target, aux, "C_PTP" in apo, "C_DIS" in apo, dict(st["vel_axis"]), st["vel_cp"],
                        (st["ori1"], st["ori2"]), st["cdis"], st["cptp"], st["base"], st["tool"])
            m.moves.append(move)
            m.items.append(("move", move))
            continue
        if (am := ASSIGN_RE.match(s)):
            _assignment(am.group("var").upper(), am.group("value").strip(), st, m, where, n)
            continue
        if BAS_RE.match(s):
            continue
        if (cm := CALL_RE.match(s)):
            m.calls.append((n, cm.group("name")))
            m.items.append(("call", n, cm.group("name")))
            continue
        m.problems.append(f"{where}: unrecognised statement: {s[:60]}")
    if not m.name:
        m.problems.append(f"{path}: no DEF line")
    if not ended:
        m.problems.append(f"{path}: the module does not end with END (a truncated file)")
    m.settings = dict(st)


_NUM_VALUE = re.compile(r"^[-+]?+(?:\d++(?:\.\d*+)?+|\.\d++)$")
_FRAME_VALUE = re.compile(r"^\{(?P<body>[^{}]*)\}$")
_KNOWN_ENUMS = {"$ORI_TYPE": ("#VAR", "#CONSTANT", "#JOINT"), "$CIRC_TYPE": ("#BASE", "#PATH")}


def _assignment(var: str, value: str, st: dict, m: Module, where: str, n: int) -> None:
    """Apply one system-variable assignment to the reader's state; a value the controller
    would refuse (or camtool does not write) is a problem."""
    def number(lo: float, hi: float, integer: bool = False) -> float | None:
        if not _NUM_VALUE.match(value):
            m.problems.append(f"{where}: {var} must be a number, found {value[:40]!r}")
            return None
        v = float(value)
        if not math.isfinite(v) or not lo <= v <= hi or (integer and v != int(v)):
            m.problems.append(f"{where}: {var} = {value} is outside {lo:g}..{hi:g}" + (" or not whole" if integer else ""))
            return None
        return v

    if (vm := re.fullmatch(r"\$VEL_(AXIS|EXTAX)\[(\d)\]", var)):
        v = number(1, 100, integer=True)
        if v is not None:
            st["vel_axis"][("A" if vm.group(1) == "AXIS" else "E") + vm.group(2)] = v
    elif var == "$VEL.CP":
        v = number(1e-6, 10.0)   # m/s
        if v is not None:
            st["vel_cp"] = v
    elif var in ("$VEL.ORI1", "$VEL.ORI2"):
        v = number(1e-3, 10000.0)
        if v is not None:
            st["ori1" if var.endswith("1") else "ori2"] = v
    elif var == "$APO.CDIS":
        v = number(0.0, 10000.0)
        if v is not None:
            st["cdis"] = v
    elif var == "$APO.CPTP":
        v = number(1, 100, integer=True)
        if v is not None:
            st["cptp"] = v
    elif var in ("$BASE", "$TOOL"):
        fm = _FRAME_VALUE.match(value)
        fields = aggregate_fields(fm.group("body")) if fm else None
        if fields is None or set(fields) != set("XYZABC"):
            m.problems.append(f"{where}: {var} must be a frame {{X, Y, Z, A, B, C}} of finite numbers")
        else:
            st["base" if var == "$BASE" else "tool"] = fm.group("body")
    elif (om := re.fullmatch(r"\$OUT\[(\d+)\]", var)):
        if value.upper() not in ("TRUE", "FALSE"):
            m.problems.append(f"{where}: {var} must be TRUE or FALSE")
        else:
            m.items.append(("out", n, int(om.group(1)), value.upper() == "TRUE"))
    elif var in _KNOWN_ENUMS:
        if value.upper() not in _KNOWN_ENUMS[var]:
            m.problems.append(f"{where}: {var} = {value[:20]} is not one of {', '.join(_KNOWN_ENUMS[var])}")
        st[var] = value.upper()
    elif var == "$ADVANCE":
        number(0, 5, integer=True)
    else:
        m.problems.append(f"{where}: camtool does not write {var}: {value[:40]}")


def program_modules(path: Path) -> list[tuple[Path, Module]]:
    """The modules of a program in run order: the entry .src (a .dat is read as its .src), then
    each module it calls (same folder, ``NAME.src``), each once."""
    path = Path(path)
    if path.suffix.lower() == ".dat":
        path = path.with_suffix(".src")
    return called_programs(path, parse_module, _module_file,
                           lambda name: f"calls {name}: no regular file {name}.src in the folder")


def _module_file(folder: Path, name: str) -> Path | None:
    for cand in (folder / f"{name}.src", folder / f"{name.lower()}.src", folder / f"{name.upper()}.src"):
        if cand.is_file():
            return cand
    return None


def _fields_frame(body: str) -> np.ndarray:
    return frame_from_fields(aggregate_fields(body))


def read_program(path: Path, robot, profile) -> ProgramMoves:
    """The program move by move (``ProgramMoves``), following the modules the entry calls: PTP
    to E6AXIS targets as joint targets, LIN / CIRC to E6POS targets as TCP poses in $BASE
    (camtool's base frame = $ROBROOT = $WORLD), timing from $VEL_AXIS (PTP, as INFORM's VJ)
    and $VEL.CP / $VEL.ORI (CP moves), approximation from $APO.CDIS (C_DIS) and $APO.CPTP
    (C_PTP); BadInput when a module cannot be read as one."""
    modules = program_modules(Path(path))
    problems = [p for _mp, mt in modules for p in mt.problems]
    if problems:
        raise BadInput(problems[0])
    seq, where, part, data_of = [], [], [], []
    starts, ends, names = set(), set(), []
    part_no = -1
    for mp, mt in modules:
        if mt.moves:
            part_no += 1
        pending = None
        for it in mt.items:
            if it[0] == "move":
                if pending is not None:
                    starts.add(len(seq))
                    names.append(pending)
                    pending = None
                seq.append(it[1])
                where.append(f"{mp}:{it[1].line}")
                part.append(max(part_no, 0))
                data_of.append(mt)
            elif it[0] == "row" or (it[0] == "out" and it[3]):
                if pending is None:
                    pending = it[2] if it[0] == "row" else f"$OUT[{it[2]}] on"
            elif (it[0] == "end_row" or (it[0] == "out" and not it[3])) and seq:
                ends.add(len(seq) - 1)
    M = len(seq)
    kw = empty_moves(M, robot.dof)
    kw["part"] = np.array(part, int)
    order = [a for ax in AXES for a in profile.axes if a.axis == ax]
    tools = {mv.tool for mv in seq if mv.kind != JOINT}
    if len(tools) > 1:
        raise BadInput(f"{where[0].rsplit(':', 1)[0]}: $TOOL changes between CP moves (camtool writes one tool)")
    tool_body = next(iter(tools)) if tools else next((mv.tool for mv in seq if mv.tool), None)
    tool_T = None
    if tool_body is not None:
        tool_T = robot.conventions.tool0_in_flange @ _fields_frame(tool_body)
    kind = np.array([mv.kind for mv in seq]) if M else np.zeros(0, str)
    if M:
        kw["kind"] = kind.astype(kw["kind"].dtype)
        values = {a.axis: np.full(M, np.nan) for a in order}
        for k, mv in enumerate(seq):
            typ, fields, _ln = _target(data_of[k], mv.target, where[k], "E6AXIS" if mv.kind == JOINT else "E6POS")
            if mv.kind == JOINT:
                for a in order:
                    if a.axis not in fields:
                        raise BadInput(f"{where[k]}: {mv.target} has no {a.axis}")
                    values[a.axis][k] = fields[a.axis]
                continue
            if mv.base is None:
                raise BadInput(f"{where[k]}: a CP move before $BASE is set")
            F = _fields_frame(mv.base)
            kw["pose"][k] = base_pose(F, frame_from_fields(fields))
            for a in order:   # the external axes a Cartesian target states
                if a.axis not in ROBOT_AXES and a.axis in fields:
                    values[a.axis][k] = fields[a.axis]
            if mv.kind == CIRCULAR:
                _t, afields, _l = _target(data_of[k], mv.aux, where[k], "E6POS")
                kw["via"][k] = base_pose(F, frame_from_fields(afields))
            if mv.vel_cp is None:
                raise BadInput(f"{where[k]}: a CP move before $VEL.CP is set")
            kw["speed_mm_s"][k] = mv.vel_cp * 1000.0
            ori = [v for v in mv.ori if v is not None]
            kw["ori_speed_deg_s"][k] = min(ori) if ori else np.nan
            kw["blend_mm"][k] = mv.cdis if mv.c_dis and mv.cdis is not None else 0.0
        kw["q"] = model_joints(profile, robot, values)
    kw["row_start"][sorted(starts)] = True
    kw["row_end"][sorted(ends)] = True
    prog = ProgramMoves(**kw, where=where, row_names=names, tool_T_mm=tool_T, conf_convention="")
    if M:
        _joint_timing(prog, seq, robot, profile, order)
    return prog


def _target(mt: Module, name: str, where: str, want: str):
    hit = mt.data.get(name.upper())
    if hit is None:
        raise BadInput(f"{where}: {name} is not declared in the data list")
    if hit[0] != want:
        raise BadInput(f"{where}: {name} is {hit[0]}, camtool reads {want} for this move")
    if want == "E6POS" and not set("XYZABC") <= set(hit[1]):
        raise BadInput(f"{where}: {name} lacks one of X, Y, Z, A, B, C")
    return hit


def _joint_timing(prog: ProgramMoves, seq: list[Move], robot, profile, order) -> None:
    """PTP durations (the axis that needs longest at its $VEL_AXIS % of the profile's
    max_speed) and C_PTP approximation distances ($APO.CPTP % of half the move, in the blend
    model's TCP-equivalent mm); both need the previous target's joints, a CP target's by the
    controller's inverse kinematics."""
    M = len(seq)
    joint = np.flatnonzero(prog.kind == JOINT)
    joint = joint[joint > 0]
    if not len(joint):
        return
    q = target_joints(prog, robot, profile) if cartesian_targets(prog).any() else prog.q
    ok = np.isfinite(q).all(axis=1)
    vmax = np.array([a.max_speed for a in order])
    ax = controller_axes(profile, robot, np.nan_to_num(q))
    V = np.stack([ax[a.axis] for a in order], axis=1)
    chain = _Chain(_robot_for(prog, robot))
    P = np.full((M, 3), np.nan)
    if ok.any():
        P[ok] = chain.fk(q[ok])[0]
    for k in joint:
        mv = seq[k]
        if not (ok[k] and ok[k - 1]):
            continue
        pct = np.array([mv.vel_axis.get(a.axis, np.nan) for a in order])
        if np.isnan(pct).any():
            raise BadInput(f"{prog.where[k]}: a PTP before $VEL_AXIS is set for every axis")
        prog.duration_s[k] = float(np.max(np.abs(V[k] - V[k - 1]) / (vmax * pct / 100.0)))
        if mv.c_ptp and mv.cptp is not None:
            leq = max(float(np.linalg.norm(P[k] - P[k - 1])),
                      float(joint_travel((q[k] - q[k - 1])[None], robot.prismatic)[0]))
            r = cptp_radius(mv.cptp, leq)
            if mv.c_dis and mv.cdis is not None:
                r = min(r, mv.cdis)
            prog.blend_mm[k] = r
        else:
            prog.blend_mm[k] = 0.0


def read(path: Path, robot, profile) -> tuple[np.ndarray, np.ndarray]:
    """(durations_s, q): each move's duration (PTP from $VEL_AXIS, CP moves their length over
    $VEL.CP; NaN for the first) and its target in rad / mm (a CP target's joints by the
    simulator's inverse kinematics), following the modules the entry calls."""
    prog = read_program(Path(path), robot, profile)
    if not (prog.kind != JOINT).any():
        return prog.duration_s, prog.q
    q = target_joints(prog, robot, profile)
    return move_durations(prog, robot, q), q
