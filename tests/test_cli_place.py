"""``camtool place`` end to end: the sample patch moved 150 mm higher (out of reach), coarse raster."""
import json

import pytest
from click.testing import CliRunner

from camtool.cli import cli as group
from camtool.commands import place
from camtool.job import load_job
from camtool.run.job_settings import JobSettings
from camtool.run.stages import path_for_job, plan_for_job, robot_for_job, surface_for_job, workpiece_for_job

from conftest import SAMPLES

if "place" not in group.commands:  # until camtool/cli.py registers it
    group.add_command(place.command)

COARSE = ("--set", "workpiece.sample_points=20000", "--set", "raster.step_over_mm=40",
          "--set", "raster.pitch_mm=20")
HIGH = ("--set", "cell.workpiece_xyz_mm=[1000,0,250]")


def invoke(*args):
    return CliRunner().invoke(group, [str(a) for a in args], catch_exceptions=False)


@pytest.fixture(scope="module")
def placed(tmp_path_factory):
    out = tmp_path_factory.mktemp("place")
    r = invoke("place", SAMPLES / "sphere.toml", *HIGH, *COARSE, "--vary", "x=-200:100", "--vary", "z=-250:50",
               "--grid", 64, "--verify", 1, "--seed", 1, "-o", out, "--json")
    return out, r


def test_place_finds_a_feasible_placement(placed):
    out, r = placed
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    user = d["user"]
    assert not user["screen"]["feasible"] and not user["planned"]["ok"] and user["planned"]["unreachable"] > 0
    c = d["chosen"]
    assert c["planned"]["ok"] and c["planned"]["unreachable"] == 0 and c["planned"]["cycle_s"] > 0
    assert c["screen"]["feasible"] and c["screen"]["reach_used"] < 1
    assert -200 <= c["offset"]["dx_mm"] <= 100 and -250 <= c["offset"]["dz_mm"] <= 50
    assert c["offset"]["dy_mm"] == 0 and c["offset"]["dyaw_deg"] == 0
    assert c["workpiece_xyz_mm"] == pytest.approx([1000 + c["offset"]["dx_mm"], 0, 250 + c["offset"]["dz_mm"]])
    assert d["ranked"] and d["ranked"][0]["rank"] == 1 and d["screen"]["feasible"] > 0
    assert d["screen"]["grid_placements"] <= 64
    # the work feed: expected by the screen, held by the planned run (its timing's median), weighed in the cost
    assert 0 < c["screen"]["feed_mm_s"] <= 100.0 and 0 < c["planned"]["feed_mm_s"] <= 100.0 * 1.001
    assert c["planned"]["feed_share"] == pytest.approx(c["planned"]["feed_mm_s"] / 100.0, abs=1e-4)
    assert d["cost"]["feed_weight"] == 3.0
    for name in ("placed_job.toml", "feasible_region.png", "placement.json"):
        assert (out / name).stat().st_size > 0
    assert (out / "feasible_region.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert json.loads((out / "placement.json").read_text())["chosen"] == c


def test_placed_job_plans_with_every_pose_reachable(placed):
    out, r = placed
    job = load_job(out / "placed_job.toml")
    d = json.loads(r.output)
    assert job.cell.workpiece_xyz_mm == pytest.approx(d["chosen"]["workpiece_xyz_mm"])
    assert job.raster.step_over_mm == 40  # the --set overrides are kept
    robot = robot_for_job(job)
    wp = workpiece_for_job(job)
    path = path_for_job(job, surface_for_job(job, wp))
    jp = plan_for_job(JobSettings.from_job(job, robot), path, robot, wp)  # PlanInfeasible if any pose is out of reach
    assert jp.reached[jp.path_index >= 0].all()


@pytest.mark.parametrize("args", [("--vary", "w=0:1"), ("--vary", "x=5:1"), ("--vary", "x=0:1", "--vary", "x=1:2"),
                                  ("-j", "0"), ("--reach-margin", "0"), ("--feed-weight", "-1"),
                                  ("--feed-weight", "nan")])
def test_bad_options_exit_2(args):
    r = invoke("place", SAMPLES / "sphere.toml", *args)
    assert r.exit_code == 2


def test_other_task_kinds_are_refused():
    r = invoke("place", SAMPLES / "sia20_wall.toml", "--vary", "x=-10:10")
    assert r.exit_code == 2 and "raster jobs" in r.output


def _strip(d):
    """The summary without timings and file names (they differ between runs)."""
    for k in ("wall_s", "plan_seconds", "files", "processes"):
        d.pop(k, None)
    d["screen"].pop("seconds", None)
    for p in d["planned"]:
        p.pop("seconds", None)
    for e in d["ranked"] + [d["user"], d["chosen"]]:
        if e and e["planned"]:
            e["planned"].pop("seconds", None)
    return d


def test_same_seed_same_result_with_two_processes(placed, tmp_path):
    _, a = placed
    b = invoke("place", SAMPLES / "sphere.toml", *HIGH, *COARSE, "--vary", "x=-200:100", "--vary", "z=-250:50",
               "--grid", 64, "--verify", 1, "--seed", 1, "-j", 2, "-o", tmp_path, "--json")
    assert b.exit_code == 0, b.output
    assert _strip(json.loads(a.output)) == _strip(json.loads(b.output))
