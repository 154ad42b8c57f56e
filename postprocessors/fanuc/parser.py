"""FANUC LS reader: ``.LS`` programs parsed into sections, instructions and positions, and the
program read back move by move (``ProgramMoves``)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from camtool.errors import BadInput
from camtool.program.calls import called_programs
from camtool.program.convention import controller_axes, model_joints
from camtool.program.moves import CIRCULAR, JOINT, LINEAR, ProgramMoves, empty_moves
from camtool.program.plan import profile_tool
from camtool.program.targets import _Chain

from .dialect import (AXES, CALL_RE, CODE_IN_COMMENT_RE, CONFIG_RE, CONT_RE, DO_RE, FRAME_FROM_PR_RE, FRAME_NUM_RE,
                      LINE_RE, MOTION_RE, POS_FIELD_RE, POS_HEAD_RE, PR_FROM_P_RE, PROG_RE, REMARK_RE, ROBOT_AXES,
                      ROW_END_RE, ROW_RE, SPEED_TERM_RE, UFUT_RE, cnt_radius, matrix_wpr)


def read_bytes(path: Path) -> bytes:
    """The bytes of one program file (the reader's only file access)."""
    from camtool.safe_io import read_program_bytes  # regular files under the cap: a FIFO never blocks

    return read_program_bytes(path)


@dataclass
class Position:
    """One ``P[n]`` of /POS: joint values (``J1``.. deg, ``E1``.. deg / mm) or a Cartesian pose
    (X, Y, Z mm, W, P, R deg, CONFIG), with its user and tool frame numbers."""

    number: int
    line: int
    uf: int
    ut: int
    joints: dict = field(default_factory=dict)
    xyzwpr: dict = field(default_factory=dict)
    config: str | None = None

    @property
    def cartesian(self) -> bool:
        return bool(self.xyzwpr)


@dataclass
class Move:
    """One motion instruction: J, L or C; its position (a C move's circle point in ``via``), its
    speed (% or mm/sec), FINE or CNT n, and the frames selected when it runs."""

    line: int
    kind: str
    p: int
    via: int | None
    speed: float
    unit: str
    cnt: int | None          # None: FINE
    uframe: int | None
    utool: int | None


@dataclass
class LsProgram:
    """What the reader finds in one .LS file; ``items`` the moves, row markers, outputs and calls
    in order: ``("move", Move)``, ``("row", line, text)``, ``("end_row", line, n)``, ``("do",
    line, n, on)``, ``("call", line, name)``."""

    name: str = ""
    attr: dict = field(default_factory=dict)
    instructions: int = 0
    items: list = field(default_factory=list)
    moves: list = field(default_factory=list)
    positions: dict = field(default_factory=dict)
    pr: dict = field(default_factory=dict)        # PR number -> P number it was copied from
    frames: dict = field(default_factory=dict)    # ("UTOOL" | "UFRAME", n) -> P number
    calls: list = field(default_factory=list)
    problems: list = field(default_factory=list)


_PARSED: dict = {}
_PARSED_MAX = 64


def forget() -> None:
    """Drop the files parsed (``PostProcessor.forget``)."""
    _PARSED.clear()


def parse_ls(path: Path) -> LsProgram:
    """Parse a camtool-style LS program; problems are collected, not raised. Cached by path and
    content (callers must not change the result)."""
    import hashlib

    path = Path(path)
    try:
        raw = read_bytes(path)
    except OSError as exc:
        pg = LsProgram()
        pg.problems.append(f"{path}: cannot read ({exc})")
        return pg
    key = (str(path), hashlib.blake2b(raw, digest_size=16).digest())
    if key not in _PARSED:
        if len(_PARSED) >= _PARSED_MAX:
            _PARSED.clear()
        _PARSED[key] = _parse(path, raw)
    return _PARSED[key]


@dataclass(frozen=True)
class _ParseState:
    """Where the reader is in a program: its section, the sections seen so far, the instruction
    number expected next, a C move waiting for its continuation line (its line and circle
    point's number) and a position being read (its number, line and lines so far)."""

    section: str | None = None
    sections: tuple[str, ...] = ()
    expect: int = 1
    pending_c: tuple[int, int] | None = None
    pos_block: tuple[int, int, tuple[str, ...]] | None = None


def _parse(path: Path, raw: bytes) -> LsProgram:
    """A program's bytes parsed line by line (the frames selected carried from instruction to
    instruction); then the checks of the whole program (a C move or a position left open, the
    sections, LINE_COUNT)."""
    pg = LsProgram()
    lines = _ls_lines(path, raw, pg.problems)
    st = _ParseState()
    state = {"uframe": None, "utool": None}
    for n, line in enumerate(lines, 1):
        st = _parse_line(pg, st, state, path, n, line, len(lines))
    pg.problems += _end_problems(pg, st, path)
    return pg


def _ls_lines(path: Path, raw: bytes, problems: list[str]) -> list[str]:
    """The program's lines without their line ends, with bytes that are not ASCII, a missing
    last CRLF and lines not ending with CRLF noted."""
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError:
        problems.append(f"{path}: not ASCII text")
        text = raw.decode("latin-1")
    if not text.endswith("\r\n"):
        problems.append(f"{path}: the file does not end with CRLF (a truncated file?)")
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines = lines[:-1]
    if any(not ln.endswith("\r") for ln in lines):
        problems.append(f"{path}: lines must end with CRLF")
    return [ln.rstrip("\r") for ln in lines]


def _parse_line(pg: LsProgram, st: _ParseState, state: dict, path: Path, n: int, line: str,
                last: int) -> _ParseState:
    """One line: a section's head, an /ATTR entry, a /MN instruction or a /POS line; the reader's
    state after it."""
    where = f"{path}:{n}"
    s = line.strip()
    if s.startswith("/") and st.pos_block is None:
        return _section_line(pg, st, where, s, n == last)
    if st.section == "/ATTR":
        if "=" in s:
            k, v = s.split("=", 1)
            pg.attr[k.strip().replace("TCD:", "").strip()] = v.strip().rstrip(";,").strip()
        return st
    if st.section == "/MN":
        return _mn_line(pg, st, state, path, n, line)
    if st.section == "/POS":
        return _pos_line(pg, st, path, n, s)
    if s:
        pg.problems.append(f"{where}: text outside the sections: {s[:40]}")
    return st


def _section_line(pg: LsProgram, st: _ParseState, where: str, s: str, is_last: bool) -> _ParseState:
    """A section's head (/PROG with the program's name, /ATTR, /APPL, /MN, /POS, /END): the
    section from there."""
    head = s.split()[0]
    if head == "/PROG":
        m = PROG_RE.match(s)
        if m:
            pg.name = m.group("name")
        else:
            pg.problems.append(f"{where}: malformed /PROG line")
    elif head not in ("/ATTR", "/APPL", "/MN", "/POS", "/END"):
        pg.problems.append(f"{where}: unknown section {head}")
    elif head == "/END" and not is_last:
        pg.problems.append(f"{where}: text after /END")
    return replace(st, section=head, sections=st.sections + (head,))


def _mn_line(pg: LsProgram, st: _ParseState, state: dict, path: Path, n: int, line: str) -> _ParseState:
    """A /MN line: a C move's continuation, or a numbered motion or other instruction."""
    where = f"{path}:{n}"
    s = line.strip()
    if st.pending_c is not None:
        cm = CONT_RE.match(line)
        if not cm:
            pg.problems.append(f"{where}: a C move needs its second position on a ':' line")
        else:
            _motion("C", cm.group("body"), st.pending_c, pg, state, path)
        return replace(st, pending_c=None)
    lm = LINE_RE.match(line)
    if not lm:
        if s:
            pg.problems.append(f"{where}: an instruction line must start with its number: {s[:50]}")
        return st
    num = int(lm.group("n"))
    if num != st.expect:
        pg.problems.append(f"{where}: line number {num}, expected {st.expect}")
    st = replace(st, expect=num + 1)
    pg.instructions += 1
    body = lm.group("body")
    if body[:1] in ("J", "L", "C") and body[1:2] == " ":
        return _motion_line(pg, st, state, path, n, body)
    _instruction(body.strip(), n, where, pg, state)
    return st


def _motion_line(pg: LsProgram, st: _ParseState, state: dict, path: Path, n: int, body: str) -> _ParseState:
    """A J or L move, or a C move's first line (its circle point: the move waits for its
    continuation line)."""
    mm = MOTION_RE.match(body.strip())
    if not mm:
        pg.problems.append(f"{path}:{n}: malformed motion: {body.strip()[:60]}")
    elif mm.group("word") == "C":
        if mm.group("rest").strip():
            pg.problems.append(f"{path}:{n}: a C move's first line holds its circle point only")
        return replace(st, pending_c=(n, int(mm.group("p"))))
    else:
        _motion(mm.group("word"), f"P[{mm.group('p')}] {mm.group('rest')}", (n, None), pg, state, path)
    return st


def _pos_line(pg: LsProgram, st: _ParseState, path: Path, n: int, s: str) -> _ParseState:
    """A /POS line: a position's head ``P[n]{``, one of its lines, or its end ``};`` (the
    position read)."""
    if st.pos_block is None:
        if not s:
            return st
        hm = POS_HEAD_RE.match(s)
        if not hm:
            pg.problems.append(f"{path}:{n}: expected P[n]{{ in /POS, found {s[:40]}")
            return st
        return replace(st, pos_block=(int(hm.group("p")), n, ()))
    if s == "};":
        _position(st.pos_block, pg, path)
        return replace(st, pos_block=None)
    number, line, body = st.pos_block
    return replace(st, pos_block=(number, line, body + (s,)))


def _end_problems(pg: LsProgram, st: _ParseState, path: Path) -> list[str]:
    """A C move or a position left open at the end, the sections out of order, and a LINE_COUNT
    that is not the number of instructions."""
    out = []
    if st.pending_c is not None:
        out.append(f"{path}:{st.pending_c[0]}: a C move without its second position")
    if st.pos_block is not None:
        out.append(f"{path}:{st.pos_block[1]}: P[{st.pos_block[0]}] is not closed (a truncated file)")
    want = ["/PROG", "/ATTR", "/MN", "/POS", "/END"]
    if [h for h in st.sections if h != "/APPL"] != want:
        out.append(f"{path}: sections {' '.join(st.sections) or 'none'}; expected {' '.join(want)}"
                   + (" (a truncated file)" if "/END" not in st.sections else ""))
    lc = pg.attr.get("LINE_COUNT")
    if lc is not None and lc.isdigit() and int(lc) != pg.instructions:
        out.append(f"{path}: LINE_COUNT = {lc} but /MN holds {pg.instructions} instructions")
    return out


def _instruction(body: str, n: int, where: str, pg: LsProgram, state: dict) -> None:
    if (rm := REMARK_RE.match(body)):
        text = rm.group("text")
        if CODE_IN_COMMENT_RE.search(text):
            pg.problems.append(f"{where}: code in a remark (a name or text that could become an instruction): "
                               f"{text[:40]!r}")
        if ROW_RE.match(text):
            pg.items.append(("row", n, text.strip()))
        elif (em := ROW_END_RE.match(text)):
            pg.items.append(("end_row", n, int(em.group("n"))))
        return
    if (fm := FRAME_NUM_RE.match(body)):
        state["uframe" if fm.group("what") == "UFRAME_NUM" else "utool"] = int(fm.group("n"))
        return
    if (pm := PR_FROM_P_RE.match(body)):
        pg.pr[int(pm.group("pr"))] = int(pm.group("p"))
        return
    if (fm := FRAME_FROM_PR_RE.match(body)):
        pr = int(fm.group("pr"))
        if pr not in pg.pr:
            pg.problems.append(f"{where}: {fm.group('what')}[{fm.group('n')}] from PR[{pr}], which the program "
                               "never set")
        else:
            pg.frames[(fm.group("what"), int(fm.group("n")))] = pg.pr[pr]
        return
    if (dm := DO_RE.match(body)):
        pg.items.append(("do", n, int(dm.group("n")), dm.group("v") == "ON"))
        return
    if (cm := CALL_RE.match(body)):
        pg.calls.append((n, cm.group("name")))
        pg.items.append(("call", n, cm.group("name")))
        return
    if body == ";":
        return
    pg.problems.append(f"{where}: unrecognised instruction: {body[:60]}")


def _motion(word: str, body: str, head, pg: LsProgram, state: dict, path: Path) -> None:
    line, via = head
    where = f"{path}:{line}"
    mm = MOTION_RE.match(f"{word} {body.strip()}")
    sm = SPEED_TERM_RE.match(mm.group("rest").strip()) if mm else None
    if not sm:
        pg.problems.append(f"{where}: malformed {word} move: speed and FINE / CNT n expected: {body.strip()[:60]}")
        return
    unit = sm.group("unit")
    v = float(sm.group("v"))
    if (word == "J") != (unit == "%"):
        pg.problems.append(f"{where}: a {word} move's speed is in {'%' if word == 'J' else 'mm/sec'}, found {unit}")
        return
    if unit == "%" and not (v == int(v) and 1 <= v <= 100):
        pg.problems.append(f"{where}: J speed must be a whole 1..100 %, found {sm.group('v')}")
        return
    if unit == "mm/sec" and not (math.isfinite(v) and 0 < v <= 10000):
        pg.problems.append(f"{where}: speed must be 0..10000 mm/sec, found {sm.group('v')}")
        return
    cnt = sm.group("cnt")
    if cnt is not None and not 0 <= int(cnt) <= 100:
        pg.problems.append(f"{where}: CNT must be 0..100, found CNT{cnt}")
        return
    mv = Move(line, {"J": JOINT, "L": LINEAR, "C": CIRCULAR}[word], int(mm.group("p")), via, v, unit,
              None if cnt is None else int(cnt), state["uframe"], state["utool"])
    pg.moves.append(mv)
    pg.items.append(("move", mv))


def _position(block, pg: LsProgram, path: Path) -> None:
    number, line, body = block
    where = f"{path}:{line}"
    text = " ".join(body)
    if number in pg.positions:
        pg.problems.append(f"{where}: P[{number}] is defined twice")
        return
    groups = text.count("GP")
    if groups != 1 or "GP1:" not in text:
        pg.problems.append(f"{where}: P[{number}]: camtool writes one group (GP1), found {groups}")
        return
    um = UFUT_RE.search(text)
    if not um:
        pg.problems.append(f"{where}: P[{number}]: no UF / UT")
        return
    pos = Position(number, line, int(um.group("uf")), int(um.group("ut")))
    rest = text.split(um.group(0), 1)[1]
    cm = CONFIG_RE.search(rest)
    if cm:
        pos.config = cm.group("conf")
        rest = rest.replace(cm.group(0), "")
    found = list(POS_FIELD_RE.finditer(rest))
    leftover = POS_FIELD_RE.sub("", rest).replace(",", " ").split()
    if leftover:
        pg.problems.append(f"{where}: P[{number}]: unrecognised values {' '.join(leftover)[:40]!r}")
        return
    for f in found:
        v = float(f.group("v"))
        if not math.isfinite(v):
            pg.problems.append(f"{where}: P[{number}]: {f.group('key')} is not a finite number")
            return
        key = f.group("key")
        target = pos.xyzwpr if key in "XYZWPR" else pos.joints
        if key in target:
            pg.problems.append(f"{where}: P[{number}]: {key} given twice")
            return
        target[key] = v
    if pos.joints and pos.xyzwpr:
        pg.problems.append(f"{where}: P[{number}] mixes joint and Cartesian values")
        return
    if pos.xyzwpr and (set(pos.xyzwpr) != set("XYZWPR") or pos.config is None):
        pg.problems.append(f"{where}: P[{number}]: a Cartesian position needs X, Y, Z, W, P, R and CONFIG")
        return
    pg.positions[number] = pos


def program_files(path: Path) -> list[tuple[Path, LsProgram]]:
    """The programs of a run in order: the entry, then every program it calls (same folder,
    ``NAME.LS``), each once."""
    return called_programs(path, parse_ls, _program_file, lambda name: f"CALL {name}: no {name}.LS in the folder")


def _program_file(folder: Path, name: str) -> Path | None:
    return next((c for c in (folder / f"{name}.LS", folder / f"{name}.ls", folder / f"{name.lower()}.ls")
                 if c.is_file()), None)


def frame_pose(pos: Position) -> np.ndarray:
    """The pose (4 x 4, mm) of a Cartesian position's X, Y, Z, W, P, R."""
    T = np.eye(4)
    T[:3, 3] = [pos.xyzwpr[k] for k in "XYZ"]
    T[:3, :3] = matrix_wpr([pos.xyzwpr[k] for k in "WPR"])[0]
    return T


@dataclass(frozen=True)
class _RunMoves:
    """The moves of a run in order with their positions' axis values (a C move's circle point
    in ``vias``, None for the others), their file:line labels and program numbers, the moves
    that start and end rows and the rows' names."""

    moves: list
    values: list
    vias: list
    where: list[str]
    part: list[int]
    starts: set[int]
    ends: set[int]
    names: list[str]


def read_program(path: Path, robot, profile) -> ProgramMoves:
    """The program move by move (``ProgramMoves``), following its CALLs: every target a
    joint-representation position (J1..J6 as the pendant shows them: the controller's J3 is
    j3 - j2), so no target depends on CONFIG; L and C moves trace the TCP of the UTOOL the
    program sets (the profile's tool when it sets none). Timing: J moves the axis that needs
    longest at its % of the profile's ``max_speed``, L / C moves their length over their
    speed. Corners: CNT n by the profile's ``cnt_mm`` model. BadInput when a program cannot be
    read as one."""
    files = program_files(Path(path))
    problems = [p for _pp, pg in files for p in pg.problems]
    if problems:
        raise BadInput(problems[0])
    order = [a for ax in AXES for a in profile.axes if a.axis == ax]
    tool_T = _program_tool(files, robot, profile)
    run = _run_moves(files, order)
    kw = empty_moves(len(run.moves), robot.dof)
    kw["part"] = np.array(run.part, int)
    if run.moves:
        _fill_moves(kw, run, robot, profile, order, tool_T)
    kw["row_start"][sorted(run.starts)] = True
    kw["row_end"][sorted(run.ends)] = True
    return ProgramMoves(**kw, where=run.where, row_names=run.names, tool_T_mm=tool_T, conf_convention="")


def _program_tool(files, robot, profile) -> np.ndarray:
    """The TCP (4 x 4, mm, in the flange) of the UTOOL the program sets (the profile's
    ``utool``), or the profile's tool when it sets none."""
    o = profile.options
    tool = None
    for _pp, pg in files:
        for (what, num), p in pg.frames.items():
            if what == "UTOOL" and num == o.get("utool", num):
                tool = robot.conventions.tool0_in_flange @ frame_pose(pg.positions[p])
    return tool if tool is not None else profile_tool(profile)


def _run_moves(files, order) -> _RunMoves:
    """The moves of the programs in run order, a program with moves a part; a row starts at the
    move after its remark (or the DO switched on) and ends at the move before its end remark
    (or the DO switched off)."""
    seq, where, part, vals, vias = [], [], [], [], []
    starts, ends, names = set(), set(), []
    part_no = -1
    for pp, pg in files:
        if pg.moves:
            part_no += 1
        pending = None
        for it in pg.items:
            if it[0] == "move":
                mv = it[1]
                w = f"{pp}:{mv.line}"
                vals.append(_joint_values(pg, mv.p, w, order))
                vias.append(_joint_values(pg, mv.via, w, order) if mv.kind == CIRCULAR else None)
                if pending is not None:
                    starts.add(len(seq))
                    names.append(pending)
                    pending = None
                seq.append(mv)
                where.append(w)
                part.append(max(part_no, 0))
            elif it[0] == "row" or (it[0] == "do" and it[3]):
                if pending is None:
                    pending = it[2] if it[0] == "row" else f"DO {it[2]} on"
            elif (it[0] == "end_row" or (it[0] == "do" and not it[3])) and seq:
                ends.add(len(seq) - 1)
    return _RunMoves(seq, vals, vias, where, part, starts, ends, names)


def _fill_moves(kw: dict, run: _RunMoves, robot, profile, order, tool_T: np.ndarray) -> None:
    """Into ``kw``: the moves' kinds and joints, an L / C move's pose (the TCP at its joint
    position) and a C move's circle point, the speeds of L / C moves, every move's corner
    radius and the J moves' durations."""
    o = profile.options
    seq = run.moves
    kind = np.array([mv.kind for mv in seq])
    kw["kind"] = kind.astype(kw["kind"].dtype)
    qw = _model_joints(profile, robot, order, run.values)
    kw["q"] = qw.copy()
    chain = _Chain(robot.with_placement(tool_T_mm=tool_T))
    cart = np.flatnonzero(kind != JOINT)
    if len(cart):
        # an L / C move ends at its joint position, its pose the TCP there; between, the controller
        # solves the joints (the ProgramMoves of a Cartesian move leaves them to its IK)
        P, R = chain.fk(qw[cart])
        kw["q"][cart] = np.nan
        kw["pose"][cart, :3, :3], kw["pose"][cart, :3, 3] = R, P
        kw["pose"][cart, 3] = [0.0, 0.0, 0.0, 1.0]
    circ = np.flatnonzero(kind == CIRCULAR)
    if len(circ):
        P, R = chain.fk(_model_joints(profile, robot, order, [run.vias[k] for k in circ]))
        kw["via"][circ, :3, :3], kw["via"][circ, :3, 3] = R, P
        kw["via"][circ, 3] = [0.0, 0.0, 0.0, 1.0]
    for k, mv in enumerate(seq):
        if mv.kind != JOINT:
            kw["speed_mm_s"][k] = mv.speed
        kw["blend_mm"][k] = 0.0 if mv.cnt is None else cnt_radius(mv.cnt, o.get("cnt", []), o.get("cnt_mm", []))
    _joint_durations(kw, seq, robot, profile, order, qw, kind)


def _model_joints(profile, robot, order, values: list) -> np.ndarray:
    """(M, dof) camtool's joints of controller axis values (one list per position, in ``order``)."""
    V = np.array(values, float)
    return model_joints(profile, robot, {a.axis: V[:, j] for j, a in enumerate(order)})


def _joint_durations(kw: dict, seq: list, robot, profile, order, qw: np.ndarray, kind: np.ndarray) -> None:
    """Each J move's duration into ``kw``: the axis that needs longest at its % of the
    profile's ``max_speed``."""
    vmax = np.array([a.max_speed for a in order])
    ax = controller_axes(profile, robot, qw)
    A = np.stack([ax[a.axis] for a in order], axis=1)
    for k in np.flatnonzero(kind == JOINT):
        if k > 0:
            kw["duration_s"][k] = float(np.max(np.abs(A[k] - A[k - 1]) / vmax)) * 100.0 / seq[k].speed


def _joint_values(pg: LsProgram, p: int, where: str, order) -> list[float]:
    pos = pg.positions.get(p)
    if pos is None:
        raise BadInput(f"{where}: P[{p}] is not in /POS")
    if pos.cartesian:
        raise BadInput(f"{where}: P[{p}] is a Cartesian position: camtool writes and reads joint positions only "
                       "(a Cartesian target would depend on CONFIG)")
    missing = [a.axis for a in order if a.axis not in pos.joints]
    if missing:
        raise BadInput(f"{where}: P[{p}] has no {', '.join(missing)}")
    return [pos.joints[a.axis] for a in order]


def written_joints(path: Path, robot, profile) -> np.ndarray:
    """(M, dof) the joint values every move's position states (rad / mm), in run order."""
    order = [a for ax in AXES for a in profile.axes if a.axis == ax]
    rows = [_joint_values(pg, it[1].p, f"{pp}:{it[1].line}", order)
            for pp, pg in program_files(Path(path)) for it in pg.items if it[0] == "move"]
    if not rows:
        return np.zeros((0, robot.dof))
    V = np.array(rows, float)
    return model_joints(profile, robot, {a.axis: V[:, j] for j, a in enumerate(order)})


def read(path: Path, robot, profile) -> tuple[np.ndarray, np.ndarray]:
    """(durations_s, q): each move's duration (J from its %, L / C their length over their speed;
    NaN for the first) and its target's joints in rad / mm (the positions' joints; the controller
    ends every move there)."""
    from camtool.program.durations import move_durations

    prog = read_program(Path(path), robot, profile)
    q = written_joints(Path(path), robot, profile)
    return move_durations(prog, robot, q), q
