"""`camtool batch` end to end on small sphere jobs: failure isolation, the summary,
local pool vs Dask giving byte-identical programs, caching and bad input."""
import json
import time

import pytest

from conftest import SAMPLES, run_camtool

GOOD = ("good1", "good2", "good3")   # three good jobs on two workers: one waits for a free slot


def sphere_job(step_over_mm: float, workpiece_xyz="[1000.0, 0.0, 100.0]") -> str:
    return f"""[workpiece]
file = "{SAMPLES / 'sphere_patch.stl'}"
[fit]
model = "auto"
[raster]
step_over_mm = {step_over_mm}
pitch_mm = 8.0
[robot]
name = "seed8"
[cell]
workpiece_xyz_mm = {workpiece_xyz}
[post]
formats = ["rapid", "csv"]
program_name = "SPHERE"
"""


@pytest.fixture(scope="module")
def jobs(tmp_path_factory):
    """Five job files: three good ones, one unreachable (5 m away), one malformed."""
    d = tmp_path_factory.mktemp("jobs")
    for i, name in enumerate(GOOD):
        (d / f"{name}.toml").write_text(sphere_job(40.0 + 5 * i))
    (d / "far.toml").write_text(sphere_job(40.0, "[6000.0, 0.0, 100.0]"))
    (d / "broken.toml").write_text("[raster\nstep_over_mm = 5\n")
    return d


@pytest.fixture(scope="module")
def mixed(jobs, tmp_path_factory):
    """The five jobs on the local pool with 2 workers."""
    from click.testing import CliRunner

    from camtool.cli import cli

    out = tmp_path_factory.mktemp("mixed")
    res = CliRunner().invoke(cli, ["batch", str(jobs), "-o", str(out), "-j", "2", "--timeout", "120"],
                             catch_exceptions=False)
    return res, out


@pytest.fixture(scope="module")
def dask_run(jobs, tmp_path_factory):
    """The good jobs on a Dask LocalCluster of 2 workers, timed."""
    from click.testing import CliRunner

    from camtool.cli import cli

    out = tmp_path_factory.mktemp("dask")
    args = ["batch", *(str(jobs / f"{n}.toml") for n in GOOD), "-o", str(out), "--executor", "dask", "-j", "2"]
    t0 = time.perf_counter()
    res = CliRunner().invoke(cli, args, catch_exceptions=False)
    return res, out, args, time.perf_counter() - t0


def test_one_failing_job_never_stops_the_others(mixed, jobs):
    res, out = mixed
    assert res.exit_code == 3, res.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["exit_code"] == 3
    names = [j["name"] for j in summary["jobs"]]
    assert names == sorted(names) == ["broken", "far", *GOOD]  # sorted by job path
    by = {j["name"]: j for j in summary["jobs"]}
    for name in GOOD:
        j = by[name]
        assert (j["status"], j["exit_code"], j["reason"]) == ("ok", 0, "")
        assert j["points"] > 100 and j["cycle_time_s"] > 0 and j["wall_time_s"] > 0
        assert f"{name}/SPHERE.mod" in j["files"] and f"{name}/report.json" in j["files"]
        assert all((out / f).is_file() for f in j["files"])
    assert (by["far"]["status"], by["far"]["exit_code"]) == ("infeasible", 3)
    assert "out of reach" in by["far"]["reason"] and "\n" not in by["far"]["reason"]
    assert not (out / "far" / "SPHERE.mod").exists()
    assert "Traceback (most recent call last)" in (out / "far" / "camtool.log").read_text()
    assert (by["broken"]["status"], by["broken"]["exit_code"]) == ("bad_input", 2)
    assert "TOML syntax error" in by["broken"]["reason"]
    assert summary["counts"] == {"ok": len(GOOD), "cached": 0, "failed": 0, "infeasible": 1, "bad_input": 1,
                                 "unavailable": 0, "timeout": 0}
    assert f"{len(GOOD)} ok, 1 infeasible, 1 bad_input" in res.output


def test_local_pool_and_dask_give_byte_identical_programs(mixed, dask_run):
    res, dask_out, _, _ = dask_run
    assert res.exit_code == 0, res.output
    _, local_out = mixed
    summary = json.loads((dask_out / "summary.json").read_text())
    assert summary["executor"] == "dask" and [j["status"] for j in summary["jobs"]] == ["ok"] * len(GOOD)
    compared = 0
    for name in GOOD:
        for prog in ("SPHERE.mod", "SPHERE.csv"):
            a, b = (local_out / name / prog).read_bytes(), (dask_out / name / prog).read_bytes()
            assert a == b, f"{name}/{prog} differs between the local pool and Dask"
            compared += 1
    assert compared == 2 * len(GOOD)
    # and the good jobs really are different programs
    assert len({(local_out / n / "SPHERE.mod").read_bytes() for n in GOOD}) == len(GOOD)


def test_second_identical_run_is_all_cached_and_fast(dask_run):
    from click.testing import CliRunner

    from camtool.cli import cli

    _, out, args, first_s = dask_run
    t0 = time.perf_counter()
    res = CliRunner().invoke(cli, [*args, "--json"], catch_exceptions=False)
    second_s = time.perf_counter() - t0
    assert res.exit_code == 0, res.output
    summary = json.loads(res.stdout)
    assert [j["status"] for j in summary["jobs"]] == ["cached"] * len(GOOD)
    assert all(j["exit_code"] == 0 and j["points"] > 100 and j["files"] for j in summary["jobs"])
    assert second_s < 0.1 * first_s, (second_s, first_s)


def test_missing_output_or_force_reruns(mixed, jobs):
    from click.testing import CliRunner

    from camtool.cli import cli

    _, out = mixed
    (out / "good1" / "SPHERE.mod").unlink()
    runner = CliRunner()
    res = runner.invoke(cli, ["batch", str(jobs / "good1.toml"), str(jobs / "good2.toml"), "-o", str(out),
                              "--json"], catch_exceptions=False)
    assert res.exit_code == 0, res.output
    assert [j["status"] for j in json.loads(res.stdout)["jobs"]] == ["ok", "cached"]
    assert (out / "good1" / "SPHERE.mod").is_file()
    res = runner.invoke(cli, ["batch", str(jobs / "good2.toml"), "-o", str(out), "--force", "--json"],
                        catch_exceptions=False)
    assert [j["status"] for j in json.loads(res.stdout)["jobs"]] == ["ok"]


@pytest.mark.parametrize("override, message", [
    ("raster.no_such_key=5", "--set raster.no_such_key: unknown key"),
    ("raster.step_over_mm=wide", "raster.step_over_mm: expected a number in 0.1..10000"),
    ("planner.max_iterations=2.5", "planner.max_iterations: expected an integer in 1..10000"),
])
def test_bad_override_exits_2_with_one_line(jobs, tmp_path, override, message):
    r = run_camtool("batch", jobs, "-o", tmp_path / "out", "--set", override)
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and message in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "out").exists()  # nothing ran


def test_bad_batch_input_exits_2(cli, tmp_path, monkeypatch):
    r = cli("batch", tmp_path / "nope.toml", "-o", tmp_path / "out")
    assert r.exit_code == 2 and "no such job file or folder" in r.stderr
    r = cli("batch", tmp_path, "-o", tmp_path / "out")
    assert r.exit_code == 2 and "no job files found" in r.stderr
    (tmp_path / "j.toml").write_text(sphere_job(40.0))
    monkeypatch.setitem(__import__("sys").modules, "distributed", None)  # as if Dask were not installed
    r = cli("batch", tmp_path / "j.toml", "-o", tmp_path / "out", "--executor", "dask")
    assert r.exit_code == 2 and "pip install 'camtool[dask]'" in r.stderr
    assert not (tmp_path / "out").exists()
