"""Format-agnostic program checking: what every plugin's check shares.

Each post-processor checks its own files (``PostProcessor.check(path, robot,
profile)``, see ``camtool/program/plugin.py``); this module imports no plugin.
It holds what every check shares:

- ``check_motion``: every joint value against the robot's position limits and
  every step against the ROBOT's speed limits (``robot.limits.velocity``),
  using the program's own timing; non-finite values and durations are findings.
- ``read_back_check``: the check of a plugin without ``check``: its ``read``
  must give back finite joint values and durations that pass ``check_motion``.
- ``check_file``: the plugin's check (its own, or the read-back check), each
  finding once. A file by path (``camtool check``): ``camtool.program.check_program``.

Tolerances: the written resolution of each format (passed in as ``tol``) plus
``SPEED_REL_TOL`` (0.1 %) on speeds.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from camtool.errors import BadInput

MAX_PER_KIND = 20
SPEED_REL_TOL = 1e-3  # speeds may exceed the robot's limit by 0.1 % (rounding of written durations)


def dedupe(findings) -> list[str]:
    """Findings in order, each once."""
    return list(dict.fromkeys(findings))


def row_marker_findings(file: Path, items, open_row: int | None) -> tuple[list[str], int | None]:
    """Row markers out of pair in one file's ``items`` (``("row", line)`` / ``("end_row", line)`` among
    others), given the row left open by the file before; returns the findings and the row open after it."""
    out = []
    for it in items:
        if it[0] == "row":
            if open_row is not None:
                out.append(f"{file}:{it[1]}: a row starts before the previous one ended")
            open_row = it[1]
        elif it[0] == "end_row":
            if open_row is None:
                out.append(f"{file}:{it[1]}: a row ends that never started")
            open_row = None
    return out, open_row


def _edge(robot, i: int, v: float) -> str:
    return f"{v:.3f} mm" if robot.prismatic[i] else f"{np.degrees(v):.4f} deg"


def resolution_tol(robot, deg: float, mm: float) -> np.ndarray:
    """Half the written resolution per joint in native units (rad / mm), plus 1e-9."""
    return np.where(robot.prismatic, 0.5 * mm, np.radians(0.5 * deg)) + 1e-9


def check_motion(q: np.ndarray, durations_s: np.ndarray, robot, where: list[str],
                 tol: np.ndarray) -> list[str]:
    """Finite, limit and speed findings for joint values (M x dof, rad / mm) and move durations.

    ``where[k]`` names move k (``file:line``); ``tol`` (dof,) is the written
    resolution in native units; a NaN duration means "not given" (the first
    move of most programs) and skips that step's speed check; an infinite one
    is a finding. Speeds are checked against ``robot.limits.velocity`` with
    ``SPEED_REL_TOL`` plus the resolution over the step.
    """
    out: list[str] = []
    q = np.asarray(q, float)
    durations_s = np.asarray(durations_s, float)
    if len(q) == 0:
        return out
    file_ = where[0].rsplit(":", 1)[0]
    bad_q = ~np.isfinite(q)
    bad_t = np.isinf(durations_s)
    for k in np.flatnonzero(bad_q.any(axis=1))[:MAX_PER_KIND]:
        names = ", ".join(robot.joint_names[i] for i in np.flatnonzero(bad_q[k]))
        out.append(f"{where[k]}: {names}: value is not a finite number")
    for k in np.flatnonzero(bad_t)[:MAX_PER_KIND]:
        out.append(f"{where[k]}: move duration is not a finite number")
    n_bad = int(bad_q.any(axis=1).sum() + bad_t.sum())
    if n_bad > MAX_PER_KIND:
        out.append(f"{file_}: ... and more values that are not finite numbers")
    if n_bad:
        return out  # limits and speeds of non-numbers mean nothing
    L = robot.limits
    low = q < L.lower[None, :] - tol[None, :]
    high = q > L.upper[None, :] + tol[None, :]
    bad = np.argwhere(low | high)
    for k, i in bad[:MAX_PER_KIND]:
        out.append(f"{where[k]}: {robot.joint_names[i]} = {_edge(robot, i, q[k, i])} outside the limits "
                   f"{_edge(robot, i, L.lower[i])} .. {_edge(robot, i, L.upper[i])}")
    if len(bad) > MAX_PER_KIND:
        out.append(f"{file_}: ... and {len(bad) - MAX_PER_KIND} more values outside the limits")
    n_speed = 0
    if len(q) > 1:
        dt = durations_s[1:]
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
        out.append(f"{file_}: ... and {n_speed - MAX_PER_KIND} more steps above the speed limits")
    return out


# --- plugins without their own check ------------------------------------------------------------

GENERIC_RESOLUTION = (1e-4, 1e-3)  # deg, mm: assumed written resolution of a plugin without check


def read_back_check(plugin, path, robot, profile) -> list[str]:
    """The check of a plugin without ``check``: read the program back with the plugin's
    ``read`` and check its joint values and durations (``check_motion``)."""
    path = Path(path)
    try:
        dur, q = plugin.read(path, robot, profile)
    except BadInput as exc:
        return [str(exc)]
    except Exception as exc:  # noqa: BLE001 - a third-party reader's failure is a finding, not a crash
        return [f"{path}: post-processor {plugin.name!r} cannot read it back "
                f"({type(exc).__name__}: {exc})"]
    try:
        q = np.asarray(q, float).reshape(-1, robot.dof)
        dur = np.asarray(dur, float).reshape(-1)
    except (TypeError, ValueError):
        return [f"{path}: the read-back values do not have {robot.dof} joint values per move"]
    if len(dur) != len(q):
        return [f"{path}: read back {len(q)} moves but {len(dur)} durations"]
    if len(q) == 0:
        return [f"{path}: no moves"]
    where = [f"{path}: move {k + 1}" for k in range(len(q))]
    return check_motion(q, dur, robot, where, resolution_tol(robot, *GENERIC_RESOLUTION))


def check_file(plugin, path, robot, profile) -> list[str]:
    """Findings for one written file: the plugin's ``check`` (by default ``read_back_check``)."""
    return dedupe(plugin.check(Path(path), robot, profile))


def arc_findings(prog, robot, q: np.ndarray, max_sweep_deg: float, min_chord_mm: float = 0.1) -> list[str]:
    """Findings for the circular moves of a program read back (``ProgramMoves``) with target
    joints ``q``: a circle point and target that define a circle with the move's start (not
    on one line, at least ``min_chord_mm`` apart), and a sweep below the controller's limit
    for one instruction (``max_sweep_deg``)."""
    from .arcs import circle_through
    from .targets import _target_poses

    circ = np.flatnonzero(np.asarray(prog.kind) == "C")
    if not len(circ):
        return []
    out = []
    P, _R = _target_poses(prog, robot, q)
    first = circ[circ == 0]
    out += [f"{prog.where[k]}: a circular move cannot be the first move (it has no start)" for k in first]
    circ = circ[circ > 0]
    via = prog.via[circ, :3, 3]
    c, rad, n, r0, sweep, ok = circle_through(P[circ - 1], via, P[circ])
    for i, k in enumerate(circ[:MAX_PER_KIND * 5]):
        d = min(np.linalg.norm(via[i] - P[k - 1]), np.linalg.norm(P[k] - via[i]), np.linalg.norm(P[k] - P[k - 1]))
        if not np.isfinite(d) or d < min_chord_mm:
            out.append(f"{prog.where[k]}: the start, circle point and target of a circular move must be at least "
                       f"{min_chord_mm:g} mm apart ({d:.4f} mm)")
        elif not ok[i]:
            out.append(f"{prog.where[k]}: the start, circle point and target of a circular move lie on one line")
        elif np.degrees(sweep[i]) >= max_sweep_deg:
            out.append(f"{prog.where[k]}: a circular move of {np.degrees(sweep[i]):.1f} deg; the controller takes "
                       f"less than {max_sweep_deg:g} deg per instruction")
    return out
