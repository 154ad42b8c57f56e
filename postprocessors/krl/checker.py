"""KUKA KRL checker: structure, names, data, settings and row markers of a program and the
modules it calls; then its targets and timing against the robot's limits."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from camtool.errors import BadInput
from camtool.program.check import arc_findings, check_motion, resolution_tol, row_marker_findings
from camtool.program.durations import move_durations
from camtool.program.moves import JOINT
from camtool.program.targets import target_joints

from .dialect import AXES, ARC_LIMIT_DEG, NAME_MAX, ROBOT_AXES, krl_name
from .parser import program_modules, read_program


def check(path: Path, robot, profile) -> list[str]:
    """Findings for a program (.src, or its .dat) and the modules it calls: DEF / END and
    DEFDAT / ENDDAT (a truncated file lacks its END), one routine per module named as its
    file, names (<= 24 characters, no keyword), every target declared with its type and all
    its values finite (E6AXIS: the mapped axes; E6POS: X, Y, Z, A, B, C), the settings a move
    relies on set before it ($VEL_AXIS, $VEL.CP, $APO.CDIS / $APO.CPTP, $BASE, $TOOL), a PTP
    first (the controller's BCO run) and an exact stop last, row markers in pairs, ASCII, line
    length, no code in comments; then every target against the robot's limits (a CP target's
    joints by the simulator's inverse kinematics) and every move's speed against the robot's
    speed limits (tolerance: the written 1e-4 deg / 1e-3 mm)."""
    path = Path(path)
    if path.suffix.lower() == ".dat":
        path = path.with_suffix(".src")
    try:
        modules = program_modules(path)
    except BadInput as exc:
        return [str(exc)]
    mapped = {a.axis for a in profile.axes}
    out, moves, where, open_row = _module_findings(modules, mapped)
    if open_row is not None:
        out.append(f"{path}: row started at line {open_row} never ends")
    if not moves:
        return out or [f"{path}: no PTP, LIN or CIRC found"]
    out += _program_findings(profile, mapped, moves, where)
    if out:
        return out
    return _motion_findings(path, robot, profile)


def _module_findings(modules, mapped: set[str]) -> tuple[list[str], list, list[str], int | None]:
    """The findings of each module in turn, with the moves of all of them, their file:line
    labels and the line of a row still open at the end."""
    out: list[str] = []
    moves, where = [], []
    open_row = None
    for mp, mt in modules:
        out += mt.problems
        out += _name_findings(mp, mt)
        out += _data_findings(mp, mt, mapped)
        rows, open_row = row_marker_findings(mp, mt.items, open_row)
        out += rows
        out += _move_findings(mp, mt, mapped)
        moves += mt.moves
        where += [f"{mp}:{mv.line}" for mv in mt.moves]
    return out, moves, where, open_row


def _name_findings(mp: Path, mt) -> list[str]:
    """The module's name: a valid KRL name, its DEF and DEFDAT named as their files."""
    out = []
    if mt.name:
        if krl_name(mt.name)[0] != mt.name.upper() or len(mt.name) > NAME_MAX:
            out.append(f"{mp}: module name {mt.name!r} is not a valid KRL name")
        if mt.name.upper() != mp.stem.upper():
            out.append(f"{mp}: DEF {mt.name} is in a file named {mp.name!r}")
    if mt.data_name and mt.data_name.upper() != mp.stem.upper():
        out.append(f"{mp.with_suffix('.dat')}: DEFDAT {mt.data_name} is in a file named {mp.stem}.dat")
    return out


def _data_findings(mp: Path, mt, mapped: set[str]) -> list[str]:
    """Targets of the data list without the values of their type: E6AXIS the mapped axes,
    E6POS X, Y, Z, A, B, C."""
    out = []
    for nm, (typ, fields, ln) in mt.data.items():
        w = f"{mp.with_suffix('.dat')}:{ln}"
        if typ == "E6AXIS":
            missing = [a for a in AXES if a in mapped and a not in fields]
            if missing or set(fields) - set(AXES):
                out.append(f"{w}: {nm}: an E6AXIS needs {', '.join(a for a in AXES if a in mapped)}, "
                           f"found {', '.join(fields)}")
        elif typ == "E6POS" and (not set("XYZABC") <= set(fields) or set(fields) - set("XYZABCST") - set(AXES)):
            out.append(f"{w}: {nm}: an E6POS needs X, Y, Z, A, B, C, found {', '.join(fields)}")
    return out


def _move_findings(mp: Path, mt, mapped: set[str]) -> list[str]:
    """Moves to targets the data list does not declare, and moves before the settings they rely
    on: $VEL_AXIS / $VEL_EXTAX and $APO.CPTP for a PTP, $VEL.CP, $BASE and $TOOL for a CP move,
    $APO.CDIS for C_DIS."""
    out = []
    for mv in mt.moves:
        w = f"{mp}:{mv.line}"
        for nm in (mv.target, mv.aux):
            if nm is not None and nm.upper() not in mt.data:
                out.append(f"{w}: {nm} is not declared in {mp.stem}.dat")
        if mv.kind == JOINT:
            unset = [a for a in AXES if a in mapped and a not in mv.vel_axis]
            if unset:
                out.append(f"{w}: PTP before $VEL_AXIS / $VEL_EXTAX is set for {', '.join(unset)}")
            if mv.c_ptp and mv.cptp is None:
                out.append(f"{w}: C_PTP before $APO.CPTP is set")
        else:
            if mv.vel_cp is None:
                out.append(f"{w}: a CP move before $VEL.CP is set")
            if mv.base is None or mv.tool is None:
                out.append(f"{w}: a CP move before $BASE and $TOOL are set")
        if mv.c_dis and mv.cdis is None:
            out.append(f"{w}: C_DIS before $APO.CDIS is set")
    return out


def _program_findings(profile, mapped: set[str], moves: list, where: list[str]) -> list[str]:
    """A first move that is not a PTP, a last move that does not stop exactly, and A1..A6 not
    all mapped."""
    out = []
    if moves[0].kind != JOINT:
        out.append(f"{where[0]}: the first move must be a PTP (the controller's BCO run), found a CP move")
    if moves[-1].c_dis or moves[-1].c_ptp:
        out.append(f"{where[-1]}: the last move must stop exactly (no C_DIS / C_PTP)")
    if not set(ROBOT_AXES) <= mapped:
        out.append(f"{profile.source}: axes: A1..A6 must all be mapped")
    return out


def _motion_findings(path: Path, robot, profile) -> list[str]:
    """Every target against the robot's limits (a CP target's joints by the simulator's inverse
    kinematics), the arcs, and every move's speed against the robot's speed limits."""
    try:
        prog = read_program(path, robot, profile)
        q = target_joints(prog, robot, profile)
        dur = move_durations(prog, robot, q)
    except BadInput as exc:
        return [str(exc)]
    bad = np.flatnonzero(~np.isfinite(q).all(axis=1))
    if len(bad):
        return [f"{prog.where[k]}: no joint values reach this target" for k in bad[:20]]
    tol = resolution_tol(robot, 1e-4, 1e-3) + (1e-6 if (prog.kind != JOINT).any() else 0.0)
    return arc_findings(prog, robot, q, ARC_LIMIT_DEG) + check_motion(q, dur, robot, prog.where, tol)
