"""KUKA KRL checker: structure, names, data, settings and row markers of a program and the
modules it calls; then its targets and timing against the robot's limits."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from camtool.errors import BadInput
from camtool.program.check import arc_findings, check_motion, resolution_tol
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
    out: list[str] = []
    try:
        modules = program_modules(path)
    except BadInput as exc:
        return [str(exc)]
    mapped = {a.axis for a in profile.axes}
    moves, where = [], []
    open_row = None
    for mp, mt in modules:
        out += mt.problems
        if mt.name:
            if krl_name(mt.name)[0] != mt.name.upper() or len(mt.name) > NAME_MAX:
                out.append(f"{mp}: module name {mt.name!r} is not a valid KRL name")
            if mt.name.upper() != mp.stem.upper():
                out.append(f"{mp}: DEF {mt.name} is in a file named {mp.name!r}")
        if mt.data_name and mt.data_name.upper() != mp.stem.upper():
            out.append(f"{mp.with_suffix('.dat')}: DEFDAT {mt.data_name} is in a file named {mp.stem}.dat")
        for nm, (typ, fields, ln) in mt.data.items():
            w = f"{mp.with_suffix('.dat')}:{ln}"
            if typ == "E6AXIS":
                missing = [a for a in AXES if a in mapped and a not in fields]
                if missing or set(fields) - set(AXES):
                    out.append(f"{w}: {nm}: an E6AXIS needs {', '.join(a for a in AXES if a in mapped)}, "
                               f"found {', '.join(fields)}")
            elif typ == "E6POS" and (not set("XYZABC") <= set(fields) or set(fields) - set("XYZABCST") - set(AXES)):
                out.append(f"{w}: {nm}: an E6POS needs X, Y, Z, A, B, C, found {', '.join(fields)}")
        for it in mt.items:
            if it[0] == "row":
                if open_row is not None:
                    out.append(f"{mp}:{it[1]}: a row starts before the previous one ended")
                open_row = it[1]
            elif it[0] == "end_row":
                if open_row is None:
                    out.append(f"{mp}:{it[1]}: a row ends that never started")
                open_row = None
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
            moves.append(mv)
            where.append(w)
    if open_row is not None:
        out.append(f"{path}: row started at line {open_row} never ends")
    if not moves:
        return out or [f"{path}: no PTP, LIN or CIRC found"]
    if moves[0].kind != JOINT:
        out.append(f"{where[0]}: the first move must be a PTP (the controller's BCO run), found a CP move")
    if moves[-1].c_dis or moves[-1].c_ptp:
        out.append(f"{where[-1]}: the last move must stop exactly (no C_DIS / C_PTP)")
    if not set(ROBOT_AXES) <= mapped:
        out.append(f"{profile.source}: axes: A1..A6 must all be mapped")
    if out:
        return out
    try:
        prog = read_program(path, robot, profile)
        q = target_joints(prog, robot, profile)
        dur = move_durations(prog, robot, q)
    except BadInput as exc:
        return [str(exc)]
    bad = np.flatnonzero(~np.isfinite(q).all(axis=1))
    if len(bad):
        return [f"{prog.where[k]}: no joint values reach this target" for k in bad[:20]]
    out += arc_findings(prog, robot, q, ARC_LIMIT_DEG)
    tol = resolution_tol(robot, 1e-4, 1e-3) + (1e-6 if (prog.kind != JOINT).any() else 0.0)
    return out + check_motion(q, dur, robot, prog.where, tol)
