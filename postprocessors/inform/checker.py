"""Yaskawa INFORM checker: positions, instructions, groups, names and row markers of a job and
the jobs it calls; then its targets and timing against the robot's limits."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from camtool.errors import BadInput
from camtool.program.check import arc_findings, check_motion, row_marker_findings
from camtool.program.durations import move_durations
from camtool.program.moves import JOINT
from camtool.program.targets import cartesian_targets, target_joints

from .dialect import ARC_LIMIT_DEG, GROUPS, group_axes, job_name
from .parser import job_files, read_program


def check(path: Path, robot, profile) -> list[str]:
    """Findings for a job and the jobs it CALLs: NPOS counts against the positions (a
    truncated job has fewer, and no END), contiguous indices, integer pulses within
    int64, values per line, references, END, CRLF, ASCII, group, names and row markers;
    then every target against the robot's limits and every move's speed against the
    robot's speed limits (tolerance: one pulse). A joint move's duration is the
    controller's: the governing axis at VJ % of the profile's ``max_speed``
    (docs/controllers.md); the resulting axis speeds must stay within
    ``robot.limits.velocity``, whatever the profile says."""
    path = Path(path)
    out: list[str] = []
    groups = group_axes(profile)
    want_group = list(groups)
    max_len = profile.options.get("job_name_length", 8)
    consistent = True
    n_moves = 0
    open_row = None
    for jp, j in job_files(path):
        out += j.problems
        consistent &= not j.problems
        n_moves += len(j.moves)
        if j.name:
            if job_name(j.name, 32)[0] != j.name or len(j.name) > max_len:
                out.append(f"{jp}: job name {j.name!r} is not valid (uppercase, digits, _, leading letter, "
                           f"<= {max_len} characters)")
            if j.name != jp.stem:
                out.append(f"{jp}: job {j.name!r} is in a file named {jp.name!r}")
        if j.group and j.group != want_group:
            out.append(f"{jp}: ///GROUP1 {','.join(j.group)} does not match the profile ({','.join(want_group)})")
            consistent = False
        for g, ax in groups.items():
            pre = GROUPS[g]
            for _i, vals, ln, kind, _rc in j.pos[pre]:
                want = len(ax) if kind == "pulse" else 6 + (len(ax) == 7)
                if len(vals) != want:
                    out.append(f"{jp}:{ln}: {pre} line has {len(vals)} values, expected {want} for group {g}")
                    consistent = False
        rows, open_row = row_marker_findings(jp, j.items, open_row)
        out += rows
    if open_row is not None:
        out.append(f"{path}: row started at line {open_row} never ends")
    if not consistent or not n_moves:
        if not n_moves and not out:
            out.append(f"{path}: no MOVJ found")
        return out
    try:
        prog = read_program(path, robot, profile)
    except BadInput as exc:
        return out + [f"{path}: {exc}"]
    if cartesian_targets(prog).any():
        q = target_joints(prog, robot, profile)
        bad = np.flatnonzero(~np.isfinite(q).all(axis=1))
        if len(bad):
            return out + [f"{prog.where[k]}: no joint values reach this position" for k in bad[:20]]
        dur = move_durations(prog, robot, q)
        out += arc_findings(prog, robot, q, ARC_LIMIT_DEG)
    else:
        q, dur = prog.q, prog.duration_s
    tol = np.zeros(robot.dof)
    for a in (a for ax in groups.values() for a in ax):
        i = robot.joint_names.index(a.joint)
        step = 0.0 if a.pulses is None else 1.0 / a.pulses   # Cartesian positions only: the term below
        tol[i] = step if robot.prismatic[i] else np.radians(step)
    if (prog.kind != JOINT).any():
        tol = tol + np.where(robot.prismatic, 1e-3, np.radians(1e-4))  # Cartesian positions: 0.001 mm / deg
    return out + check_motion(q, dur, robot, prog.where, tol + 1e-9)
