"""ABB RAPID writer and reader: round trips, splitting, names, grammar (rapidchecker), determinism."""
import importlib.util
import re
import subprocess
import sys

import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.program.profiles import parse_profile
from camtool.program.profiles import load_profile
from camtool.robots import get_robot
from post_fixtures import smooth_trajectory
from postprocessors.abb_rapid import RESERVED, RapidPost, fmt_t, parse_module, rapid_identifier
from camtool.program.process import ProcessInfo
from test_post import rows_trajectory

POST = RapidPost()


def _setup(robot_name, **options):
    r = get_robot(robot_name)
    p = load_profile(None, robot_name, "rapid", r)
    return r, (p.with_changes(options=options) if options else p)


def on_the_plan(q_read, dur, tr, robot, tol_deg=0.5e-4, tol_mm=0.5e-3):
    """Every target lies on the planned motion at the time the program reaches it: a waypoint,
    or a point of the trajectory's quintic pieces between two (a corner or a bowed chord needed
    it); to the written resolution plus what 1 ms of motion moves."""
    from camtool.program.candidates import hermite

    t = tr.t_s[0] + np.r_[0.0, np.cumsum(dur[1:])]
    k = np.clip(np.searchsorted(tr.t_s, t, side="right") - 1, 0, len(tr.t_s) - 2)
    q_plan = hermite(tr.t_s, tr.q, tr.qd, tr.qdd, k, np.clip(t, tr.t_s[k], tr.t_s[k + 1]))
    speed = np.abs(tr.qd).max(axis=0)
    tol = np.where(robot.prismatic, tol_mm, np.radians(tol_deg)) + 1e-3 * speed + 1e-9
    bad = np.abs(q_read - q_plan) > tol[None, :]
    assert not bad.any(), f"targets {np.flatnonzero(bad.any(axis=1))[:5]} are off the planned motion"


@pytest.mark.parametrize("robot_name", ["seed8", "irb2400"])
def test_round_trip_every_shipped_profile(robot_name, tmp_path):
    """Fewer moves than waypoints; every target is on the planned motion at the time the
    program reaches it (joint targets to the written resolution, robtargets through the
    simulator's inverse kinematics), so the program's clock follows the plan's."""
    r, p = _setup(robot_name)
    tr = rows_trajectory(r)
    files = POST.write(tr, r, p, tmp_path, process=ProcessInfo())
    assert [f.suffix for f in files] == [".pgf", ".mod"]
    dur, q = POST.read(files[0], r, p)
    assert q.shape[1] == r.dof and 10 < len(q) < len(tr.q)
    cart = robot_name == "irb2400"
    assert np.isnan(dur[0])  # the first move comes from wherever the robot is
    on_the_plan(q, dur, tr, r, *((2e-3, 2e-3) if cart else (0.5e-4, 0.5e-3)))
    assert np.allclose(q[0], tr.q[0], atol=1e-5) and np.allclose(q[-1], tr.q[-1], atol=1e-5)
    assert abs(np.nansum(dur) - tr.duration_s) < 1e-3
    text = files[1].read_text()
    assert ("MoveL [[" in text) == cart


def test_moves_along_a_joint_line_merge_into_one_per_zone_stretch(tmp_path):
    """Joint values linear in time: the controller's joint interpolation is the plan, so only
    the anchors remain (the ends and each row's first and last work point)."""
    from dataclasses import replace

    r, p = _setup("seed8")
    tr = rows_trajectory(r, rows=2)
    s = np.linspace(0.0, 1.0, len(tr.t_s))[:, None]
    mid = (r.limits.lower + r.limits.upper) / 2
    span = (r.limits.upper - r.limits.lower) * 0.05
    tr = replace(tr, q=mid + s * span)
    _dur, q = POST.read(POST.write(tr, r, p, tmp_path)[0], r, p)
    assert len(q) == 2 + 2 * 2


def test_move_lines_and_unconnected_axes(tmp_path):
    r, p = _setup("seed8")
    files = POST.write(rows_trajectory(r, rows=2), r, p, tmp_path)
    text = files[1].read_text()
    moves = [ln.strip() for ln in text.splitlines() if ln.strip().startswith("MoveAbsJ")]
    assert "\\T:=" not in moves[0] and ", v100, fine," in moves[0]
    assert all(re.search(r", v1000 \\T:=\d+\.\d{4}, z\d+, camtool_tool \\WObj:=camtool_wobj;$", m)
               for m in moves[1:-1])  # blended: no exact stop between the first and the last move
    assert ", fine, camtool_tool" in moves[-1]
    # eax_a = track (mm), eax_b = j4 (deg), eax_c..f not connected
    eax = re.search(r"\],\[([^\]]*)\]\]", moves[3]).group(1).split(",")
    assert eax[2:] == ["9E9"] * 4 and "9E9" not in eax[:2]
    assert re.fullmatch(r"-?\d+\.\d{3}", eax[0]) and re.fullmatch(r"-?\d+\.\d{4}", eax[1])
    assert "PERS tooldata camtool_tool:=[TRUE," in text and "PERS wobjdata camtool_wobj:=[FALSE,TRUE," in text
    assert files[0].read_text().count("<Module>CAMTOOL.mod</Module>") == 1
    # every row is named where it starts and where it ends; without a signal, the header says so
    assert text.count("! Row ") == 2 and "! Row 1 of 2" in text and text.count("! End of row ") == 2
    assert "no signal configured (profile options.process_signal)" in text and "SetDO" not in text


def test_process_signal_switches_around_every_row(tmp_path):
    r, p = _setup("seed8", process_signal="doPolish")
    process = ProcessInfo(row_labels=("segment 4", "segment 5"), job_name="part.toml", job_time="2024/05/06 07:08")
    lines = [ln.strip() for ln in POST.write(rows_trajectory(r, rows=2), r, p, tmp_path, process=process)[1]
             .read_text().splitlines()]
    on = [i for i, ln in enumerate(lines) if ln == "SetDO doPolish, 1;"]
    off = [i for i, ln in enumerate(lines) if ln == "SetDO doPolish, 0;"]
    assert len(on) == len(off) == 2 and on[0] < off[0] < on[1] < off[1]
    assert lines[on[0] - 1] == "! Row 1 of 2: segment 4" and lines[on[0] + 1].startswith("MoveAbsJ")
    assert lines[off[0] - 1].startswith("MoveAbsJ") and lines[off[0] + 1] == "! End of row 1"
    assert "! Job: part.toml; date 2024/05/06 07:08 UTC (options.date = job)." in lines
    assert any("SetDO doPolish, 1 before each row" in ln for ln in lines)


def test_cartesian_moves_in_the_work_object(tmp_path):
    """irb2400 (motion = cartesian): MoveL with robtargets in the work object at the workpiece
    frame, confdata from the planned joints and the TCP speed of the plan; free motion stays
    MoveAbsJ. The reader gives the targets back as base-frame poses."""
    from camtool.transforms import matrix_from_xyz_rpy

    r, p = _setup("irb2400")
    p = p.with_changes(wobj={"xyz_mm": [900.0, -50.0, 600.0], "rpy_deg": [0.0, -90.0, 0.0]})
    tr = rows_trajectory(r, rows=2)
    files = POST.write(tr, r, p, tmp_path)
    text = files[1].read_text()
    lin = [ln.strip() for ln in text.splitlines() if ln.strip().startswith("MoveL")]
    assert lin and all(re.fullmatch(r"MoveL \[\[[^\]]+\],\[[^\]]+\],\[-?\d+,-?\d+,-?\d+,\d\],\[(9E9,){5}9E9\]\], "
                                    r"\[\d+\.\d\d,\d+\.\d,5000,1000\], z\d+, camtool_tool \\WObj:=camtool_wobj;", m)
                       for m in lin)
    assert "PERS wobjdata camtool_wobj:=[FALSE,TRUE,\"\",[[900.000,-50.000,600.000]," in text
    prog = POST.read_program(files[0], r, p)
    cart = np.flatnonzero(prog.kind == "L")
    assert len(cart) == len(lin) and prog.kind[0] == "J"
    # the poses read back (work object applied) are the TCP of the planned motion
    W = matrix_from_xyz_rpy(p.wobj["xyz_mm"], p.wobj["rpy_deg"])
    assert np.allclose(W[:3, 3], [900.0, -50.0, 600.0])
    dur, q = POST.read(files[0], r, p)
    on_the_plan(q, dur, tr, r, 2e-3, 2e-3)
    P = np.array([r.fk_tcp(qq)[:3, 3] for qq in q[cart]])
    assert np.abs(P - prog.pose[cart, :3, 3]).max() < 2e-3
    assert POST.check(files[0], r, p) == []


def test_long_program_is_split_into_modules_off_the_surface(tmp_path):
    r, p = _setup("irb2400", lines_per_module=60, motion="joint")
    tr = rows_trajectory(r, rows=4)
    files = POST.write(tr, r, p, tmp_path)
    assert len(files) > 3 and [f.name for f in files[:3]] == ["CAMTOOL.pgf", "CAMTOOL.mod", "CAMTOOL_001.mod"]
    main = parse_module(files[1])
    assert main.problems == [] and main.moves == [] and main.procs == ["main"]
    assert [c for _n, c in main.calls] == [f"CAMTOOL_{i:03d}_run" for i in range(1, len(files) - 1)]
    parts = [parse_module(f) for f in files[2:]]
    assert all(0 < len(m.moves) <= 60 for m in parts)
    for m in parts:  # a module never starts or ends on the surface: rows are whole
        kinds = [it[0] for it in m.items if it[0] in ("row", "end_row")]
        assert kinds == ["row", "end_row"] * (len(kinds) // 2)
        assert m.moves[-1].zone == "fine"  # the module after it is loaded there, off the surface
    dur, q = POST.read(files[0], r, p)  # the reader follows the Loads
    assert len(q) == sum(len(m.moves) for m in parts)
    assert np.isnan(dur[0]) and not np.isnan(dur[len(parts[0].moves)])  # continuity across modules


def test_a_row_longer_than_a_module_is_bad_input(tmp_path):
    r, p = _setup("seed8", lines_per_module=5)
    with pytest.raises(BadInput, match=r"options.lines_per_module: more than 5 moves between two points off the "
                                       r"surface"):
        POST.write(rows_trajectory(r, rows=1), r, p, tmp_path)


@pytest.mark.parametrize("raw", ["my part 1", "Teil_Größe", "PROC", "1st", "x" * 40, "tool0"])
def test_identifiers_are_sanitised_with_a_note(raw, caplog):
    name, note = rapid_identifier(raw)
    assert re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,31}", name)
    assert name.upper() not in RESERVED and name not in ("tool0", "wobj0", "load0")
    assert note and raw in note


def test_program_name_with_spaces_and_non_ascii(tmp_path, caplog):
    r, p = _setup("irb2400")
    files = POST.write(smooth_trajectory(r, 5), r, p.with_changes(program_name="Pièce 7 gauche"), tmp_path)
    assert files[1].name == "Pi_ce_7_gauche.mod"
    assert files[1].read_text().startswith("MODULE Pi_ce_7_gauche\n")
    assert any("Pièce 7 gauche" in rec.getMessage() for rec in caplog.records)


def test_same_trajectory_gives_identical_bytes(tmp_path):
    r, p = _setup("seed8", lines_per_module=60)
    tr = rows_trajectory(r, rows=4)
    process = ProcessInfo(job_time="2024/01/02 03:04")
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a = [f.read_bytes() for f in POST.write(tr, r, p, tmp_path / "a", process=process)]
    b = [f.read_bytes() for f in POST.write(tr, r, p, tmp_path / "b", process=process)]
    assert a == b and len(a) > 3
    assert b"date 2024/01/02 03:04 UTC" in a[1]


def test_fmt_t_rounds_up():
    assert fmt_t(0.01) == "0.0100"
    assert fmt_t(0.010001) == "0.0101"
    assert fmt_t(0.0) == "0.0001"


def test_axis_map_outside_rapid_axes_is_refused(tmp_path):
    r = get_robot("irb2400")
    data = {"format": "rapid", "axes": {f"j{i}": {"axis": f"rax_{i}"} for i in range(1, 7)}}
    data["axes"]["j6"] = {"axis": "rax_7"}
    p = parse_profile(data, "mine.toml", "rapid", r, POST.options_schema)
    with pytest.raises(BadInput, match=r"mine.toml: axes.j6.axis: expected one of rax_1"):
        POST.write(smooth_trajectory(r, 5), r, p, tmp_path)


def test_missing_joint_in_axis_map_is_refused(tmp_path):
    r = get_robot("seed8")
    p = load_profile(None, "seed8", "rapid", r)
    p = p.with_changes()
    object.__setattr__(p, "axes", tuple(a for a in p.axes if a.joint != "track"))
    with pytest.raises(BadInput, match=r"axes: joint\(s\) track of robot seed8 have no controller axis"):
        POST.write(smooth_trajectory(r, 5), r, p, tmp_path)


# --- external grammar check: rapidchecker (AGPL, test-only, run as a separate process) ----------

def _rapidchecker(path, cwd):
    return subprocess.run([sys.executable, "-m", "rapidchecker", str(path)], capture_output=True, text=True,
                          cwd=cwd, timeout=120)


needs_rapidchecker = pytest.mark.skipif(importlib.util.find_spec("rapidchecker") is None,
                                        reason="rapidchecker is not installed (pip install -e '.[test]')")


@needs_rapidchecker
def test_rapidchecker_accepts_main_and_split_modules(tmp_path):
    """Every instruction kind camtool writes: MoveAbsJ, MoveL with robtargets and inline
    speed data, SetDO, row comments, Load / late-bound calls / UnLoad."""
    r, p = _setup("seed8", lines_per_module=25, process_signal="doTool")
    files = POST.write(rows_trajectory(r, rows=2, per_row=6, free=3), r, p, tmp_path)
    ri, pi = _setup("irb2400", process_signal="doTool")
    cart = POST.write(rows_trajectory(ri, rows=1, per_row=6, free=2), ri, pi.with_changes(program_name="Cart"),
                      tmp_path)
    assert len(files) > 2 and "MoveL" in cart[1].read_text()
    for f in (files[1], files[2], cart[1]):
        res = _rapidchecker(f, tmp_path)
        assert res.returncode == 0, f"{f.name}: {res.stdout}"


@needs_rapidchecker
def test_rapidchecker_rejects_a_broken_module(tmp_path):
    """Makes sure the grammar check above can fail: bad indentation and a lowercase keyword."""
    r, p = _setup("irb2400")
    f = POST.write(smooth_trajectory(r, 4), r, p, tmp_path)[1]
    f.write_text(f.read_text().replace("  PROC main()", " proc main()"))
    assert _rapidchecker(f, tmp_path).returncode != 0


def test_movec_is_read_and_simulated_on_its_circle(tmp_path):
    """A MoveL turned into a MoveC through a point just off the line (a program written with
    options.arcs = false) checks clean, is read back and moves on the circle."""
    from camtool.simulate import simulate

    r, p = _setup("irb2400", arcs=False)
    files = POST.write(rows_trajectory(r, rows=1), r, p, tmp_path)
    lines = files[1].read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.strip().startswith("MoveL") and i > 0
             and lines[i - 1].strip().startswith("MoveL"))
    prev = re.match(r"\s*MoveL (\[\[[^\]]*\],\[[^\]]*\],\[[^\]]*\],\[[^\]]*\]\])", lines[k - 1]).group(1)
    cur = re.match(r"(\s*)MoveL (\[\[([^\]]*)\],(.*))$", lines[k])
    a = np.array([float(v) for v in re.match(r"\[\[([^\]]*)\]", prev).group(1).split(",")])
    b = np.array([float(v) for v in cur.group(3).split(",")])
    via_xyz = (a + b) / 2 + np.array([0.0, 0.0, 0.01])  # 0.01 mm off the chord: a huge, flat circle
    via = prev.replace(re.match(r"\[\[([^\]]*)\]", prev).group(1), ",".join(f"{v:.3f}" for v in via_xyz), 1)
    lines[k] = f"{cur.group(1)}MoveC {via}, {cur.group(2)}"
    files[1].write_text("\n".join(lines) + "\n")
    assert POST.check(files[0], r, p) == []
    prog = POST.read_program(files[0], r, p)
    c = np.flatnonzero(prog.kind == "C")
    assert len(c) == 1 and np.isfinite(prog.via[c[0]]).all()
    rep = simulate(prog, r)
    assert rep.limit_violations == 0 and rep.speed_violations == 0
