"""`camtool check`: exit codes, --json, --format, and bad files that are findings, not crashes."""
import json
import re
from dataclasses import replace

import pytest
from click.testing import CliRunner

from camtool.cli import cli
from camtool.program.profiles import Profile
from camtool.program.profiles import default_options, load_profile
from camtool.robots import get_robot
from post_fixtures import smooth_trajectory
from test_post import CENTRES, rows_trajectory
from postprocessors.abb_rapid import RapidPost
from postprocessors.csv_joint import CsvPost
from postprocessors.yaskawa_inform import InformPost
from test_post_inform import sia20_profile_with_pulses


def _load_profile(tmp_path, robot_name, fmt, r, pulses=False):
    """The shipped profile; with ``pulses`` for the sia20's INFORM, the shipped one plus test pulse
    factors (the shipped one has none: every position is a ///RECTAN pose, so no position is in
    pulses)."""
    if pulses and (robot_name, fmt) == ("sia20", "inform"):
        return load_profile(sia20_profile_with_pulses(tmp_path), robot_name, fmt, r)
    return load_profile(None, robot_name, fmt, r)


def _smooth(r, n):
    """``smooth_trajectory``, moved for the sia20 to a posture away from its singularities
    (``CENTRES``): about mid-range the SIA20D is near straight, axes S and T nearly in line, where
    joint values read back by IK from ///RECTAN poses at 0.001 mm are ill-posed."""
    tr = smooth_trajectory(r, n)
    if r.name == "sia20":
        mid = (r.limits.lower + r.limits.upper) / 2
        tr = replace(tr, q=tr.q - mid + r.q_from_edge(CENTRES[r.name]))
    return tr


def _program(tmp_path, fmt, robot_name, n=20, pulses=False):
    r = get_robot(robot_name)
    if fmt == "csv":
        p = Profile("<t>", "csv", options=default_options("csv"))
    else:
        p = _load_profile(tmp_path, robot_name, fmt, r, pulses)
    post = {"rapid": RapidPost(), "inform": InformPost(), "csv": CsvPost()}[fmt]
    return post.write(_smooth(r, n), r, p, tmp_path)[0]


def _process_program(tmp_path, fmt, robot_name, **options):
    """A program of a raster-like trajectory (rows, leads, free motion)."""
    r = get_robot(robot_name)
    p = _load_profile(tmp_path, robot_name, fmt, r)
    if options:
        p = p.with_changes(options=options)
    post = {"rapid": RapidPost(), "inform": InformPost()}[fmt]
    return post.write(rows_trajectory(r, rows=2), r, p, tmp_path)[0]


def _check(f, *args):
    """``camtool check``, with the test-pulse profile a program beside it was written with."""
    prof = f.parent / "sia20_pulses_inform.toml"
    extra = ["--profile", prof] if prof.exists() and "--profile" not in args else []
    return CliRunner().invoke(cli, ["check", *map(str, (f, *args, *extra))])


@pytest.mark.parametrize("fmt,robot_name,moves", [("rapid", "seed8", 20), ("inform", "sia20", 20),
                                                  ("csv", "irb2400", 20)])
def test_json_of_a_clean_program(fmt, robot_name, moves, tmp_path):
    f = _program(tmp_path, fmt, robot_name)
    res = _check(f, "--robot", robot_name, "--json")
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["file"] == str(f) and out["format"] == fmt and out["robot"] == robot_name
    if fmt != "csv":  # moves merged, or the planned motion followed closer: count what the program holds
        text = "".join(g.read_text() for g in sorted(f.parent.glob("*.mod" if fmt == "rapid" else "*.JBI")))
        moves = len(re.findall(r"^\s*(?:MoveAbsJ|MoveL|MOVJ|MOVL) ", text, flags=re.M))
        # a run of MOVC lines is a move to the first, then an arc per circle point and end point
        moves += sum(1 + (len(run.splitlines()) - 1) // 2
                     for run in re.findall(r"(?:^MOVC [^\n]*\n?)+", text, flags=re.M))
    assert out["ok"] is True and out["findings"] == [] and out["moves"] == moves
    # the first move (from wherever the robot is) has no duration: the steps of the 8 s trajectory
    assert out["duration_s"] == pytest.approx(8.0, rel=0.01 if fmt == "inform" else 1e-3)
    assert set(out) == {"file", "format", "robot", "profile", "ok", "findings", "moves", "duration_s"}


def test_json_with_findings_exits_2(tmp_path):
    f = _program(tmp_path, "csv", "seed8")
    lines = f.read_text().splitlines()
    f.write_text("\n".join(lines[:-2]) + "\n")  # cut at a row boundary
    res = _check(f, "--robot", "seed8", "--json")
    assert res.exit_code == 2
    out = json.loads(res.stdout)
    assert out["ok"] is False and out["moves"] == 19
    assert any("no trailer" in x for x in out["findings"])


def test_json_of_an_unreadable_program_has_null_figures(tmp_path):
    f = _program(tmp_path, "inform", "sia20", pulses=True)
    # the first position stated in pulses (the MOVL positions are ///RECTAN poses)
    raw = f.read_bytes()
    spoilt = re.sub(rb"(?m)^(C\d{5})=-?\d+,", rb"\1=99999999999999999999,", raw, count=1)
    assert spoilt != raw
    f.write_bytes(spoilt)
    res = _check(f, "--robot", "sia20", "--json")
    assert res.exit_code == 2
    out = json.loads(res.stdout)
    assert out["ok"] is False and out["moves"] is None and out["duration_s"] is None
    assert any("pulse value 99999999999999999999 is beyond the int64 range" in x for x in out["findings"])


def test_jbi_pulse_beyond_int64_is_bad_input_not_an_internal_error(tmp_path):
    f = _program(tmp_path, "inform", "seed8")
    f.write_bytes(re.sub(rb"C00007=(-?\d+),", b"C00007=-9223372036854775809,", f.read_bytes()))
    res = _check(f, "--robot", "seed8")
    assert res.exit_code == 2, res.output
    assert "internal error" not in res.output
    assert any(ln.startswith(f"{f}:") and "pulse value -9223372036854775809 is beyond the int64 range" in ln
               for ln in res.stdout.splitlines())


@pytest.mark.parametrize("fmt,robot_name,old,new", [
    ("rapid", "irb2400", rb"\\T:=[0-9.]+, z", rb"\\T:=nan, z"),
    ("rapid", "irb2400", rb"MoveL \[\[[-0-9.]+,", rb"MoveL [[nan,"),
    ("rapid", "irb2400", rb"\], \[[0-9.]+,", rb"], [inf,"),
    ("rapid", "irb2400", rb"MoveAbsJ \[\[[-0-9.]+,", rb"MoveAbsJ [[inf,"),
    ("rapid", "irb2400", rb"tooldata camtool_tool:=\[TRUE,\[\[[-0-9.]+,", rb"tooldata camtool_tool:=[TRUE,[[nan,"),
    ("inform", "sia20", rb"VJ=[0-9.]+ PL=1\r\n", rb"VJ=nan PL=1\r\n"),
    ("inform", "sia20", rb"V=[0-9.]+ PL=", rb"V=inf PL="),
    ("csv", "seed8", rb"\n2\.", rb"\nnan,"),
    ("csv", "seed8", rb",-?[0-9.]+(e-?\d+)?\n", rb",inf\n"),
])
def test_nan_and_inf_fail_the_check(fmt, robot_name, old, new, tmp_path):
    f = _program(tmp_path, fmt, robot_name) if fmt == "csv" else _process_program(tmp_path, fmt, robot_name)
    target = f.with_suffix(".mod") if fmt == "rapid" else f  # the .pgf names the module
    raw = target.read_bytes()
    spoilt = re.sub(old, new, raw, count=1)
    assert spoilt != raw
    assert _check(f, "--robot", robot_name).exit_code == 0
    target.write_bytes(spoilt)
    res = _check(f, "--robot", robot_name)
    assert res.exit_code == 2, res.output
    assert res.stdout.strip() and "internal error" not in res.output


def test_truncated_programs_exit_2(tmp_path):
    for fmt, robot_name in (("rapid", "irb2400"), ("inform", "sia20"), ("csv", "irb2400")):
        d = tmp_path / fmt
        d.mkdir()
        f = _program(d, fmt, robot_name)
        target = f.with_suffix(".mod") if fmt == "rapid" else f
        sep = b"\r\n" if fmt == "inform" else b"\n"
        lines = target.read_bytes().split(sep)
        target.write_bytes(sep.join(lines[:len(lines) // 2]) + sep)
        res = _check(f, "--robot", robot_name)
        assert res.exit_code == 2, (fmt, res.output)


def test_format_option_and_unknown_extension(tmp_path):
    f = _program(tmp_path, "csv", "seed8")
    g = f.rename(f.with_suffix(".txt"))
    res = _check(g, "--robot", "seed8")
    assert res.exit_code == 2 and "unknown program type '.txt'" in res.output and "--format" in res.output
    res = _check(g, "--robot", "seed8", "--format", "csv")
    assert res.exit_code == 0, res.output
    res = _check(g, "--robot", "seed8", "--format", "gcode")
    assert res.exit_code == 2 and "no post-processor 'gcode'" in res.output
