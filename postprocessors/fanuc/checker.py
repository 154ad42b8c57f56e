"""FANUC LS checker: sections, numbering, names, positions, frames and row markers of a program
and the programs it calls; then its targets and timing against the robot's and the
controller's limits."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from camtool.errors import BadInput
from camtool.program.check import arc_findings, check_motion, resolution_tol
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
    out: list[str] = []
    try:
        files = program_files(path)
    except BadInput as exc:
        return [str(exc)]
    mapped = [a.axis for a in profile.axes]
    max_len = profile.options.get("program_name_length", 8)
    n_moves, last = 0, None
    open_row = None
    for pp, pg in files:
        out += pg.problems
        if pg.name:
            if program_name(pg.name, 36)[0] != pg.name or len(pg.name) > max_len:
                out.append(f"{pp}: program name {pg.name!r} is not valid (upper-case letters, digits, _, a leading "
                           f"letter, <= {max_len} characters)")
            if pg.name != pp.stem:
                out.append(f"{pp}: /PROG {pg.name} is in a file named {pp.name!r}")
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
            n_moves += 1
            last = (w, mv)
        for p, k in used.items():
            if k > 1:
                out.append(f"{pp}: P[{p}] is the target of {k} moves (camtool writes one position per move)")
        for it in pg.items:
            if it[0] == "row":
                if open_row is not None:
                    out.append(f"{pp}:{it[1]}: a row starts before the previous one ended")
                open_row = it[1]
            elif it[0] == "end_row":
                if open_row is None:
                    out.append(f"{pp}:{it[1]}: a row ends that never started")
                open_row = None
    if open_row is not None:
        out.append(f"{path}: row started at line {open_row} never ends")
    if not n_moves:
        return out or [f"{path}: no J, L or C move found"]
    if last[1].cnt is not None:
        out.append(f"{last[0]}: the last move must be FINE, found CNT{last[1].cnt}")
    if set(mapped) - set(AXES):
        out.append(f"{profile.source}: axes: expected J1..J6, E1..E3")
    if out:
        return out
    try:
        prog = read_program(path, robot, profile)
    except BadInput as exc:
        return [str(exc)]
    q = written_joints(path, robot, profile)
    dur = move_durations(prog, robot, q)
    # the simulator solves a Cartesian move's end from the move before it: it must land on the joints
    # the position states (the controller ends there), not on another configuration
    solved = target_joints(prog, robot, profile)
    off = np.flatnonzero(np.any(np.abs(solved - q) > np.radians(2e-3), axis=1) | ~np.isfinite(solved).all(axis=1))
    for k in off[:20]:
        out.append(f"{prog.where[k]}: the TCP of this L / C move is reached in another configuration than its "
                   "joint position (the program's moves and the simulation would differ)")
    if (prog.kind == CIRCULAR).any():
        out += arc_findings(prog, robot, q, ARC_LIMIT_DEG)
    tol = resolution_tol(robot, 1e-3, 1e-3)
    out += check_motion(q, dur, robot, prog.where, tol)
    conv = robot.conventions
    qc = conv.controller_from_model(q)
    bad = np.flatnonzero(conv.controller_limit_violations(qc, tol=float(np.max(tol))).any(axis=1))
    for k in bad[:20]:
        out += [f"{prog.where[k]}: {f}" for f in conv.check_controller_limits(qc[k], tol=float(np.max(tol)))]
    return out
