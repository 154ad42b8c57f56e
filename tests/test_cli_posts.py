"""`camtool posts` and `camtool check` from the command line."""
import json
import re

from click.testing import CliRunner

from camtool.cli import cli
from camtool.program.profiles import default_profile_path
from camtool.program.profiles import load_profile
from camtool.robots import get_robot
from post_fixtures import profile_for_tests, smooth_trajectory
from postprocessors.abb_rapid import RapidPost
from postprocessors.yaskawa_inform import InformPost


def test_posts_lists_the_builtins():
    res = CliRunner().invoke(cli, ["posts"])
    assert res.exit_code == 0
    for line in ("rapid    .mod", "inform   .JBI", "csv      .csv", "lines_per_module", "angle_unit"):
        assert line in res.output


def test_posts_json():
    res = CliRunner().invoke(cli, ["posts", "--json"])
    rows = {r["name"]: r for r in json.loads(res.output)}
    assert rows["inform"]["source"] == "camtool"
    assert rows["inform"]["options"]["pl"] == {"type": "int", "default": 0,
                                               "doc": rows["inform"]["options"]["pl"]["doc"]}


def _program(tmp_path, fmt, robot_name):
    r = get_robot(robot_name)
    p = profile_for_tests(robot_name, fmt, r, tmp_path)
    post = RapidPost() if fmt == "rapid" else InformPost()
    return post.write(smooth_trajectory(r, 20), r, p, tmp_path)[0]


def test_check_clean_program_exits_0(tmp_path):
    f = _program(tmp_path, "rapid", "seed8")
    res = CliRunner().invoke(cli, ["check", str(f), "--robot", "seed8"])
    assert res.exit_code == 0, res.output
    assert res.stdout == ""


def test_check_with_findings_exits_2_one_line_each(tmp_path):
    f = _program(tmp_path, "inform", "sia20")
    raw = f.read_bytes()
    n = int(re.search(rb"///NPOS (\d+),", raw).group(1))
    f.write_bytes(raw.replace(b"///NPOS %d," % n, b"///NPOS %d," % (n + 1), 1))
    res = CliRunner().invoke(cli, ["check", str(f), "--robot", "sia20"])
    assert res.exit_code == 2
    lines = res.stdout.splitlines()
    assert any(f"NPOS says {n + 1} C positions" in ln for ln in lines)
    assert all(ln.startswith(str(f)) for ln in lines)


def test_check_with_an_explicit_profile(tmp_path):
    f = _program(tmp_path, "inform", "seed8")
    prof = tmp_path / "p.toml"
    shipped = default_profile_path("seed8", "inform").read_text()
    prof.write_text(shipped.replace("pulses = 1341.380", "pulses = 2000.0"))
    res = CliRunner().invoke(cli, ["check", str(f), "--robot", "seed8", "--profile", str(prof)])
    assert res.exit_code == 0  # different pulses: other joint values, still inside the limits
    prof.write_text(prof.read_text().replace("pulses = 2000.0", "pulses = 100.0"))
    res = CliRunner().invoke(cli, ["check", str(f), "--robot", "seed8", "--profile", str(prof)])
    assert res.exit_code == 2 and "j2 = " in res.stdout


def test_check_bad_usage_is_one_line(tmp_path):
    res = CliRunner().invoke(cli, ["check", str(tmp_path / "nothing.mod"), "--robot", "seed8"])
    assert res.exit_code == 2 and "program file not found" in res.output
    res = CliRunner().invoke(cli, ["check", str(tmp_path / "x.mod"), "--robot", "irb2400_paper"])
    assert res.exit_code == 2 and "no default rapid profile for robot 'irb2400_paper'" in res.output
