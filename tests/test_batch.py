"""camtool.batch as a library: finding and naming jobs, overrides, the cache
manifest, and the isolation of one job process (crash, traceback, timeout)."""
import json
import os
import shutil
import sys
import time
from pathlib import Path

import pytest

from camtool.batch import cache, runner
from camtool.batch.executors import run_batch
from camtool.batch.runner import JobSpec, discover_jobs, job_names, prepare_batch, reason_from_log
from camtool.errors import BadInput

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "samples"


def write_job(path: Path, workpiece: Path, extra: str = "") -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f'[workpiece]\nfile = "{workpiece}"\n[fit]\nmodel = "plane"\n{extra}')
    return path


def test_discover_sorts_dedupes_and_names_duplicates_stably(tmp_path):
    wp = SAMPLES / "plate_hole.stl"
    a = write_job(tmp_path / "a" / "job.toml", wp)
    b = write_job(tmp_path / "b" / "job.toml", wp)
    c = write_job(tmp_path / "a" / "other.toml", wp)
    (tmp_path / "a" / "notes.txt").write_text("not a job")
    jobs = discover_jobs([tmp_path / "b", tmp_path / "a", a])
    assert jobs == sorted([a.resolve(), b.resolve(), c.resolve()])
    names = job_names(jobs)
    assert names[c.resolve()] == "other"
    assert names[a.resolve()].startswith("job-") and names[b.resolve()].startswith("job-")
    assert names[a.resolve()] != names[b.resolve()]
    # the same job keeps its folder name whatever else is in the batch
    assert job_names(discover_jobs([b, a]))[a.resolve()] == names[a.resolve()]


def test_discover_bad_input(tmp_path):
    with pytest.raises(BadInput, match="no such job file or folder"):
        discover_jobs([tmp_path / "missing.toml"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(BadInput, match="no job files found"):
        discover_jobs([tmp_path / "empty"])


@pytest.mark.parametrize("override, message", [
    ("raster.nope=1", "unknown key"),
    ("nosection.key=1", "unknown section"),
    ("raster.step_over_mm=fast", "expected a number in 0.1..10000"),
    ("raster.step_over_mm=-5", "expected a number in 0.1..10000"),
    ("raster.step_over_mm", "expected SECTION.KEY=VALUE"),
])
def test_bad_override_stops_the_batch_before_any_job(tmp_path, override, message):
    job = write_job(tmp_path / "j.toml", SAMPLES / "plate_hole.stl")
    with pytest.raises(BadInput, match=message):
        prepare_batch([job], tmp_path / "out", [override])
    assert not (tmp_path / "out").exists()


def test_malformed_job_is_a_per_job_bad_input(tmp_path):
    good = write_job(tmp_path / "good.toml", SAMPLES / "plate_hole.stl")
    (tmp_path / "typo.toml").write_text("[raster]\nstep_over = 5\n")
    specs, decided = prepare_batch([tmp_path], tmp_path / "out", ["raster.step_over_mm=30"])
    assert [s.job for s in specs] == [str(good.resolve())]
    assert specs[0].overrides == ("raster.step_over_mm=30",)
    (bad,) = decided
    assert (bad.status, bad.exit_code, bad.name) == ("bad_input", 2, "typo")
    assert "raster.step_over: unknown key" in bad.reason
    assert "unknown key" in (tmp_path / "out" / "typo" / "camtool.log").read_text()


def test_fingerprint_follows_every_input(tmp_path):
    from camtool.job import load_job

    wp = tmp_path / "plate.stl"
    shutil.copy(SAMPLES / "plate_hole.stl", wp)
    job_file = write_job(tmp_path / "j.toml", wp)
    fp = cache.fingerprint(load_job(job_file), [])
    assert fp == cache.fingerprint(load_job(job_file), [])
    assert fp != cache.fingerprint(load_job(job_file, ["raster.step_over_mm=5"]), ["raster.step_over_mm=5"])
    with open(wp, "ab") as f:
        f.write(b"\0")
    fp_wp = cache.fingerprint(load_job(job_file), [])
    assert fp_wp != fp
    job_file.write_text(job_file.read_text() + "# a comment\n")
    assert cache.fingerprint(load_job(job_file), []) not in (fp, fp_wp)


def test_up_to_date_needs_same_fingerprint_and_existing_outputs(tmp_path):
    (tmp_path / "P.mod").write_text("x")
    cache.write_manifest(tmp_path, {"fingerprint": "abc", "status": "ok", "files": ["P.mod"]})
    assert cache.up_to_date(tmp_path, "abc")["files"] == ["P.mod"]
    assert cache.up_to_date(tmp_path, "abd") is None
    (tmp_path / "P.mod").unlink()
    assert cache.up_to_date(tmp_path, "abc") is None
    (tmp_path / "P.mod").write_text("x")
    cache.forget(tmp_path)  # before a rerun: manifest and listed outputs go
    assert not (tmp_path / "P.mod").exists() and cache.read_manifest(tmp_path) is None


def test_reason_from_log():
    assert reason_from_log("Traceback...\ncamtool: error: 3 poses out of reach\n", 3) == "3 poses out of reach"
    text = ("camtool: internal error: KeyError: 'x' (rerun with --debug for the traceback, and please report it)")
    assert reason_from_log(text, 1) == "internal error: KeyError: 'x'"
    assert reason_from_log("# header\nTraceback\n  File x\nRuntimeError: boom\n", 1) == "RuntimeError: boom"
    assert reason_from_log("", -9) == "killed by signal SIGKILL"


def fake_spec(tmp_path, name, timeout=None):
    return JobSpec(job=str(tmp_path / f"{name}.toml"), name=name, outdir=str(tmp_path / "out" / name),
                   timeout_s=timeout)


def test_a_crash_or_traceback_in_one_job_does_not_stop_the_others(tmp_path, monkeypatch):
    """Each job is its own process: abort() and an uncaught exception stay inside it."""
    scripts = {
        "abort": "import os; os.abort()",
        "boom": "raise RuntimeError('boom in the job')",
        # a job's result goes to the pipe its batch passed (CAMTOOL_RESULT_FD), never to its stdout
        "fine": ("import json, os, sys; print('noise on stdout'); "
                 "os.write(int(os.environ['CAMTOOL_RESULT_FD']), json.dumps({'points_total': 7, "
                 "'cycle_time_s': 1.5, 'programs': [sys.argv[1] + '/P.mod'], 'plots': []}).encode())"),
    }
    monkeypatch.setattr(runner, "job_command",
                        lambda spec: [sys.executable, "-c", scripts[spec.name], spec.outdir])
    results = run_batch([fake_spec(tmp_path, n) for n in ("fine", "boom", "abort")], "local", 2)
    by = {r.name: r for r in results}
    assert [r.name for r in results] == ["abort", "boom", "fine"]  # sorted by job path
    assert (by["abort"].status, by["abort"].exit_code, by["abort"].reason) == ("failed", 1, "killed by signal SIGABRT")
    assert (by["boom"].status, by["boom"].exit_code) == ("failed", 1)
    assert by["boom"].reason == "RuntimeError: boom in the job"
    log = (tmp_path / "out" / "boom" / "camtool.log").read_text()
    assert "Traceback (most recent call last)" in log and "# failed: exit code 1" in log
    assert (by["fine"].status, by["fine"].points, by["fine"].cycle_time_s) == ("ok", 7, 1.5)
    assert "P.mod" in by["fine"].files
    manifest = json.loads((tmp_path / "out" / "fine" / ".camtool-cache.json").read_text())
    assert manifest["status"] == "ok" and manifest["points"] == 7


def test_timeout_kills_the_whole_job_process_group(tmp_path, monkeypatch):
    pidfile = tmp_path / "grandchild.pid"
    script = ("import subprocess, sys, time; "
              "p = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(60)']); "
              f"open({str(pidfile)!r}, 'w').write(str(p.pid)); time.sleep(60)")
    monkeypatch.setattr(runner, "job_command", lambda spec: [sys.executable, "-c", script])
    t0 = time.perf_counter()
    result = runner.run_one(fake_spec(tmp_path, "slow", timeout=1.5))
    assert time.perf_counter() - t0 < 10
    assert (result.status, result.exit_code) == ("timeout", runner.TIMEOUT_EXIT)
    assert "1.5 s timeout" in result.reason
    pid = int(pidfile.read_text())
    for _ in range(50):  # the grandchild was killed with its group (it may linger briefly as a zombie)
        try:
            os.kill(pid, 0)
            if Path(f"/proc/{pid}/stat").exists() and Path(f"/proc/{pid}/stat").read_text().split()[2] == "Z":
                break
        except ProcessLookupError:
            break
        time.sleep(0.1)
    else:
        pytest.fail("the job's child process survived the timeout")
