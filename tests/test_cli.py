"""CLI basics: version, robots, fk, and error mapping."""
import json

import numpy as np
import pytest

from conftest import SAMPLES, run_camtool


def test_version(cli):
    r = cli("--version")
    assert r.exit_code == 0 and "camtool" in r.output


def test_fk_seed8_home_json(cli):
    r = cli("fk", "seed8", *[0] * 8, "--json")
    assert r.exit_code == 0
    d = json.loads(r.output)
    assert np.allclose(d["position_mm"], [0, 0, 1448])
    assert np.allclose(d["quaternion_wxyz"], [1, 0, 0, 0])


def test_fk_degrees(cli):
    r = cli("fk", "sia20_paper", 90, 0, 0, 0, 0, 0, 0, "--deg", "--json")
    assert np.allclose(json.loads(r.output)["position_mm"], [0, 0, 1291])
    r = cli("fk", "sia20", 90, 0, 0, 0, 0, 0, 0, "--deg", "--json")   # the SIA20D: 410 + 490 + 420 + 180
    assert np.allclose(json.loads(r.output)["position_mm"], [0, 0, 1500])


def test_fk_negative_values_and_wrong_count(cli):
    assert cli("fk", "irb2400", "-0.5", 0, 0, 0, 0, 0).exit_code == 0
    r = cli("fk", "irb2400", 0, 0)
    assert r.exit_code == 2 and "has 6 joints" in r.output


def test_robots_json_lists_seven_with_limits(cli):
    r = cli("robots", "--json")
    robots = {d["name"]: d for d in json.loads(r.output)}
    assert set(robots) == {"seed8", "irb2400", "irb2400_paper", "sia20", "sia20_paper", "kr16", "m20ia"}
    seed8 = robots["seed8"]
    assert seed8["dof"] == 8 and seed8["joints"][0]["type"] == "prismatic"
    assert seed8["joints"][0]["lower"] == -1000 and seed8["joints"][1]["upper"] == pytest.approx(170)
    assert robots["irb2400"]["joints"][1]["lower"] == pytest.approx(-100)


# libraries that cost start-up time and that `camtool --help` and `camtool robots` do not need (issue #25);
# the robots are Pinocchio models, so listing them loads Pinocchio
HEAVY = ("scipy", "open3d", "trimesh", "plotly", "matplotlib", "numba", "cv2", "pinocchio")


@pytest.mark.parametrize("args, needed", [(["--help"], ()), (["robots"], ("pinocchio",)),
                                          (["robots", "--json"], ("pinocchio",))])
def test_start_up_loads_no_heavy_library(args, needed):
    import subprocess
    import sys

    code = ("import atexit, sys\n"   # main() leaves by os._exit, after the exit handlers (cli.leave)
            f"sys.argv = ['camtool', *{args!r}]\n"
            "from camtool.cli import main\n"
            f"atexit.register(lambda: print(sorted({{m.partition('.')[0] for m in sys.modules}} & set({HEAVY!r})), "
            "file=sys.stderr))\n"
            "main()\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stderr.splitlines()[-1] == repr(sorted(needed))


@pytest.mark.parametrize("code, status, stderr", [(3, 3, ""), (None, 0, ""), ("bad", 1, "bad\n")])
def test_leave_runs_exit_handlers_and_flushes(code, status, stderr):
    """``cli.leave`` ends the process at once, but only after the exit handlers ran and both streams were
    flushed: the code as the interpreter's own exit gives it (None 0, a message 1)."""
    import subprocess
    import sys

    script = ("import atexit, sys\n"
              "from camtool.cli import leave\n"
              "atexit.register(lambda: sys.stdout.write(' handled'))\n"
              "sys.stdout.write('unflushed')\n"
              f"leave({code!r})\n"
              "print('not reached')\n")
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert (r.returncode, r.stdout, r.stderr) == (status, "unflushed handled", stderr)


def test_output_cut_short_by_its_reader_is_no_error():
    """`camtool robots | head -1`: the reader goes away; camtool exits 0, without a traceback."""
    import subprocess
    import sys

    p = subprocess.Popen([sys.executable, "-m", "camtool.cli", "robots"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE)
    p.stdout.readline()
    p.stdout.close()
    _, err = p.communicate(timeout=60)
    assert p.returncode == 0 and b"Traceback" not in err


def test_unknown_robot_one_line_exit_2():
    r = run_camtool("fk", "ur5", 0)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "unknown robot" in r.stderr




def test_run_prints_each_workpiece_warning_once(cli, monkeypatch):
    """A re-plan (leads lifted clear, a partial run) passes the workpiece and its fit to the stage log again: each
    warning is still one line on stderr (the IEA blade's fold warning came twice)."""
    from contextlib import nullcontext
    from types import SimpleNamespace

    import camtool.run.part_stages as part_stages
    import camtool.run.pipeline as pipeline
    from camtool.errors import BadInput

    def run_job(job, outdir, compare=False, on_stage=None, part=None):
        fold, dup = "part.stl: the surface folds back onto itself at 1 triangle", "part.stl: 3 duplicate vertices"
        on_stage("workpiece", SimpleNamespace(warnings=(fold,)))
        on_stage("fit", SimpleNamespace(warnings=(fold,)))
        on_stage("workpiece", SimpleNamespace(warnings=(fold, dup)))   # the re-plan
        raise BadInput("the motion check failed")

    monkeypatch.setattr(part_stages, "PartAhead", lambda job: nullcontext())
    monkeypatch.setattr(pipeline, "run_job", run_job)
    r = cli("run", SAMPLES / "irb2400_plate.toml", "--quiet")
    lines = r.stderr.strip().splitlines()
    assert r.exit_code == 2
    assert lines.count("camtool: warning: part.stl: the surface folds back onto itself at 1 triangle") == 1
    assert lines.count("camtool: warning: part.stl: 3 duplicate vertices") == 1
