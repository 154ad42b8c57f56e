"""The program checker: clean programs pass; each kind of defect is found."""
import re

import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.program.profiles import Profile
from camtool.program.profiles import default_options, load_profile
from camtool.robots import get_robot
from post_fixtures import profile_for_tests, smooth_trajectory, with_q
from test_post import rows_trajectory
from postprocessors.abb_rapid import RapidPost
from camtool.program.check_program import check_program
from postprocessors.csv_joint import CsvPost
from postprocessors.yaskawa_inform import InformPost
from postprocessors.fanuc import FanucPost
from postprocessors.krl import KrlPost


def _write(fmt, robot_name, tmp_path, n=40, cartesian=False, **options):
    """A program of a raster-like trajectory (rows with leads, free motion between them) of
    about n waypoints; joint moves only unless ``cartesian`` (the profile's own motion)."""
    r = get_robot(robot_name)
    if fmt != "csv" and not cartesian:
        options.setdefault("motion", "joint")
    if fmt == "csv":
        p = Profile("<t>", "csv", options=default_options("csv"))
    else:
        p = profile_for_tests(robot_name, fmt, r, tmp_path)
    if options:
        p = p.with_changes(options=options)
    post = {"rapid": RapidPost(), "inform": InformPost(), "csv": CsvPost()}[fmt]
    rows = max(1, n // 14)
    tr = smooth_trajectory(r, n) if fmt == "csv" else rows_trajectory(r, rows=rows, per_row=8, free=3)
    files = post.write(tr, r, p, tmp_path)
    return r, p, files


@pytest.mark.parametrize("fmt,robot_name", [("rapid", "seed8"), ("rapid", "irb2400"), ("inform", "seed8"),
                                            ("inform", "sia20"), ("csv", "seed8"), ("csv", "irb2400_paper")])
def test_written_programs_are_clean(fmt, robot_name, tmp_path):
    r, p, files = _write(fmt, robot_name, tmp_path, lines_per_module=20) if fmt == "rapid" else \
        _write(fmt, robot_name, tmp_path)
    for f in files:
        assert check_program(f, r, p) == [], f.name


@pytest.mark.parametrize("fmt,robot_name", [("rapid", "irb2400"), ("inform", "sia20")])
def test_written_cartesian_programs_are_clean(fmt, robot_name, tmp_path):
    r, p, files = _write(fmt, robot_name, tmp_path, n=60, cartesian=True)
    text = files[-1].read_bytes()
    assert (b"MoveL [[" if fmt == "rapid" else b"\r\nMOVL C") in text
    for f in files:
        assert check_program(f, r, p) == [], f.name


def _edit(path, old, new, count=1):
    data = path.read_bytes().decode("ascii")
    assert old in data
    path.write_bytes(data.replace(old, new, count).encode("ascii"))


def test_rapid_value_beyond_limits_is_flagged(tmp_path):
    r, p, files = _write("rapid", "irb2400", tmp_path)
    first = re.search(r"MoveAbsJ \[\[([-0-9.]+),", files[1].read_text()).group(1)
    _edit(files[1], f"[[{first},", "[[190.0000,")
    found = check_program(files[0], r, p)
    assert any("j1 = 190.0000 deg outside the limits -180.0000 deg .. 180.0000 deg" in f for f in found)
    assert all(re.match(r".+CAMTOOL\.mod:\d+: ", f) for f in found)


def test_rapid_too_short_duration_is_flagged(tmp_path):
    r, p, files = _write("rapid", "irb2400", tmp_path)
    t = re.findall(r"\\T:=([0-9.]+)", files[1].read_text())[5]
    _edit(files[1], f"\\T:={t}", "\\T:=0.0001")
    found = check_program(files[1], r, p)
    assert found and all("speed" in f and "above the limit" in f for f in found)


def test_rapid_structure_defects(tmp_path):
    r, p, files = _write("rapid", "seed8", tmp_path, n=8)
    text = files[1].read_text()
    files[1].write_text(text.replace(",9E9,", ",0.0000,", 1).replace("  ENDPROC\n", "  ENDPROC \n")
                        .replace(", fine, camtool_tool", ", z1, camtool_tool").replace("PERS wobjdata", "PERS wobj"))
    found = "\n".join(check_program(files[0], r, p))
    assert "is not connected (profile) and must be 9E9" in found
    assert "trailing white space" in found
    assert "the last move must be fine" in found
    assert "wobjdata 'camtool_wobj' is not declared" in found


def test_rapid_missing_split_module_is_flagged(tmp_path):
    r, p, files = _write("rapid", "irb2400", tmp_path, n=30, lines_per_module=20)
    files[3].unlink()
    found = "\n".join(check_program(files[0], r, p))
    assert "CAMTOOL_002.mod: cannot read" in found and "CAMTOOL_002_run" in found


def test_inform_value_beyond_limits_is_flagged(tmp_path):
    r, p, files = _write("inform", "sia20", tmp_path)
    line = next(ln for ln in files[0].read_bytes().decode().split("\r\n") if ln.startswith("C00003="))
    vals = line.split("=")[1].split(",")
    vals[0] = str(int(200 * 1435.27))  # s = 200 deg, limit 180
    _edit(files[0], line, "C00003=" + ",".join(vals))
    found = check_program(files[0], r, p)
    assert any("s = 200.0000 deg outside the limits" in f for f in found)


def test_inform_vj_never_exceeds_the_robot_even_with_a_faster_profile(tmp_path):
    """A profile whose max_speed is above the robot's limit: the writer caps VJ at what the
    robot allows, so the check stays clean; a VJ raised by hand is flagged."""
    r = get_robot("sia20")
    p = profile_for_tests("sia20", "inform", r, tmp_path).with_changes(options={"motion": "joint"})
    fast = p.with_changes()
    object.__setattr__(fast, "axes", tuple(a if a.joint != "t" else type(a)(**{**a.__dict__, "max_speed": 800.0})
                                           for a in p.axes))
    tr = smooth_trajectory(r, 40, duration_s=1.0, fraction=0.5)
    q = np.tile(tr.q[:1], (len(tr.q), 1))
    q[:, 6] = tr.q[:, 6]  # only t moves: it needs up to ~565 deg/s, its limit is 400
    tr = with_q(tr, q)
    f = InformPost().write(tr, r, fast, tmp_path)[0]
    assert check_program(f, r, fast) == []
    f.write_bytes(re.sub(rb"VJ=\d+\.\d\d PL=([1-8])", rb"VJ=100.00 PL=\1", f.read_bytes()))
    found = check_program(f, r, fast)
    assert any(re.search(r"t speed [0-9.]+ deg/s above the limit 400.00 deg/s", x) for x in found)


@pytest.mark.parametrize("old,new,message", [
    ("///NPOS 40,40,0,0,0,0", "///NPOS 41,40,0,0,0,0", "NPOS says 41 C positions, the file has 40"),
    ("C00007=", "C00070=", "C indices must be contiguous"),
    ("MOVJ C00005 BC00005", "MOVJ C00099 BC00005", "C00099 is not defined"),
    ("\r\nEND\r\n", "\r\n", "does not end with END"),
    ("BC00002=", "BC00002=1,", "BC lines have different numbers of values"),
    ("///GROUP1 RB1,BS1", "///GROUP1 RB1", "does not match the profile"),
    ("//NAME CAMTOOL", "//NAME CAMTOOLXX", "is not valid"),
    ("VJ=10.00", "VJ=0.00", "VJ=0.00 outside"),
])
def test_inform_structure_defects(old, new, message, tmp_path):
    r, p, files = _write("inform", "seed8", tmp_path)
    if old.startswith("///NPOS"):  # the counts of the file at hand
        line = next(ln for ln in files[0].read_bytes().decode().split("\r\n") if ln.startswith("///NPOS"))
        c = int(line.split()[1].split(",")[0])
        old, new = line, line.replace(f"NPOS {c},", f"NPOS {c + 1},", 1)
        message = f"NPOS says {c + 1} C positions, the file has {c}"
    _edit(files[0], old, new)
    found = check_program(files[0], r, p)
    assert any(message in f for f in found), found


def test_inform_line_ends_and_ascii(tmp_path):
    r, p, files = _write("inform", "sia20", tmp_path)
    raw = files[0].read_bytes()
    files[0].write_bytes(raw.replace(b"\r\n", b"\n"))
    assert any("CRLF" in f for f in check_program(files[0], r, p))
    files[0].write_bytes(raw.replace(b"NOP", "NÖP".encode("latin-1")))
    assert any("not ASCII" in f for f in check_program(files[0], r, p))


def test_inform_missing_called_job_is_flagged(tmp_path):
    r, p, files = _write("inform", "seed8", tmp_path, n=30, lines_per_job=20)
    files[2].unlink()
    assert any("CAMTOO_2.JBI: cannot read" in f for f in check_program(files[0], r, p))


def test_csv_defects(tmp_path):
    r, p, files = _write("csv", "seed8", tmp_path)
    lines = files[0].read_text().splitlines()
    cells = lines[5].split(",")
    cells[2] = "175.0"  # j2 beyond 170 deg
    lines[5] = ",".join(cells)
    files[0].write_text("\n".join(lines) + "\n")
    found = check_program(files[0], r, None)
    assert any(":6: j2 = 175.0000 deg outside the limits" in f for f in found)
    assert any(":6: j2 speed" in f for f in found)  # the jump is also far too fast
    files[0].write_text("\n".join([lines[0].replace("j2_deg", "j9_deg")] + lines[1:]) + "\n")
    assert any("expected j2_<unit>" in f for f in check_program(files[0], r, None))


def test_csv_time_must_increase(tmp_path):
    r, p, files = _write("csv", "irb2400", tmp_path)
    header, *rows = files[0].read_text().splitlines()
    rows[3], rows[4] = rows[4], rows[3]
    files[0].write_text("\n".join([header, *rows]) + "\n")
    assert any("move duration" in f and "not positive" in f for f in check_program(files[0], r, None))


def test_unknown_file_type_is_bad_input(tmp_path):
    f = tmp_path / "x.prg"
    f.write_text("DEF x()\nEND\n")
    with pytest.raises(BadInput, match="unknown program type"):
        check_program(f, get_robot("seed8"))


# --- each built-in owns its check; the helper module imports no plugin ---------------------------

@pytest.mark.parametrize("cls", [RapidPost, InformPost, CsvPost, KrlPost, FanucPost])
def test_each_builtin_plugin_owns_its_check(cls):
    """Each built-in checks its files itself, with the checker of its own package (next to its
    writer and reader): defined on the class, or its PackagedPost checker module."""
    from camtool.program.plugin import PackagedPost

    assert cls().own_check
    if issubclass(cls, PackagedPost):
        assert cls.checker.__name__ == f"{cls.__module__}.checker" and callable(cls.checker.check)
    else:
        assert "check" in vars(cls)


def test_the_check_helpers_import_no_plugin():
    import subprocess
    import sys
    code = ("import sys, camtool.program.check, camtool.program.check_program; "
            "print([m for m in sys.modules if m.startswith('postprocessors')])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_check_program_with_an_explicit_format(tmp_path):
    r, p, files = _write("csv", "seed8", tmp_path)
    other = files[0].with_suffix(".txt")
    files[0].rename(other)
    with pytest.raises(BadInput, match="unknown program type '.txt'"):
        check_program(other, r)
    assert check_program(other, r, fmt="csv") == []


# --- NaN and inf anywhere ----------------------------------------------------------------------

@pytest.mark.parametrize("bad", ["nan", "inf", "-inf", "1e999"])
def test_rapid_non_finite_joint_value_is_flagged(bad, tmp_path):
    r, p, files = _write("rapid", "irb2400", tmp_path)
    first = re.search(r"MoveAbsJ \[\[([-0-9.]+),", files[1].read_text()).group(1)
    _edit(files[1], f"[[{first},", f"[[{bad},")
    found = check_program(files[0], r, p)
    assert any("CAMTOOL.mod:" in f and ("malformed MoveAbsJ" in f or "finite" in f) for f in found), found


@pytest.mark.parametrize("data", ["tooldata", "wobjdata"])
@pytest.mark.parametrize("bad", ["nan", "-inf", "1e999"])
def test_rapid_non_finite_tool_or_work_object_is_flagged(data, bad, tmp_path):
    r, p, files = _write("rapid", "irb2400", tmp_path)
    text = files[1].read_text()
    line = next(ln for ln in text.splitlines() if f"PERS {data}" in ln)
    spoilt = re.sub(r"\[\[(-?[0-9.]+),", f"[[{bad},", line, count=1)
    assert spoilt != line
    files[1].write_text(text.replace(line, spoilt))
    found = check_program(files[0], r, p)
    assert any("holds a value that is not a finite number" in f for f in found), found


@pytest.mark.parametrize("bad", ["nan", "inf", "1e999"])
def test_rapid_non_finite_duration_is_flagged(bad, tmp_path):
    r, p, files = _write("rapid", "irb2400", tmp_path)
    t = re.findall(r"\\T:=([0-9.]+)", files[1].read_text())[5]
    _edit(files[1], f"\\T:={t}", f"\\T:={bad}")
    found = check_program(files[0], r, p)
    assert any("malformed MoveAbsJ" in f or "finite" in f for f in found), found


@pytest.mark.parametrize("old,new", [("C00003=", "C00003=nan,"), ("VJ=", "VJ=nan"), ("C00005=", "C00005=inf,")])
def test_inform_non_finite_values_are_flagged(old, new, tmp_path):
    r, p, files = _write("inform", "sia20", tmp_path)
    _edit(files[0], old, new)
    assert check_program(files[0], r, p)


@pytest.mark.parametrize("column", [0, 3])  # t_s, a joint
@pytest.mark.parametrize("bad", ["nan", "inf", "-inf", "1e999"])
def test_csv_non_finite_values_are_flagged(column, bad, tmp_path):
    r, p, files = _write("csv", "seed8", tmp_path)
    lines = files[0].read_text().splitlines()
    cells = lines[7].split(",")
    cells[column] = bad
    lines[7] = ",".join(cells)
    files[0].write_text("\n".join(lines) + "\n")
    found = check_program(files[0], r, None)
    assert any(":8: " in f and "not a finite number" in f for f in found), found


def test_motion_with_non_finite_values_is_flagged():
    from camtool.program.check import check_motion
    r = get_robot("irb2400")
    q = smooth_trajectory(r, 5).q
    where = [f"x:{k}" for k in range(5)]
    tol = np.full(r.dof, 1e-9)
    dur = np.array([np.nan, 0.5, 0.5, 0.5, 0.5])
    assert check_motion(q, dur, r, where, tol) == []
    q2 = q.copy()
    q2[2, 1] = np.nan
    assert check_motion(q2, dur, r, where, tol) == ["x:2: j2: value is not a finite number"]
    dur2 = dur.copy()
    dur2[3] = np.inf
    assert check_motion(q, dur2, r, where, tol) == ["x:3: move duration is not a finite number"]


# --- speeds against the ROBOT's limits ---------------------------------------------------------

def _derated(robot, factor):
    from dataclasses import replace
    return replace(robot, limits=replace(robot.limits, velocity=robot.limits.velocity * factor))


def test_inform_speed_is_checked_against_the_robot_not_the_profile(tmp_path):
    """With the shipped profile (max_speed = the library's limit), a robot with lower speed
    limits fails the VJ-timed moves: the limit comes from the robot given to the check."""
    r = get_robot("sia20")
    # joint moves: the fixture's sinusoid passes near the SIA20D's wrist-over-S singularity, where
    # MOVL would need unbounded S speeds (a real finding, not what this test is about)
    p = profile_for_tests("sia20", "inform", r, tmp_path).with_changes(options={"motion": "joint"})
    f = InformPost().write(smooth_trajectory(r, 40, duration_s=4.0), r, p, tmp_path)[0]
    assert check_program(f, r, p) == []
    found = check_program(f, _derated(r, 0.5), p)
    assert found and all("above the limit" in f or "more steps above" in f for f in found)
    assert any(re.search(r"speed [0-9.]+ deg/s above the limit [0-9.]+ deg/s", f) for f in found)


def test_inform_vj_at_100_with_a_faster_controller_is_flagged(tmp_path):
    """A profile with the controller's real max_speed above the robot's limit: VJ=100.00 moves
    run faster than the robot allows."""
    r, p, files = _write("inform", "sia20", tmp_path, n=20)
    text = files[0].read_bytes().decode()
    fast = p.with_changes()
    object.__setattr__(fast, "axes", tuple(type(a)(**{**a.__dict__, "max_speed": a.max_speed * 1.5})
                                           for a in p.axes))
    files[0].write_bytes(re.sub(r"VJ=\d+\.\d\d", "VJ=100.00", text).encode())
    assert check_program(files[0], r, p) == []  # at VJ 100 % of the robot's own limit: allowed
    found = check_program(files[0], r, fast)
    assert any("above the limit" in f for f in found)


def test_speed_tolerance_is_small(tmp_path):
    """0.1 % over the robot's limit passes, 1 % does not (CSV timing is exact)."""
    r = get_robot("irb2400")
    p = Profile("<t>", "csv", options=default_options("csv"))
    tr = smooth_trajectory(r, 3)
    v = r.limits.velocity[0]
    for factor, ok in ((1.0005, True), (1.01, False)):
        q = np.tile(tr.q[:1], (3, 1))
        q[1:, 0] += np.array([1.0, 2.0]) * v * 0.1 * factor  # 0.1 s per step
        f = CsvPost().write(with_q(tr, q, np.array([0.0, 0.1, 0.2])), r, p, tmp_path)[0]
        assert (check_program(f, r, None) == []) is ok


# --- truncated files ---------------------------------------------------------------------------

def _cuts(data: bytes, sep: bytes):
    """Every prefix of ``data`` that ends at a line boundary, and a few that end mid-line."""
    ends = [i + len(sep) for i in range(len(data)) if data.startswith(sep, i)][:-1]
    return ends + [len(data) - 1, len(data) // 2 + 3, len(data) // 3 + 1]


@pytest.mark.parametrize("fmt,robot_name,which", [("rapid", "seed8", 0), ("rapid", "seed8", 1), ("rapid", "irb2400", 1),
                                                  ("rapid", "irb2400", 3), ("inform", "seed8", 0),
                                                  ("inform", "sia20", 0), ("inform", "seed8", 2),
                                                  ("csv", "seed8", 0), ("csv", "irb2400", 0)])
def test_every_truncated_file_is_flagged(fmt, robot_name, which, tmp_path):
    split = {"rapid": dict(lines_per_module=20), "inform": dict(lines_per_job=20)}.get(fmt, {}) if which else {}
    r, p, files = _write(fmt, robot_name, tmp_path, n=40 if which else 20, **split)
    assert len(files) > which
    p = None if fmt == "csv" else p
    assert check_program(files[0], r, p) == []
    target = files[which]
    data = target.read_bytes()
    for cut in _cuts(data, b"\r\n" if fmt == "inform" else b"\n"):
        target.write_bytes(data[:cut])
        assert check_program(files[0], r, p), f"{target.name} cut at byte {cut} passed"
    target.write_bytes(data)
    assert check_program(files[0], r, p) == []


def test_truncated_rapid_module_names_the_missing_end(tmp_path):
    r, p, files = _write("rapid", "irb2400", tmp_path, n=10)
    lines = files[1].read_text().splitlines()
    files[1].write_text("\n".join(lines[:-4]) + "\n")
    found = "\n".join(check_program(files[0], r, p))
    assert "PROC without ENDPROC" in found and "does not end with ENDMODULE" in found


def test_truncated_inform_job_names_npos_and_end(tmp_path):
    r, p, files = _write("inform", "sia20", tmp_path, n=10)
    lines = files[0].read_bytes().decode().split("\r\n")
    c = int(next(ln for ln in lines if ln.startswith("///NPOS")).split()[1].split(",")[0])
    cut = next(i for i, ln in enumerate(lines) if ln.startswith("C00006="))
    files[0].write_bytes(("\r\n".join(lines[:cut]) + "\r\n").encode())
    found = "\n".join(check_program(files[0], r, p))
    assert f"NPOS says {c} C positions, the file has 6" in found and "does not end with END" in found


def test_truncated_csv_names_the_trailer(tmp_path):
    r, p, files = _write("csv", "seed8", tmp_path, n=10)
    lines = files[0].read_text().splitlines()
    assert lines[-1] == "# END 10 rows"
    files[0].write_text("\n".join(lines[:-3]) + "\n")
    assert any("no trailer '# END 8 rows'" in f for f in check_program(files[0], r, None))
    files[0].write_text("\n".join(lines[:5] + lines[6:]) + "\n")  # a row lost in the middle
    assert any("the trailer says 10 rows, the file has 9" in f for f in check_program(files[0], r, None))


# --- unreadable values -------------------------------------------------------------------------

def test_jbi_pulse_beyond_int64_is_a_finding_and_bad_input_when_read(tmp_path):
    r, p, files = _write("inform", "sia20", tmp_path, n=10)
    line = next(ln for ln in files[0].read_bytes().decode().split("\r\n") if ln.startswith("C00004="))
    vals = line.split("=")[1].split(",")
    vals[2] = str(2 ** 63)
    _edit(files[0], line, "C00004=" + ",".join(vals))
    found = check_program(files[0], r, p)
    assert any(f"CAMTOOL.JBI:{12}: pulse value {2 ** 63} is beyond the int64 range" in f for f in found), found
    with pytest.raises(BadInput, match="beyond the int64 range"):
        InformPost().read(files[0], r, p)
    vals[2] = str(2 ** 63 - 1)  # the largest int64 reads; it is just far outside the limits
    _edit(files[0], f"C00004={','.join(vals[:2])},{2 ** 63}", f"C00004={','.join(vals[:2])},{2 ** 63 - 1}")
    assert any("outside the limits" in f for f in check_program(files[0], r, p))


def test_row_markers_out_of_pair_are_findings_across_files():
    from camtool.program.check import row_marker_findings

    out, open_row = row_marker_findings("A.mod", [("row", 3), ("move", 4), ("row", 5)], None)
    assert out == ["A.mod:5: a row starts before the previous one ended"] and open_row == 5
    out, open_row = row_marker_findings("B.mod", [("end_row", 2), ("end_row", 7)], open_row)
    assert out == ["B.mod:7: a row ends that never started"] and open_row is None
