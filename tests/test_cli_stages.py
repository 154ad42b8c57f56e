"""Stage commands: fit, raster, plan, time and post resumed from saved files reproduce `camtool run`."""
import filecmp
import json
from pathlib import Path

from conftest import SAMPLES, run_camtool

SMALL = ["--set", "raster.step_over_mm=60", "--set", "raster.pitch_mm=8"]


def test_resumed_stages_reproduce_run_byte_for_byte(tmp_path):
    job = SAMPLES / "sphere.toml"
    whole, staged = tmp_path / "run", tmp_path / "staged"
    r = run_camtool("run", job, "-o", whole, *SMALL)
    assert r.returncode == 0, r.stderr
    steps = [("fit", job, "-o", staged, *SMALL),
             ("raster", job, "--from", staged / "surface.json", "-o", staged, *SMALL),
             ("plan", job, "--from", staged / "path.npz", "-o", staged, *SMALL),
             ("time", job, "--from", staged / "joint_path.npz", "-o", staged, *SMALL),
             ("post", job, "--from", staged / "trajectory.npz", "-o", staged / "programs", *SMALL)]
    for args in steps:
        r = run_camtool(*args)
        assert r.returncode == 0, (args[0], r.stderr)
    programs = sorted(Path(p).name for p in json.loads((whole / "report.json").read_text())["programs"])
    assert programs, "the run wrote no program"
    match, mismatch, errors = filecmp.cmpfiles(whole, staged / "programs", programs, shallow=False)
    assert not mismatch and not errors and len(match) == len(programs)


def test_resuming_from_the_wrong_stage_is_one_line(tmp_path):
    job = SAMPLES / "sphere.toml"
    r = run_camtool("raster", job, "-o", tmp_path, *SMALL)
    assert r.returncode == 0, r.stderr
    r = run_camtool("time", job, "--from", tmp_path / "path.npz", "-o", tmp_path, *SMALL)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "expected JointPath" in r.stderr
