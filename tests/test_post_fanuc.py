"""FANUC LS writer, reader and checker (issue #47): /PROG /ATTR /MN /POS /END, numbered lines,
J / L / C with FINE / CNT, % and mm/sec, joint-representation positions in the pendant's
convention (J3 from the horizontal), UF / UT, frames, names, splitting, the checker's findings."""
import re

import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.program.process import ProcessInfo
from camtool.program.profiles import load_profile
from camtool.robots import get_robot
from postprocessors.fanuc import FanucPost
from postprocessors.fanuc.dialect import cnt_radius, ls_number, matrix_wpr, program_name, wpr_deg
from test_post import rows_trajectory
from test_post_krl import on_the_path

POST = FanucPost()
CENTRE = [0.0, 10.0, 20.0, 0.0, -50.0, 0.0]   # J5 bent: away from the wrist singularity


def _setup(**options):
    r = get_robot("m20ia")
    p = load_profile(None, "m20ia", "fanuc", r)
    return r, (p.with_changes(options=options) if options else p)


def _write(tmp_path, rows=3, process=None, **options):
    r, p = _setup(**options)
    tr = rows_trajectory(r, rows=rows, centre=CENTRE)
    files = POST.write(tr, r, p, tmp_path, process=process or ProcessInfo())
    return r, p, tr, files


def test_round_trip_on_the_plan(tmp_path):
    """Every position is a joint position on the planned motion (to the written 0.001 deg), the
    program's clock within 0.5 % of the plan's, L and C moves among J moves."""
    r, p, tr, files = _write(tmp_path)
    assert [f.name for f in files] == ["CAMTOOL.LS"]
    dur, q = POST.read(files[0], r, p)
    assert 10 < len(q) < len(tr.q) and np.isnan(dur[0])
    on_the_path(q, tr, 5e-3)   # 0.001 deg written (J3 = j3 - j2 adds two roundings), the plan sampled every ms
    assert abs(np.nansum(dur) - tr.duration_s) < 0.005 * tr.duration_s
    assert POST.check(files[0], r, p) == []
    prog = POST.read_program(files[0], r, p)
    assert {"J", "L", "C"} <= set(prog.kind) and prog.kind[0] == "J"


def test_positions_are_the_pendant_s_joints(tmp_path):
    """J3 in a position is the pendant's, from the horizontal: j3 - j2 of camtool's serial joints
    (fanuc_driver's J23 linkage); the other joints as they are."""
    r, p, tr, files = _write(tmp_path, rows=1)
    text = files[0].read_text()
    first = re.search(r"P\[3\]\{\s*GP1:\s*UF : 1, UT : 1,\s*J1=\s*(\S+) deg,\s*J2=\s*(\S+) deg,\s*J3=\s*(\S+) deg,"
                      r"\s*J4=\s*(\S+) deg,\s*J5=\s*(\S+) deg,\s*J6=\s*(\S+) deg\s*\};", text)
    J = np.array([float(v) for v in first.groups()])
    q = np.degrees(tr.q[0])
    assert np.allclose(J, [q[0], q[1], q[2] - q[1], q[3], q[4], q[5]], atol=1e-3)


def test_layout(tmp_path):
    process = ProcessInfo(job_name="part.toml", job_time="2024/05/06 07:08", row_labels=("segment 4",) * 3)
    r, p, tr, files = _write(tmp_path, process=process, process_output=5)
    raw = files[0].read_bytes()
    text = raw.decode("ascii")
    assert text.count("\n") == text.count("\r\n") and text.endswith("/END\r\n")
    lines = text.split("\r\n")[:-1]
    heads = [ln.split()[0] for ln in lines if ln.startswith("/")]
    assert heads == ["/PROG", "/ATTR", "/MN", "/POS", "/END"] and lines[0] == "/PROG  CAMTOOL"
    assert "CREATE\t\t= DATE 24-05-06  TIME 07:08:00;" in lines and "DEFAULT_GROUP\t= 1,*,*,*,*;" in lines
    mn = lines[lines.index("/MN") + 1:lines.index("/POS")]
    numbered = [ln for ln in mn if re.match(r"^\s*\d+:", ln)]
    assert [int(ln.split(":")[0]) for ln in numbered] == list(range(1, len(numbered) + 1))
    assert f"LINE_COUNT\t= {len(numbered)};" in lines
    assert all(len(ln.split(":", 1)[0]) == 4 for ln in numbered)
    moves = [ln.split(":", 1)[1] for ln in numbered if re.match(r"^\s*\d+:[JLC] ", ln)]
    assert moves[0].startswith("J P[3] 10% FINE") and moves[-1].endswith("FINE    ;")
    assert all(re.fullmatch(r"J P\[\d+\] \d+% (FINE|CNT\d+)    ;|L P\[\d+\] \d+mm/sec (FINE|CNT\d+)    ;|C P\[\d+\]    ",
                            m) for m in moves)
    conts = [ln for ln in mn if ln.startswith("    :  P[")]
    assert len(conts) == sum(m.startswith("C ") for m in moves) > 0
    # frames: the tool and the work object through PR[100], then selected; every position records them
    for ins in ("PR[100]=P[1]    ;", "UTOOL[1]=PR[100] ;", "PR[100]=P[2]    ;", "UFRAME[1]=PR[100] ;",
                "UFRAME_NUM=1 ;", "UTOOL_NUM=1 ;"):
        assert any(ln.endswith(":  " + ins) for ln in numbered), ins
    assert text.count("UF : 1, UT : 1,\t\r\n") == text.count("J1=")
    # rows named where they start and end, the output switched around them
    body = [ln.split(":", 1)[1].strip() for ln in numbered]
    on = [i for i, b in enumerate(body) if b == "DO[5]=ON ;"]
    assert len(on) == 3 and body[on[0] - 1] == "!ROW 1/3 segment 4 ;"
    assert body.count("DO[5]=OFF ;") == 3 and "!END ROW 1 ;" in body


def test_tool_and_user_frame_are_the_job_s(tmp_path):
    from camtool.transforms import matrix_from_xyz_rpy

    r, p = _setup()
    p = p.with_changes(wobj={"xyz_mm": [1100.0, 0.0, 900.0], "rpy_deg": [0.0, -90.0, 0.0]},
                       tool={"tcp_xyz_mm": [0.0, 10.0, 120.0], "tcp_rpy_deg": [0.0, 20.0, 0.0]})
    files = POST.write(rows_trajectory(r, rows=1, centre=CENTRE), r, p, tmp_path)
    prog = POST.read_program(files[0], r, p)
    assert np.allclose(prog.tool_T_mm, matrix_from_xyz_rpy([0.0, 10.0, 120.0], [0.0, 20.0, 0.0]), atol=1e-3)
    text = files[0].read_text()
    uf = re.search(r"P\[2\]\{.*?X =\s*(\S+)\s+mm,\s*Y =\s*(\S+)\s+mm,\s*Z =\s*(\S+)\s+mm,\s*W =\s*(\S+) deg,"
                   r"\s*P =\s*(\S+) deg,\s*R =\s*(\S+) deg", text, re.S)
    v = [float(x) for x in uf.groups()]
    assert np.allclose(v[:3], [1100.0, 0.0, 900.0 - 525.0])   # in World, 525 mm above base_link
    assert np.allclose(matrix_wpr(v[3:])[0], matrix_from_xyz_rpy([0, 0, 0], [0.0, -90.0, 0.0])[:3, :3], atol=1e-5)


def test_frames_by_hand_are_stated_in_the_header(tmp_path):
    r, p, tr, files = _write(tmp_path, rows=1, set_frames=False, utool=3, uframe=2)
    text = files[0].read_text()
    assert "UTOOL[" not in text and "PR[" not in text and "UTOOL_NUM=3 ;" in text and "UFRAME_NUM=2 ;" in text
    assert "!set UTOOL_ 3 by hand to ;" in text and "UF : 2, UT : 3," in text
    assert POST.check(files[0], r, p.with_changes(options={"set_frames": False, "utool": 3, "uframe": 2})) == []


def test_numbers_as_the_controller_lists_them():
    assert ls_number(0.5) == "      .500" and ls_number(-0.35) == "     -.350" and ls_number(-0.0001) == "     0.000"
    assert ls_number(123.4567) == "   123.457" and len(ls_number(-1234.5)) == 10
    R = matrix_wpr([10.0, 20.0, 30.0])[0]
    assert np.allclose(wpr_deg(R)[0], [10.0, 20.0, 30.0])


def test_cnt_model():
    levels, radii = [1, 10, 100], [0.1, 1.0, 10.0]
    assert cnt_radius(10, levels, radii) == pytest.approx(1.0) and cnt_radius(0, levels, radii) == 0.0
    assert cnt_radius(55, levels, radii) == pytest.approx(5.5)


def test_program_names(tmp_path, caplog):
    assert program_name("part-1")[0] == "PART_1" and program_name("9lives")[0] == "P9LIVES"
    assert program_name("a" * 40, 36)[0] == "A" * 36 and program_name("call")[0] == "CALL_1"
    r, p = _setup()
    files = POST.write(rows_trajectory(r, rows=1, centre=CENTRE), r, p.with_changes(program_name="sphere job"),
                       tmp_path)
    assert files[0].name == "SPHERE_J.LS" and "not valid" in caplog.text


def test_long_program_is_split_off_the_surface(tmp_path):
    r, p, tr, files = _write(tmp_path, lines_per_program=25)
    names = [f.name for f in files]
    assert names[0] == "CAMTOOL.LS" and "CAMTOO_1.LS" in names and "CAMTOO_2.LS" in names
    main = files[0].read_text()
    assert "CALL CAMTOO_1    ;" in main and "UTOOL[1]=PR[100] ;" in main and ":J P[" not in main
    assert POST.check(files[0], r, p) == []
    prog = POST.read_program(files[0], r, p)
    ends = np.flatnonzero(np.diff(prog.part))
    assert len(ends) >= 1 and (prog.blend_mm[ends] == 0).all()
    dur, q = POST.read(files[0], r, p)
    assert abs(np.nansum(dur) - tr.duration_s) < 0.005 * tr.duration_s


def test_same_trajectory_gives_identical_bytes(tmp_path):
    process = ProcessInfo(job_time="2024/01/02 03:04")
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    r, p, tr, a = _write(tmp_path / "a", process=process)
    b = POST.write(tr, r, p, tmp_path / "b", process=process)
    assert [x.read_bytes() for x in a] == [y.read_bytes() for y in b]


def _broken(tmp_path, edit):
    r, p, tr, files = _write(tmp_path, rows=1)
    raw = files[0].read_bytes().decode("ascii")
    files[0].write_bytes(edit(raw).encode("latin-1"))
    return POST.check(files[0], r, p)


@pytest.mark.parametrize("edit,expect", [
    (lambda s: s[:s.index("/END")], "a truncated file"),
    (lambda s: s[:s.rindex("};")], "not closed"),
    (lambda s: s.replace("LINE_COUNT\t= ", "LINE_COUNT\t= 1", 1), "LINE_COUNT"),
    (lambda s: s.replace("  17:J", "  18:J", 1), "line number 18, expected 17"),
    (lambda s: s.replace(":J P[3] 10%", ":J P[3] 150%", 1), "whole 1..100"),
    (lambda s: s.replace(":J P[3] 10% FINE", ":J P[3] 10mm/sec FINE", 1), "speed is in %"),
    (lambda s: s.replace("P[3]{\r\n   GP1:\r\n\tUF : 1,", "P[3]{\r\n   GP1:\r\n\tUF : 2,", 1), "UF 2 / UT 1"),
    (lambda s: s.replace(":J P[3] ", ":J P[999] ", 1), "P[999] is not in /POS"),
    (lambda s: s.replace("!job ", "!J P[3] 100% FINE ", 1), "code in a remark"),
    (lambda s: s.replace("/PROG  CAMTOOL", "/PROG  OTHER", 1), "is in a file named"),
    (lambda s: s.replace("\r\n", "\n", 2), "CRLF"),
    (lambda s: s.replace("J1=", "J1=1e999", 1), "unrecognised values"),
    (lambda s: s[:s.rindex("FINE    ;")] + "CNT50    ;" + s[s.rindex("FINE    ;") + 9:], "must be FINE"),
])
def test_check_finds_broken_ls(tmp_path, edit, expect):
    found = _broken(tmp_path, edit)
    assert any(expect in f for f in found), found


def test_a_cartesian_target_is_refused(tmp_path):
    """camtool writes and reads joint positions only: a Cartesian P as a move's target (whose
    CONFIG public sources read differently) is a finding."""
    def cart(s):
        return re.sub(r"P\[3\]\{\r\n   GP1:\r\n\tUF : 1, UT : 1,\t\r\n[^}]*\};",
                      "P[3]{\r\n   GP1:\r\n\tUF : 1, UT : 1,\t\tCONFIG : 'N U T, 0, 0, 0',\r\n\tX =  900.000  mm,\t"
                      "Y =  0.000  mm,\tZ =  500.000  mm,\r\n\tW =  180.000 deg,\tP =  0.000 deg,\tR =  0.000 deg\r\n};", s)
    found = _broken(tmp_path, cart)
    assert any("P[3] is Cartesian" in f for f in found), found


def test_the_pendant_s_j3_limit_is_checked(tmp_path):
    """A J3 (from the horizontal) beyond the manual's range is a finding even where the serial joint is
    inside its own: the controller limits the axis it shows."""
    r, p, tr, files = _write(tmp_path, rows=1)
    text = files[0].read_bytes().decode("ascii")
    m = re.search(r"(P\[3\]\{\r\n   GP1:\r\n\tUF : 1, UT : 1,\t\r\n\tJ1=\s*\S+ deg,\tJ2=)(\s*\S+)( deg,\tJ3=)(\s*\S+)( deg)", text)
    new = m.group(1) + ls_number(-90.0) + m.group(3) + ls_number(-186.0) + m.group(5)   # (serial j3 = J3 + J2 = -276 deg)
    files[0].write_bytes(text.replace(m.group(0), new).encode("ascii"))
    found = POST.check(files[0], r, p)
    assert any("controller axis J3 = -186.0000 deg is beyond its limits" in f for f in found), found


@pytest.mark.parametrize("option,value,expect", [
    ("cnt", [10, 5], "options.cnt"), ("cnt_mm", [1.0, -1.0, 2.0, 3.0, 4.0, 5.0, 6.0], "options.cnt_mm"),
    ("utool", 0, "options.utool"), ("program_name_length", 40, "program_name_length"),
])
def test_bad_options_are_refused(tmp_path, option, value, expect):
    r = get_robot("m20ia")
    body = open(load_profile(None, "m20ia", "fanuc", r).source).read()
    body = re.sub(rf"^{option} = .*$", f"{option} = {value}", body, flags=re.M)
    f = tmp_path / "p.toml"
    f.write_text(body)
    with pytest.raises(BadInput, match=expect):
        load_profile(f, "m20ia", "fanuc", r)


def test_a_profile_without_max_speed_is_refused(tmp_path):
    r = get_robot("m20ia")
    body = open(load_profile(None, "m20ia", "fanuc", r).source).read().replace(", max_speed = 195.0", "")
    f = tmp_path / "p.toml"
    f.write_text(body)
    with pytest.raises(BadInput, match="axes.j1.max_speed: missing"):
        load_profile(f, "m20ia", "fanuc", r)


def test_a_called_program_that_is_a_fifo_is_a_finding_not_a_hang(tmp_path):
    import os

    r, p, tr, files = _write(tmp_path, lines_per_program=25)
    part = tmp_path / "CAMTOO_2.LS"
    part.unlink()
    os.mkfifo(part)
    found = POST.check(files[0], r, p)
    assert found and any("CAMTOO_2.LS" in f for f in found)
