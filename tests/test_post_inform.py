"""Yaskawa INFORM writer and reader: pulses, layout, VJ, splitting, names, bad profiles."""
import re

import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.program.profiles import load_profile
from camtool.robots import get_robot
from post_fixtures import smooth_trajectory, with_q
from camtool.program.process import ProcessInfo
from postprocessors.yaskawa_inform import InformPost, job_name, parse_jbi, vj_percent
from test_post import rows_trajectory

POST = InformPost()

IRB2400_PROFILE = """
format = "inform"
[axes]
j1 = { axis = "RB1:1", unit = "deg", pulses = 1341.38, max_speed = 150.0 }
j2 = { axis = "RB1:2", unit = "deg", pulses = 1907.674, max_speed = 150.0, sign = -1 }
j3 = { axis = "RB1:3", unit = "deg", pulses = 1592.889, max_speed = 150.0, zero_pulses = 1000 }
j4 = { axis = "RB1:4", unit = "deg", pulses = 1022.862, max_speed = 360.0 }
j5 = { axis = "RB1:5", unit = "deg", pulses = 980.239, max_speed = 360.0, offset = 5.0 }
j6 = { axis = "RB1:6", unit = "deg", pulses = 454.754, max_speed = 450.0 }
"""


# The shipped sia20 profile has no pulse factors (they are the controller's; no public source
# gives an SIA20D's): the pulse tests give the profile factors, as a user copies them from theirs.
SIA20_TEST_PULSES = {"s": 1435.27, "l": 1435.27, "u": 1137.78, "r": 910.22, "b": 910.22, "t": 455.11, "e": 1137.78}


def sia20_profile_with_pulses(tmp_path):
    """The shipped sia20 profile plus pulse factors (test values, not a real SIA20D's)."""
    from camtool.program.profiles import default_profile_path
    text = default_profile_path("sia20", "inform").read_text()
    for j, v in SIA20_TEST_PULSES.items():
        text = re.sub(rf'^({j} = {{ axis = "RB1:\d", )', rf"\g<1>pulses = {v}, zero_pulses = 0, ", text, flags=re.M)
    f = tmp_path / "sia20_pulses_inform.toml"
    f.write_text(text)
    return f


def _profile(robot_name, tmp_path, **options):
    r = get_robot(robot_name)
    if robot_name == "irb2400":
        f = tmp_path / "irb2400_inform.toml"
        f.write_text(IRB2400_PROFILE)
        p = load_profile(f, "irb2400", "inform", r)
    elif robot_name == "sia20":
        p = load_profile(sia20_profile_with_pulses(tmp_path), "sia20", "inform", r)
    else:
        p = load_profile(None, robot_name, "inform", r)
    return r, (p.with_changes(options=options) if options else p)


@pytest.mark.parametrize("robot_name", ["seed8", "sia20", "irb2400"])
def test_round_trip_within_one_pulse(robot_name, tmp_path):
    """Joint moves (the sia20 as MOVJ too): every target is on the planned motion (a waypoint,
    or a point between two) within one pulse, reached when the plan reaches it."""
    from test_post_rapid import on_the_plan

    r, p = _profile(robot_name, tmp_path, motion="joint")
    tr = rows_trajectory(r)
    files = POST.write(tr, r, p, tmp_path)
    dur, q = POST.read(files[0], r, p)
    assert q.shape[1] == r.dof and len(q) <= len(tr.q)
    step = max(1.0 / a.pulses for a in p.axes)  # deg (or mm) of one pulse
    dur[1:] = np.maximum(dur[1:], 0)
    # VJ rounds each move's time to 0.01 %: the clock is right to a few ms
    on_the_plan(q, dur, tr, r, tol_deg=step + 0.02, tol_mm=step + 0.02)
    assert abs(np.nansum(dur) - tr.duration_s) < 0.005 * tr.duration_s


def test_seed8_layout(tmp_path):
    r, p = _profile("seed8", tmp_path, date="2001/02/03 04:05")
    files = POST.write(rows_trajectory(r, rows=2), r, p, tmp_path, process=ProcessInfo(job_name="sphere.toml"))
    raw = files[0].read_bytes()
    raw.decode("ascii")
    assert raw.count(b"\r\n") == raw.count(b"\n") and raw.endswith(b"END\r\n")
    lines = raw.decode().split("\r\n")[:-1]
    n = int(lines[3].split()[1].split(",")[0])
    assert lines[:8] == ["/JOB", "//NAME CAMTOOL", "//POS", f"///NPOS {n},{n},0,0,0,0", "///TOOL 0",
                         "///POSTYPE PULSE", "///PULSE", lines[7]]
    c = [ln for ln in lines if ln.startswith("C0")]
    bc = [ln for ln in lines if ln.startswith("BC")]
    assert len(c) == n and len(bc) == n
    assert all(len(ln.split("=")[1].split(",")) == 7 for ln in c)
    assert all(len(ln.split("=")[1].split(",")) == 1 for ln in bc)
    inst = lines[lines.index("//INST"):]
    assert inst[:6] == ["//INST", "///DATE 2001/02/03 04:05", "///COMM camtool sphere.toml", "///ATTR SC,RW",
                        "///GROUP1 RB1,BS1", "NOP"]
    assert "'NO PROCESS OUTPUT CONFIGURED" in inst
    moves = [ln for ln in lines if ln.startswith("MOV")]
    assert moves[0] == "MOVJ C00000 BC00000 VJ=10.00 PL=0"
    assert all(re.fullmatch(r"MOVJ C\d{5} BC\d{5} VJ=\d+\.\d{2} PL=[1-8]", m) for m in moves[1:-1])
    assert moves[-1].endswith(" PL=0")
    assert [ln for ln in inst if ln.startswith("'ROW") or ln.startswith("'END ROW")] == \
        ["'ROW 1/2", "'END ROW 1", "'ROW 2/2", "'END ROW 2"]
    assert parse_jbi(files[0]).problems == []


def test_process_output_switches_around_every_row(tmp_path):
    r, p = _profile("seed8", tmp_path, process_output=7)
    lines = POST.write(rows_trajectory(r, rows=2), r, p, tmp_path,
                       process=ProcessInfo(row_labels=("segment 3", "segment 4")))[0].read_bytes().decode().split("\r\n")
    on = [i for i, ln in enumerate(lines) if ln == "DOUT OT#(7) ON"]
    off = [i for i, ln in enumerate(lines) if ln == "DOUT OT#(7) OFF"]
    assert len(on) == len(off) == 2 and on[0] < off[0] < on[1] < off[1]
    assert lines[on[0] - 1] == "'ROW 1/2 SEGMENT 3" and lines[on[0] + 1].startswith("MOVJ")
    assert lines[off[0] + 1] == "'END ROW 1" and "'PROCESS OUTPUT OT#(7)" in lines


def test_sia20_cartesian_positions(tmp_path):
    """sia20 (motion = cartesian): MOVL to ///RECTAN positions with ///RCONF and the E axis as
    Re, V in mm/s; the job reads back and checks clean (options.arcs = false: MOVL only)."""
    r, p = _profile("sia20", tmp_path)
    p = p.with_changes(options={"arcs": False})
    tr = rows_trajectory(r, rows=2)
    f = POST.write(tr, r, p, tmp_path)[0]
    text = f.read_bytes().decode()
    assert "///ATTR SC,RW,RJ\r\n" in text and "///POSTYPE BASE\r\n///RECTAN\r\n///RCONF " in text
    lines = text.split("\r\n")
    rect = [ln for ln in lines if re.fullmatch(r"C\d{5}=-?\d+\.\d{3}(,-?\d+\.\d{3}){2}(,-?\d+\.\d{4}){4}", ln)]
    movl = [ln for ln in lines if re.fullmatch(r"MOVL C\d{5} V=\d+\.\d PL=\d", ln)]
    assert rect and movl
    assert re.search(r"///RCONF [01](,[01]){5},0,0\r\n", text)
    assert POST.check(f, r, p) == []
    prog = POST.read_program(f, r, p)
    lin = prog.kind == "L"
    assert lin.sum() == len(movl) and np.isfinite(prog.q[lin, 2]).all()  # e (RB1:7) is fixed by Re
    P = np.array([r.fk_tcp(qq)[:3, 3] for qq in tr.q])
    d = np.min(np.linalg.norm(prog.pose[lin, None, :3, 3] - P[None], axis=2), axis=1)
    assert d.max() < 2e-3  # every position is the TCP of a planned waypoint


def test_vj_formula():
    # axis 0 needs 10 deg in 0.5 s at vmax 100 deg/s -> 20 %; axis 1 needs 5 mm at 500 mm/s -> 2 %
    assert vj_percent(np.array([10.0, -5.0]), 0.5, np.array([100.0, 500.0])) == 20.0
    assert vj_percent(np.array([1.0]), 1.0, np.array([300.0])) == 0.33  # 0.333.. rounded down
    assert vj_percent(np.array([0.0]), 1.0, np.array([100.0])) == 0.01
    assert vj_percent(np.array([500.0]), 1.0, np.array([100.0])) == 100.0


def test_vj_reproduces_the_timing(tmp_path):
    r, p = _profile("sia20", tmp_path, motion="joint")
    tr = rows_trajectory(r, rows=2)
    dur, _q = POST.read(POST.write(tr, r, p, tmp_path)[0], r, p)
    assert abs(np.nansum(dur) - tr.duration_s) < 0.005 * tr.duration_s  # the job's clock tracks the plan


def test_long_job_is_split_off_the_surface_with_a_main_job(tmp_path):
    r, p = _profile("seed8", tmp_path, lines_per_job=60)
    tr = rows_trajectory(r, rows=4)
    files = POST.write(tr, r, p.with_changes(program_name="sphere"), tmp_path)
    assert [f.name for f in files[:2]] == ["SPHERE.JBI", "SPHERE_1.JBI"] and len(files) > 2
    main = parse_jbi(files[0])
    assert main.problems == [] and [c for _n, c in main.calls] == [f.stem for f in files[1:]]
    for f in files[1:]:
        j = parse_jbi(f)
        assert j.problems == [] and 0 < j.npos[0] <= 60 and len(j.moves) == j.npos[0]
        kinds = [it[0] for it in j.items if it[0] in ("row", "end_row")]
        assert kinds == ["row", "end_row"] * (len(kinds) // 2)  # rows are whole: no CALL on the surface
        assert j.moves[-1].pl == 0  # CALL JOB ends the motion: said so, off the surface
    _dur, q = POST.read(files[0], r, p)
    assert len(q) == sum(len(parse_jbi(f).moves) for f in files[1:])


def test_job_names_are_sanitised_to_eight_characters(tmp_path, caplog):
    assert job_name("my long job name")[0] == "MY_LONG_"
    assert job_name("7up")[0] == "P7UP"
    assert job_name("ÄBC")[0] == "P_BC"
    r, p = _profile("sia20", tmp_path)
    f = POST.write(smooth_trajectory(r, 5), r, p.with_changes(program_name="Pièce 12"), tmp_path)[0]
    assert f.name == "PI_CE_12.JBI" and "//NAME PI_CE_12\r\n" in f.read_bytes().decode()
    assert any("Pièce 12" in rec.getMessage() for rec in caplog.records)


def test_profile_missing_pulses_is_refused(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text(IRB2400_PROFILE.replace("pulses = 980.239, ", ""))
    with pytest.raises(BadInput, match=r"bad.toml: axes.j5.pulses: missing"):
        load_profile(f, "irb2400", "inform", get_robot("irb2400"))


def test_profile_naming_an_unknown_joint_is_refused(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text(IRB2400_PROFILE + 'j7 = { axis = "RB1:7", pulses = 100.0, max_speed = 100.0 }\n')
    with pytest.raises(BadInput, match=r"bad.toml: axes.j7: robot irb2400 has no joint 'j7'"):
        load_profile(f, "irb2400", "inform", get_robot("irb2400"))


def test_profile_with_gap_in_axis_numbers_is_refused(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text(IRB2400_PROFILE.replace('"RB1:6"', '"RB1:8"'))
    with pytest.raises(BadInput, match=r"RB1 axes must be numbered 1..6"):
        load_profile(f, "irb2400", "inform", get_robot("irb2400"))


def test_same_trajectory_gives_identical_bytes(tmp_path):
    r, p = _profile("seed8", tmp_path, lines_per_job=60)
    tr = rows_trajectory(r, rows=4)
    process = ProcessInfo(job_time="2024/01/02 03:04")
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a = [f.read_bytes() for f in POST.write(tr, r, p, tmp_path / "a", process=process)]
    b = [f.read_bytes() for f in POST.write(with_q(tr, tr.q.copy()), r, p, tmp_path / "b", process=process)]
    assert a == b and len(a) > 2 and b"///DATE 2024/01/02 03:04\r\n" in a[1]


def _movc(tmp_path, n_points=3, fpt=False):
    """A sia20 Cartesian job whose first run of MOVL lines on a row is turned into MOVC
    points (``n_points`` of them; with ``fpt``, FPT on the third)."""
    r = get_robot("sia20")
    p = load_profile(sia20_profile_with_pulses(tmp_path), "sia20", "inform", r).with_changes(options={"arcs": False})
    files = InformPost().write(rows_trajectory(r, rows=1), r, p, tmp_path)
    lines = files[0].read_bytes().decode("ascii").split("\r\n")
    k = next(i for i, ln in enumerate(lines) if ln.startswith("MOVL") and lines[i + 1].startswith("MOVL")
             and lines[i + 2].startswith("MOVL") and lines[i + 3].startswith("MOVL"))
    for i in range(k, k + n_points):
        lines[i] = lines[i].replace("MOVL", "MOVC", 1) + (" FPT" if fpt and i == k + 2 else "")
    files[0].write_bytes("\r\n".join(lines).encode("ascii"))
    return r, p, files[0], k


def test_movc_is_read_checked_and_simulated(tmp_path):
    """Three MOVC points: a linear move to the first, then one circular move through the
    second to the third; the job checks clean and the simulator runs it on its circle."""
    from camtool.simulate import simulate

    r, p, f, _k = _movc(tmp_path)
    assert InformPost().check(f, r, p) == []
    prog = InformPost().read_program(f, r, p)
    c = np.flatnonzero(prog.kind == "C")
    assert len(c) == 1 and np.isfinite(prog.via[c[0]]).all() and prog.kind[c[0] - 1] == "L"
    rep = simulate(prog, r)
    assert rep.limit_violations == 0 and rep.speed_violations == 0


@pytest.mark.parametrize("n,fpt", [(2, False), (4, True)])
def test_an_arc_without_three_movc_points_is_a_finding(tmp_path, n, fpt):
    r, p, f, _k = _movc(tmp_path, n_points=n, fpt=fpt)
    assert any("fewer than three MOVC points" in x for x in InformPost().check(f, r, p))


def test_sia20_rows_on_circles_become_movc_arcs(tmp_path):
    """Rows on a circle: the MOVL to the row's start becomes the arc's first MOVC point, then
    circle point and target (FPT where the next arc follows); the job checks clean, reads
    back as circular moves and the simulation keeps it within the tolerance. (With position
    levels of a few mm: the default PL=1 of 12.5 mm cuts the corner between two arcs by more
    than the tolerance, and FitArcs gives such arcs up.)"""
    from camtool.program.post import ResolvedPost, write_programs
    from camtool.settings import PostSettings

    r = get_robot("sia20")  # joint moves in pulses (test factors): this synthetic job passes near the
    # SIA20D's straight-arm singularity, where reading a RECTAN joint move back by IK is ill-posed
    p = load_profile(sia20_profile_with_pulses(tmp_path), "sia20", "inform", r).with_changes(
        options={"pl_mm": [0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0]})
    report = {}
    files = write_programs(rows_trajectory(r, rows=2), r, PostSettings.make(formats=["inform"]),
                           {"inform": ResolvedPost("inform", POST, p)}, tmp_path / "o", report=report)
    text = files[0].read_bytes().decode("ascii")
    movc = [ln for ln in text.split("\r\n") if ln.startswith("MOVC")]
    assert len(movc) >= 3 and "ARCS" in text
    assert POST.check(files[0], r, p) == []
    prog = POST.read_program(files[0], r, p)
    assert (prog.kind == "C").sum() >= 1 and np.isfinite(prog.via[prog.kind == "C"]).all()
    assert report["inform"]["max_deviation_mm"] <= 0.1 and report["inform"]["moves"] == len(prog)


def test_default_position_levels_give_up_arcs_they_cannot_blend(tmp_path):
    r = get_robot("sia20")
    p = load_profile(sia20_profile_with_pulses(tmp_path), "sia20", "inform", r)
    text = POST.write(rows_trajectory(r, rows=2), r, p, tmp_path)[0].read_bytes().decode("ascii")
    assert POST.check(tmp_path / "CAMTOOL.JBI", r, p) == []
    assert "MOVL" in text


def test_a_row_left_open_at_the_end_of_the_job_is_a_finding(tmp_path):
    r, p = _profile("seed8", tmp_path)
    f = POST.write(rows_trajectory(r, rows=2), r, p, tmp_path)[0]
    assert POST.check(f, r, p) == []
    raw = f.read_bytes()
    assert raw.count(b"'END ROW 2\r\n") == 1
    f.write_bytes(raw.replace(b"'END ROW 2\r\n", b""))
    assert any("never ends" in s for s in POST.check(f, r, p))
