"""ABB RAPID writer: the program model's moves as ``MoveAbsJ`` / ``MoveL`` / ``MoveC``
statements in modules, with a ``.pgf`` program file (see ``postprocessors.rapid``)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from camtool import __version__
from camtool.program.convention import controller_axes, controller_pose
from camtool.robots.confdata import abb_confdata
from camtool.program.kinematics import Kinematics
from camtool.program.plan import KIND_CIRCULAR, KIND_LINEAR, move_lengths, plan_moves, profile_tool, split_parts
from camtool.program.steps import context_for, program_steps
from camtool.program.process import ProcessInfo, program_date
from camtool.transforms import matrix_from_xyz_rpy, quaternion_wxyz_from_matrix

from .dialect import (BLEND_ZONES, comment_text, EAX, MAX_ARC_DEG, RAX, T_RESOLUTION_S, V_RESOLUTION, ZONE_MM, _angles, _quat_column,
                      fmt_column, fmt_num, rapid_identifier, validate_profile)


def write(trajectory, robot, profile, outdir: Path, process: ProcessInfo | None = None) -> list[Path]:
    """Write ``<NAME>.pgf`` and ``<NAME>.mod`` (plus ``<NAME>_NNN.mod`` parts when split)."""
    validate_profile(profile, robot)
    process = process if process is not None else ProcessInfo()
    outdir = Path(outdir)
    o = profile.options
    name, _ = rapid_identifier(profile.program_name, 24)
    tool, _ = rapid_identifier(profile.tool["name"])
    wobj, _ = rapid_identifier(profile.wobj["name"])
    robot = robot.with_placement(tool_T_mm=profile_tool(profile))  # the TCP the program declares
    cart = o["motion"] == "cartesian"
    lo, hi = BLEND_ZONES.index(o["zone"]), BLEND_ZONES.index(o["max_zone"])
    levels = [ZONE_MM[z] for z in BLEND_ZONES[:hi + 1]]
    plan = plan_moves(trajectory, robot, process, linear=cart, levels_mm=levels, min_level_on_surface=lo)
    steps = program_steps(arcs_max_sweep_deg=MAX_ARC_DEG if cart and o["arcs"] else None)
    plan = steps.apply(plan, context_for(trajectory, robot, process, plan, levels, lo))
    n = len(plan)
    kind = np.array(plan.kind)
    length = move_lengths(plan)
    parts = split_parts(n, o["lines_per_module"], plan.free, "moves", f"{profile.source}: options.lines_per_module")
    level = plan.level.copy()
    for r in parts[:-1]:
        level[r.stop - 1] = -1  # a module ends with a stop: the next one is loaded there
    zone_names = np.array(BLEND_ZONES + ("fine",))[level]  # level -1 -> fine
    # --- timing: \T for joint moves, a TCP speed for linear moves; the clock tracks the plan
    dt = np.diff(plan.t)
    fastest = np.max(np.abs(np.diff(plan.q, axis=0)) / robot.limits.velocity[None, :], axis=1) \
        if n > 1 else np.zeros(0)
    angle = np.r_[0.0, _angles(plan.R[:-1], plan.R[1:])] if n > 1 else np.zeros(n)
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
    # --- targets
    axes = controller_axes(profile, robot, plan.q)
    units = {a.axis: a.unit for a in profile.axes}
    cols = {ax: (fmt_column(axes[ax], 3 if units[ax] == "mm" else 4) if ax in axes else ["9E9"] * n)
            for ax in RAX + EAX}
    rax_txt = [",".join(v) for v in zip(*(cols[a] for a in RAX))]
    eax_txt = [",".join(v) for v in zip(*(cols[a] for a in EAX))]
    lin_idx = np.flatnonzero((kind == KIND_LINEAR) | (kind == KIND_CIRCULAR))
    robt = {}
    if len(lin_idx):
        robt = dict(zip(lin_idx.tolist(), _robtargets(robot, profile, plan.P[lin_idx], plan.R[lin_idx],
                                                      plan.q[lin_idx], [eax_txt[i] for i in lin_idx])))
    circ_idx = np.flatnonzero(kind == KIND_CIRCULAR)
    via = {}
    if len(circ_idx):
        via_axes = controller_axes(profile, robot, plan.via_q[circ_idx])
        via_eax = [",".join(v) for v in zip(*((fmt_column(via_axes[a], 3 if units[a] == "mm" else 4)
                                                if a in via_axes else ["9E9"] * len(circ_idx)) for a in EAX))]
        via = dict(zip(circ_idx.tolist(), _robtargets(robot, profile, plan.via_P[circ_idx], plan.via_R[circ_idx],
                                                      plan.via_q[circ_idx], via_eax)))
    moves = []
    for i in range(n):
        if i == 0:
            moves.append(f"MoveAbsJ [[{rax_txt[0]}],[{eax_txt[0]}]], {o['approach_speed']}, fine, {tool} "
                         f"\\WObj:={wobj};")
        elif kind[i] == KIND_LINEAR:
            moves.append(f"MoveL {robt[i]}, {speed_txt[i]}, {zone_names[i]}, {tool} \\WObj:={wobj};")
        elif kind[i] == KIND_CIRCULAR:
            moves.append(f"MoveC {via[i]}, {robt[i]}, {speed_txt[i]}, {zone_names[i]}, {tool} \\WObj:={wobj};")
        else:
            moves.append(f"MoveAbsJ [[{rax_txt[i]}],[{eax_txt[i]}]], {o['speed']} \\T:={t_txt[i]}, "
                         f"{zone_names[i]}, {tool} \\WObj:={wobj};")
    # --- process markers and I/O around the rows
    sig = o["process_signal"]
    labels = list(process.row_labels)
    before: dict[int, list[str]] = {}
    after: dict[int, list[str]] = {}
    row_no = 0
    for i in np.flatnonzero(plan.row_start | plan.row_end):
        if plan.row_start[i]:
            row_no = int(plan.row[i]) + 1
            label = f": {comment_text(labels[row_no - 1], 40)}" if row_no - 1 < len(labels) else ""
            before[i] = [f"! Row {row_no} of {plan.rows}{label}"] + ([f"SetDO {sig}, 1;"] if sig else [])
        if plan.row_end[i]:
            after[i] = ([f"SetDO {sig}, 0;"] if sig else []) + [f"! End of row {int(plan.row[i]) + 1}"]

    def body(r):
        out = []
        for i in r:
            out += before.get(i, [])
            out.append(moves[i])
            out += after.get(i, [])
        return out

    n_lin = int((kind == KIND_LINEAR).sum())
    n_circ = int((kind == KIND_CIRCULAR).sum())
    stops = int((level < 0).sum())
    date = program_date(o["date"], process)
    header = [f"! Generated by camtool {__version__} for robot {comment_text(robot.name, 32)}: {n} moves ({n_lin} MoveL, "
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
    decl = [_tooldata(tool, profile.tool), _wobjdata(wobj, profile.wobj)]
    files: dict[str, list[str]] = {}
    if len(parts) == 1:
        files[name] = _module(name, header, decl, "main", body(parts[0]))
    else:
        main_body = []
        for i, r in enumerate(parts, 1):
            part = f"{name}_{i:03d}"
            where = f"{o['module_dir'].rstrip('/')}/{part}.mod"
            main_body += [f'Load \\Dynamic, "{where}";', f'%"{part}_run"%;', f'UnLoad "{where}";']
            files[part] = _module(part, [f"! Part {i} of {len(parts)} of {name}: moves "
                                              f"{r.start + 1}..{r.stop}; it starts and ends off the surface."],
                                       [], f"{part}_run", body(r))
        files = {name: _module(name, header + [f"! Runs {len(parts)} modules in turn."], decl, "main",
                                    main_body), **files}
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
