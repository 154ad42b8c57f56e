"""A hostile cell, second round (issue #49): malformed values are one line and exit 2, never an internal
error, and refused before any work."""
from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest

from conftest import ROOT, SAMPLES

SPHERE = SAMPLES / "sphere.toml"
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def camtool(*args, timeout=60, cwd=None):
    return subprocess.run([sys.executable, "-m", "camtool.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env=ENV, cwd=cwd)


def one_line(r, expect=""):
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2, r.stderr
    assert len(lines) == 1 and lines[0].startswith("camtool: error: "), r.stderr
    assert "internal error" not in r.stderr and expect in lines[0], lines[0]
    return lines[0]


def test_a_300_character_name_is_one_line(tmp_path):
    long = "a" * 300
    one_line(camtool("run", tmp_path / f"{long}.toml", "-o", tmp_path / "out"), "too long")
    one_line(camtool("fit", tmp_path / f"{long}.stl", "-o", tmp_path / "out"), "too long")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("value", ["9" * 5000, "9" * 400])
def test_a_huge_integer_in_set_is_one_line(tmp_path, value):
    one_line(camtool("run", SPHERE, "-o", tmp_path / "out", "--set", f"raster.lead_mm={value}"), "digits")


def test_a_huge_integer_in_a_job_robot_or_profile_toml_is_one_line(tmp_path):
    job = tmp_path / "job.toml"
    job.write_text(SPHERE.read_text().replace("lead_mm = 20.0", "lead_mm = " + "9" * 5000))
    one_line(camtool("run", job, "-o", tmp_path / "out"), "digits")
    robot = tmp_path / "r.toml"
    robot.write_text((ROOT / "camtool/robots/data/seed8.toml").read_text() + "\nx = " + "9" * 5000 + "\n")
    job.write_text(SPHERE.read_text().replace('name = "seed8"', f'name = "{robot}"'))
    one_line(camtool("run", job, "-o", tmp_path / "out"), "digits")
    profile = tmp_path / "p.toml"
    profile.write_text("x = " + "9" * 5000 + "\n")
    from camtool.errors import BadInput
    from camtool.program.profiles import read_profile_file

    with pytest.raises(BadInput, match="digits"):
        read_profile_file(profile)


def test_a_nul_byte_in_post_profiles_is_one_line(tmp_path):
    one_line(camtool("run", SPHERE, "-o", tmp_path / "out", "--set", 'post.profiles={rapid="a\\u0000b"}'), "NUL")


def test_a_process_grid_of_a_micrometre_is_refused_before_any_work(tmp_path):
    t = time.monotonic()
    one_line(camtool("run", SPHERE, "-o", tmp_path / "out", "--set", "process.kind=polish",
                     "--set", "process.grid_mm=0.001"), "process.grid_mm")
    assert time.monotonic() - t < 30 and not (tmp_path / "out").exists()


def test_the_map_grid_refuses_too_many_cells_as_bad_input():
    from types import SimpleNamespace

    import numpy as np

    from camtool.errors import BadInput
    from camtool.process.grid import grid_shape

    boundary = SimpleNamespace(bounds=lambda: (np.zeros(2), np.full(2, 1000.0)))
    with pytest.raises(BadInput, match="grid_mm"):
        grid_shape(SimpleNamespace(boundary=boundary, model="plane"), 0.06, 1.0)
