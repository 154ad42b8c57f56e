"""The program checker: clean programs pass; each kind of defect is found."""
import re

import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.profiles import Profile, default_options, load_profile
from camtool.robots import get_robot
from post_fixtures import smooth_trajectory, with_q
from postprocessors.abb_rapid import RapidPost
from postprocessors.check import check_program
from postprocessors.csv_joint import CsvPost
from postprocessors.yaskawa_inform import InformPost


def _write(fmt, robot_name, tmp_path, n=40, **options):
    r = get_robot(robot_name)
    if fmt == "csv":
        p = Profile("<t>", "csv", options=default_options("csv"))
    else:
        p = load_profile(None, robot_name, fmt, r)
    if options:
        p = p.with_changes(options=options)
    post = {"rapid": RapidPost(), "inform": InformPost(), "csv": CsvPost()}[fmt]
    files = post.write(smooth_trajectory(r, n), r, p, tmp_path)
    return r, p, files


@pytest.mark.parametrize("fmt,robot_name", [("rapid", "seed8"), ("rapid", "irb2400"), ("inform", "seed8"),
                                            ("inform", "sia20"), ("csv", "seed8"), ("csv", "irb2400_paper")])
def test_written_programs_are_clean(fmt, robot_name, tmp_path):
    r, p, files = _write(fmt, robot_name, tmp_path, lines_per_module=15) if fmt == "rapid" else \
        _write(fmt, robot_name, tmp_path)
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
    r, p, files = _write("rapid", "irb2400", tmp_path, n=30, lines_per_module=10)
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


def test_inform_vj_above_the_speed_limit_is_flagged(tmp_path):
    r = get_robot("sia20")
    p = load_profile(None, "sia20", "inform", r)
    fast = p.with_changes()
    object.__setattr__(fast, "axes", tuple(a if a.joint != "t" else type(a)(**{**a.__dict__, "max_speed": 800.0})
                                           for a in p.axes))
    tr = smooth_trajectory(r, 40, duration_s=1.0, fraction=0.5)
    q = np.tile(tr.q[:1], (len(tr.q), 1))
    q[:, 6] = tr.q[:, 6]  # only t moves: it needs up to ~565 deg/s, its limit is 400
    tr = with_q(tr, q)
    f = InformPost().write(tr, r, fast, tmp_path)[0]
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
    r, p, files = _write("inform", "seed8", tmp_path, n=30, lines_per_job=10)
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
    f = tmp_path / "x.src"
    f.write_text("DEF x()\nEND\n")
    with pytest.raises(BadInput, match="unknown program type"):
        check_program(f, get_robot("seed8"))
