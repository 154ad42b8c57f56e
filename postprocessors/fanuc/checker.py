"""FANUC LS checker: sections, numbering, names, positions, frames and row markers of a program
and the programs it calls; then its targets and timing against the robot's and the
controller's limits."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from camtool.errors import BadInput
from camtool.program.check import arc_findings, check_motion, resolution_tol, row_marker_findings
from camtool.program.durations import move_durations
from camtool.program.moves import CIRCULAR
from camtool.program.targets import target_joints

from .dialect import ARC_LIMIT_DEG, AXES, program_name
from .parser import program_files, read_program, written_joints


def check(path: Path, robot, profile) -> list[str]:
    """Findings for a program (.LS) and the programs it calls: the sections /PROG, /ATTR, /MN,
    /POS, /END in order (a truncated file lacks /END or a position's ``};``), instructions
    numbered 1, 2, ... and counted by LINE_COUNT, CRLF and ASCII, the program name (as the
    file, valid, at most ``program_name_length``), every referenced position defined once and
    used once, joint positions with every mapped axis, each position's UF / UT the frames
    selected when it is moved to, J speeds whole 1..100 %, L / C speeds in mm/sec, FINE or CNT
    0..100, the last move FINE, row markers in pairs, no code in remarks; then every target
    against the robot's joint limits and the controller's axis limits (its J3, from the
    horizontal), and every move's speed against the robot's speed limits (tolerance: the
    written 0.001 deg)."""
    path = Path(path)
    try:
        files = program_files(path)
    except BadInput as exc:
        return [str(exc)]
    mapped = [a.axis for a in profile.axes]
    out, moves, open_row = _program_file_findings(files, mapped, profile.options.get("program_name_length", 8))
    if open_row is not None:
        out.append(f"{path}: row started at line {open_row} never ends")
    if not moves:
        return out or [f"{path}: no J, L or C move found"]
    last = moves[-1]
    if last[1].cnt is not None:
        out.append(f"{last[0]}: the last move must be FINE, found CNT{last[1].cnt}")
    if set(mapped) - set(AXES):
        out.append(f"{profile.source}: axes: expected J1..J6, E1..E3")
    if out:
        return out
    return _motion_findings(path, robot, profile)


def _program_file_findings(files, mapped: list[str], max_len: int) -> tuple[list[str], list[tuple], int | None]:
    """The findings of each program in turn, with the moves of all of them (``(file:line,
    move)``) and the line of a row still open at the end."""
    out: list[str] = []
    moves: list[tuple] = []
    open_row = None
    for pp, pg in files:
        out += pg.problems
        out += _name_findings(pp, pg, max_len)
        found, used = _position_findings(pp, pg, mapped)
        out += found
        moves += [(f"{pp}:{mv.line}", mv) for mv in pg.moves]
        for p, k in used.items():
            if k > 1:
                out.append(f"{pp}: P[{p}] is the target of {k} moves (camtool writes one position per move)")
        rows, open_row = row_marker_findings(pp, pg.items, open_row)
        out += rows
    return out, moves, open_row


def _name_findings(pp: Path, pg, max_len: int) -> list[str]:
    """The program's name: valid, at most ``max_len`` characters, its file's."""
    out = []
    if pg.name:
        if program_name(pg.name, 36)[0] != pg.name or len(pg.name) > max_len:
            out.append(f"{pp}: program name {pg.name!r} is not valid (upper-case letters, digits, _, a leading "
                       f"letter, <= {max_len} characters)")
        if pg.name != pp.stem:
            out.append(f"{pp}: /PROG {pg.name} is in a file named {pp.name!r}")
    return out


def _position_findings(pp: Path, pg, mapped: list[str]) -> tuple[list[str], dict[int, int]]:
    """The positions the moves refer to: in /POS, joint positions with the mapped axes, recorded
    in the frames the move runs with; and how many moves use each."""
    out = []
    used: dict[int, int] = {}
    for mv in pg.moves:
        w = f"{pp}:{mv.line}"
        for p in (mv.p, mv.via):
            if p is None:
                continue
            used[p] = used.get(p, 0) + 1
            pos = pg.positions.get(p)
            if pos is None:
                out.append(f"{w}: P[{p}] is not in /POS")
                continue
            if pos.cartesian:
                out.append(f"{w}: P[{p}] is Cartesian; camtool writes joint positions only (no CONFIG)")
                continue
            missing = [a for a in mapped if a not in pos.joints]
            extra = [k for k in pos.joints if k not in mapped]
            if missing or extra:
                out.append(f"{pp}:{pos.line}: P[{p}] needs {', '.join(mapped)}, found {', '.join(pos.joints)}")
            if (pos.uf, pos.ut) != (mv.uframe, mv.utool):
                out.append(f"{w}: P[{p}] is recorded in UF {pos.uf} / UT {pos.ut}, the move runs with UFRAME_NUM "
                           f"{mv.uframe} / UTOOL_NUM {mv.utool}")
    return out, used


def _motion_findings(path: Path, robot, profile) -> list[str]:
    """The Cartesian moves' configurations and arcs, every target against the robot's limits,
    every move's speed against its speed limits, then the controller's axis limits."""
    try:
        prog = read_program(path, robot, profile)
    except BadInput as exc:
        return [str(exc)]
    q = written_joints(path, robot, profile)
    dur = move_durations(prog, robot, q)
    out = _configuration_findings(prog, robot, profile, q)
    if (prog.kind == CIRCULAR).any():
        out += arc_findings(prog, robot, q, ARC_LIMIT_DEG)
    tol = resolution_tol(robot, 1e-3, 1e-3)
    out += check_motion(q, dur, robot, prog.where, tol)
    return out + _controller_limit_findings(prog, robot, q, float(np.max(tol)))


def _configuration_findings(prog, robot, profile, q: np.ndarray) -> list[str]:
    """L / C moves whose TCP the simulator reaches in another configuration than their joint
    position."""
    # the simulator solves a Cartesian move's end from the move before it: it must land on the joints
    # the position states (the controller ends there), not on another configuration
    solved = target_joints(prog, robot, profile)
    off = np.flatnonzero(np.any(np.abs(solved - q) > np.radians(2e-3), axis=1) | ~np.isfinite(solved).all(axis=1))
    return [f"{prog.where[k]}: the TCP of this L / C move is reached in another configuration than its joint "
            "position (the program's moves and the simulation would differ)" for k in off[:20]]


def _controller_limit_findings(prog, robot, q: np.ndarray, tol: float) -> list[str]:
    """Targets beyond the controller's axis limits (its J3 from the horizontal)."""
    conv = robot.conventions
    qc = conv.controller_from_model(q)
    bad = np.flatnonzero(conv.controller_limit_violations(qc, tol=tol).any(axis=1))
    out = []
    for k in bad[:20]:
        out += [f"{prog.where[k]}: {f}" for f in conv.check_controller_limits(qc[k], tol=tol)]
    return out
