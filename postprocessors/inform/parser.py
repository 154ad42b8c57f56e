"""Yaskawa INFORM reader: ``.JBI`` jobs parsed into positions and instructions, and a job
(with the jobs it calls) read back move by move (``ProgramMoves``)."""
from __future__ import annotations


from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from camtool.errors import BadInput
from camtool.program.convention import base_pose, controller_axes, model_joints, robot_frame
from camtool.program.durations import move_durations
from camtool.program.moves import CIRCULAR, JOINT, LINEAR, ProgramMoves, empty_moves
from camtool.program.targets import cartesian_targets, target_joints

from .dialect import (CIRCLE_POINT, CALL_RE, CODE_IN_COMMENT_RE, DATE_RE, DOUT_RE, FLOAT_RE, GROUPS, INT64, INTS_RE, LONG_RE, MOVE_RE, PL_MM, POS_RE,
                      ROW_END_RE, ROW_RE, group_axes, matrix_xyz_deg)


def read_bytes(path: Path) -> bytes:
    """The bytes of one job file (the reader's only file access)."""
    from camtool.safe_io import read_program_bytes  # regular files under the cap: a FIFO never blocks

    return read_program_bytes(path)


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
    fpt: bool = False  # MOVC ... FPT: this point ends one arc and starts the next


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
        raw = read_bytes(path)
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


def forget() -> None:
    """Drop the files parsed and the programs read (``PostProcessor.forget``)."""
    _PARSED.clear()
    _READ.clear()


@dataclass(frozen=True)
class _ParseState:
    """Where the reader is in a job: its section (``pos`` / ``inst``), and the position type
    and ///RCONF values the next C position lines take."""

    section: str = ""
    postype: str = "pulse"
    rconf: list[int] | None = None


def _parse_jbi(path, raw: bytes) -> JbiText:
    """A job's bytes parsed line by line; then the short pulse lines' values in bulk and the
    checks of the whole job (END, //NAME, NPOS, positions, moves, arcs)."""
    j = JbiText()
    p = f"{path}"
    bulk: list = []  # short pulse lines: (position entry, its values' text)
    lines = _job_lines(p, raw, j.problems)
    st = _ParseState()
    for n, line in enumerate(lines, 1):
        st = _parse_line(j, bulk, st, p, n, line, len(lines))
    _bulk_pulses(bulk)
    for pre in j.pos:
        j.pos[pre] = [tuple(e) for e in j.pos[pre]]
    j.problems += _frame_problems(j, p, lines)
    j.problems += _npos_problems(j, p)
    j.problems += _position_problems(j, p)
    j.problems += _move_problems(j, p)
    j.problems += arc_problems(p, j.moves)
    return j


def _job_lines(p: str, raw: bytes, problems: list[str]) -> list[str]:
    """The job's lines (split at CRLF), with bytes that are not ASCII and a missing last CRLF noted."""
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError as exc:
        problems.append(f"{p}: not ASCII (byte {exc.start})")
        text = raw.decode("latin-1")
    if not text.endswith("\r\n"):
        problems.append(f"{p}: the file must end with CRLF")
    lines = text.split("\r\n")
    if lines[-1] == "":
        lines = lines[:-1]
    return lines


def _parse_line(j: JbiText, bulk: list, st: _ParseState, p: str, n: int, line: str, last: int) -> _ParseState:
    """One line: a position, a move, a header line or an instruction; the state after it."""
    where = f"{p}:{n}"
    if "\n" in line or "\r" in line:
        j.problems.append(f"{where}: line ending is not CRLF")
        line = line.replace("\r", "").replace("\n", "")
    if n == 1:
        if line != "/JOB":
            j.problems.append(f"{where}: expected /JOB, found {line[:40]!r}")
        return st
    if st.section == "pos" and line[:1] in ("C", "B", "E") and (m := POS_RE.match(line)):
        _position_line(j, bulk, st, n, where, m)
        return st
    if st.section == "inst" and line[:3] == "MOV" and (m := MOVE_RE.match(line)):
        _move_line(j, n, where, m)
        return st
    new = _state_line(j, st, where, line)
    if new is not None:
        return new
    if not _header_line(j, where, line):
        _instruction_line(j, st, n, where, line, last)
    return st


def _position_line(j: JbiText, bulk: list, st: _ParseState, n: int, where: str, m) -> None:
    """A position line (C / BC / EC): short pulse lines are left to the bulk conversion."""
    pre, num, txt = m.groups()
    kind = st.postype if pre == "C" else "pulse"
    if kind == "pulse" and INTS_RE.match(txt) and not LONG_RE.search(txt):
        # no value can leave int64: converted in bulk below
        entry = [int(num), None, n, kind, st.rconf]
        j.pos[pre].append(entry)
        bulk.append((entry, txt))
        return
    vals = _position_values(j, where, kind, txt)
    if vals is not None:
        j.pos[m.group(1)].append((int(m.group(2)), vals, n, kind, st.rconf))


def _position_values(j: JbiText, where: str, kind: str, txt: str) -> list | None:
    """A position's values: int64 pulses or finite decimal numbers, or None with a bad value noted."""
    cells = txt.split(",")
    if kind == "pulse":
        if not INTS_RE.match(txt):
            _bad_value(j, f"{where}: pulse values must be integers")
            return None
        big = next((c for c in cells if len(c.lstrip("-").lstrip("0")) > 19
                    or not INT64[0] <= int(c) <= INT64[1]), None)
        if big is not None:
            shown = big if len(big) <= 30 else big[:27] + "..."
            _bad_value(j, f"{where}: pulse value {shown} is beyond the int64 range")
            return None
        return [int(c) for c in cells]
    if not all(FLOAT_RE.match(c) for c in cells):
        _bad_value(j, f"{where}: Cartesian values must be finite decimal numbers")
        return None
    return [float(c) for c in cells]


def _bad_value(j: JbiText, text: str) -> None:
    """Note a position line whose values cannot be read (a problem too)."""
    j.bad_values.append(text)
    j.problems.append(j.bad_values[-1])


def _move_line(j: JbiText, n: int, where: str, m) -> None:
    """A MOVJ / MOVL / MOVC instruction: its move, or a problem."""
    refs = {}
    for tok in m.group(2).split():
        pre = tok.rstrip("0123456789")
        if pre in refs:
            j.problems.append(f"{where}: {pre} given twice")
        refs[pre] = int(tok[len(pre):])
    kind = {"MOVJ": JOINT, "MOVL": LINEAR, "MOVC": CIRCLE_POINT}[m.group(1)]
    if (kind == JOINT) != (m.group(3) is not None):
        j.problems.append(f"{where}: {m.group(1)} takes {'VJ' if kind == JOINT else 'V'}=")
        return
    if m.group(6) and kind != CIRCLE_POINT:
        j.problems.append(f"{where}: FPT belongs to MOVC only")
        return
    mv = JbiMove(n, refs, float(m.group(3)) if m.group(3) else float("nan"), int(m.group(5)), kind,
                 float(m.group(4)) if m.group(4) else float("nan"), bool(m.group(6)))
    j.moves.append(mv)
    j.items.append(("move", mv))


def _state_line(j: JbiText, st: _ParseState, where: str, line: str) -> _ParseState | None:
    """//POS, //INST, and in //POS ///POSTYPE and ///RCONF: the state after the line, or None
    for any other line."""
    if line == "//POS":
        return replace(st, section="pos")
    if line == "//INST":
        return replace(st, section="inst")
    if st.section == "pos" and line.startswith("///POSTYPE "):
        kind = line[11:]
        if kind not in ("PULSE", "BASE"):
            j.problems.append(f"{where}: ///POSTYPE {kind} is not supported (PULSE or BASE)")
        return replace(st, postype="pulse" if kind == "PULSE" else "rectan")
    if st.section == "pos" and line.startswith("///RCONF "):
        try:
            rconf = [int(x) for x in line[9:].split(",")]
        except ValueError:
            j.problems.append(f"{where}: RCONF must be integers")
            return st
        if len(rconf) < 6 or any(v not in (0, 1) for v in rconf):
            j.problems.append(f"{where}: RCONF needs at least 6 values of 0 or 1")
        return replace(st, rconf=rconf)
    return None


def _header_line(j: JbiText, where: str, line: str) -> bool:
    """//NAME, ///NPOS, ///TOOL, ///GROUP1, ///ATTR, ///COMM, ///DATE and the lines that
    carry nothing (///PULSE, ///RECTAN, NOP); False for any other line."""
    if line.startswith("//NAME "):
        j.name = line[7:]
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
    elif line in ("///PULSE", "///RECTAN", "NOP") or line.startswith("///DATE "):
        if line.startswith("///DATE ") and not DATE_RE.match(line[8:]):
            j.problems.append(f"{where}: DATE must be yyyy/mm/dd hh:mm")
    else:
        return False
    return True


def _instruction_line(j: JbiText, st: _ParseState, n: int, where: str, line: str, last: int) -> None:
    """A comment (a row's start or end in //INST), DOUT, CALL JOB or END; any other line is a
    problem."""
    if line.startswith("'"):
        if CODE_IN_COMMENT_RE.search(line[1:]):
            j.problems.append(f"{where}: code in a comment (a name or text that could become an instruction): "
                              f"{line[:40]!r}")
        if st.section == "inst" and ROW_RE.match(line):
            j.items.append(("row", n, line[1:]))
        elif st.section == "inst" and ROW_END_RE.match(line):
            j.items.append(("end_row", n))
    elif st.section == "inst" and (m := DOUT_RE.match(line)):
        j.items.append(("dout", n, int(m.group(1)), m.group(2) == "ON"))
    elif st.section == "inst" and (m := CALL_RE.match(line)):
        j.calls.append((n, m.group(1)))
    elif line == "END":
        if n != last:
            j.problems.append(f"{where}: text after END")
    else:
        j.problems.append(f"{where}: unrecognised line: {line[:60]}")


def _bulk_pulses(bulk: list) -> None:
    """The values of every short pulse line, converted at once into their entries."""
    if not bulk:
        return
    flat = np.array(",".join(txt for _e, txt in bulk).split(","), dtype=np.int64).tolist()
    i = 0
    for entry, txt in bulk:
        c = txt.count(",") + 1
        entry[1] = flat[i:i + c]
        i += c


def _frame_problems(j: JbiText, p: str, lines: list[str]) -> list[str]:
    """A job that does not end with END, or has no //NAME."""
    out = []
    if not lines or lines[-1] != "END":
        out.append(f"{p}: the job does not end with END")
    if not j.name:
        out.append(f"{p}: no //NAME line")
    return out


def _npos_problems(j: JbiText, p: str) -> list[str]:
    """///NPOS against the positions the job has (and no P / BP / EX variables)."""
    out = []
    if len(j.npos) == 6:
        for k, pre in enumerate(("C", "BC", "EC")):
            if j.npos[k] != len(j.pos[pre]):
                out.append(f"{p}: NPOS says {j.npos[k]} {pre} positions, the file has {len(j.pos[pre])}")
        if any(j.npos[3:]):
            out.append(f"{p}: NPOS counts P/BP/EX variables, which camtool never writes")
    elif not j.npos:
        out.append(f"{p}: no ///NPOS line")
    return out


def _position_problems(j: JbiText, p: str) -> list[str]:
    """The positions' order, indices and value counts, and the ///ATTR Cartesian ones need."""
    out = []
    order = [ln for pre in ("C", "BC", "EC") for (_i, _v, ln, _k, _r) in j.pos[pre]]
    if order != sorted(order):
        out.append(f"{p}: positions must come as all C lines, then BC, then EC")
    for pre, items in j.pos.items():
        idx = [it[0] for it in items]
        if idx != list(range(len(idx))):
            bad = next(k for k, i in enumerate(idx) if i != k)
            out.append(f"{p}:{items[bad][2]}: {pre} indices must be contiguous from 00000")
        for kind in ("pulse", "rectan"):
            counts = {len(it[1]) for it in items if it[3] == kind}
            if len(counts) > 1:
                out.append(f"{p}: {pre} lines have different numbers of values ({sorted(counts)})")
    if any(it[3] == "rectan" for it in j.pos["C"]) and j.attr and "RJ" not in j.attr.split(","):
        out.append(f"{p}: Cartesian positions need ///ATTR SC,RW,RJ")
    return out


def _move_problems(j: JbiText, p: str) -> list[str]:
    """Each move's references, groups, speed, position type and PL."""
    out = []
    need = {"RB1": "C", "BS1": "BC", "ST1": "EC"}
    for mv in j.moves:
        for pre, i in mv.refs.items():
            if i >= len(j.pos[pre]):
                out.append(f"{p}:{mv.line}: {pre}{i:05d} is not defined in //POS")
        for g in j.group:
            if g in need and need[g] not in mv.refs:
                out.append(f"{p}:{mv.line}: group {g} needs a {need[g]} position on every move")
        if mv.kind == JOINT and not 0.01 <= mv.vj <= 100.0:
            out.append(f"{p}:{mv.line}: VJ={mv.vj:.2f} outside 0.01..100.00")
        if mv.kind in (LINEAR, CIRCLE_POINT) and not mv.v > 0:
            out.append(f"{p}:{mv.line}: V={mv.v} must be above 0")
        if mv.kind in (LINEAR, CIRCLE_POINT) and "C" in mv.refs and mv.refs["C"] < len(j.pos["C"]) \
                and j.pos["C"][mv.refs["C"]][3] != "rectan":
            word = "MOVL" if mv.kind == LINEAR else "MOVC"
            out.append(f"{p}:{mv.line}: {word} to a pulse position (camtool writes Cartesian ones)")
        if not 0 <= mv.pl <= 8:
            out.append(f"{p}:{mv.line}: PL={mv.pl} outside 0..8")
    return out


MAX_CALLS = 10_000          # CALL JOB lines one job may hold (camtool writes one per part)
MAX_RUN_MOVES = 5_000_000   # moves of a job and its called jobs, in run order (the pose cap)


def job_files(path: Path) -> list[tuple[Path, JbiText]]:
    """A job and, in run order, the jobs it CALLs (found as NAME.JBI in the same folder).

    Each called job is read and parsed once, however often it is called; more than ``MAX_CALLS``
    calls, or more than ``MAX_RUN_MOVES`` moves in run order, is BadInput (one line) before any work
    per call: 100,000 ``CALL JOB:NEW`` lines re-read the called job 100,000 times."""
    path = Path(path)
    j = parse_jbi(path)
    if len(j.calls) > MAX_CALLS:
        raise BadInput(f"{path}: {len(j.calls)} CALL JOB lines; camtool follows at most {MAX_CALLS}")
    out = [(path, j)]
    called: dict[str, tuple[Path, JbiText]] = {}
    moves = len(j.moves)
    for _n, name in j.calls:
        if name not in called:
            called[name] = (path.parent / f"{name}.JBI", parse_jbi(path.parent / f"{name}.JBI"))
        out.append(called[name])
        moves += len(called[name][1].moves)
        if moves > MAX_RUN_MOVES:
            raise BadInput(f"{path}: its calls run more than {MAX_RUN_MOVES} moves; camtool checks at most that many")
    return out



def arc_problems(p, moves) -> list[str]:
    """Problems of a job's MOVC sequence: every arc needs its three MOVC points (module doc
    of ``postprocessors.inform``)."""
    out, count, first = [], 0, None  # MOVC points of the open arc, the line it starts at
    for mv in list(moves) + [None]:
        if mv is not None and mv.kind == CIRCLE_POINT:
            if count == 0:
                first = mv.line
            count += 1
            if count == 3:  # the arc's last point; with FPT it is also the next arc's first
                count = 1 if mv.fpt else 0
                first = mv.line
            continue
        if count == 2 or (count == 1 and first is not None and _opened_by_fpt(moves, first)):
            out.append(f"{p}:{first}: the arc that starts here has fewer than three MOVC points")
        count, first = 0, None
    return out


def _opened_by_fpt(moves, line: int) -> bool:
    return any(mv.line == line and mv.kind == CIRCLE_POINT and mv.fpt for mv in moves)


def _arcs(moves: list, refs: list) -> tuple[list, list]:
    """Moves with their MOVC points assembled into arcs: the first point of an arc is a linear
    move (kind L), the circle point goes into the next move's ``via`` and the last point is a
    circular move (kind C); an FPT point ends one arc and starts the next."""
    out_m, out_r, state, via = [], [], "idle", None
    for mv, rf in zip(moves, refs):
        if mv.kind != CIRCLE_POINT:
            out_m.append(mv)
            out_r.append(rf)
            state = "idle"
            continue
        if state == "idle":
            out_m.append(replace(mv, kind=LINEAR))
            out_r.append(rf)
            state = "start"
        elif state in ("start", "chain"):
            via, state = rf, "via"
        else:
            out_m.append(replace(mv, kind=CIRCULAR))
            out_r.append({**rf, "via": via})
            state = "chain" if mv.fpt else "idle"
    return out_m, out_r


def _collect(path: Path, profile):
    """Moves (MOVC points assembled into arcs), their positions per prefix, file:line labels,
    parts and markers of a job and the jobs it calls."""
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


def _assemble_arcs(moves, posns, where, part, starts, ends):
    """``_arcs`` over the collected moves, with the markers and labels moved along."""
    if not any(mv.kind == CIRCLE_POINT for mv in moves):
        return moves, posns, where, part, starts, ends
    keep = []  # the indices of the collected moves that remain moves
    state = "idle"
    for i, mv in enumerate(moves):
        if mv.kind != CIRCLE_POINT:
            keep.append(i)
            state = "idle"
        elif state == "idle":
            keep.append(i)
            state = "start"
        elif state in ("start", "chain"):
            state = "via"
        else:
            keep.append(i)
            state = "chain" if mv.fpt else "idle"
    new_index = {old: k for k, old in enumerate(keep)}
    # a marker on a dropped circle point moves to the next kept move (start) / previous (end)
    def forward(i):
        while i not in new_index and i < len(moves):
            i += 1
        return new_index.get(i, len(keep) - 1)

    def backward(i):
        while i not in new_index and i > 0:
            i -= 1
        return new_index.get(i, 0)
    m2, r2 = _arcs(moves, posns)
    return (m2, r2, [where[i] for i in keep], [part[i] for i in keep], {forward(i) for i in starts},
            {backward(i) for i in ends})

def read_program(path: Path, robot, profile) -> ProgramMoves:
    """Every MOVJ / MOVL of a job and the jobs it calls, in run order, with the process
    markers (``'ROW`` / ``DOUT``) and the jobs as parts; Cartesian positions as TCP poses
    in the robot base frame (the Re value, if any, fixes the 7th axis)."""
    files = job_files(Path(path))
    key = (str(path), tuple(id(j) for _jp, j in files), id(profile), robot.name, id(robot))
    hit = _READ.get(key)
    if hit is not None and hit[0] == [j for _jp, j in files] and hit[2] is profile and hit[3] is robot:
        return hit[1]
    prog = _read_program(path, robot, profile)
    if len(_READ) >= 16:  # a few programs: a check and the simulation of the same file share them
        _READ.clear()
    _READ[key] = ([j for _jp, j in files], prog, profile, robot)  # the objects kept: their ids stay theirs
    return prog

def _read_program(path: Path, robot, profile) -> ProgramMoves:
    """The moves of a job and the jobs it calls: kinds, blends, axis values and poses, joint
    values, durations of joint moves and speeds of Cartesian ones, row markers."""
    files, moves, posns, where, part, starts, ends, names = _collect(path, profile)
    moves, posns, where, part, starts, ends = _assemble_arcs(moves, posns, where, part, starts, ends)
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
    values = _axis_values(kw, robot, groups, posns, where, kind)
    kw["q"] = model_joints(profile, robot, values)
    if M > 1:
        V = np.stack([values[a.axis] for a in order], axis=1)
        vj = np.array([mv.vj for mv in moves])
        step = np.max(np.abs(np.diff(V, axis=0)) / vmax[None, :], axis=1)  # NaN next to a Cartesian target
        ok = (kind[1:] == JOINT) & (vj[1:] > 0) & np.isfinite(step)
        kw["duration_s"][1:][ok] = step[ok] * 100.0 / vj[1:][ok]
    lin = (kind == LINEAR) | (kind == CIRCULAR)
    kw["speed_mm_s"][lin] = np.array([mv.v for mv in moves])[lin] if M else kw["speed_mm_s"][lin]
    kw["row_start"][sorted(starts)] = True
    kw["row_end"][sorted(ends)] = True
    prog = ProgramMoves(**kw, where=where, row_names=names, conf_convention="yaskawa")
    _durations_after_cartesian(prog, robot, profile, groups, moves, vmax)
    return prog


def _axis_values(kw: dict, robot, groups: dict, posns: list, where: list[str], kind: np.ndarray) -> dict:
    """The controller axis values (deg / mm, NaN where a position gives none) of every move,
    group by group; Cartesian positions' poses, RCONF and circle points go into ``kw``."""
    M = len(posns)
    values = {a.axis: np.full(M, np.nan) for ax in groups.values() for a in ax}
    for g, pre in GROUPS.items():
        if g not in groups:
            continue
        ax = groups[g]
        refs = [r.get(pre) for r in posns]
        _pulse_values(values, g, pre, ax, refs, where)
        _rectan_values(kw, values, robot, ax, refs, where)
        if pre == "C":  # the circle points of circular moves
            _circle_points(kw, robot, posns, where, kind)
    return values


def _pulse_values(values: dict, g: str, pre: str, ax: list, refs: list, where: list[str]) -> None:
    """The axis values of one group's pulse positions: (pulses - zero) / pulses per unit."""
    pulse = [k for k, r in enumerate(refs) if r is not None and r[3] == "pulse"]
    if not pulse:
        return
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


def _rectan_values(kw: dict, values: dict, robot, ax: list, refs: list, where: list[str]) -> None:
    """The TCP poses (robot frame) and RCONF of one group's Cartesian positions, and the 7th
    axis value they carry."""
    rect = [k for k, r in enumerate(refs) if r is not None and r[3] == "rectan"]
    if not rect:
        return
    want = 6 + (len(ax) == 7)
    bad = next((k for k in rect if len(refs[k][1]) != want), None)
    if bad is not None:
        raise BadInput(f"{where[bad]}: a Cartesian C position needs {want} values")
    arr = np.array([refs[k][1] for k in rect], dtype=float)
    T = np.broadcast_to(np.eye(4), (len(rect), 4, 4)).copy()
    T[:, :3, :3] = matrix_xyz_deg(arr[:, 3:6])
    T[:, :3, 3] = arr[:, :3]
    kw["pose"][rect] = base_pose(robot_frame(robot), T)  # positions in the robot frame
    if len(ax) == 7:
        values[ax[6].axis][rect] = arr[:, 6]
    for k in rect:
        rc = refs[k][4]
        if rc:
            kw["conf"][k, :] = [rc[0], rc[1], rc[2], rc[3] * 4 + rc[4] * 2 + rc[5]]


def _circle_points(kw: dict, robot, posns: list, where: list[str], kind: np.ndarray) -> None:
    """The circle point (robot frame) of every circular move, from its Cartesian C position."""
    for k in np.flatnonzero(kind == CIRCULAR):
        vp = (posns[k].get("via") or {}).get("C")
        if vp is None or vp[3] != "rectan" or len(vp[1]) < 6:
            raise BadInput(f"{where[k]}: the circle point of this arc is not a Cartesian C position")
        V = np.eye(4)
        V[:3, :3] = matrix_xyz_deg(np.array(vp[1][3:6], float)[None])[0]
        V[:3, 3] = vp[1][:3]
        kw["via"][k] = base_pose(robot_frame(robot), V)


def _durations_after_cartesian(prog: ProgramMoves, robot, profile, groups: dict, moves: list,
                               vmax: np.ndarray) -> None:
    """A joint move after a Cartesian one: its VJ duration from the axis values of the
    Cartesian target (by the simulator's inverse kinematics)."""
    need = np.flatnonzero((prog.kind == JOINT) & np.isnan(prog.duration_s))
    need = need[(need > 0)]
    if len(need) and cartesian_targets(prog).any():   # MOVJ to a ///RECTAN position too
        q = target_joints(prog, robot, profile)
        ax = controller_axes(profile, robot, np.nan_to_num(q))
        vals = np.stack([ax[a.axis] for a2 in groups.values() for a in a2], axis=1)
        for k in need:
            mv = moves[k]
            if mv.vj > 0 and np.isfinite(q[k - 1]).all() and np.isfinite(q[k]).all():
                prog.duration_s[k] = float(np.max(np.abs(vals[k] - vals[k - 1]) / vmax)) * 100.0 / mv.vj

def read(path: Path, robot, profile) -> tuple[np.ndarray, np.ndarray]:
    """(durations_s, q): per move the duration implied by VJ and the profile's max speeds
    (MOVL: its length over V; NaN for the first move) and the target in rad / mm (a
    Cartesian target's joints by the simulator's inverse kinematics); follows CALL JOB."""

    prog = read_program(Path(path), robot, profile)
    if not (prog.kind != JOINT).any():
        return prog.duration_s, prog.q
    q = target_joints(prog, robot, profile)
    return move_durations(prog, robot, q), q

# --- checking --------------------------------------------------------------------------
