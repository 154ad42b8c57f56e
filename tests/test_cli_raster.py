"""``camtool raster`` end to end on the sample jobs (workpiece -> fit -> raster)."""
import json

import numpy as np
import pytest

from camtool.run.stage_files import load_stage as load_path
from camtool.path.toolpath import ZONE_CODE
from camtool.transforms import matrix_from_xyz_rpy

from conftest import SAMPLES, run_camtool

FAST = ("--set", "workpiece.sample_points=20000")  # a lighter fit keeps the tests quick


@pytest.fixture(scope="module")
def plate_run(tmp_path_factory):
    """One run on the plate job with --json, --save and --plot."""
    out = tmp_path_factory.mktemp("raster")
    from click.testing import CliRunner

    from camtool.cli import cli as group

    # the default sampling: with 20k points the fitted hole's corners come out chamfered
    args = ["raster", str(SAMPLES / "plate_hole.toml"), "--json",
            "--save", str(out / "plate.npz"), "--plot", str(out / "plate.png")]
    r = CliRunner().invoke(group, args, catch_exceptions=False)
    return r, out


def test_sphere_job_text(cli):
    r = cli("raster", SAMPLES / "sphere.toml", *FAST)
    assert r.exit_code == 0, r.output
    lines = dict(line.split(None, 1) if not line.startswith(("work points", "zone points", "path length"))
                 else (line[:16].strip(), line[16:].strip()) for line in r.output.strip().splitlines())
    assert lines["surface"] == "sphere"
    assert 70 <= int(lines["rows"]) <= 76
    assert 9000 <= int(lines["work points"]) <= 11500  # the seed's "about 10,000 points"
    assert float(lines["coverage"].split()[0]) >= 99.5


def test_plate_job_json_save_plot(plate_run):
    r, out = plate_run
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    assert d["surface"] == "plane"
    assert d["coverage"] >= 0.995
    assert d["segments"] > d["rows"]  # rows through the hole are split
    assert d["work_points"] + d["zone_points"] > d["work_points"] > 2000
    path = load_path(out / "plate.npz")
    assert np.count_nonzero(path.zone == ZONE_CODE["work"]) == d["work_points"]
    assert path.length_mm() == pytest.approx(d["path_length_mm"], abs=1e-2)
    png = (out / "plate.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20000


def test_plate_work_points_avoid_the_hole(plate_run):
    _, out = plate_run
    path = load_path(out / "plate.npz")
    # back into the plate frame of samples/plate_hole.stl: hole 20..100 x -10..70 mm
    T = matrix_from_xyz_rpy([700, 0, 350], [0, -90, 0])
    p = (path.poses_mm[path.is_work, :3, 3] - T[:3, 3]) @ T[:3, :3]
    assert np.allclose(p[:, 2], 0, atol=0.5)
    inside = (p[:, 0] > 21) & (p[:, 0] < 99) & (p[:, 1] > -9) & (p[:, 1] < 69)
    assert not inside.any()
    assert np.all(np.abs(p[:, 0]) < 200) and np.all(np.abs(p[:, 1]) < 150)
    # tool z points into the plate: world +x, since the plate faces the robot (-x)
    assert np.allclose(path.poses_mm[path.is_work, :3, 2], [1, 0, 0], atol=1e-3)


def test_set_override_changes_the_raster(cli):
    base = json.loads(cli("raster", SAMPLES / "plate_hole.toml", *FAST, "--json").output)
    fine = json.loads(cli("raster", SAMPLES / "plate_hole.toml", *FAST, "--json",
                          "--set", "raster.step_over_mm=5", "--set", "raster.free_spin=true").output)
    assert fine["rows"] > 1.8 * base["rows"] and fine["free_spin"] and not base["free_spin"]


@pytest.mark.parametrize("args, words", [
    (("--set", "raster.step_over_mm=5000"), "larger than the patch"),
    (("--set", "raster.pitch_mm=0"), "raster.pitch_mm"),
    (("--set", "raster.tilt_deg=95"), "raster.tilt_deg"),
    (("--plot", "out.pdf"), "expected a .png"),
])
def test_bad_input_exit_2(cli, args, words):
    r = cli("raster", SAMPLES / "plate_hole.toml", *FAST, *args)
    assert r.exit_code == 2
    assert words in r.output and "Traceback" not in r.output


def test_missing_job_file_subprocess(tmp_path):
    r = run_camtool("raster", tmp_path / "nope.toml")
    assert r.returncode == 2
    assert "job file not found" in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_help_lists_options(cli):
    r = cli("raster", "--help")
    for opt in ("--json", "--plot", "--save", "--set"):
        assert opt in r.output
