"""Job files: defaults, overrides and precise errors for bad input."""

import pytest

from camtool.errors import BadInput
from camtool.job import SCHEMA, load_job, schema_markdown

from conftest import ROOT, run_camtool


def write(tmp_path, text, name="job.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


GOOD = '[workpiece]\nfile = "part.stl"\n'


def test_defaults_filled(tmp_path):
    job = load_job(write(tmp_path, GOOD))
    for section, keys in SCHEMA.items():
        for k in keys:
            assert k in job.sections[section]
    assert job.raster.step_over_mm == 10.0
    assert job.robot.name == "seed8"
    assert job.resolve("part.stl") == tmp_path / "part.stl"


def test_override(tmp_path):
    job = load_job(write(tmp_path, GOOD), ["raster.step_over_mm=5", "fit.model=plane"])
    assert job.raster.step_over_mm == 5.0 and job.fit.model == "plane"
    with pytest.raises(BadInput, match="raster.nope: unknown key"):
        load_job(write(tmp_path, GOOD), ["raster.nope=1"])


@pytest.mark.parametrize("text, match", [
    (GOOD + "[raster]\nstepover = 3\n", r"job.toml: raster.stepover: unknown key"),
    (GOOD + "[raster]\nstep_over_mm = \"ten\"\n", r"raster.step_over_mm: expected a number in 0.1..10000 mm, found 'ten'"),
    (GOOD + "[raster]\nstep_over_mm = -5\n", r"raster.step_over_mm: expected a number in 0.1..10000 mm, found -5"),
    (GOOD + "[raster]\npitch_mm = 0\n", r"raster.pitch_mm: expected a number in 0.1..10000 mm, found 0"),
    (GOOD + "[robot]\nname = \"kuka\"\n", r"robot.name: expected a built-in robot .* found 'kuka'"),
    (GOOD + "[robot]\nname = \"arm.urdf\"\n", r"robot.name: robot file .*arm.urdf not found"),
    (GOOD + "[fit]\nmodel = \"cone\"\n", r"fit.model: expected one of 'auto', 'plane', 'sphere', 'cylinder', 'freeform', found 'cone'"),
    (GOOD + "[cell]\nbase_xyz_mm = [1, 2]\n", r"cell.base_xyz_mm: expected a list of 3 numbers"),
    (GOOD + "[planner]\nmax_iterations = 2.5\n", r"planner.max_iterations: expected an integer"),
    (GOOD + "[bogus]\nx = 1\n", r"bogus: unknown section"),
    ("[workpiece]\n", r"workpiece.file: expected the workpiece file name"),
    (GOOD + "[raster\nstep_over_mm = 1\n", r"TOML syntax error: .*line 3"),
    (GOOD + "[raster]\nstep_over_mm = = 1\n", r"TOML syntax error: .*line 4"),
])
def test_bad_job_messages(tmp_path, text, match):
    with pytest.raises(BadInput, match=match):
        load_job(write(tmp_path, text))


def test_missing_file(tmp_path):
    with pytest.raises(BadInput, match="job file not found"):
        load_job(tmp_path / "nope.toml")


@pytest.mark.parametrize("text, key", [
    (GOOD + "[raster]\nstepover = 3\n", "raster.stepover"),
    (GOOD + "[raster]\nstep_over_mm = true\n", "raster.step_over_mm"),
    (GOOD + "[raster]\nstep_over_mm = -1\n", "raster.step_over_mm"),
    (GOOD + "[robot]\nname = \"kuka\"\n", "robot.name"),
    (GOOD + "[raster\n", "line 3"),
])
def test_cli_bad_job_exits_2_with_one_line(tmp_path, text, key):
    r = run_camtool("run", write(tmp_path, text))
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and key in lines[0] and "Traceback" not in r.stderr


def test_cli_missing_job_exits_2(tmp_path):
    r = run_camtool("run", tmp_path / "missing.toml")
    assert r.returncode == 2 and "job file not found" in r.stderr


def test_docs_job_reference_is_current():
    assert (ROOT / "docs" / "job-file.md").read_text() == schema_markdown()
