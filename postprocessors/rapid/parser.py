"""ABB RAPID reader: ``.pgf`` program files and ``.mod`` modules parsed into statements, and
the program read back move by move (``ProgramMoves``)."""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from camtool.errors import BadInput
from camtool.program.convention import base_pose, model_joints
from camtool.program.durations import move_durations
from camtool.program.moves import CIRCULAR, JOINT, LINEAR, ProgramMoves, empty_moves
from camtool.program.targets import target_joints

from .dialect import (CALL_RE, CODE_IN_COMMENT_RE, CONF_RE, EAX, LOAD_RE, MODULE_RE, MOVE_RE, MOVEC_RE, MOVEL_RE, PERS_RE, PROC_RE,
                      RAX, ROW_END_RE, ROW_RE, SETDO_RE, SPEEDS, UNLOAD_RE, ZONE_MM)


def read_bytes(path: Path) -> bytes:
    """The bytes of one program file (the readers' only file access)."""
    from camtool.safe_io import read_program_bytes  # regular files under the cap: a FIFO never blocks

    return read_program_bytes(path)


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


def forget() -> None:
    """Drop the files parsed and the programs read (``PostProcessor.forget``)."""
    _PARSED.clear()
    _READ.clear()


def parse_module(path: Path) -> ModuleText:
    """Parse a camtool-style RAPID module; structural problems are collected, not raised.
    The result is cached by the file's path and content (callers must not change it)."""
    import hashlib

    path = Path(path)
    try:
        raw = read_bytes(path)
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
    """A module's text parsed line by line; then the jointtargets' values in bulk and the
    module's frame (MODULE, PROC / ENDPROC, ENDMODULE)."""
    m = ModuleText()
    bulk: list = []  # well-formed jointtargets: (move, rax text, eax text, where)
    lines = _module_lines(path, text, m.problems)
    depth = 0
    ps = str(path)
    for n, line in enumerate(lines, 1):
        depth = _parse_line(m, bulk, depth, n, f"{ps}:{n}", line, len(lines))
    _bulk_values(bulk, m)
    if not m.name:
        m.problems.append(f"{path}: no MODULE line")
    if depth:
        m.problems.append(f"{path}: PROC without ENDPROC")
    if not lines or lines[-1].strip() != "ENDMODULE":
        m.problems.append(f"{path}: the module does not end with ENDMODULE")
    return m


def _module_lines(path: Path, text: str, problems: list[str]) -> list[str]:
    """The module's lines, with a missing last newline and CR characters noted."""
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines = lines[:-1]
    else:
        problems.append(f"{path}:{len(lines)}: no newline at end of file")
    if "\r" in text:
        problems.append(f"{path}: CR characters found (RAPID modules use LF line ends here)")
    return lines


def _parse_line(m: ModuleText, bulk: list, depth: int, n: int, where: str, line: str, last: int) -> int:
    """One line: a comment, a move or another statement; the PROC depth after it."""
    if line != line.rstrip():
        m.problems.append(f"{where}: trailing white space")
    if "\t" in line:
        m.problems.append(f"{where}: tab character")
    s = line.strip()
    if not s:
        return depth
    if s.startswith("!"):
        _comment(m, depth, n, where, s)
    elif s[:4] == "Move":
        _move_statement(m, bulk, depth, n, where, line, s)
    else:
        depth = _statement(m, depth, n, where, line, s, last)
    return depth


def _comment(m: ModuleText, depth: int, n: int, where: str, s: str) -> None:
    """A comment: code in it is a problem; inside a PROC it may mark a row's start or end."""
    if CODE_IN_COMMENT_RE.search(s[1:]):
        m.problems.append(f"{where}: code in a comment (a name or text that could become a statement): "
                          f"{s[:60]!r}")
    if depth and ROW_RE.match(s):
        m.items.append(("row", n, s.lstrip("! ").strip()))
    elif depth and (em := ROW_END_RE.match(s)):
        m.items.append(("end_row", n, int(em.group("n"))))


def _move_statement(m: ModuleText, bulk: list, depth: int, n: int, where: str, line: str, s: str) -> None:
    """A MoveAbsJ / MoveL / MoveC statement: its move, or a problem; a well-formed jointtarget's
    values are left to the bulk conversion."""
    first = s.split(None, 1)[0]
    kind = {"MoveAbsJ": JOINT, "MoveL": LINEAR, "MoveC": CIRCULAR}.get(first)
    regex = {JOINT: MOVE_RE, LINEAR: MOVEL_RE, CIRCULAR: MOVEC_RE}.get(kind)
    mv = regex.match(line) if regex else None
    word = first if kind else s[:8]
    if not mv or not depth:
        m.problems.append(f"{where}: malformed {word}" + ("" if mv else f": {s[:60]}"))
        return
    t = mv.group("t")
    if t and not math.isfinite(float(t)):
        m.problems.append(f"{where}: \\T must be a finite number of seconds, found {t}")
        return
    if mv.group("speed")[:1] == "[" and not _all_finite(mv.group("speed")):
        m.problems.append(f"{where}: speed data must be finite numbers")
        return
    tail = (mv.group("speed"), float(t) if t else None, mv.group("zone"), mv.group("tool"), mv.group("wobj"))
    if kind == JOINT and mv.group("rax").count(",") == 5 and mv.group("eax").count(",") == 5:
        move = Move(n, None, None, *tail)  # values converted in bulk after the loop
        bulk.append((move, mv.group("rax"), mv.group("eax"), where))
    elif kind == JOINT:
        values = _jointtarget(mv, where, m.problems)
        if values is None:
            return
        move = Move(n, *values, *tail)
    else:
        to = _robtarget(mv, "", where, m.problems)
        via = _robtarget(mv, "c", where, m.problems) if kind == CIRCULAR else None
        if to is None or (kind == CIRCULAR and via is None):
            return
        move = Move(n, [], to[3], *tail, kind=kind, to=to, via=via)
    m.moves.append(move)
    m.items.append(("move", move))


def _jointtarget(mv, where: str, problems: list[str]):
    """(rax, eax) of a matched jointtarget that is not 6 + 6 values, or None with a problem noted."""
    try:
        rax, eax = _floats(mv.group("rax")), _floats(mv.group("eax"))
    except ValueError:
        problems.append(f"{where}: jointtarget values must be numbers")
        return None
    if not all(math.isfinite(v) for v in rax + eax):
        problems.append(f"{where}: jointtarget values must be finite numbers")
        return None
    if len(rax) != 6 or len(eax) != 6:
        problems.append(f"{where}: jointtarget needs 6 robot and 6 external values, found "
                        f"{len(rax)} and {len(eax)}")
        return None
    return rax, eax


def _statement(m: ModuleText, depth: int, n: int, where: str, line: str, s: str, last: int) -> int:
    """Any statement but a move: the module and its PROCs, data, SetDO, Load, calls; the
    PROC depth after it."""
    if s.startswith("%%%"):
        m.problems.append(f"{where}: '%%%' header is not allowed in a .mod file")
    elif (mm := MODULE_RE.match(line)):
        if m.name:
            m.problems.append(f"{where}: second MODULE in one file")
        m.name = mm.group("name")
    elif s == "ENDMODULE":
        if depth:
            m.problems.append(f"{where}: ENDMODULE inside a PROC")
        if n != last:
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
    return depth


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
        root = ET.fromstring(read_bytes(path))
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



def read_program(path: Path, robot, profile) -> ProgramMoves:
    """Every motion instruction of a program (.pgf or .mod and the modules it loads) in
    run order, with the process markers (``! Row`` / ``SetDO``) and modules as parts;
    Cartesian targets as TCP poses in the robot base frame (the work object applied)."""
    modules = program_modules(Path(path))
    key = (str(path), tuple(id(mt) for _p, mt in modules), id(profile), robot.name, id(robot))
    hit = _READ.get(key)
    if hit is not None and hit[0] == [mt for _p, mt in modules] and hit[2] is profile and hit[3] is robot:
        return hit[1]
    prog = _read_program(modules, robot, profile)
    if len(_READ) >= 16:  # a few programs: a check and the simulation of the same file share them
        _READ.clear()
    _READ[key] = ([mt for _p, mt in modules], prog, profile, robot)  # the objects kept: their ids stay theirs
    return prog

def _read_program(modules, robot, profile) -> ProgramMoves:
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
        kw["q"] = model_joints(profile, robot, {a: AX[:, j] for j, a in enumerate(axis_names)})
        kw["duration_s"] = np.array([np.nan if mv.t_s is None else mv.t_s for mv in seq], float)
        kw["blend_mm"] = np.array([ZONE_MM.get(mv.zone, 0.0) for mv in seq], float)
        frames = {}
        for k in np.flatnonzero(kind != JOINT):
            mv = seq[k]
            if mv.wobj not in frames:
                frames[mv.wobj] = _wobj_frame(values, mv.wobj)
            F = frames[mv.wobj]
            kw["pose"][k] = base_pose(F, _pose(mv.to[0], mv.to[1]))
            kw["conf"][k] = mv.to[2]
            if mv.via is not None:
                kw["via"][k] = base_pose(F, _pose(mv.via[0], mv.via[1]))
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

def read(path: Path, robot, profile) -> tuple[np.ndarray, np.ndarray]:
    """(durations_s, q): each move's duration (\\T; for a MoveL its length over its TCP
    speed; NaN for the first) and its target in rad / mm (a Cartesian target's joints by
    the simulator's inverse kinematics), following a .pgf and the Loads of a main module."""

    prog = read_program(Path(path), robot, profile)
    q = target_joints(prog, robot, profile)
    return move_durations(prog, robot, q), q

def moves_to_arrays(moves: list[Move], robot, profile) -> tuple[np.ndarray, np.ndarray]:
    """Durations (s, NaN when absent) and joint values (rad / mm) of parsed joint moves."""
    dur = np.array([np.nan if m.t_s is None else m.t_s for m in moves])
    if not moves:
        return dur, np.zeros((0, robot.dof))
    names = RAX + EAX
    AX = np.array([m.rax + m.eax for m in moves], float)
    values = {a.axis: AX[:, names.index(a.axis)] for a in profile.axes}
    return dur, model_joints(profile, robot, values)

