"""Yaskawa INFORM writer: the program model's moves as ``MOVJ`` / ``MOVL`` instructions with
their positions, in jobs (see ``postprocessors.inform``)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from camtool import __version__
from camtool.program.convention import controller_axes, controller_pose_base
from camtool.robots.confdata import yaskawa_rconf
from camtool.program.kinematics import Kinematics
from camtool.program.moves import JOINT
from camtool.program.plan import KIND_LINEAR, plan_moves, profile_tool, split_parts
from camtool.program.process import ProcessInfo, program_date

from .dialect import (GROUPS, comment_text, V_STEP, _fmt_column, euler_xyz_deg, group_axes, job_name, pulse_free,
                      to_pulses, validate_profile)


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
    cart = o["motion"] == "cartesian"
    radii = [float(v) for v in o["pl_mm"]][:o["max_pl"]]
    plan = plan_moves(trajectory, robot, process, linear=cart, levels_mm=radii,
                      min_level_on_surface=max(1, o["pl"]) - 1)
    n = len(plan)
    kind = np.array(plan.kind)
    length = np.r_[0.0, np.linalg.norm(np.diff(plan.P, axis=0), axis=1)]
    kind[(kind == KIND_LINEAR) & (length < 1e-3)] = JOINT
    parts = split_parts(n, o["lines_per_job"], plan.free, "positions", f"{profile.source}: options.lines_per_job")
    pl = plan.level + 1  # level -1 (exact stop) -> PL=0
    for r in parts[:-1]:
        pl[r.stop - 1] = 0  # CALL JOB ends the motion: the job before ends with a stop
    groups = group_axes(profile)
    pulses = to_pulses(profile, robot, plan.q)
    axes = controller_axes(profile, robot, plan.q)
    order = [a for ax in groups.values() for a in ax]
    vmax = np.array([a.max_speed for a in order])
    values = np.stack([axes[a.axis] for a in order], axis=1)
    # --- timing: VJ for joint moves, V for linear ones; the job's clock tracks the plan
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
        if kind[i] == KIND_LINEAR:
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
    # --- positions
    lin = kind == KIND_LINEAR
    cart_pos = np.ones(n, bool) if pulse_free(profile) else lin   # no pulse factors: every position Cartesian
    pos_txt: dict[str, list[str]] = {}
    for g, pre in GROUPS.items():
        if g in pulses:
            pos_txt[pre] = [",".join(map(str, row)) for row in pulses[g].tolist()]
    pos_txt.setdefault("C", [""] * n)
    rconf = [None] * n
    if cart_pos.any():
        li = np.flatnonzero(cart_pos)
        P, R = controller_pose_base(profile, plan.P[li], plan.R[li], robot)  # in the robot frame
        ang = euler_xyz_deg(R)
        rb = groups["RB1"]
        extra = [axes[rb[6].axis][li]] if len(rb) == 7 else []
        cols = [P[:, 0], P[:, 1], P[:, 2], ang[:, 0], ang[:, 1], ang[:, 2], *extra]
        dec = [3, 3, 3, 4, 4, 4, 4]
        txt = [_fmt_column(c, d) for c, d in zip(cols, dec)]
        rc = _rconf(robot, plan.q[li], o["rconf_fields"])
        for j, i in enumerate(li):
            pos_txt["C"][i] = ",".join(t[j] for t in txt)
            rconf[i] = rc[j]
    # --- instructions
    out_no = o["process_output"]
    labels = list(process.row_labels)
    before: dict[int, list[str]] = {}
    after: dict[int, list[str]] = {}
    for i in np.flatnonzero(plan.row_start | plan.row_end):
        r = int(plan.row[i]) + 1
        if plan.row_start[i]:
            label = f" {comment_text(labels[r - 1], 24).upper()}" if r - 1 < len(labels) else ""
            before[i] = [f"'ROW {r}/{plan.rows}{label}"[:33]] + ([f"DOUT OT#({out_no}) ON"] if out_no else [])
        if plan.row_end[i]:
            after[i] = ([f"DOUT OT#({out_no}) OFF"] if out_no else []) + [f"'END ROW {r}"]
    date = program_date(o["date"], process)
    comm = comment_text(f"camtool {process.job_name or name}", 32)
    n_lin = int(lin.sum())
    notes = [f"'camtool {__version__} {comment_text(robot.name, 64)} {n} moves",
             f"'{n_lin} MOVL {n - n_lin} MOVJ {int((pl == 0).sum())} STOPS",
             f"'PATH TOL {process.path_tol_mm:g} MM",
             f"'{comment_text(robot.conventions.source, 12).upper()} ROBOT {comment_text(robot.name, 24).upper()}",
             "'" + comment_text("AXES " + " ".join(robot.conventions.controller_axis_names), 60),
             ("'POSITIONS RECTAN ROBOT FRAME NO PULSE FACTORS" if pulse_free(profile) else "'PULSES FROM THE PROFILE"),
             (f"'PROCESS OUTPUT OT#({out_no})" if out_no else "'NO PROCESS OUTPUT CONFIGURED")]
    header = dict(tool=profile.tool["number"], date=date, group=",".join(groups), comm=comm,
                  attr="SC,RW,RJ" if cart_pos.any() else "SC,RW", notes=notes)
    files: dict[str, list[str]] = {}
    job = dict(kind=kind, pos_txt=pos_txt, rconf=rconf, speed=speed, pl=pl, before=before, after=after,
               rconf_fields=o["rconf_fields"])
    if len(parts) == 1:
        files[name] = _job(name, parts[0], header, job)
    else:
        names = []
        for i, r in enumerate(parts, 1):
            s = f"_{i}"
            part = name[:o["job_name_length"] - len(s)] + s
            names.append(part)
            files[part] = _job(part, r, header, job)
        main = ["/JOB", f"//NAME {name}", "//POS", "///NPOS 0,0,0,0,0,0", "//INST", f"///DATE {date}",
                f"///COMM {comm}", "///ATTR SC,RW", f"///GROUP1 {header['group']}", "NOP"] + notes \
            + [f"CALL JOB:{n_}" for n_ in names] + ["END"]
        files = {name: main, **files}
    written_files = []
    for job_, lines in files.items():
        p = outdir / f"{job_}.JBI"
        p.write_bytes(("\r\n".join(lines) + "\r\n").encode("ascii"))
        written_files.append(p)
    return written_files

def _job(name, r: range, header, job) -> list[str]:
    lines = ["/JOB", f"//NAME {name}", "//POS"]
    pos_txt, kind, rconf = job["pos_txt"], job["kind"], job["rconf"]
    counts = [len(r) if pre in pos_txt else 0 for pre in GROUPS.values()]
    lines += [f"///NPOS {counts[0]},{counts[1]},{counts[2]},0,0,0", f"///TOOL {header['tool']}"]
    state = None
    for i, k in enumerate(r):
        want = ("rectan", rconf[k]) if rconf[k] is not None else ("pulse", None)
        if want != state:
            if want[0] == "pulse":
                lines += ["///POSTYPE PULSE", "///PULSE"]
            else:
                if state is None or state[0] != "rectan":
                    lines += ["///POSTYPE BASE", "///RECTAN"]
                lines.append(f"///RCONF {want[1]}")
            state = want
        lines.append(f"C{i:05d}={pos_txt['C'][k]}")
    for pre in ("BC", "EC"):
        if pre in pos_txt:
            if state is None or state[0] != "pulse":
                lines += ["///POSTYPE PULSE", "///PULSE"]
                state = ("pulse", None)
            lines += [f"{pre}{i:05d}={pos_txt[pre][k]}" for i, k in enumerate(r)]
    lines += ["//INST", f"///DATE {header['date']}", f"///COMM {header['comm']}", f"///ATTR {header['attr']}",
              f"///GROUP1 {header['group']}", "NOP"] + header["notes"]
    for i, k in enumerate(r):
        lines += job["before"].get(k, [])
        refs = " ".join(f"{pre}{i:05d}" for pre in pos_txt)
        word = "MOVL" if kind[k] == KIND_LINEAR else "MOVJ"
        lines.append(f"{word} {refs} {job['speed'][k]} PL={job['pl'][k]}")
        lines += job["after"].get(k, [])
    return lines + ["END"]

# --- reading ---------------------------------------------------------------------------
