"""ABB RAPID checker: structure, declarations, values, zones and speed data of a program and
the modules it loads; then its targets and timing against the robot's limits."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from camtool.errors import BadInput
from camtool.program.check import arc_findings, check_motion, resolution_tol, row_marker_findings
from camtool.program.durations import move_durations
from camtool.program.moves import JOINT
from camtool.program.targets import target_joints

from .dialect import ARC_LIMIT_DEG, BUILTIN_DATA, EAX, NOT_CONNECTED, RAX, ZONE_MM, rapid_identifier
from .parser import _speed_ok, moves_to_arrays, program_modules, read_bytes, read_program


def check(path: Path, robot, profile) -> list[str]:
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
    if path.suffix.lower() == ".pgf" and not read_bytes(path).endswith(b"\n"):
        out.append(f"{path}: no newline at end of file")
    entry = path.suffix.lower() == ".pgf" or "main" in modules[0][1].procs
    found, moves, where, open_row = _module_findings(modules, profile, entry)
    out += found
    out += _program_findings(path, modules, entry, moves, where, open_row)
    if not moves and not out:
        out.append(f"{path}: no MoveAbsJ found")
    if not moves or any("connected" in f for f in out):
        return out
    return out + _motion_findings(path, robot, profile, moves, where, entry)


def _module_findings(modules, profile, entry: bool) -> tuple[list[str], list, list[str], int | None]:
    """The findings of each module in turn, with the moves of all of them, their file:line
    labels and the line of a row still open at the end."""
    mapped = {a.axis for a in profile.axes}
    procs = {p for _mp, mt in modules for p in mt.procs}
    declared = {n: t for _mp, mt in modules for n, t in mt.data.items()}
    out: list[str] = []
    moves, where = [], []
    open_row = None
    for mp, mt in modules:
        out += mt.problems
        out += _name_findings(mp, mt, procs)
        rows, open_row = row_marker_findings(mp, mt.items, open_row)
        out += rows
        if not mt.moves:
            continue
        w_mod = [f"{mp}:{mv.line}" for mv in mt.moves]
        out += _axis_findings(mt, w_mod, mapped)
        out += _zone_speed_findings(mt, w_mod)
        if entry:  # a split module alone relies on the main module's declarations
            out += _declaration_findings(mt, w_mod, declared)
        moves += mt.moves
        where += w_mod
    return out, moves, where, open_row


def _name_findings(mp: Path, mt, procs: set[str]) -> list[str]:
    """The module's name against its file's, identifiers, and calls of routines no module defines."""
    out = []
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
    return out


def _axis_findings(mt, w_mod: list[str], mapped: set[str]) -> list[str]:
    """9E9 on a connected axis, or anything else on an axis the profile leaves unconnected."""
    out = []
    # axis values of every move: jointtargets in full, robtargets' external axes (NaN on rax)
    AX = np.array([(mv.rax if mv.kind == JOINT else [np.nan] * 6) + mv.eax for mv in mt.moves], float)
    for j, ax in enumerate(RAX + EAX):
        col = AX[:, j]
        bad = np.flatnonzero(col >= 8.9e9) if ax in mapped else \
            np.flatnonzero(np.isfinite(col) & (col != NOT_CONNECTED))
        for i in bad[:20]:
            out.append(f"{w_mod[i]}: {ax} is connected (profile) but written as 9E9" if ax in mapped else
                       f"{w_mod[i]}: {ax} is not connected (profile) and must be 9E9, found {col[i]}")
    return out


def _zone_speed_findings(mt, w_mod: list[str]) -> list[str]:
    """Unknown zones, then unknown speed data."""
    out = []
    for i, mv in enumerate(mt.moves):
        if mv.zone not in ZONE_MM:
            out.append(f"{w_mod[i]}: unknown zone {mv.zone!r}")
    speeds = {mv.speed for mv in mt.moves}
    bad_speeds = {sp for sp in speeds if not _speed_ok(sp)}
    if bad_speeds:
        out += [f"{w_mod[i]}: unknown speed data {mv.speed!r}" for i, mv in enumerate(mt.moves)
                if mv.speed in bad_speeds]
    return out


def _declaration_findings(mt, w_mod: list[str], declared: dict[str, str]) -> list[str]:
    """Tools and work objects the moves use that the program does not declare."""
    out = []
    for kind, attr in (("tooldata", "tool"), ("wobjdata", "wobj")):
        names_used = {getattr(mv, attr) for mv in mt.moves}
        undeclared = {nm for nm in names_used if nm and nm not in BUILTIN_DATA and declared.get(nm) != kind}
        out += [f"{w_mod[i]}: {kind} {getattr(mv, attr)!r} is not declared in the program"
                for i, mv in enumerate(mt.moves) if getattr(mv, attr) in undeclared]
    return out


def _program_findings(path: Path, modules, entry: bool, moves: list, where: list[str],
                      open_row: int | None) -> list[str]:
    """An entry program's unended row, missing PROC main() and last move that is not fine."""
    out = []
    if open_row is not None and entry:
        out.append(f"{path}: row started at line {open_row} never ends")
    if entry and "main" not in modules[0][1].procs:
        out.append(f"{modules[0][0]}: the main module has no PROC main()")
    if entry and moves and moves[-1].zone != "fine":
        out.append(f"{where[-1]}: the last move must be fine, found {moves[-1].zone}")
    return out


def _motion_findings(path: Path, robot, profile, moves: list, where: list[str], entry: bool) -> list[str]:
    """Every target against the robot's limits and every step's speed against its speed
    limits; with Cartesian moves, their arcs too (read through ``read_program``)."""
    if any(mv.kind != JOINT for mv in moves):
        if not entry:
            return []  # a part alone: its work object is declared in the main module
        try:
            prog = read_program(path, robot, profile)
            q = target_joints(prog, robot, profile)
            dur = move_durations(prog, robot, q)
        except BadInput as exc:
            return [str(exc)]
        bad = np.flatnonzero(~np.isfinite(q).all(axis=1))
        if len(bad):
            return [f"{prog.where[k]}: no joint values reach this target in its configuration" for k in bad[:20]]
        return arc_findings(prog, robot, q, ARC_LIMIT_DEG) + check_motion(
            q, dur, robot, prog.where, resolution_tol(robot, 1e-4, 1e-3) + 1e-6)
    dur, q = moves_to_arrays(moves, robot, profile)
    return check_motion(q, dur, robot, where, resolution_tol(robot, 1e-4, 1e-3))
