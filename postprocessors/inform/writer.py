"""Yaskawa INFORM writer: the program model's moves as ``MOVJ`` / ``MOVL`` instructions with
their positions, in jobs (see ``postprocessors.inform``)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from camtool import __version__
from camtool.program.convention import controller_axes, controller_pose_base, stated_joints
from camtool.robots.confdata import yaskawa_rconf
from camtool.program.kinematics import Kinematics
from camtool.program.moves import JOINT
from camtool.program.plan import (KIND_CIRCULAR, KIND_LINEAR, move_lengths, part_names, planned_moves, profile_tool,
                                  row_markers, split_parts, stop_at_part_ends)
from camtool.program.process import ProcessInfo, program_date

from .dialect import (comment_text, euler_xyz_deg, _fmt_column, group_axes, GROUPS, job_name, MAX_ARC_DEG,
                      pulse_free, to_pulses, V_STEP, validate_profile)


def _rconf(robot, q: np.ndarray, n_fields: int) -> list[str]:
    """``///RCONF`` values (flip, lower arm, rear, R>=180, T>=180, S>=180, 0...) per target, from
    the controller's axis values (robots/confdata.py; flip = B < 0 is unverified)."""
    return [",".join(str(int(v)) for v in r) for r in yaskawa_rconf(robot, q, n_fields)]




def write(trajectory, robot, profile, outdir: Path, process: ProcessInfo | None = None) -> list[Path]:
    """Write ``NAME.JBI`` (plus ``NAME_1.JBI`` ... parts and a main job when split)."""
    validate_profile(profile, robot)
    process = process if process is not None else ProcessInfo()
    o = profile.options
    outdir = Path(outdir)
    name, _ = job_name(profile.program_name, o["job_name_length"])
    robot = robot.with_placement(tool_T_mm=profile_tool(profile))  # the TCP the program declares
    plan = _plan(trajectory, robot, profile, process)
    kind = np.array(plan.kind)
    parts = split_parts(len(plan), o["lines_per_job"], plan.free, "positions", f"{profile.source}: options.lines_per_job")
    pl = _pl(plan, parts)
    groups = group_axes(profile)
    speed = _speeds(plan, robot, profile, groups, kind)
    pos_txt, rconf, via_txt, via_rconf = _targets(plan, robot, profile, groups, kind)
    before, after = _row_markers(plan, process, o["process_output"])
    header = _header(robot, profile, process, name, groups, kind, pl, rconf)
    job = dict(kind=kind, pos_txt=pos_txt, rconf=rconf, speed=speed, pl=pl, before=before, after=after,
               rconf_fields=o["rconf_fields"], via_txt=via_txt, via_rconf=via_rconf)
    return _write_files(outdir, _jobs(name, parts, header, job, o["job_name_length"]))


def _plan(trajectory, robot, profile, process: ProcessInfo):
    """The job's moves: planned within the profile's PL radii, then the program steps (arcs)."""
    o = profile.options
    cart = o["motion"] == "cartesian"
    radii = [float(v) for v in o["pl_mm"]][:o["max_pl"]]
    lo = max(1, o["pl"]) - 1
    held = stated_joints(profile, robot, [f"RB1:{i}" for i in range(1, 7)])  # Re (7th axis), BS1, ST1
    return planned_moves(trajectory, robot, process, linear=cart, levels_mm=radii, min_level_on_surface=lo, held=held,
                         arcs_max_sweep_deg=MAX_ARC_DEG if cart and o["arcs"] else None, arc_start_linear=True)


def _pl(plan, parts: list[range]) -> np.ndarray:
    """Each move's PL, 0 (an exact stop) at the end of every job but the last."""
    return stop_at_part_ends(plan.level, parts) + 1  # level -1 (exact stop) -> PL=0; CALL JOB ends the motion


def _speeds(plan, robot, profile, groups: dict, kind: np.ndarray) -> list[str]:
    """VJ of joint moves, V of linear ones: the job's clock tracks the plan."""
    o = profile.options
    n = len(plan)
    length = move_lengths(plan)
    axes = controller_axes(profile, robot, plan.q)
    order = [a for ax in groups.values() for a in ax]
    vmax = np.array([a.max_speed for a in order])
    values = np.stack([axes[a.axis] for a in order], axis=1)
    speed = [""] * n
    speed[0] = f"VJ={o['approach_vj']:.2f}"
    fastest = np.max(np.abs(np.diff(plan.q, axis=0)) / robot.limits.velocity[None, :], axis=1) \
        if n > 1 else np.zeros(0)
    governing = np.max(np.abs(np.diff(values, axis=0)) / vmax[None, :], axis=1) if n > 1 else np.zeros(0)
    dt = np.diff(plan.t)
    planned = written = 0.0
    for i in range(1, n):
        planned += dt[i - 1]
        want = max(planned - written, 1e-4)
        if kind[i] in (KIND_LINEAR, KIND_CIRCULAR):
            v = max(V_STEP, round(length[i] / want / V_STEP) * V_STEP)
            speed[i] = f"V={v:.1f}"
            written += length[i] / v
        else:
            g = governing[i - 1]
            if g <= 0:
                speed[i] = "VJ=0.01"
                continue
            cap = 100.0 if fastest[i - 1] <= 0 else min(100.0, math.floor(100 * g / fastest[i - 1] * 100 + 1e-6) / 100)
            vj = min(cap, max(0.01, round(100 * g / want, 2)))
            speed[i] = f"VJ={vj:.2f}"
            written += 100 * g / vj
    return speed


def _targets(plan, robot, profile, groups: dict, kind: np.ndarray) -> tuple[dict, list, dict, list]:
    """Position texts and ///RCONF values of the targets, and of the circular moves' circle
    points (a circle point gets a position of its own, before its target's)."""
    o = profile.options
    pos_txt, rconf = _positions(robot, profile, groups, plan.P, plan.R, plan.q, kind != JOINT, o["rconf_fields"])
    circ = np.flatnonzero(kind == KIND_CIRCULAR)
    via_txt, via_rconf = {}, [None] * len(plan)
    if len(circ):
        vt, vr = _positions(robot, profile, groups, plan.via_P[circ], plan.via_R[circ], plan.via_q[circ],
                            np.ones(len(circ), bool), o["rconf_fields"])
        via_txt = {pre: dict(zip(circ.tolist(), vt[pre])) for pre in vt}
        for j, k in enumerate(circ):
            via_rconf[k] = vr[j]
    return pos_txt, rconf, via_txt, via_rconf


def _row_markers(plan, process: ProcessInfo, out_no) -> tuple[dict[int, list[str]], dict[int, list[str]]]:
    """The comments and DOUT instructions before a row's first move and after its last one."""
    def start(r: int, label: str | None) -> list[str]:
        text = f" {comment_text(label, 24).upper()}" if label is not None else ""
        return [f"'ROW {r}/{plan.rows}{text}"[:33]] + ([f"DOUT OT#({out_no}) ON"] if out_no else [])

    def end(r: int) -> list[str]:
        return ([f"DOUT OT#({out_no}) OFF"] if out_no else []) + [f"'END ROW {r}"]

    return row_markers(plan, process, start, end)


def _header(robot, profile, process: ProcessInfo, name: str, groups: dict, kind: np.ndarray, pl: np.ndarray,
            rconf: list) -> dict:
    """A job's header: tool, date, group, comment, attributes and the comment lines after NOP."""
    o = profile.options
    out_no = o["process_output"]
    n = len(kind)
    date = program_date(o["date"], process)
    comm = comment_text(f"camtool {process.job_name or name}", 32)
    n_lin = int((kind == KIND_LINEAR).sum())
    n_circ = int(len(np.flatnonzero(kind == KIND_CIRCULAR)))
    notes = [f"'camtool {__version__} {comment_text(robot.name, 64)} {n} moves",
             f"'{n_lin} MOVL {n_circ} ARCS {n - n_lin - n_circ} MOVJ {int((pl == 0).sum())} STOPS" if n_circ else
             f"'{n_lin} MOVL {n - n_lin} MOVJ {int((pl == 0).sum())} STOPS",
             f"'PATH TOL {process.path_tol_mm:g} MM",
             f"'{comment_text(robot.conventions.source, 12).upper()} ROBOT {comment_text(robot.name, 24).upper()}",
             "'" + comment_text("AXES " + " ".join(robot.conventions.controller_axis_names), 60),
             ("'POSITIONS RECTAN ROBOT FRAME NO PULSE FACTORS" if pulse_free(profile) else "'PULSES FROM THE PROFILE"),
             (f"'PROCESS OUTPUT OT#({out_no})" if out_no else "'NO PROCESS OUTPUT CONFIGURED")]
    return dict(tool=profile.tool["number"], date=date, group=",".join(groups), comm=comm,
                attr="SC,RW,RJ" if any(r is not None for r in rconf) else "SC,RW", notes=notes)


def _jobs(name: str, parts: list[range], header: dict, job: dict, name_length: int) -> dict[str, list[str]]:
    """The jobs' lines by job name: one job, or a main job calling the parts in turn."""
    if len(parts) == 1:
        return {name: _job(name, parts[0], header, job)}
    names = part_names(name, len(parts), name_length)
    files = {part: _job(part, r, header, job) for part, r in zip(names, parts)}
    main = ["/JOB", f"//NAME {name}", "//POS", "///NPOS 0,0,0,0,0,0", "//INST", f"///DATE {header['date']}",
            f"///COMM {header['comm']}", "///ATTR SC,RW", f"///GROUP1 {header['group']}", "NOP"] + header["notes"] \
        + [f"CALL JOB:{n_}" for n_ in names] + ["END"]
    return {name: main, **files}


def _write_files(outdir: Path, files: dict[str, list[str]]) -> list[Path]:
    """Write each job as ``NAME.JBI`` (CRLF line ends); the paths written."""
    written_files = []
    for job_, lines in files.items():
        p = outdir / f"{job_}.JBI"
        p.write_bytes(("\r\n".join(lines) + "\r\n").encode("ascii"))
        written_files.append(p)
    return written_files

def _positions(robot, profile, groups, P, R, q, cart, rconf_fields: int) -> tuple[dict, list]:
    """Position texts per prefix (C, BC, EC) and ///RCONF values of targets: pulses for every
    group, the C position of a Cartesian target (``cart``) as its TCP pose in the base frame
    (mm, Rx Ry Rz deg, the 7th axis), with its RCONF."""
    pulses = to_pulses(profile, robot, q)
    axes = controller_axes(profile, robot, q)
    if pulse_free(profile):  # no pulse factors: every position Cartesian, never made-up pulses
        cart = np.ones(len(q), bool)
    pos_txt: dict[str, list[str]] = {}
    for g, pre in GROUPS.items():
        if g in pulses:
            pos_txt[pre] = [",".join(map(str, row)) for row in pulses[g].tolist()]
    pos_txt.setdefault("C", [""] * len(q))
    rconf = [None] * len(q)
    if np.any(cart):
        li = np.flatnonzero(cart)
        Pb, Rb = controller_pose_base(profile, P[li], R[li], robot)  # in the robot frame
        ang = euler_xyz_deg(Rb)
        rb = groups["RB1"]
        extra = [axes[rb[6].axis][li]] if len(rb) == 7 else []
        cols = [Pb[:, 0], Pb[:, 1], Pb[:, 2], ang[:, 0], ang[:, 1], ang[:, 2], *extra]
        dec = [3, 3, 3, 4, 4, 4, 4]
        txt = [_fmt_column(c, d) for c, d in zip(cols, dec)]
        rc = _rconf(robot, q[li], rconf_fields)
        for j, i in enumerate(li):
            pos_txt["C"][i] = ",".join(t[j] for t in txt)
            rconf[i] = rc[j]
    return pos_txt, rconf


def _instructions(r: range, job) -> list[dict]:
    """The instructions of the moves ``r``: one per move, two for a circular move (its circle
    point, then its target); the linear move to an arc's first point is its first MOVC, and
    an arc followed by another ends with FPT."""
    kind, pos_txt, n = job["kind"], job["pos_txt"], len(job["kind"])
    out = []
    for k in r:
        nxt = kind[k + 1] if k + 1 < n else ""
        common = dict(speed=job["speed"][k], pl=job["pl"][k], move=k)
        if kind[k] == KIND_CIRCULAR:
            out.append(dict(word="MOVC", pos={pre: job["via_txt"][pre][k] for pre in pos_txt}, rect=True,
                            rconf=job["via_rconf"][k], fpt=False, **common))
            out.append(dict(word="MOVC", pos={pre: pos_txt[pre][k] for pre in pos_txt}, rect=True,
                            rconf=job["rconf"][k], fpt=nxt == KIND_CIRCULAR, **common))
            continue
        word = "MOVJ" if kind[k] == JOINT else ("MOVC" if nxt == KIND_CIRCULAR else "MOVL")
        out.append(dict(word=word, pos={pre: pos_txt[pre][k] for pre in pos_txt}, rect=job["rconf"][k] is not None,
                        rconf=job["rconf"][k], fpt=False, **common))
    return out


def _job(name, r: range, header, job) -> list[str]:
    lines = ["/JOB", f"//NAME {name}", "//POS"]
    pos_txt = job["pos_txt"]
    ins = _instructions(r, job)
    counts = [len(ins) if pre in pos_txt else 0 for pre in GROUPS.values()]
    lines += [f"///NPOS {counts[0]},{counts[1]},{counts[2]},0,0,0", f"///TOOL {header['tool']}"]
    state = None
    for i, it in enumerate(ins):
        want = ("rectan", it["rconf"]) if it["rect"] else ("pulse", None)
        if want != state:
            if want[0] == "pulse":
                lines += ["///POSTYPE PULSE", "///PULSE"]
            else:
                if state is None or state[0] != "rectan":
                    lines += ["///POSTYPE BASE", "///RECTAN"]
                lines.append(f"///RCONF {want[1]}")
            state = want
        lines.append(f"C{i:05d}={it['pos']['C']}")
    for pre in ("BC", "EC"):
        if pre in pos_txt:
            if state is None or state[0] != "pulse":
                lines += ["///POSTYPE PULSE", "///PULSE"]
                state = ("pulse", None)
            lines += [f"{pre}{i:05d}={it['pos'][pre]}" for i, it in enumerate(ins)]
    lines += ["//INST", f"///DATE {header['date']}", f"///COMM {header['comm']}", f"///ATTR {header['attr']}",
              f"///GROUP1 {header['group']}", "NOP"] + header["notes"]
    for i, it in enumerate(ins):
        k = it["move"]
        first = i == 0 or ins[i - 1]["move"] != k
        last = i + 1 == len(ins) or ins[i + 1]["move"] != k
        if first:
            lines += job["before"].get(k, [])
        refs = " ".join(f"{pre}{i:05d}" for pre in pos_txt)
        lines.append(f"{it['word']} {refs} {it['speed']} PL={it['pl']}" + (" FPT" if it["fpt"] else ""))
        if last:
            lines += job["after"].get(k, [])
    return lines + ["END"]

# --- reading ---------------------------------------------------------------------------
