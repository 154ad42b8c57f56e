"""ABB RAPID writer and reader: round trips, splitting, names, grammar (rapidchecker), determinism."""
import importlib.util
import re
import subprocess
import sys

import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.profiles import load_profile, parse_profile
from camtool.robots import get_robot
from post_fixtures import smooth_trajectory
from postprocessors.abb_rapid import RESERVED, RapidPost, fmt_t, parse_module, rapid_identifier

POST = RapidPost()


def _setup(robot_name, **options):
    r = get_robot(robot_name)
    p = load_profile(None, robot_name, "rapid", r)
    return r, (p.with_changes(options=options) if options else p)


@pytest.mark.parametrize("robot_name", ["seed8", "irb2400"])
def test_round_trip_every_shipped_profile(robot_name, tmp_path):
    r, p = _setup(robot_name)
    tr = smooth_trajectory(r, 120)
    files = POST.write(tr, r, p, tmp_path)
    assert [f.suffix for f in files] == [".pgf", ".mod"]
    dur, q = POST.read(files[0], r, p)
    assert q.shape == tr.q.shape
    err = np.abs(q - tr.q)
    assert np.all(np.degrees(err[:, ~r.prismatic]) <= 0.5e-4 + 1e-9)  # written to 1e-4 deg
    assert np.all(err[:, r.prismatic] <= 0.5e-3 + 1e-9)  # written to 1e-3 mm
    assert np.isnan(dur[0])  # the first move comes from wherever the robot is
    dt = np.diff(tr.t_s)
    assert np.all(dur[1:] >= dt - 1e-12) and np.all(dur[1:] - dt < 1e-4 + 1e-12)  # \T rounded up to 0.1 ms


def test_move_lines_and_unconnected_axes(tmp_path):
    r, p = _setup("seed8")
    files = POST.write(smooth_trajectory(r, 10), r, p, tmp_path)
    text = files[1].read_text()
    moves = [ln.strip() for ln in text.splitlines() if ln.strip().startswith("MoveAbsJ")]
    assert len(moves) == 10
    assert "\\T:=" not in moves[0] and ", v100, fine," in moves[0]
    assert all(re.search(r", v1000 \\T:=\d+\.\d{4}, z1, camtool_tool \\WObj:=camtool_wobj;$", m) for m in moves[1:-1])
    assert ", fine, camtool_tool" in moves[-1]
    # eax_a = track (mm), eax_b = j4 (deg), eax_c..f not connected
    eax = re.search(r"\],\[([^\]]*)\]\]", moves[3]).group(1).split(",")
    assert eax[2:] == ["9E9"] * 4 and "9E9" not in eax[:2]
    assert re.fullmatch(r"-?\d+\.\d{3}", eax[0]) and re.fullmatch(r"-?\d+\.\d{4}", eax[1])
    assert "PERS tooldata camtool_tool:=[TRUE," in text and "PERS wobjdata camtool_wobj:=[FALSE,TRUE," in text
    assert files[0].read_text().count("<Module>CAMTOOL.mod</Module>") == 1


def test_long_program_is_split_into_modules(tmp_path):
    r, p = _setup("irb2400", lines_per_module=25)
    tr = smooth_trajectory(r, 60)
    files = POST.write(tr, r, p, tmp_path)
    assert [f.name for f in files] == ["CAMTOOL.pgf", "CAMTOOL.mod", "CAMTOOL_001.mod", "CAMTOOL_002.mod",
                                       "CAMTOOL_003.mod"]
    main = parse_module(files[1])
    assert main.problems == [] and main.moves == [] and main.procs == ["main"]
    assert [c for _n, c in main.calls] == ["CAMTOOL_001_run", "CAMTOOL_002_run", "CAMTOOL_003_run"]
    assert [len(parse_module(f).moves) for f in files[2:]] == [25, 25, 10]
    dur, q = POST.read(files[0], r, p)  # the reader follows the Loads
    assert np.degrees(np.abs(q - tr.q)).max() <= 0.5e-4 + 1e-9
    assert np.isnan(dur[0]) and not np.isnan(dur[25])  # continuity across modules


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
    r, p = _setup("seed8", lines_per_module=30)
    tr = smooth_trajectory(r, 70)
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a = [f.read_bytes() for f in POST.write(tr, r, p, tmp_path / "a")]
    b = [f.read_bytes() for f in POST.write(tr, r, p, tmp_path / "b")]
    assert a == b and len(a) == 5


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
    r, p = _setup("seed8", lines_per_module=6)
    files = POST.write(smooth_trajectory(r, 12), r, p, tmp_path)
    unsplit = POST.write(smooth_trajectory(r, 8), r, p.with_changes(program_name="Single"), tmp_path)
    for f in (files[1], files[2], unsplit[1]):
        res = _rapidchecker(f, tmp_path)
        assert res.returncode == 0, f"{f.name}: {res.stdout}"


@needs_rapidchecker
def test_rapidchecker_rejects_a_broken_module(tmp_path):
    """Makes sure the grammar check above can fail: bad indentation and a lowercase keyword."""
    r, p = _setup("irb2400")
    f = POST.write(smooth_trajectory(r, 4), r, p, tmp_path)[1]
    f.write_text(f.read_text().replace("  PROC main()", " proc main()"))
    assert _rapidchecker(f, tmp_path).returncode != 0
