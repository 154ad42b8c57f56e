"""FANUC LS writer: the program model's moves as ``J`` / ``L`` / ``C`` instructions to
joint-representation positions ``P[n]`` (see ``postprocessors.fanuc``)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from camtool import __version__
from camtool.program.convention import controller_axes, tool_in_tool0, wobj_frame
from camtool.program.plan import (KIND_CIRCULAR, KIND_JOINT, KIND_LINEAR, move_lengths, part_names, planned_moves,
                                  profile_tool, row_markers, split_parts, stop_at_part_ends)
from camtool.program.process import ProcessInfo, program_date

from .dialect import (ATTR_COMMENT_MAX, AXES, MAX_ARC_DEG, ROBOT_AXES, comment_text, ls_number, program_name,
                      validate_profile, wpr_deg)

NEWLINE = "\r\n"


def write(trajectory, robot, profile, outdir: Path, process: ProcessInfo | None = None) -> list[Path]:
    """Write ``NAME.LS`` (plus ``NAME_1.LS`` ... parts and a main program when split)."""
    validate_profile(profile, robot)
    process = process if process is not None else ProcessInfo()
    outdir = Path(outdir)
    o = profile.options
    name, _ = program_name(profile.program_name, o["program_name_length"])
    robot = robot.with_placement(tool_T_mm=profile_tool(profile))  # the TCP UTOOL holds
    radii = [float(v) for v in o["cnt_mm"]]
    plan = planned_moves(trajectory, robot, process, linear=True, levels_mm=radii,
                         arcs_max_sweep_deg=MAX_ARC_DEG if o["arcs"] else None)
    kind = np.array(plan.kind)
    parts = split_parts(len(plan), o["lines_per_program"], plan.free, "moves",
                        f"{profile.source}: options.lines_per_program")
    level = stop_at_part_ends(plan.level, parts)   # CALL ends the motion: the program before ends with FINE
    order = [a for ax in AXES for a in profile.axes if a.axis == ax]
    values, via_values = _axis_values(plan, robot, profile, order, kind)
    speed = _speeds(plan, kind, values, np.array([a.max_speed for a in order]), robot, move_lengths(plan), o)
    before, after = _row_markers(plan, process, o["process_output"])
    frames = _frames(robot, tool_in_tool0(robot, profile_tool(profile)), wobj_frame(profile))
    header = _header(robot, profile, process, name, plan, level, frames)
    job = dict(kind=kind, values=values, via=via_values, speed=speed, term=_terms(level, o["cnt"]), before=before,
               after=after, order=order, o=o, frames=frames)
    return _write_files(outdir, _programs(name, parts, header, job, o["program_name_length"]))


def _terms(level: np.ndarray, cnt: list) -> list[str]:
    """Each move's termination: FINE, or CNT n of its level."""
    return [("FINE" if lv < 0 else f"CNT{int(cnt[lv])}") for lv in level]


def _axis_values(plan, robot, profile, order: list, kind: np.ndarray) -> tuple[np.ndarray, dict | None]:
    """The controller's axis values (in ``order``) of every move's position, and of each C
    move's circle point by move index (None without C moves)."""
    axes = controller_axes(profile, robot, plan.q)
    values = np.stack([axes[a.axis] for a in order], axis=1)
    via_values = None
    circ = np.flatnonzero(kind == KIND_CIRCULAR)
    if len(circ):
        va = controller_axes(profile, robot, plan.via_q[circ])
        via_values = dict(zip(circ.tolist(), np.stack([va[a.axis] for a in order], axis=1)))
    return values, via_values


def _row_markers(plan, process: ProcessInfo, out_no) -> tuple[dict[int, list[str]], dict[int, list[str]]]:
    """The remarks and DO instructions before a row's first move and after its last one."""
    def start(r: int, label: str | None) -> list[str]:
        text = f" {comment_text(label, 12)}" if label is not None else ""
        return [f"!ROW {r}/{plan.rows}{text} ;"] + ([f"DO[{out_no}]=ON ;"] if out_no else [])

    def end(r: int) -> list[str]:
        return ([f"DO[{out_no}]=OFF ;"] if out_no else []) + [f"!END ROW {r} ;"]

    return row_markers(plan, process, start, end)


def _header(robot, profile, process: ProcessInfo, name: str, plan, level: np.ndarray, frames: dict) -> dict:
    """A program's header: the date, the remarks the entry program starts with (counts, job,
    conventions, process output, frames) and the /ATTR comment."""
    o = profile.options
    out_no = o["process_output"]
    n = len(plan)
    kind = np.array(plan.kind)
    date = program_date(o["date"], process)
    n_lin, n_circ = int((kind == KIND_LINEAR).sum()), len(np.flatnonzero(kind == KIND_CIRCULAR))
    notes = [f"camtool {__version__} {comment_text(robot.name, 12)}",
             f"{n} moves {n_lin} L {n_circ} C {n - n_lin - n_circ} J",
             f"{int((level < 0).sum())} FINE {plan.rows} rows tol {process.path_tol_mm:g} mm",
             f"job {comment_text(process.job_name or 'unknown', 24)}",
             f"date {date.replace('/', '-').replace(':', 'h')} UTC",
             "joint positions deg",
             "J3 from the horizontal",
             f"{comment_text(robot.conventions.source, 12)} robot {comment_text(robot.name, 12)}"]
    notes.append(f"process output DO {out_no}" if out_no else "no process output configured")
    if o["set_frames"]:
        notes.append("tool and user frame set below")
    else:
        notes += [f"set UTOOL {o['utool']} by hand to", frames["tool_text"], f"set UFRAME {o['uframe']} to",
                  frames["frame_text"]]
    return {"date": date, "notes": [f"!{comment_text(t)} ;" for t in notes],
            "comment": comment_text(f"camtool {process.job_name or name}", ATTR_COMMENT_MAX)}


def _programs(name: str, parts: list[range], header: dict, job: dict, max_len: int) -> dict[str, list[str]]:
    """The programs' lines by program name: one program, or a main program calling the parts in
    turn."""
    if len(parts) == 1:
        return {name: _program(name, parts[0], header, job, setup_frames=True)}
    names = part_names(name, len(parts), max_len)
    files = {part: _program(part, r, header, job, setup_frames=False) for part, r in zip(names, parts)}
    return {name: _main(name, header, names, job), **files}


def _write_files(outdir: Path, files: dict[str, list[str]]) -> list[Path]:
    """Write each program as ``NAME.LS`` (CRLF line ends); the paths written."""
    written = []
    for prog, lines in files.items():
        p = outdir / f"{prog}.LS"
        p.write_bytes((NEWLINE.join(lines) + NEWLINE).encode("ascii"))
        written.append(p)
    return written


def _frames(robot, tool: np.ndarray, wobj: np.ndarray) -> dict:
    """The tool (in the all-zeros tool frame) and the user frame (in World, the controller's
    robot frame) as X, Y, Z (mm) and W, P, R (deg), and their one-line texts."""
    world = robot.conventions.pose_in_robot_frame(wobj)
    out = {}
    for key, T in (("tool", tool), ("frame", world)):
        v = np.r_[T[:3, 3], wpr_deg(T[:3, :3])[0]]
        v[np.abs(v) < 5e-4] = 0.0
        out[key] = v
        out[f"{key}_text"] = " ".join(f"{x:.3f}".rstrip("0").rstrip(".") for x in v)
    return out


def _speeds(plan, kind, values, vmax, robot, length, o) -> list[str]:
    """Each move's speed: J in integer % of the axes' maximum speeds, L / C in integer mm/sec,
    rounded so that the program's clock tracks the plan's (the error of one move is carried into
    the next), never faster than the robot's speed limits allow."""
    n = len(plan)
    out = [""] * n
    out[0] = f"{int(o['approach_percent'])}%"
    dt = np.diff(plan.t)
    governing = np.max(np.abs(np.diff(values, axis=0)) / vmax[None, :], axis=1) if n > 1 else np.zeros(0)
    fastest = np.max(np.abs(np.diff(plan.q, axis=0)) / robot.limits.velocity[None, :], axis=1) \
        if n > 1 else np.zeros(0)
    planned = written = 0.0
    for i in range(1, n):
        planned += dt[i - 1]
        want = max(planned - written, 1e-4)
        if kind[i] == KIND_JOINT:
            g = governing[i - 1]
            if g <= 0:
                out[i] = "1%"
                continue
            cap = 100 if fastest[i - 1] <= 0 else int(min(100, math.floor(100 * g / fastest[i - 1] + 1e-6)))
            pct = int(min(max(cap, 1), max(1, round(100 * g / want))))
            out[i] = f"{pct}%"
            written += 100 * g / pct
        else:
            v = max(1, int(round(length[i] / want)))
            out[i] = f"{v}mm/sec"
            written += length[i] / v
    return out


def _position(p: int, values: np.ndarray, order, uf: int, ut: int) -> list[str]:
    """A joint-representation position (J1..J6 deg, E1.. deg / mm) as the controller lists it."""
    fields = [f"{a.axis}={ls_number(v)} {a.unit}" for a, v in zip(order, values)]
    robot_f = [f for f, a in zip(fields, order) if a.axis in ROBOT_AXES]
    ext_f = [f for f, a in zip(fields, order) if a.axis not in ROBOT_AXES]
    lines = [f"P[{p}]{{", "   GP1:", f"\tUF : {uf}, UT : {ut},\t",
             "\t" + ",\t".join(robot_f[:3]) + ",", "\t" + ",\t".join(robot_f[3:]) + ("," if ext_f else "")]
    if ext_f:
        lines.append("\t" + ",\t".join(ext_f))
    return lines + ["};"]


def _cartesian(p: int, v: np.ndarray) -> list[str]:
    """A Cartesian position (X, Y, Z mm, W, P, R deg) used as frame data only (never a motion target)."""
    return [f"P[{p}]{{", "   GP1:", "\tUF : 0, UT : 0,\t\tCONFIG : 'N U T, 0, 0, 0',",
            f"\tX ={ls_number(v[0])}  mm,\tY ={ls_number(v[1])}  mm,\tZ ={ls_number(v[2])}  mm,",
            f"\tW ={ls_number(v[3])} deg,\tP ={ls_number(v[4])} deg,\tR ={ls_number(v[5])} deg", "};"]


def _attr(name: str, header: dict, line_count: int) -> list[str]:
    y, mo, d = header["date"][:10].split("/")
    hm = header["date"][11:16]
    stamp = f"DATE {y[2:]}-{mo}-{d}  TIME {hm}:00"
    return [f"/PROG  {name}", "/ATTR", "OWNER\t\t= MNEDITOR;", f"COMMENT\t\t= \"{header['comment']}\";",
            "PROG_SIZE\t= 0;", f"CREATE\t\t= {stamp};", f"MODIFIED\t= {stamp};", "FILE_NAME\t= ;",
            "VERSION\t\t= 0;", f"LINE_COUNT\t= {line_count};", "MEMORY_SIZE\t= 0;", "PROTECT\t\t= READ_WRITE;",
            "TCD:  STACK_SIZE\t= 0,", "      TASK_PRIORITY\t= 50,", "      TIME_SLICE\t= 0,",
            "      BUSY_LAMP_OFF\t= 0,", "      ABORT_REQUEST\t= 0,", "      PAUSE_REQUEST\t= 0;",
            "DEFAULT_GROUP\t= 1,*,*,*,*;", "CONTROL_CODE\t= 00000000 00000000;"]


def _numbered(instructions: list[str]) -> list[str]:
    """/MN lines: each instruction numbered from 1; a motion's letter right after the colon, other
    instructions after two spaces; a C move's second position on a continuation line."""
    out = []
    for k, ins in enumerate(instructions, 1):
        if ins[:2] in ("J ", "L ", "C "):
            first, *rest = ins.split("\n")
            out.append(f"{k:4d}:{first}")
            out += [f"    :  {r}" for r in rest]
        else:
            out.append(f"{k:4d}:  {ins}")
    return out


def _frame_setup(job) -> tuple[list[str], list[list[str]], int]:
    """Instructions selecting (and, with set_frames, writing) UTOOL / UFRAME; the frame positions."""
    o = job["o"]
    ins, pos = [], []
    p = 0
    if o["set_frames"]:
        pr = o["frame_register"]
        for what, key, num in (("UTOOL", "tool", o["utool"]), ("UFRAME", "frame", o["uframe"])):
            p += 1
            pos.append(_cartesian(p, job["frames"][key]))
            ins += [f"PR[{pr}]=P[{p}]    ;", f"{what}[{num}]=PR[{pr}] ;"]
    ins += [f"UFRAME_NUM={o['uframe']} ;", f"UTOOL_NUM={o['utool']} ;"]
    return ins, pos, p


def _program(name: str, r: range, header: dict, job, setup_frames: bool) -> list[str]:
    o = job["o"]
    ins = list(header["notes"]) if setup_frames else [f"!part of {comment_text(name, 20)} ;"]
    pos: list[list[str]] = []
    p = 0
    if setup_frames:
        fi, pos, p = _frame_setup(job)
        ins += fi
    else:
        ins += [f"UFRAME_NUM={o['uframe']} ;", f"UTOOL_NUM={o['utool']} ;"]
    for i in r:
        ins += job["before"].get(i, [])
        k = job["kind"][i]
        if k == KIND_CIRCULAR:
            pos.append(_position(p + 1, job["via"][i], job["order"], o["uframe"], o["utool"]))
            pos.append(_position(p + 2, job["values"][i], job["order"], o["uframe"], o["utool"]))
            ins.append(f"C P[{p + 1}]    \nP[{p + 2}] {job['speed'][i]} {job['term'][i]}    ;")
            p += 2
        else:
            p += 1
            pos.append(_position(p, job["values"][i], job["order"], o["uframe"], o["utool"]))
            ins.append(f"{'J' if k == KIND_JOINT else 'L'} P[{p}] {job['speed'][i]} {job['term'][i]}    ;")
        ins += job["after"].get(i, [])
    return _attr(name, header, len(ins)) + ["/MN"] + _numbered(ins) + ["/POS"] + [ln for b in pos for ln in b] \
        + ["/END"]


def _main(name: str, header: dict, parts: list[str], job) -> list[str]:
    fi, pos, _p = _frame_setup(job)
    ins = list(header["notes"]) + fi + [f"CALL {p}    ;" for p in parts]
    return _attr(name, header, len(ins)) + ["/MN"] + _numbered(ins) + ["/POS"] + [ln for b in pos for ln in b] \
        + ["/END"]
