"""``camtool design`` end to end on the seed sphere job with tiny settings."""
import json

import pytest
from click.testing import CliRunner

from camtool.cli import cli as group
from camtool.job import load_job

from conftest import SAMPLES

LIGHT = ("--set", "workpiece.sample_points=20000", "--set", "raster.step_over_mm=20",
         "--set", "raster.pitch_mm=10")
TINY = ("--particles", "4", "--explore-iters", "1", "--iters", "1", "--max-checks", "3", *LIGHT)


def invoke(*args):
    return CliRunner().invoke(group, [str(a) for a in args], catch_exceptions=False)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    out = tmp_path_factory.mktemp("design")
    args = ("design", SAMPLES / "sphere.toml", "--vary", "L1=400:600", "--vary", "L3=300:500", *TINY,
            "--seed", "3", "--json")
    a = invoke(*args, "-o", out / "a")
    b = invoke(*args, "-o", out / "b")
    return out, a, b


def test_design_json_and_files(runs):
    out, a, _ = runs
    assert a.exit_code == 0, a.output
    d = json.loads(a.output)
    assert d["evaluations"] == 4 * (1 + 1 + 1)
    assert d["planner_runs"] >= d["designs_planned"] > 0
    assert set(d["narrowed"]) == {"L1", "L3"}
    for n, (lo, hi) in d["narrowed"].items():
        assert d["variables"][n][0] <= lo < hi <= d["variables"][n][1]
    assert d["front"] and all(row["singularities"] >= 0 for row in d["front"])
    c = d["chosen"]
    assert c["full"]["unreachable"] == 0 and c["full"]["valid"]
    assert c["full"]["length_mm"] == pytest.approx(c["design"]["L1"] + c["design"]["L3"] + 400 + 150)
    assert d["reference"]["design"] == {"L1": 480.0, "L3": 418.0}
    assert d["reference"]["full"]["valid"]
    for name in ("design_space.png", "pareto_front.png", "chosen_job.toml", "chosen_robot.toml", "design.json"):
        assert (out / "a" / name).stat().st_size > 0
    assert (out / "a" / "design_space.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_same_seed_same_result(runs):
    _, a, b = runs
    da, db = json.loads(a.output), json.loads(b.output)
    for k in ("wall_s", "plan_s", "files"):
        da.pop(k), db.pop(k)
    assert da == db


def test_chosen_job_runs(runs, tmp_path):
    out, a, _ = runs
    chosen = json.loads(a.output)["chosen"]["design"]
    job = load_job(out / "a" / "chosen_job.toml")
    assert job.robot.params["L1"] == chosen["L1"] and job.robot.params["L3"] == chosen["L3"]
    assert job.resolve(job.workpiece.file).is_file()
    r = invoke("run", out / "a" / "chosen_job.toml", "-o", tmp_path / "run", "--set", 'post.formats=["csv"]',
               "--json")
    assert r.exit_code == 0, r.output
    report = json.loads(r.output)
    assert report["status"] == "ok" and report["retracts"] + report["reverse_plans"] == 0


@pytest.mark.parametrize("args, message", [
    (("--vary", "X=1:2"), "has no parameter 'X'"),
    (("--vary", "L1=500:500"), "empty range"),
    (("--vary", "L1=600:300"), "empty range"),
    (("--vary", "L1"), "expected NAME=LO:HI"),
    (("--particles", "1"), "--particles"),
    (("--coarse", "0"), "--coarse"),
])
def test_bad_input_one_line_exit_2(args, message, tmp_path):
    r = invoke("design", SAMPLES / "sphere.toml", *args, "-o", tmp_path)
    assert r.exit_code == 2
    assert message in r.output
    assert len(r.output.strip().splitlines()) == 1


def test_no_valid_design_exit_3(tmp_path):
    r = invoke("design", SAMPLES / "sphere.toml", "--vary", "L1=100:150", "--vary", "L3=100:150", *TINY,
               "-o", tmp_path)
    assert r.exit_code == 3
    assert "no design reaches every point" in r.output
    d = json.loads((tmp_path / "design.json").read_text())
    assert d["chosen"] is None and d["front"] == [] and d["invalid_designs"] > 0
