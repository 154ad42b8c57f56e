"""ABB RAPID writer: the program model's moves as ``MoveAbsJ`` / ``MoveL`` / ``MoveC``
statements in modules, with a ``.pgf`` program file (see ``postprocessors.rapid``)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camtool import __version__
from camtool.program.convention import controller_axes, controller_pose, stated_joints
from camtool.robots.confdata import abb_confdata
from camtool.program.kinematics import Kinematics
from camtool.program.plan import (KIND_CIRCULAR, KIND_LINEAR, move_lengths, planned_moves, profile_tool, row_markers,
                                  split_parts, stop_at_part_ends)
from camtool.program.steps import rotation_angles_rad
from camtool.program.process import ProcessInfo, program_date
from camtool.transforms import matrix_from_xyz_rpy, quaternion_wxyz_from_matrix

from .dialect import (BLEND_ZONES, comment_text, EAX, MAX_ARC_DEG, RAX, T_RESOLUTION_S, V_RESOLUTION, ZONE_MM, _quat_column,
                      fmt_column, fmt_num, rapid_identifier, validate_profile)


@dataclass(frozen=True)
class _Names:
    """The RAPID identifiers of the program, its tool and its work object."""

    program: str
    tool: str
    wobj: str


@dataclass(frozen=True)
class _Targets:
    """Per move the jointtarget's axis texts, and the robtargets (and circle points) of the
    Cartesian moves by move index."""

    rax: list[str]
    eax: list[str]
    robt: dict[int, str]
    via: dict[int, str]


def write(trajectory, robot, profile, outdir: Path, process: ProcessInfo | None = None) -> list[Path]:
    """Write ``<NAME>.pgf`` and ``<NAME>.mod`` (plus ``<NAME>_NNN.mod`` parts when split)."""
    validate_profile(profile, robot)
    process = process if process is not None else ProcessInfo()
    outdir = Path(outdir)
    o = profile.options
    names = _names(profile)
    robot = robot.with_placement(tool_T_mm=profile_tool(profile))  # the TCP the program declares
    plan = _plan(trajectory, robot, profile, process)
    parts = split_parts(len(plan), o["lines_per_module"], plan.free, "moves", f"{profile.source}: options.lines_per_module")
    level = stop_at_part_ends(plan.level, parts)  # a module ends with a stop: the next one is loaded there
    moves = _move_lines(plan, robot, profile, names, level)
    before, after = _row_markers(plan, process, o["process_signal"])
    header = _header(trajectory, robot, profile, process, plan, level)
    decl = [_tooldata(names.tool, profile.tool), _wobjdata(names.wobj, profile.wobj)]
    bodies = [_body(r, moves, before, after) for r in parts]
    return _write_files(outdir, names.program, _modules(names.program, header, decl, parts, bodies, o["module_dir"]))


def _names(profile) -> _Names:
    """The program's (24 characters at most), tool's and work object's identifiers."""
    name, _ = rapid_identifier(profile.program_name, 24)
    tool, _ = rapid_identifier(profile.tool["name"])
    wobj, _ = rapid_identifier(profile.wobj["name"])
    return _Names(name, tool, wobj)


def _plan(trajectory, robot, profile, process: ProcessInfo):
    """The program's moves: planned within the profile's zones, then the program steps (arcs)."""
    o = profile.options
    cart = o["motion"] == "cartesian"
    lo, hi = BLEND_ZONES.index(o["zone"]), BLEND_ZONES.index(o["max_zone"])
    levels = [ZONE_MM[z] for z in BLEND_ZONES[:hi + 1]]
    held = stated_joints(profile, robot, RAX)  # the joints on eax_a..eax_f (a 7th joint, a track)
    return planned_moves(trajectory, robot, process, linear=cart, levels_mm=levels, min_level_on_surface=lo, held=held,
                         arcs_max_sweep_deg=MAX_ARC_DEG if cart and o["arcs"] else None)


def _timing(plan, robot, kind: np.ndarray) -> tuple[list[str], list[str]]:
    """Speed data texts of linear moves and \\T texts of joint moves: the clock tracks the plan."""
    n = len(plan)
    length = move_lengths(plan)
    dt = np.diff(plan.t)
    fastest = np.max(np.abs(np.diff(plan.q, axis=0)) / robot.limits.velocity[None, :], axis=1) \
        if n > 1 else np.zeros(0)
    angle = np.r_[0.0, rotation_angles_rad(plan.R[:-1], plan.R[1:])] if n > 1 else np.zeros(n)
    speed_txt = [""] * n
    t_txt = [""] * n
    planned = written = 0.0
    for i in range(1, n):
        planned += dt[i - 1]
        want = max(planned - written, T_RESOLUTION_S)
        if kind[i] in (KIND_LINEAR, KIND_CIRCULAR):
            v = max(V_RESOLUTION, round(length[i] / want / V_RESOLUTION) * V_RESOLUTION)
            dur = length[i] / v
            v_ori = max(0.1, math.ceil(math.degrees(angle[i]) / dur * 10 - 1e-9) / 10)
            speed_txt[i] = f"[{v:.2f},{v_ori:.1f},5000,1000]"
            written += dur
        else:
            lo_ticks = math.ceil(max(fastest[i - 1], T_RESOLUTION_S) / T_RESOLUTION_S - 1e-6)
            ticks = max(lo_ticks, round(want / T_RESOLUTION_S))
            t_txt[i] = f"{ticks * T_RESOLUTION_S:.4f}"
            written += ticks * T_RESOLUTION_S
    return speed_txt, t_txt


def _axis_texts(axes: dict, names, units: dict, n: int) -> list[str]:
    """Per target the comma-joined values of the axes ``names`` (9E9 for an axis not connected)."""
    cols = [fmt_column(axes[ax], 3 if units[ax] == "mm" else 4) if ax in axes else ["9E9"] * n for ax in names]
    return [",".join(v) for v in zip(*cols)]


def _targets(plan, robot, profile, kind: np.ndarray) -> _Targets:
    """The jointtargets' axis texts of every move, the robtargets of the linear and circular
    moves and the circle points of the circular ones."""
    n = len(plan)
    axes = controller_axes(profile, robot, plan.q)
    units = {a.axis: a.unit for a in profile.axes}
    rax_txt = _axis_texts(axes, RAX, units, n)
    eax_txt = _axis_texts(axes, EAX, units, n)
    lin_idx = np.flatnonzero((kind == KIND_LINEAR) | (kind == KIND_CIRCULAR))
    robt = {}
    if len(lin_idx):
        robt = dict(zip(lin_idx.tolist(), _robtargets(robot, profile, plan.P[lin_idx], plan.R[lin_idx],
                                                      plan.q[lin_idx], [eax_txt[i] for i in lin_idx])))
    circ_idx = np.flatnonzero(kind == KIND_CIRCULAR)
    via = {}
    if len(circ_idx):
        via_axes = controller_axes(profile, robot, plan.via_q[circ_idx])
        via_eax = _axis_texts(via_axes, EAX, units, len(circ_idx))
        via = dict(zip(circ_idx.tolist(), _robtargets(robot, profile, plan.via_P[circ_idx], plan.via_R[circ_idx],
                                                      plan.via_q[circ_idx], via_eax)))
    return _Targets(rax_txt, eax_txt, robt, via)


def _move_lines(plan, robot, profile, names: _Names, level: np.ndarray) -> list[str]:
    """One MoveAbsJ / MoveL / MoveC statement per move, the first an exact approach."""
    o = profile.options
    tool, wobj = names.tool, names.wobj
    kind = np.array(plan.kind)
    zone_names = np.array(BLEND_ZONES + ("fine",))[level]  # level -1 -> fine
    speed_txt, t_txt = _timing(plan, robot, kind)
    tg = _targets(plan, robot, profile, kind)
    moves = []
    for i in range(len(plan)):
        if i == 0:
            moves.append(f"MoveAbsJ [[{tg.rax[0]}],[{tg.eax[0]}]], {o['approach_speed']}, fine, {tool} "
                         f"\\WObj:={wobj};")
        elif kind[i] == KIND_LINEAR:
            moves.append(f"MoveL {tg.robt[i]}, {speed_txt[i]}, {zone_names[i]}, {tool} \\WObj:={wobj};")
        elif kind[i] == KIND_CIRCULAR:
            moves.append(f"MoveC {tg.via[i]}, {tg.robt[i]}, {speed_txt[i]}, {zone_names[i]}, {tool} \\WObj:={wobj};")
        else:
            moves.append(f"MoveAbsJ [[{tg.rax[i]}],[{tg.eax[i]}]], {o['speed']} \\T:={t_txt[i]}, "
                         f"{zone_names[i]}, {tool} \\WObj:={wobj};")
    return moves


def _row_markers(plan, process: ProcessInfo, sig: str) -> tuple[dict[int, list[str]], dict[int, list[str]]]:
    """The comments and SetDO statements before a row's first move and after its last one."""
    def start(row_no: int, label: str | None) -> list[str]:
        text = f": {comment_text(label, 40)}" if label is not None else ""
        return [f"! Row {row_no} of {plan.rows}{text}"] + ([f"SetDO {sig}, 1;"] if sig else [])

    def end(row_no: int) -> list[str]:
        return ([f"SetDO {sig}, 0;"] if sig else []) + [f"! End of row {row_no}"]

    return row_markers(plan, process, start, end)


def _body(r: range, moves: list[str], before: dict, after: dict) -> list[str]:
    """The statements of the moves ``r`` with their row markers."""
    out = []
    for i in r:
        out += before.get(i, [])
        out.append(moves[i])
        out += after.get(i, [])
    return out


def _header(trajectory, robot, profile, process: ProcessInfo, plan, level: np.ndarray) -> list[str]:
    """The main module's comment lines: the counts, job, profile, conventions and process."""
    o = profile.options
    sig = o["process_signal"]
    n = len(plan)
    kind = np.array(plan.kind)
    n_lin = int((kind == KIND_LINEAR).sum())
    n_circ = int((kind == KIND_CIRCULAR).sum())
    stops = int((level < 0).sum())
    date = program_date(o["date"], process)
    return [f"! Generated by camtool {__version__} for robot {comment_text(robot.name, 32)}: {n} moves ({n_lin} MoveL, "
            + (f"{n_circ} MoveC, " if n_circ else "") + f"{n - n_lin - n_circ} MoveAbsJ), {stops} exact stops, {plan.rows} rows, {trajectory.duration_s:.3f} s",
            f"! Job: {comment_text(process.job_name or 'unknown', 60)}; date {comment_text(date, 16)} UTC "
            f"(options.date = {comment_text(o['date'], 16)}).",
            f"! Profile: {comment_text(Path(profile.source).name, 60)}. Units: mm, deg, s; 9E9 = axis not connected.",
            f"! Conventions: {comment_text(robot.conventions.summary(), 200)}.",
            f"! Moves merged and corners blended within {process.path_tol_mm:g} mm of the planned path "
            "(post.path_tol_mm).",
            (f"! Process: SetDO {sig}, 1 before each row's first work point, 0 after its last one."
             if sig else "! Process: no signal configured (profile options.process_signal); this program "
                         "switches nothing.")]


def _modules(name: str, header: list[str], decl: list[str], parts: list[range], bodies: list[list[str]],
             module_dir: str) -> dict[str, list[str]]:
    """The modules' lines by module name: one module, or a main module loading the parts in turn."""
    if len(parts) == 1:
        return {name: _module(name, header, decl, "main", bodies[0])}
    files: dict[str, list[str]] = {}
    main_body = []
    for i, (r, body) in enumerate(zip(parts, bodies), 1):
        part = f"{name}_{i:03d}"
        where = f"{module_dir.rstrip('/')}/{part}.mod"
        main_body += [f'Load \\Dynamic, "{where}";', f'%"{part}_run"%;', f'UnLoad "{where}";']
        files[part] = _module(part, [f"! Part {i} of {len(parts)} of {name}: moves "
                                     f"{r.start + 1}..{r.stop}; it starts and ends off the surface."],
                              [], f"{part}_run", body)
    return {name: _module(name, header + [f"! Runs {len(parts)} modules in turn."], decl, "main", main_body),
            **files}


def _write_files(outdir: Path, name: str, files: dict[str, list[str]]) -> list[Path]:
    """Write the .pgf program file, then each module; the paths written."""
    written = [outdir / f"{name}.pgf"]
    written[0].write_bytes(("<?xml version=\"1.0\" encoding=\"ISO-8859-1\" ?>\n<Program>\n"
                            f"  <Module>{name}.mod</Module>\n</Program>\n").encode("ascii"))
    for mod, lines in files.items():
        p = outdir / f"{mod}.mod"
        p.write_bytes(("\n".join(lines) + "\n").encode("latin-1"))
        written.append(p)
    return written

def _robtargets(robot, profile, P, R, q, eax_txt) -> list[str]:
    """robtarget texts (position, quaternion, confdata, external axes) of TCP poses (base frame)
    with joint values ``q``: the pose in the work object, cf1 / cf4 / cf6 from the axis
    quadrants and cfx from the arm configuration."""
    Pw, Rw = controller_pose(profile, P, R)
    Q = _quat_column(Rw)
    # cf1, cf4, cf6, cfx from the controller's axis values (robots/confdata.py: the coupled
    # axis 3 and the controller's directions, not camtool's joints)
    conf = abb_confdata(robot, q)
    cf, cfx = conf[:, :3], conf[:, 3]
    px = [fmt_column(Pw[:, j], 3) for j in range(3)]
    qx = [fmt_column(Q[:, j], 6) for j in range(4)]
    return [f"[[{px[0][j]},{px[1][j]},{px[2][j]}],[{qx[0][j]},{qx[1][j]},{qx[2][j]},{qx[3][j]}],"
            f"[{int(cf[j, 0])},{int(cf[j, 1])},{int(cf[j, 2])},{int(cfx[j])}],[{eax_txt[j]}]]" for j in range(len(P))]


def _module(name, header, decl, proc, body) -> list[str]:
    return ([f"MODULE {name}"] + [f"  {h}" for h in header] + [f"  {d}" for d in decl]
            + [f"  PROC {proc}()"] + [f"    {b}" for b in body] + ["  ENDPROC", "ENDMODULE"])

def _quat(rpy_deg) -> str:
    q = quaternion_wxyz_from_matrix(matrix_from_xyz_rpy([0, 0, 0], rpy_deg)[:3, :3])
    return ",".join(fmt_num(v, 6) for v in q)

def _tooldata(name: str, tool: dict) -> str:
    xyz = ",".join(fmt_num(v, 3) for v in tool["tcp_xyz_mm"])
    cog = ",".join(fmt_num(v, 3) for v in tool["cog_mm"])
    mass = fmt_num(max(float(tool["mass_kg"]), 0.001), 3)  # the controller refuses a zero mass
    return f"PERS tooldata {name}:=[TRUE,[[{xyz}],[{_quat(tool['tcp_rpy_deg'])}]],[{mass},[{cog}],[1,0,0,0],0,0,0]];"

def _wobjdata(name: str, wobj: dict) -> str:
    xyz = ",".join(fmt_num(v, 3) for v in wobj["xyz_mm"])
    return f'PERS wobjdata {name}:=[FALSE,TRUE,"",[[{xyz}],[{_quat(wobj["rpy_deg"])}]],[[0,0,0],[1,0,0,0]]];'
