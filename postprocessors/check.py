"""The program checker: validates written programs independently of the writers' state.

``check_program(path, robot, profile)`` reads a RAPID program (.pgf / .mod),
an INFORM job (.JBI) or a CSV back from disk and returns findings, one line
each (``file:line: message``); an empty list means clean. It checks:

- structure: RAPID module/proc nesting, statements, identifiers, declared
  tool/work object, 6+6 jointtarget values, 9E9 exactly on unconnected axes,
  zones and speeds, a ``fine`` last move; INFORM NPOS counts, contiguous
  indices, values per line, references, END, CRLF, ASCII, group and names;
  CSV header and columns.
- every joint value against the robot's position limits;
- every step against the robot's speed limits, using the program's own
  timing: RAPID ``\\T``, CSV ``t_s``, INFORM VJ with the profile's max speeds.

Tolerances allow for the written resolution only (1e-4 deg, 1e-3 mm, one
pulse) plus 0.1 % on speeds.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from camtool.errors import BadInput

from . import abb_rapid as rapid
from . import yaskawa_inform as inform
from .csv_joint import CsvPost

MAX_PER_KIND = 20
SPEED_REL_TOL = 1e-3


def format_of(path: Path) -> str:
    """The format of a program file from its extension (rapid, inform, csv)."""
    ext = Path(path).suffix.lower()
    fmt = {".pgf": "rapid", ".mod": "rapid", ".jbi": "inform", ".csv": "csv"}.get(ext)
    if fmt is None:
        raise BadInput(f"{path}: unknown program type {ext!r} (expected .pgf, .mod, .JBI or .csv)")
    return fmt


def check_program(path, robot, profile=None) -> list[str]:
    """Findings for one program file (empty when clean); see module doc.

    ``profile`` is needed for RAPID and INFORM (the axis map); None takes the
    shipped default for the robot.
    """
    path = Path(path)
    if not path.is_file():
        raise BadInput(f"{path}: program file not found")
    fmt = format_of(path)
    if profile is None and fmt != "csv":
        from camtool.profiles import load_profile
        profile = load_profile(None, robot.name, fmt, robot)
    findings = {"rapid": _check_rapid, "inform": _check_inform, "csv": _check_csv}[fmt](path, robot, profile)
    return _dedupe(findings)


def _dedupe(findings: list[str]) -> list[str]:
    seen, out = set(), []
    for f in findings:
        if f not in seen:
            seen.add(f)
            out.append(f)
    return out


def _edge(robot, i: int, v: float) -> str:
    return f"{v:.3f} mm" if robot.prismatic[i] else f"{np.degrees(v):.4f} deg"


def check_motion(q: np.ndarray, durations_s: np.ndarray, robot, where: list[str],
                 tol: np.ndarray) -> list[str]:
    """Limit and speed findings for joint values (M x dof, rad / mm) and move durations.

    ``where[k]`` names move k (``file:line``); ``tol`` (dof,) is the written
    resolution in native units; a NaN duration skips that step's speed check.
    """
    out: list[str] = []
    L = robot.limits
    low = q < L.lower[None, :] - tol[None, :]
    high = q > L.upper[None, :] + tol[None, :]
    bad = np.argwhere(low | high)
    for k, i in bad[:MAX_PER_KIND]:
        out.append(f"{where[k]}: {robot.joint_names[i]} = {_edge(robot, i, q[k, i])} outside the limits "
                   f"{_edge(robot, i, L.lower[i])} .. {_edge(robot, i, L.upper[i])}")
    if len(bad) > MAX_PER_KIND:
        out.append(f"{where[0].rsplit(':', 1)[0]}: ... and {len(bad) - MAX_PER_KIND} more values outside the limits")
    n_speed = 0
    if len(q) > 1:
        dt = np.asarray(durations_s[1:], float)
        dq = np.abs(np.diff(q, axis=0))
        known = ~np.isnan(dt)
        still = np.all(dq <= tol[None, :], axis=1)  # a move that goes nowhere (a dwell) takes no time
        for k in np.flatnonzero(known & (dt <= 0) & ~still) + 1:
            out.append(f"{where[k]}: move duration {durations_s[k]:.4f} s is not positive")
        timed = known & (dt > 0)
        safe_dt = np.where(timed, dt, 1.0)[:, None]
        allowed = L.velocity[None, :] * (1 + SPEED_REL_TOL) + 2 * tol[None, :] / safe_dt
        over = np.argwhere((dq / safe_dt > allowed) & timed[:, None])
        n_speed = len(over)
        for k0, i in over[:MAX_PER_KIND]:
            k = k0 + 1
            unit = "mm/s" if robot.prismatic[i] else "deg/s"
            conv = (lambda x: x) if robot.prismatic[i] else np.degrees
            out.append(f"{where[k]}: {robot.joint_names[i]} speed {conv(dq[k0, i] / dt[k0]):.2f} {unit} above the "
                       f"limit {conv(L.velocity[i]):.2f} {unit} (step over {dt[k0]:.4f} s)")
    if n_speed > MAX_PER_KIND:
        out.append(f"{where[0].rsplit(':', 1)[0]}: ... and {n_speed - MAX_PER_KIND} more steps above the speed limits")
    return out


# --- RAPID --------------------------------------------------------------------------------------

def _check_rapid(path: Path, robot, profile) -> list[str]:
    out: list[str] = []
    try:
        modules = rapid.program_modules(path)
    except BadInput as exc:
        return [str(exc)]
    mapped = {a.axis for a in profile.axes}
    names = rapid.RAX + rapid.EAX
    procs = {p for _mp, mt in modules for p in mt.procs}
    declared = {n: t for _mp, mt in modules for n, t in mt.data.items()}
    entry = path.suffix.lower() == ".pgf" or "main" in modules[0][1].procs
    moves, where = [], []
    for mp, mt in modules:
        out += mt.problems
        if mt.name:
            ident, _ = rapid.rapid_identifier(mt.name)
            if ident != mt.name or len(mt.name) > 32:
                out.append(f"{mp}: module name {mt.name!r} is not a valid RAPID identifier")
            if mt.name != mp.stem:
                out.append(f"{mp}: module {mt.name!r} is in a file named {mp.name!r}")
        for p in mt.procs + list(mt.data):
            if rapid.rapid_identifier(p)[0] != p and p not in rapid.BUILTIN_DATA:
                out.append(f"{mp}: {p!r} is not a valid RAPID identifier")
        for n, proc in mt.calls:
            if proc not in procs:
                out.append(f"{mp}:{n}: %\"{proc}\"% calls a routine no loaded module defines")
        for mv in mt.moves:
            w = f"{mp}:{mv.line}"
            vals = dict(zip(names, mv.rax + mv.eax))
            for ax in names:
                if ax in mapped and vals[ax] >= 8.9e9:
                    out.append(f"{w}: {ax} is connected (profile) but written as 9E9")
                elif ax not in mapped and vals[ax] != rapid.NOT_CONNECTED:
                    out.append(f"{w}: {ax} is not connected (profile) and must be 9E9, found {vals[ax]}")
            if mv.zone not in rapid.ZONES:
                out.append(f"{w}: unknown zone {mv.zone!r}")
            if mv.speed not in rapid.SPEEDS:
                out.append(f"{w}: unknown speed data {mv.speed!r}")
            for kind, name in (("tooldata", mv.tool), ("wobjdata", mv.wobj)):
                # a split module alone relies on the main module's declarations
                if entry and name and name not in rapid.BUILTIN_DATA and declared.get(name) != kind:
                    out.append(f"{w}: {kind} {name!r} is not declared in the program")
            moves.append(mv)
            where.append(w)
    if entry and "main" not in modules[0][1].procs:
        out.append(f"{modules[0][0]}: the main module has no PROC main()")
    if entry and moves and moves[-1].zone != "fine":
        out.append(f"{where[-1]}: the last move must be fine, found {moves[-1].zone}")
    if not moves or out:
        if not moves and not out:
            out.append(f"{path}: no MoveAbsJ found")
        if any("connected" in f for f in out):
            return out
    dur, q = rapid.RapidPost.moves_to_arrays(moves, robot, profile)
    tol = np.where(robot.prismatic, 0.5e-3, np.radians(0.5e-4)) + 1e-9
    return out + check_motion(q, dur, robot, where, tol)


# --- INFORM -------------------------------------------------------------------------------------

def _check_inform(path: Path, robot, profile) -> list[str]:
    out: list[str] = []
    groups = inform.group_axes(profile)
    want_group = list(groups)
    max_len = profile.options.get("job_name_length", 8)
    moves, pulses, where = [], {g: [] for g in inform.GROUPS}, []
    consistent = True
    for jp, j in inform.job_files(path):
        out += j.problems
        consistent &= not j.problems
        if j.name:
            if inform.job_name(j.name, 32)[0] != j.name or len(j.name) > max_len:
                out.append(f"{jp}: job name {j.name!r} is not valid (uppercase, digits, _, leading letter, "
                           f"<= {max_len} characters)")
            if j.name != jp.stem:
                out.append(f"{jp}: job {j.name!r} is in a file named {jp.name!r}")
        if j.group and j.group != want_group:
            out.append(f"{jp}: ///GROUP1 {','.join(j.group)} does not match the profile ({','.join(want_group)})")
            consistent = False
        for g, ax in groups.items():
            pre = inform.GROUPS[g]
            for _i, vals, ln in j.pos[pre]:
                if len(vals) != len(ax):
                    out.append(f"{jp}:{ln}: {pre} line has {len(vals)} values, group {g} has {len(ax)} axes")
                    consistent = False
        for mv in j.moves:
            moves.append(mv)
            where.append(f"{jp}:{mv.line}")
            for g, pre in inform.GROUPS.items():
                if g in groups and pre in mv.refs and mv.refs[pre] < len(j.pos[pre]):
                    pulses[g].append(j.pos[pre][mv.refs[pre]][1])
    if not consistent or not moves:
        if not moves and not out:
            out.append(f"{path}: no MOVJ found")
        return out
    try:
        dur, q = inform.InformPost().moves_to_arrays(moves, pulses, robot, profile)
    except BadInput as exc:
        return out + [f"{path}: {exc}"]
    order = [a for ax in groups.values() for a in ax]
    tol = np.zeros(robot.dof)
    for a in order:
        i = robot.joint_names.index(a.joint)
        step = 1.0 / a.pulses
        tol[i] = step if robot.prismatic[i] else np.radians(step)
    return out + check_motion(q, dur, robot, where, tol + 1e-9)


# --- CSV ----------------------------------------------------------------------------------------

def _check_csv(path: Path, robot, profile) -> list[str]:
    try:
        t_s, q = CsvPost().read_trajectory(path, robot)
    except BadInput as exc:
        return [str(exc)]
    where = [f"{path}:{k + 2}" for k in range(len(t_s))]
    if len(t_s) == 0:
        return [f"{path}: no rows"]
    out = []
    if not np.all(np.isfinite(t_s)) or not np.all(np.isfinite(q)):
        out.append(f"{path}: values must be finite")
        return out
    dur = np.concatenate([[np.nan], np.diff(t_s)])
    return out + check_motion(q, dur, robot, where, np.full(robot.dof, 1e-9))
