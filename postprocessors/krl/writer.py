"""KUKA KRL writer: the program model's moves as ``PTP`` / ``LIN`` / ``CIRC`` statements in a
``.src`` file, their targets in the ``.dat`` data list of the same name (see
``postprocessors.krl``)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camtool import __version__
from camtool.program.convention import controller_axes, controller_pose, tool_in_tool0, wobj_frame
from camtool.program.moves import joint_travel
from camtool.program.plan import (KIND_CIRCULAR, KIND_JOINT, KIND_LINEAR, move_lengths, planned_moves, profile_tool,
                                  row_markers, split_parts, stop_at_part_ends)
from camtool.program.process import ProcessInfo, program_date
from camtool.program.steps import rotation_angles_rad

from .dialect import (AXES, EXTERNAL_AXES, LINE_MAX, MAX_ARC_DEG, ROBOT_AXES, VEL_CP_DECIMALS, comment_text,
                      cptp_percent, fmt_column, frame_text, krl_name, validate_profile)

NEWLINE = "\r\n"   # the controller's files are Windows text files


@dataclass(frozen=True)
class _Motion:
    """Per move what its speeds and approximation are written from: its kind, the controller's
    axis values (the profile's axes in controller order, their names and maximum speeds), its
    length (mm), its length in the blend model's units, its approximation radius (mm) and its
    level (-1: an exact stop)."""

    kind: np.ndarray
    axis_names: list[str]
    values: np.ndarray
    vmax: np.ndarray
    length: np.ndarray
    leq: np.ndarray
    radius: np.ndarray
    level: np.ndarray


def write(trajectory, robot, profile, outdir: Path, process: ProcessInfo | None = None) -> list[Path]:
    """Write ``NAME.src`` and ``NAME.dat`` (plus ``NAME_NNN.src`` / ``.dat`` parts when split);
    the entry file (``NAME.src``) first."""
    validate_profile(profile, robot)
    process = process if process is not None else ProcessInfo()
    outdir = Path(outdir)
    o = profile.options
    name, _ = krl_name(profile.program_name, 20)   # room for the parts' _NNN
    robot = robot.with_placement(tool_T_mm=profile_tool(profile))  # the TCP the program declares
    levels = [float(v) for v in o["cdis_mm"]]
    plan = planned_moves(trajectory, robot, process, linear=True, levels_mm=levels,
                         arcs_max_sweep_deg=MAX_ARC_DEG if o["arcs"] else None)
    parts = split_parts(len(plan), o["lines_per_file"], plan.free, "moves", f"{profile.source}: options.lines_per_file")
    level = stop_at_part_ends(plan.level, parts)   # a module ends with a stop: the next one is called there
    axes = controller_axes(profile, robot, plan.q)
    motion = _motion(plan, robot, profile, axes, levels, level)
    pre, moves = _moves(plan, robot, motion, o, {r.start for r in parts})
    targets = _targets(plan, motion.kind, profile, robot, axes)
    before, after = _row_markers(plan, process, o["process_output"])
    header = _header(trajectory, robot, profile, process, plan, level)
    bodies = [_body(r, pre, moves, before, after) for r in parts]
    return _write_files(outdir, _modules(name, header, _settings(robot, profile), parts, bodies, targets))


def _motion(plan, robot, profile, axes: dict, levels: list[float], level: np.ndarray) -> _Motion:
    """The controller's axis values and the moves' lengths in the blend model's units, their
    approximation radii."""
    n = len(plan)
    order = [a for ax in AXES for a in profile.axes if a.axis == ax]
    length = move_lengths(plan)
    leq = np.maximum(length, np.r_[0.0, joint_travel(np.diff(plan.q, axis=0), robot.prismatic)]) if n > 1 \
        else np.zeros(n)
    return _Motion(kind=np.array(plan.kind), axis_names=[a.axis for a in order],
                   values=np.stack([axes[a.axis] for a in order], axis=1),
                   vmax=np.array([a.max_speed for a in order]), length=length, leq=leq,
                   radius=np.where(level >= 0, np.asarray(levels + [0.0])[level], 0.0), level=level)


def _row_markers(plan, process: ProcessInfo, out_no) -> tuple[dict[int, list[str]], dict[int, list[str]]]:
    """The comments and $OUT assignments before a row's first move and after its last one."""
    def start(row_no: int, label: str | None) -> list[str]:
        text = f": {comment_text(label, 40)}" if label is not None else ""
        return [f"; Row {row_no} of {plan.rows}{text}"] + ([f"$OUT[{out_no}]=TRUE"] if out_no else [])

    def end(row_no: int) -> list[str]:
        return ([f"$OUT[{out_no}]=FALSE"] if out_no else []) + [f"; End of row {row_no}"]

    return row_markers(plan, process, start, end)


def _header(trajectory, robot, profile, process: ProcessInfo, plan, level: np.ndarray) -> list[str]:
    """The main module's comment lines: the counts, job, profile, conventions, targets and process."""
    o = profile.options
    out_no = o["process_output"]
    n = len(plan)
    kind = np.array(plan.kind)
    n_lin = int((kind == KIND_LINEAR).sum())
    n_circ = int((kind == KIND_CIRCULAR).sum())
    date = program_date(o["date"], process)
    return [f"; Generated by camtool {__version__} for robot {comment_text(robot.name, 24)}: {n} moves ({n_lin} LIN, "
            f"{n_circ} CIRC, {n - n_lin - n_circ} PTP), {int((level < 0).sum())} exact stops, {plan.rows} rows, "
            f"{trajectory.duration_s:.3f} s",
            f"; Job: {comment_text(process.job_name or 'unknown', 60)}; date {comment_text(date, 16)} UTC",
            f"; Profile: {comment_text(Path(profile.source).name, 60)}. Units: mm, deg, s; $VEL.CP in m/s",
            *_wrapped("; Conventions: ", comment_text(robot.conventions.summary(), 400)),
            "; PTP targets are axis values (E6AXIS): no Status and Turn. LIN and CIRC targets are the TCP",
            "; in $BASE (E6POS without S and T: the controller keeps its configuration on CP moves).",
            f"; Moves merged and corners approximated within {process.path_tol_mm:g} mm of the planned path "
            "(post.path_tol_mm).",
            (f"; Process: $OUT[{out_no}] TRUE before each row's first work point, FALSE after its last one."
             if out_no else "; Process: no output configured (profile options.process_output); this program "
                            "switches nothing.")]


def _settings(robot, profile) -> list[str]:
    """The assignments every module starts with: BAS's initialisation (the main module's only),
    $BASE, $TOOL, the orientation and circle types, the advance run and the orientation speeds."""
    o = profile.options
    return ["BAS(#INITMOV,0)",
            f"$BASE={{{frame_text(wobj_frame(profile))}}}",
            f"$TOOL={{{frame_text(tool_in_tool0(robot, profile_tool(profile)))}}}",
            "$ORI_TYPE=#VAR", "$CIRC_TYPE=#BASE", "$ADVANCE=3",
            f"$VEL.ORI1={o['ori_vel_deg_s']:.1f}", f"$VEL.ORI2={o['ori_vel_deg_s']:.1f}"]


def _body(r: range, pre: list[list[str]], moves: list[str], before: dict, after: dict) -> list[str]:
    """The statements of the moves ``r``: each move's assignments and its statement, with the row
    markers."""
    out = []
    for i in r:
        out += before.get(i, [])
        out += pre[i]
        out.append(moves[i])
        out += after.get(i, [])
    return out


def _modules(name: str, header: list[str], settings: list[str], parts: list[range], bodies: list[list[str]],
             targets: list[list[str]]) -> dict[str, tuple[list[str], list[str]]]:
    """The modules' .src and .dat lines by module name: one module, or a main module calling
    the parts in turn."""
    if len(parts) == 1:
        return {name: (_src(name, header + settings, bodies[0]), _dat(name, [targets[i] for i in parts[0]]))}
    files: dict[str, tuple[list[str], list[str]]] = {}
    calls = []
    for k, (r, body) in enumerate(zip(parts, bodies), 1):
        part = f"{name}_{k:03d}"
        calls.append(f"{part}( )")
        files[part] = (_src(part, [f"; Part {k} of {len(parts)} of {name}: moves {r.start + 1}..{r.stop}; it "
                                   "starts and ends off the surface."] + settings[1:], body),
                       _dat(part, [targets[i] for i in r]))
    return {name: (_src(name, header + settings + [f"; Runs {len(parts)} modules in turn."], calls), _dat(name, [])),
            **files}


def _write_files(outdir: Path, files: dict[str, tuple[list[str], list[str]]]) -> list[Path]:
    """Write each module's .src and .dat (CRLF line ends); the paths written, in that order."""
    written = []
    for mod, (src, dat) in files.items():
        for ext, lines in ((".src", src), (".dat", dat)):
            p = outdir / f"{mod}{ext}"
            p.write_bytes((NEWLINE.join(lines) + NEWLINE).encode("ascii"))
            written.append(p)
    return written


def _wrapped(prefix: str, text: str) -> list[str]:
    """``text`` over as many comment lines as LINE_MAX needs, each starting with ``prefix``."""
    width = min(LINE_MAX, 120) - len(prefix)
    words, lines, cur = text.split(" "), [], ""
    for w in words:
        if cur and len(cur) + 1 + len(w) > width:
            lines.append(cur)
            cur = w
        else:
            cur = f"{cur} {w}" if cur else w
    lines.append(cur)
    return [prefix + lines[0]] + ["; " + ln for ln in lines[1:]]


def _vel_var(axis: str) -> str:
    """The speed variable (% of the axis's maximum) of a controller axis: $VEL_AXIS[n] for A1..A6,
    $VEL_EXTAX[n] for E1..E6."""
    return f"$VEL_AXIS[{axis[1:]}]" if axis.startswith("A") else f"$VEL_EXTAX[{axis[1:]}]"


def _moves(plan, robot, m: _Motion, o, starts: set[int]) -> tuple[list[list[str]], list[str]]:
    """Per move: the assignments before it (speeds, approximation) and its statement. The
    program's clock tracks the plan's: each move's written duration is rounded so that the
    error of one is carried into the next, never faster than the robot's speed limits."""
    kind, values, vmax, axis_names = m.kind, m.values, m.vmax, m.axis_names
    length, leq, radius, level = m.length, m.leq, m.radius, m.level
    n = len(plan)
    pre: list[list[str]] = [[] for _ in range(n)]
    moves = [""] * n
    dt = np.diff(plan.t)
    governing = np.max(np.abs(np.diff(values, axis=0)) / vmax[None, :], axis=1) if n > 1 else np.zeros(0)
    fastest = np.max(np.abs(np.diff(plan.q, axis=0)) / robot.limits.velocity[None, :], axis=1) \
        if n > 1 else np.zeros(0)
    angle = np.r_[0.0, rotation_angles_rad(plan.R[:-1], plan.R[1:])] if n > 1 else np.zeros(n)
    planned = written = 0.0
    step = 10.0 ** -VEL_CP_DECIMALS * 1000.0   # mm/s of one written digit of $VEL.CP
    for i in range(n):
        if i in starts:   # every module states the speeds and approximation its moves use
            state = {"vel_axis": None, "cp": None, "ori": float(o["ori_vel_deg_s"]), "cdis": None, "cptp": None}
        lines = pre[i]
        nxt_cp = i + 1 < n and kind[i + 1] != KIND_JOINT
        if i > 0:
            planned += dt[i - 1]
        want = max(planned - written, 1e-4)
        if kind[i] == KIND_JOINT:
            if i == 0:
                pct = int(o["approach_vel_axis"])
            else:
                g = governing[i - 1]
                cap = 100 if fastest[i - 1] <= 0 else int(min(100, math.floor(100 * g / fastest[i - 1] + 1e-6)))
                pct = int(min(max(cap, 1), max(1, round(100 * g / want)))) if g > 0 else 1
                written += 100 * g / pct
            if pct != state["vel_axis"]:
                lines += [f"{_vel_var(ax)}={pct}" for ax in axis_names]
                state["vel_axis"] = pct
            apo = ""
            if level[i] >= 0:
                cptp = cptp_percent(radius[i], leq[i])
                if cptp != state["cptp"]:
                    lines.append(f"$APO.CPTP={cptp}")
                    state["cptp"] = cptp
                apo = " C_PTP"
                if nxt_cp:   # a PTP approximated into a CP move needs C_DIS too (KUKA)
                    apo += " C_DIS"
                    if radius[i] != state["cdis"]:
                        lines.append(f"$APO.CDIS={radius[i]:g}")
                        state["cdis"] = radius[i]
            moves[i] = f"PTP XP{i + 1}{apo}"
        else:
            v = max(step, round(length[i] / want / step) * step)
            if v != state["cp"]:
                lines.append(f"$VEL.CP={v / 1000.0:.{VEL_CP_DECIMALS}f}")
                state["cp"] = v
            dur = length[i] / v
            need = math.degrees(angle[i]) / dur if dur > 0 else 0.0
            if need > state["ori"]:
                ori = math.ceil(need * 10 - 1e-9) / 10
                lines += [f"$VEL.ORI1={ori:.1f}", f"$VEL.ORI2={ori:.1f}"]
                state["ori"] = ori
            written += max(dur, math.degrees(angle[i]) / state["ori"])
            apo = ""
            if level[i] >= 0:
                if radius[i] != state["cdis"]:
                    lines.append(f"$APO.CDIS={radius[i]:g}")
                    state["cdis"] = radius[i]
                apo = " C_DIS"
            moves[i] = (f"CIRC XA{i + 1}, XP{i + 1}{apo}" if kind[i] == KIND_CIRCULAR else f"LIN XP{i + 1}{apo}")
    return pre, moves


def _targets(plan, kind, profile, robot, axes) -> list[list[str]]:
    """The data list declarations of each move's target (and a CIRC's auxiliary point):
    E6AXIS for PTP (axis values, deg / mm), E6POS without S and T for LIN and CIRC (the TCP in
    $BASE, mm and KUKA's A, B, C)."""
    n = len(plan)
    units = {a.axis: a.unit for a in profile.axes}
    cols = {ax: (fmt_column(axes[ax], 3 if units[ax] == "mm" else 4) if ax in axes else ["0.0"] * n) for ax in AXES}
    ext = [",".join(f"{e} {cols[e][i]}" for e in EXTERNAL_AXES) for i in range(n)]
    out: list[list[str]] = [[] for _ in range(n)]
    cart = np.flatnonzero(kind != KIND_JOINT)
    P, R = controller_pose(profile, plan.P[cart], plan.R[cart]) if len(cart) else (None, None)
    for i in np.flatnonzero(kind == KIND_JOINT):
        ax = ",".join(f"{a} {cols[a][i]}" for a in ROBOT_AXES)
        out[i].append(f"DECL E6AXIS XP{i + 1}={{{ax},{ext[i]}}}")
    for j, i in enumerate(cart):
        if kind[i] == KIND_CIRCULAR:
            vP, vR = controller_pose(profile, plan.via_P[[i]], plan.via_R[[i]])
            out[i].append(f"DECL E6POS XA{i + 1}={{{frame_text(_pose(vP[0], vR[0]))},{ext[i]}}}")
        out[i].append(f"DECL E6POS XP{i + 1}={{{frame_text(_pose(P[j], R[j]))},{ext[i]}}}")
    return out


def _pose(p, R) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def _src(name: str, header: list[str], body: list[str]) -> list[str]:
    return [f"DEF {name}( )"] + header + body + ["END"]


def _dat(name: str, targets: list[list[str]]) -> list[str]:
    return [f"DEFDAT {name}"] + [d for t in targets for d in t] + ["ENDDAT"]
