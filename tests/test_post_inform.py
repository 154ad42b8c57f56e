"""Yaskawa INFORM writer and reader: pulses, layout, VJ, splitting, names, bad profiles."""
import re

import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.profiles import load_profile
from camtool.robots import get_robot
from post_fixtures import smooth_trajectory, with_q
from postprocessors.yaskawa_inform import InformPost, job_name, parse_jbi, vj_percent

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


def _profile(robot_name, tmp_path, **options):
    r = get_robot(robot_name)
    if robot_name == "irb2400":
        f = tmp_path / "irb2400_inform.toml"
        f.write_text(IRB2400_PROFILE)
        p = load_profile(f, "irb2400", "inform", r)
    else:
        p = load_profile(None, robot_name, "inform", r)
    return r, (p.with_changes(options=options) if options else p)


@pytest.mark.parametrize("robot_name", ["seed8", "sia20", "irb2400"])
def test_round_trip_within_one_pulse(robot_name, tmp_path):
    r, p = _profile(robot_name, tmp_path)
    tr = smooth_trajectory(r, 150)
    files = POST.write(tr, r, p, tmp_path)
    dur, q = POST.read(files[0], r, p)
    assert q.shape == tr.q.shape
    written, back = POST.to_pulses(p, r, tr.q), POST.to_pulses(p, r, q)
    for g in written:
        assert np.abs(written[g] - back[g]).max() <= 1
    for a in p.axes:  # and in joint units: within one pulse
        i = r.joint_names.index(a.joint)
        err = np.abs(q[:, i] - tr.q[:, i])
        err = err if r.prismatic[i] else np.degrees(err)
        assert err.max() <= 1.0 / a.pulses + 1e-12


def test_seed8_layout(tmp_path):
    r, p = _profile("seed8", tmp_path)
    files = POST.write(smooth_trajectory(r, 30), r, p, tmp_path)
    raw = files[0].read_bytes()
    raw.decode("ascii")
    assert raw.count(b"\r\n") == raw.count(b"\n") and raw.endswith(b"END\r\n")
    lines = raw.decode().split("\r\n")[:-1]
    assert lines[:8] == ["/JOB", "//NAME CAMTOOL", "//POS", "///NPOS 30,30,0,0,0,0", "///TOOL 0",
                         "///POSTYPE PULSE", "///PULSE", lines[7]]
    c = [ln for ln in lines if ln.startswith("C0")]
    bc = [ln for ln in lines if ln.startswith("BC")]
    assert len(c) == 30 and len(bc) == 30
    assert all(len(ln.split("=")[1].split(",")) == 7 for ln in c)
    assert all(len(ln.split("=")[1].split(",")) == 1 for ln in bc)
    for needed in ("//INST", "///DATE 2000/01/01 00:00", "///ATTR SC,RW", "///GROUP1 RB1,BS1", "NOP"):
        assert needed in lines
    moves = [ln for ln in lines if ln.startswith("MOVJ")]
    assert moves[0] == "MOVJ C00000 BC00000 VJ=10.00 PL=0"
    assert all(re.fullmatch(r"MOVJ C\d{5} BC\d{5} VJ=\d+\.\d{2} PL=0", m) for m in moves)
    assert parse_jbi(files[0]).problems == []


def test_sia20_uses_rb1_alone(tmp_path):
    r, p = _profile("sia20", tmp_path)
    text = POST.write(smooth_trajectory(r, 12), r, p, tmp_path)[0].read_bytes().decode()
    assert "///GROUP1 RB1\r\n" in text and "BC0" not in text and "///NPOS 12,0,0,0,0,0" in text


def test_vj_formula():
    # axis 0 needs 10 deg in 0.5 s at vmax 100 deg/s -> 20 %; axis 1 needs 5 mm at 500 mm/s -> 2 %
    assert vj_percent(np.array([10.0, -5.0]), 0.5, np.array([100.0, 500.0])) == 20.0
    assert vj_percent(np.array([1.0]), 1.0, np.array([300.0])) == 0.33  # 0.333.. rounded down
    assert vj_percent(np.array([0.0]), 1.0, np.array([100.0])) == 0.01
    assert vj_percent(np.array([500.0]), 1.0, np.array([100.0])) == 100.0


def test_vj_reproduces_the_timing(tmp_path):
    r, p = _profile("sia20", tmp_path)
    tr = smooth_trajectory(r, 60, duration_s=4.0)
    dur, _q = POST.read(POST.write(tr, r, p, tmp_path)[0], r, p)
    ratio = dur[1:] / np.diff(tr.t_s)
    assert ratio.min() > 0.98 and np.median(ratio) < 1.02  # never much faster; about right


def test_long_job_is_split_with_a_main_job(tmp_path):
    r, p = _profile("seed8", tmp_path, lines_per_job=40)
    tr = smooth_trajectory(r, 100)
    files = POST.write(tr, r, p.with_changes(program_name="sphere"), tmp_path)
    assert [f.name for f in files] == ["SPHERE.JBI", "SPHERE_1.JBI", "SPHERE_2.JBI", "SPHERE_3.JBI"]
    main = parse_jbi(files[0])
    assert main.problems == [] and [c for _n, c in main.calls] == ["SPHERE_1", "SPHERE_2", "SPHERE_3"]
    for f, n in zip(files[1:], (40, 40, 20)):
        j = parse_jbi(f)
        assert j.problems == [] and j.npos[:2] == [n, n] and len(j.moves) == n
    _dur, q = POST.read(files[0], r, p)
    assert q.shape == tr.q.shape


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
    r, p = _profile("seed8", tmp_path, lines_per_job=30)
    tr = smooth_trajectory(r, 70)
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a = [f.read_bytes() for f in POST.write(tr, r, p, tmp_path / "a")]
    b = [f.read_bytes() for f in POST.write(with_q(tr, tr.q.copy()), r, p, tmp_path / "b")]
    assert a == b and len(a) == 4
