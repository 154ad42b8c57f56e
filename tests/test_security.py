"""A hostile or careless cell (issue #28): one fast test per finding; docs/security.md says what holds.

Every reproducer runs under tmp_path with a subprocess timeout, so a regression shows as a failure,
never as a hung suite. The victims live beside the output folder: none may change.
"""
from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest

from camtool import safe_io
from camtool.errors import BadInput
from camtool.run.output import MANIFEST, place, staged_output

from conftest import SAMPLES

SPHERE = SAMPLES / "sphere.toml"
SMALL = ["--set", "raster.step_over_mm=60", "--set", "raster.pitch_mm=8", "--set", 'post.formats=["csv"]']
LIMIT_S = 120  # no reproducer may take longer: a hang fails the test


def camtool(*args, timeout=LIMIT_S, env=None, cwd=None):
    return subprocess.run([sys.executable, "-m", "camtool.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env=env, cwd=cwd)


def one_error_line(r, code=2, expect=""):
    lines = r.stderr.strip().splitlines()
    assert r.returncode == code, r.stderr
    assert len(lines) == 1 and lines[0].startswith("camtool: error: "), r.stderr
    assert "Traceback" not in r.stderr + r.stdout
    assert expect in lines[0], lines[0]
    return lines[0]


@pytest.fixture
def victim(tmp_path):
    v = tmp_path / "victim"
    v.write_text("precious\n")
    return v


# ---------------------------------------------------------------- 1. symlinks in the output folder

def test_symlinked_manifest_tmp_is_refused_and_not_followed(tmp_path, victim):
    out = tmp_path / "out"
    out.mkdir()
    (out / ".camtool-manifest.tmp").symlink_to(victim)
    one_error_line(camtool("run", SPHERE, "-o", out, *SMALL), expect="is a symlink")
    assert victim.read_text() == "precious\n"


def test_symlinked_programs_manifest_tmp_is_refused_by_post(tmp_path, victim):
    out = tmp_path / "out"
    out.mkdir()
    (out / ".camtool-programs.json.tmp").symlink_to(victim)
    one_error_line(camtool("post", SPHERE, "-o", out, *SMALL), expect="is a symlink")
    assert victim.read_text() == "precious\n"


def test_symlinked_batch_log_is_refused_and_not_followed(tmp_path, victim):
    jobs = tmp_path / "jobs"
    jobs.mkdir()
    (jobs / "a.toml").write_text("[raster\n")
    out = tmp_path / "out"
    (out / "a").mkdir(parents=True)
    (out / "a" / "camtool.log").symlink_to(victim)
    one_error_line(camtool("batch", jobs, "-o", out), expect="is a symlink")
    assert victim.read_text() == "precious\n"


def test_a_log_link_planted_while_the_batch_runs_is_never_opened(tmp_path, victim):
    (tmp_path / "camtool.log").symlink_to(victim)  # after the batch's own check: new_file refuses it
    with pytest.raises(BadInput, match="is a symlink"):
        safe_io.new_file(tmp_path, "camtool.log")
    with pytest.raises(BadInput, match="is a symlink"):
        safe_io.new_file(tmp_path, "camtool.log", append=True)
    assert victim.read_text() == "precious\n"


def test_plots_linked_to_another_folder_is_refused(tmp_path):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    out = tmp_path / "out"
    out.mkdir()
    (out / "plots").symlink_to(elsewhere, target_is_directory=True)
    one_error_line(camtool("run", SPHERE, "-o", out, *SMALL), expect="is a symlink")
    assert list(elsewhere.iterdir()) == []


def test_place_walks_with_nofollow_even_when_a_link_appears_late(tmp_path):
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    elsewhere.mkdir()
    with staged_output(out) as stage:
        (stage / "plots").mkdir()
        (stage / "plots" / "x.png").write_text("png")
        (out / "plots").symlink_to(elsewhere, target_is_directory=True)  # after the folder check
        with pytest.raises(BadInput, match="is a symlink"):
            place(stage, out)
    assert list(elsewhere.iterdir()) == []


def test_a_fifo_under_the_output_folder_is_refused(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    os.mkfifo(out / "report.html")
    with pytest.raises(BadInput, match="FIFO"):
        safe_io.check_outdir(out)


# ---------------------------------------------------------------- 2. a planted manifest

def test_planted_manifest_deletes_nothing_outside_the_output_folder(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    v1, v2 = tmp_path / "victim1", tmp_path / "abs" / "victim2"
    v2.parent.mkdir()
    v1.write_text("1")
    v2.write_text("2")
    (out / MANIFEST).write_text(json.dumps({"files": ["../victim1", str(v2), "a/../../victim1"]}))
    with staged_output(out) as stage:
        (stage / "report.json").write_text("{}")
        place(stage, out)
    assert v1.read_text() == "1" and v2.read_text() == "2"
    assert json.loads((out / MANIFEST).read_text())["files"] == ["report.json"]


def test_remove_file_refuses_names_that_leave_the_folder(tmp_path):
    (tmp_path / "x").write_text("x")
    out = tmp_path / "out"
    out.mkdir()
    for name in ("../x", str(tmp_path / "x"), "", ".", "a/../../x"):
        assert safe_io.remove_file(out, name) is False
    assert (tmp_path / "x").exists()


# ---------------------------------------------------------------- 4. hangs: FIFOs and devices as inputs

def _fifo(tmp_path, name):
    f = tmp_path / name
    os.mkfifo(f)
    return f


def test_a_fifo_job_file_is_refused_at_once(tmp_path):
    t0 = time.monotonic()
    one_error_line(camtool("run", _fifo(tmp_path, "job.toml"), "-o", tmp_path / "out", timeout=30), expect="FIFO")
    assert time.monotonic() - t0 < 30


def test_dev_zero_as_a_job_is_refused_not_read(tmp_path):
    one_error_line(camtool("run", "/dev/zero", "-o", tmp_path / "out", timeout=30), expect="device")


def test_read_input_bytes_caps_and_refuses_special_files(tmp_path, monkeypatch):
    with pytest.raises(BadInput, match="FIFO"):
        safe_io.read_input_bytes(_fifo(tmp_path, "p"), "profile")
    with pytest.raises(BadInput, match="device"):
        safe_io.read_input_bytes("/dev/zero", "workpiece")
    big = tmp_path / "big.toml"
    big.write_bytes(b"#" * (2 * 1024 * 1024))
    monkeypatch.setenv("CAMTOOL_MAX_JOB_MB", "1")
    with pytest.raises(BadInput, match="over the 1 MB cap for a job file .CAMTOOL_MAX_JOB_MB"):
        safe_io.read_input_bytes(big, "job")
    monkeypatch.setenv("CAMTOOL_MAX_JOB_MB", "3")
    assert len(safe_io.read_input_bytes(big, "job")) == 2 * 1024 * 1024


def _fifo_job(tmp_path, name="a"):
    jobs = tmp_path / "jobs"
    jobs.mkdir(exist_ok=True)
    fifo = _fifo(tmp_path, "part.stl")
    (jobs / f"{name}.toml").write_text(f"[workpiece]\nfile = '{fifo}'\n")
    return jobs


def test_batch_with_a_fifo_workpiece_ends_within_its_timeout(tmp_path):
    jobs = _fifo_job(tmp_path)
    r = camtool("batch", jobs, "-o", tmp_path / "out", "--timeout", "5", "--json", timeout=60)
    assert r.returncode == 3, r.stderr
    job = json.loads(r.stdout)["jobs"][0]
    assert job["status"] == "bad_input" and "FIFO" in job["reason"]


def test_watch_once_with_a_fifo_workpiece_ends_within_its_timeout(tmp_path):
    jobs = _fifo_job(tmp_path)
    r = camtool("watch", jobs, "-o", tmp_path / "out", "--template", SPHERE, "--once", "--interval", "0.05",
                "--timeout", "5", "--json", timeout=60)
    assert r.returncode == 3, r.stderr
    assert json.loads(r.stdout)["jobs"][0]["status"] == "bad_input"


def test_a_fifo_stage_file_is_refused(tmp_path):
    from camtool.run.stage_files import load_stage

    with pytest.raises(BadInput, match="FIFO"):
        load_stage(_fifo(tmp_path, "trajectory.npz"))


# ---------------------------------------------------------------- 5. batch job stems

def test_batch_job_stems_are_safe_names(tmp_path):
    from camtool.batch.runner import job_names

    names = job_names([tmp_path / "...toml", tmp_path / "a b.toml", tmp_path / "\nx.toml", tmp_path / "плита.toml"])
    assert sorted(names.values()) == ["_x", "a_b", "job", "плита"]
    assert safe_io.safe_name("..") == "job" and safe_io.safe_name("../../etc") == "_.._etc"


def test_batch_of_a_dotdot_stem_writes_nothing_outside_the_output_folder(tmp_path):
    jobs = tmp_path / "jobs"
    jobs.mkdir()
    (jobs / "...toml").write_text("[raster\n")
    (tmp_path / "report.json").write_text("foreign")
    out = tmp_path / "area" / "out"
    r = camtool("batch", jobs, "-o", out, "--json", timeout=60)
    assert r.returncode == 3, r.stderr
    assert json.loads(r.stdout)["jobs"][0]["outdir"] == "job"
    assert (tmp_path / "report.json").read_text() == "foreign"
    assert sorted(p.name for p in (tmp_path / "area").iterdir()) == ["out"]


# ---------------------------------------------------------------- 6. names that clash with camtool's files

@pytest.mark.parametrize("name", ["points", "Report", "plots", "trajectory"])
def test_program_names_that_clash_with_camtools_files_are_refused(tmp_path, cli, name):
    r = cli("run", SPHERE, "-o", tmp_path / "out", "--set", f"post.program_name={name}")
    assert r.exit_code == 2 and "clash with camtool's own" in r.stderr, r.stderr
    assert f"post.program_name = {name!r}" in r.stderr and not (tmp_path / "out").exists()


# ---------------------------------------------------------------- 8. two runs into one folder

def test_a_second_process_writing_into_a_locked_folder_is_refused(tmp_path):
    out = tmp_path / "out"
    with safe_io.locked(out):
        one_error_line(camtool("run", SPHERE, "-o", out, *SMALL), expect="another camtool process is writing")
    with safe_io.locked(out):  # released: the lock can be taken again
        pass


# ---------------------------------------------------------------- 9. SIGTERM reaches the batch's jobs

def _children(pid: int) -> set[int]:
    kids = set()
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            kids |= {int(x) for x in (task / "children").read_text().split()}
        except OSError:
            pass
    return kids


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def test_sigterm_to_batch_kills_its_jobs(tmp_path):
    jobs = tmp_path / "jobs"
    jobs.mkdir()
    (jobs / "a.toml").write_text(SPHERE.read_text().replace('file = "', f'file = "{SAMPLES}/'))
    proc = subprocess.Popen([sys.executable, "-m", "camtool.cli", "batch", jobs, "-o", tmp_path / "out", "-j", "1"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 60
        kids: set[int] = set()
        while not kids and time.monotonic() < deadline:
            time.sleep(0.2)
            kids = _children(proc.pid)
        assert kids, "the batch started no job"
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=120)  # generous: two test workers on two cores beside other work; a hang still fails
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == 130
    deadline = time.monotonic() + 10
    while any(_alive(k) for k in kids) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_alive(k) for k in kids), "a job outlived its batch"


# ---------------------------------------------------------------- 10. exit 2, not 1

def test_a_folder_where_a_program_goes_is_exit_2_and_keeps_the_previous_run(tmp_path):
    out = tmp_path / "out"
    with staged_output(out) as stage:
        (stage / "OLD.JBI").write_text("old")
        (stage / "report.json").write_text("{}")
        place(stage, out)
    (out / "NEW.JBI").mkdir()
    with staged_output(out) as stage:
        (stage / "NEW.JBI").write_text("new")
        (stage / "report.json").write_text("{}")
        with pytest.raises(BadInput, match="NEW.JBI: is a folder where camtool places a file"):
            place(stage, out)
    assert (out / "OLD.JBI").read_text() == "old" and (out / "report.json").exists()


def test_a_full_disk_while_staging_is_one_line_and_keeps_the_previous_programs(tmp_path):
    out = tmp_path / "out"
    with staged_output(out) as stage:
        (stage / "A.mod").write_text("old")
        place(stage, out)
    with pytest.raises(BadInput, match="the disk is full; the previous outputs are left as they were"):
        with staged_output(out):
            raise OSError(errno.ENOSPC, "No space left on device", str(out / "x"))
    assert (out / "A.mod").read_text() == "old"


def test_cli_maps_disk_errors_to_exit_2(tmp_path, monkeypatch):
    from click.testing import CliRunner

    from camtool import cli as cli_module

    def full(*a, **k):
        raise OSError(errno.ENOSPC, "No space left on device", "/out/x")

    # run imports run_job when called (the speed branch's lazy imports): patch it where it lives
    monkeypatch.setattr("camtool.run.pipeline.run_job", full)
    r = CliRunner().invoke(cli_module.cli, ["run", str(SPHERE), "-o", str(tmp_path / "o")])
    assert r.exit_code == 2 and "the disk is full" in r.output and "please report" not in r.output


def test_deep_toml_is_one_line_exit_2(tmp_path):
    job = tmp_path / "deep.toml"
    job.write_text("x = " + "[" * 100_000 + "]" * 100_000 + "\n")
    one_error_line(camtool("run", job, "-o", tmp_path / "out", timeout=60), expect="nested too deeply")


@pytest.mark.parametrize("args, expect", [
    (["watch", "IN", "--template", str(SPHERE), "--interval", "nan", "--once"], "--interval"),
    (["watch", "IN", "--template", str(SPHERE), "--interval", "inf", "--once"], "--interval"),
    (["batch", "IN", "--timeout", "inf"], "--timeout"),
    (["batch", "IN", "--timeout", "nan"], "--timeout"),
    (["batch", "IN", "-j", "100000"], "-j"),
])
def test_unbounded_numbers_on_the_command_line_are_one_line_exit_2(tmp_path, cli, args, expect):
    (tmp_path / "in").mkdir()
    args = [str(tmp_path / "in") if a == "IN" else a for a in args]
    r = cli(*args, "-o", tmp_path / "out")
    lines = r.stderr.strip().splitlines()
    assert r.exit_code == 2 and len(lines) == 1 and lines[0].startswith("camtool: error: "), r.stderr
    assert expect in lines[0] and not (tmp_path / "out").exists()


# ---------------------------------------------------------------- 11. stale files

def test_a_rerun_killed_by_its_timeout_leaves_no_previous_report_or_plot(tmp_path):
    from camtool.batch import cache
    from camtool.batch.runner import JobSpec, run_one

    folder = tmp_path / "out" / "a"
    with staged_output(folder) as stage:  # the previous run as placed
        for name in ("A.csv", "report.json", "report.html", "points.csv", "plots/joint_angle.png"):
            (stage / name).parent.mkdir(parents=True, exist_ok=True)
            (stage / name).write_text("old")
        place(stage, folder)
    cache.write_manifest(folder, {"fingerprint": "old", "status": "ok", "files": ["A.csv", "report.json"]})
    r = run_one(JobSpec(job=str(SPHERE), name="a", outdir=str(folder), timeout_s=0.05, fingerprint="new"))
    assert r.status == "timeout"
    left = sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())
    assert left == [".camtool-lock", "camtool.log"] or left == ["camtool.log"], left


# ---------------------------------------------------------------- 14. smaller findings

def test_root_and_home_are_refused_as_output_folders(tmp_path):
    home = tmp_path / "home"
    home.mkdir()
    (home / "report.json").write_text("mine")
    env = {**os.environ, "HOME": str(home)}
    one_error_line(camtool("run", SPHERE, "-o", home, *SMALL, env=env), expect="the home folder")
    one_error_line(camtool("run", SPHERE, "-o", "/", *SMALL, env=env), expect="the root folder")
    assert (home / "report.json").read_text() == "mine"


def test_a_folder_holding_a_foreign_report_is_refused(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "report.json").write_text("someone else's")
    one_error_line(camtool("run", SPHERE, "-o", out, *SMALL), expect="that camtool did not write")
    assert (out / "report.json").read_text() == "someone else's"


def test_a_huge_program_name_is_refused_with_a_short_line(tmp_path):
    job = tmp_path / "big.toml"
    job.write_text(f"[workpiece]\nfile = '{SAMPLES / 'sphere_patch.stl'}'\n[post]\nprogram_name = '{'A' * 1_000_000}'\n")
    r = camtool("run", job, "-o", tmp_path / "out", timeout=60)
    one_error_line(r, expect="at most 4096 are accepted")
    assert len(r.stderr) < 2000


def test_error_lines_are_bounded_and_escaped():
    from camtool.cli import MAX_MESSAGE, one_line

    text = one_line("a\nb\x1b[31m" + "x" * 10_000)
    assert "\n" not in text and "\x1b" not in text and len(text) <= MAX_MESSAGE + 20
    assert safe_io.snippet("x" * 500, 10).startswith("'xxxxxxxxxx'... (490 more")


def test_a_newline_in_a_watched_file_name_stays_inside_the_comment(tmp_path):
    from camtool.batch.watch import write_derived_job

    wp = tmp_path / "part\n[post]\nformats = ['evil']\n.stl"
    out = write_derived_job({"workpiece": {"file": ""}}, wp, tmp_path / "o" / "job.toml", tmp_path / "t\n.toml")
    data = tomllib.loads(out.read_text())
    assert set(data) == {"workpiece"} and data["workpiece"]["file"] == str(wp.resolve())


def test_watch_output_folders_are_safe_names(tmp_path):
    from camtool.batch.watch import output_names

    names = output_names([tmp_path / "..\n.stl", tmp_path / "a.toml"])
    assert all("/" not in n and "\n" not in n and not n.startswith(".") for n in names.values())


# ---------------------------------------------------------------- 13. degenerate inputs

@pytest.mark.parametrize("points", [3, 20])
def test_too_few_points_for_a_surface_is_one_line(tmp_path, cli, points):
    cloud = tmp_path / "scan.xyz"
    cloud.write_text("".join(f"{30.0 * (i % 5)} {30.0 * (i // 5) + 7.0 * (i % 2)} {0.01 * i}\n" for i in range(points)))
    (tmp_path / "job.toml").write_text("[workpiece]\nfile = 'scan.xyz'\n")
    r = cli("fit", tmp_path / "job.toml", "-o", tmp_path / "out")
    assert r.exit_code == 2, r.stderr
    assert f"too few points for a surface: {points}, need at least 100" in r.stderr


def test_a_pitch_longer_than_the_part_is_one_line(tmp_path, cli):
    r = cli("raster", SPHERE, "-o", tmp_path / "out", "--set", "raster.pitch_mm=5000")
    assert r.exit_code == 2 and "raster.pitch_mm: 5000 mm is longer than the part" in r.stderr, r.stderr


# ---------------------------------------------------------------- 4. hangs: files camtool check follows, profiles

def _check_ends_quickly(tmp_path, program, robot="irb2400"):
    r = camtool("check", program, "--robot", robot, timeout=60)
    assert r.returncode == 2, r.stdout + r.stderr
    assert "FIFO" in r.stdout + r.stderr and "Traceback" not in r.stdout + r.stderr
    return r


def test_check_of_a_pgf_naming_a_fifo_module_ends(tmp_path):
    _fifo(tmp_path, "MAIN.mod")
    (tmp_path / "P.pgf").write_text('<?xml version="1.0"?>\n<Program>\n  <Module>MAIN.mod</Module>\n</Program>\n')
    _check_ends_quickly(tmp_path, tmp_path / "P.pgf")


def test_check_of_a_load_dynamic_naming_a_fifo_ends(tmp_path):
    _fifo(tmp_path, "PART.mod")
    (tmp_path / "MAIN.mod").write_text('MODULE MAIN\n  PROC main()\n    Load \\Dynamic, "HOME:/PART.mod";\n'
                                       '  ENDPROC\nENDMODULE\n')
    _check_ends_quickly(tmp_path, tmp_path / "MAIN.mod")


def test_check_of_a_call_job_naming_a_fifo_ends(tmp_path):
    _fifo(tmp_path, "PART.JBI")
    (tmp_path / "MAIN.JBI").write_text("/JOB\n//NAME MAIN\n//POS\n///NPOS 0,0,0,0,0,0\n//INST\n///DATE 2024/01/01 00:00\n"
                                       "///ATTR SC,RW\n///GROUP1 RB1\nNOP\nCALL JOB:PART\nEND\n".replace("\n", "\r\n"), newline="")
    _check_ends_quickly(tmp_path, tmp_path / "MAIN.JBI", robot="sia20")


def test_a_fifo_or_dev_zero_profile_is_refused_at_once(tmp_path):
    for prof in (_fifo(tmp_path, "prof.toml"), Path("/dev/zero")):
        r = camtool("run", SPHERE, "-o", tmp_path / "out", "--set", 'post.formats=["rapid"]',
                    "--set", f"post.profiles={{rapid = '{prof}'}}", timeout=60)
        assert r.returncode == 2 and ("FIFO" in r.stderr or "device" in r.stderr), r.stderr


def test_a_file_where_a_folder_goes_is_one_line(tmp_path):
    (tmp_path / "plots").write_text("not a folder")
    with pytest.raises(BadInput, match="plots: is a file where camtool needs a folder"):
        safe_io.check_target(tmp_path, "plots/joint_angle.png")


# ---------------------------------------------------------------- 11. code dropped in a folder (issue #49)

PLANTED = ("numpy", "click", "camtool")
# launched as a user launches it, by its console script (``python -m`` would put the folder first itself)
CAMTOOL_SCRIPT = str(Path(sys.executable).with_name("camtool"))


def _plant(folder: Path, marks: Path) -> None:
    """A numpy.py, click.py and camtool.py that leave a mark when imported, then fail loudly."""
    for name in PLANTED:
        (folder / f"{name}.py").write_text(
            f"open({str(marks / name)!r}, 'w').write('imported')\nraise SystemExit('planted {name} ran')\n")


def test_code_dropped_in_the_batch_folder_or_the_job_folder_is_never_imported(tmp_path):
    jobs, marks = tmp_path / "jobs", tmp_path / "marks"
    jobs.mkdir()
    marks.mkdir()
    (jobs / "a.toml").write_text(SPHERE.read_text().replace('file = "', f'file = "{SAMPLES}/'))
    _plant(jobs, marks)  # the folder batch runs from, and the job's own folder
    r = subprocess.run([CAMTOOL_SCRIPT, "batch", jobs / "a.toml", "-o", tmp_path / "out",
                        "-j", "1", *SMALL], capture_output=True, text=True, timeout=LIMIT_S, cwd=jobs)
    assert not list(marks.iterdir()), r.stderr
    assert r.returncode == 0, r.stderr + (tmp_path / "out" / "a" / "camtool.log").read_text()


def test_code_dropped_in_the_hot_folder_is_never_imported(tmp_path):
    hot, marks = tmp_path / "hot", tmp_path / "marks"
    hot.mkdir()
    marks.mkdir()
    (hot / "part.stl").write_bytes((SAMPLES / "plate_hole.stl").read_bytes())
    _plant(hot, marks)  # the watcher's working folder and the folder its jobs come from
    r = subprocess.run([CAMTOOL_SCRIPT, "watch", hot, "-o", tmp_path / "out", "--template",
                        SAMPLES / "plate_hole.toml", "--set", "raster.step_over_mm=40", "--set", "raster.pitch_mm=8",
                        "--set", 'post.formats=["csv"]', "--once", "--interval", "0.1", "-j", "1"],
                       capture_output=True, text=True, timeout=LIMIT_S, cwd=hot)
    assert not list(marks.iterdir()), r.stderr
    assert r.returncode == 0, r.stderr


# ---------------------------------------------------------------- 12. text that leaves the run (issue #49)

def test_joint_names_never_become_spreadsheet_formulas():
    import dataclasses

    from camtool.program.text import column_names
    from camtool.robots.library import get_robot
    from postprocessors.csv.dialect import columns_for
    from postprocessors.csv.parser import columns

    hostile = ["=1+1", "+1+2", "@SUM(A1:A9)", "-2+3", "j5", "j5", "cmd|' /C calc'!A0", "ok_name", "\t=x"]
    names = column_names(hostile)
    assert len(set(names)) == len(names)
    assert all(n[:1].isalpha() and n.replace("_", "").isalnum() for n in names), names
    robot = get_robot("seed8")
    robot = dataclasses.replace(robot, joint_names=tuple(hostile[:robot.dof]))
    header = columns_for(robot, "deg")
    assert not [c for c in header if c[:1] in "=+-@\t\r"], header
    t, q = columns("x.csv", header, np.zeros((2, robot.dof + 1)), robot)  # read back by the same names
    assert q.shape == (2, robot.dof)


def test_a_workpiece_line_is_never_quoted_into_an_error(tmp_path):
    secret = "root-password-hunter2-do-not-leak"
    for name, text in [("a.xyz", f"1 2 3\n{secret} 5 6\n"), ("b.obj", f"v 1 2 3\nv {secret}\n"),
                       ("c.ply", f"ply\nformat ascii 1.0\n{secret}\nend_header\n"),
                       ("d.stl", f"solid x\nfacet normal 0 0 1\nouter loop\nvertex {secret} 0 0\n"),
                       ("e.off", f"OFF\n3 1 0\n{secret}\n0 1 0\n0 0 1\n3 0 1 2\n"),
                       ("f.pcd", f"# .PCD\n{secret}\n")]:
        f = tmp_path / name
        f.write_text(text)
        r = camtool("fit", f, "-o", tmp_path / f"out_{name}")
        assert r.returncode == 2, r.stderr
        assert "hunter2" not in r.stderr + r.stdout, (name, r.stderr)
