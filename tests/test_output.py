"""One consistent run per output folder: staging, placing, stale files and leftovers of killed runs."""
import json
import os
import subprocess
import sys

from camtool.run.output import MANIFEST, STAGING_PREFIX, place, remove_leftovers, staged_output

from conftest import SAMPLES, run_camtool


def _write(folder, files):
    for name, text in files.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_text(text)


def test_place_replaces_the_previous_run_and_keeps_foreign_files(tmp_path):
    out = tmp_path / "out"
    with staged_output(out) as stage:
        _write(stage, {"A.mod": "old", "A_2.mod": "old part 2", "report.json": '{"status": "ok"}'})
        place(stage, out)
    (out / "notes.txt").write_text("mine")
    with staged_output(out) as stage:
        _write(stage, {"A.mod": "new", "plots/x.png": "png", "report.json": json.dumps({"file": str(stage / "A.mod")})})
        placed = place(stage, out)
    assert (out / "A.mod").read_text() == "new" and not (out / "A_2.mod").exists()   # stale part removed
    assert (out / "notes.txt").read_text() == "mine"                                 # not camtool's: kept
    assert placed[-1].name == "report.json"                                          # report placed last
    assert json.loads((out / "report.json").read_text())["file"] == str(out / "A.mod")  # paths as placed
    assert sorted(json.loads((out / MANIFEST).read_text())["files"]) == ["A.mod", "plots/x.png", "report.json"]
    assert not [p for p in out.iterdir() if p.name.startswith(STAGING_PREFIX)]       # staging removed


def test_leftovers_of_killed_runs_are_removed_running_ones_kept(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    gone = tmp_path / f"{STAGING_PREFIX}{dead.stdout.strip()}-abc"
    gone.mkdir()
    (gone / "half.mod").write_text("half")
    post_tmp = tmp_path / ".camtool-post-xyz"
    post_tmp.mkdir()
    alive = tmp_path / f"{STAGING_PREFIX}{os.getppid()}-def"
    alive.mkdir()
    removed = remove_leftovers(tmp_path)
    assert gone in removed and post_tmp in removed and alive.exists()


def test_an_infeasible_rerun_leaves_no_program_of_the_earlier_run(tmp_path):
    small = ["--set", "raster.step_over_mm=60", "--set", "raster.pitch_mm=8", "--set", 'post.formats=["csv"]']
    r = run_camtool("run", SAMPLES / "sphere.toml", "-o", tmp_path, *small)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "SPHERE.csv").exists()
    r = run_camtool("run", SAMPLES / "sphere.toml", "-o", tmp_path, *small,
                    "--set", "cell.workpiece_xyz_mm=[2400.0, 0.0, 100.0]")
    assert r.returncode == 3, r.stderr
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["status"] == "infeasible"
    assert not (tmp_path / "SPHERE.csv").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".camtool-run-")]


def test_a_run_failing_where_no_stage_reports_leaves_a_report_of_itself(tmp_path, monkeypatch):
    """Issue #48: a failed run leaves a report of itself or none, never the previous run's report."""
    import pytest

    from camtool.errors import BadInput
    from camtool.job import load_job
    from camtool.run import pipeline, tasks

    small = ["raster.step_over_mm=60", "raster.pitch_mm=8", 'post.formats=["csv"]']
    pipeline.run_job(load_job(SAMPLES / "sphere.toml", small), tmp_path)
    assert json.loads((tmp_path / "report.json").read_text())["status"] == "ok"
    assert (tmp_path / "SPHERE.csv").exists() and (tmp_path / "report.html").exists()

    def timing_fails(*args, **kwargs):  # a stage that writes no report (timing) failing inside: exit 1
        raise RuntimeError("time law: the spline leaves the joint range")

    with monkeypatch.context() as m:
        m.setitem(tasks.TASKS, "raster", timing_fails)
        with pytest.raises(RuntimeError):
            pipeline.run_job(load_job(SAMPLES / "sphere.toml", small), tmp_path)
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["status"] == "failed" and report["exit_code"] == 1 and "spline" in report["reason"]
    assert sorted(p.name for p in tmp_path.rglob("*") if p.is_file() and not p.name.startswith(".")) == ["report.json"]

    with pytest.raises(BadInput):  # a bad post: refused before any work, and reported
        pipeline.run_job(load_job(SAMPLES / "sphere.toml", small[:2] + ['post.formats=["nosuch"]']), tmp_path)
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["status"] == "bad_input" and report["exit_code"] == 2 and "nosuch" in report["reason"]
