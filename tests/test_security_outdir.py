"""A hostile cell, second round (issue #49): the output folder is resolved once without following links,
held by its descriptor from the first check to the last rename, and every command that writes into -o
(stage commands too) checks and locks it as `camtool run` does."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from camtool import safe_io
from camtool.errors import BadInput

from conftest import ROOT, SAMPLES

ENV = {**os.environ, "PYTHONPATH": str(ROOT)}
SPHERE = SAMPLES / "sphere.toml"
SMALL = ["--set", "raster.step_over_mm=60", "--set", "raster.pitch_mm=8", "--set", 'post.formats=["csv"]']


def camtool(*args, timeout=120, env=None):
    return subprocess.run([sys.executable, "-m", "camtool.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env=env or ENV)


def one_line(r, expect=""):
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2, r.stderr
    assert len(lines) == 1 and lines[0].startswith("camtool: error: "), r.stderr
    assert "internal error" not in r.stderr and expect in lines[0], lines[0]


def _tree(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")} if folder.exists() else set()


# ---------------------------------------------------------------- resolving -o

def test_dotdot_through_a_link_is_refused(tmp_path):
    home = tmp_path / "home"
    home.mkdir()
    (home / "report.json").write_text("{}")
    (tmp_path / "A").mkdir()
    (tmp_path / "A" / "x").symlink_to(home)
    with pytest.raises(BadInput, match="is a symlink"):
        safe_io.resolve_outdir(tmp_path / "A" / "x" / ".." / ".." / "home")
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "report.json").write_text('{"foreign": 1}')
    (tmp_path / "link").symlink_to(tmp_path / "A")
    with pytest.raises(BadInput, match="is a symlink"):
        safe_io.resolve_outdir(f"{tmp_path}/link/../out")
    assert (tmp_path / "out" / "report.json").read_text() == '{"foreign": 1}'
    assert _tree(home) == {"report.json"}


def test_dotdot_without_a_link_is_the_folder_it_names(tmp_path):
    (tmp_path / "a").mkdir()
    fd = safe_io.resolve_outdir(f"{tmp_path}/a/../b")
    try:
        assert os.readlink(f"/proc/self/fd/{fd}") == str(tmp_path / "b")
    finally:
        os.close(fd)


# ---------------------------------------------------------------- held by its descriptor

@pytest.mark.parametrize("swap", ["symlink", "rename"])
def test_a_held_output_folder_swapped_mid_run_is_never_written_elsewhere(tmp_path, swap):
    out, moved, elsewhere = tmp_path / "out", tmp_path / "moved", tmp_path / "elsewhere"
    elsewhere.mkdir()
    with safe_io.held_outdir(out, check=True), safe_io.locked(out):
        safe_io.write_file(out, "a.txt", "1")
        os.rename(out, moved)
        if swap == "symlink":
            out.symlink_to(elsewhere)
        safe_io.make_folder(out, "plots")
        safe_io.write_file(out / "plots", "b.png", "2")
        stage = Path(safe_io.at(out)) / ".stage"
        stage.mkdir()
        (stage / "c.mod").write_text("3")
        safe_io.place_file(stage / "c.mod", out, "c.mod")
        with safe_io.new_file(out, "camtool.log") as log:
            log.write(b"x")
        safe_io.remove_file(out, "a.txt")
    assert _tree(elsewhere) == set()
    assert out.is_symlink() if swap == "symlink" else not out.exists()  # never re-created
    assert {"plots/b.png", "c.mod", "camtool.log", ".camtool-lock"} <= _tree(moved)
    assert not (moved / "a.txt").exists()


# ---------------------------------------------------------------- stage commands: run's rules

def test_fit_refuses_home_a_symlink_and_a_fifo_as_output_folder(tmp_path):
    home = tmp_path / "home"
    home.mkdir()
    one_line(camtool("fit", SPHERE, "-o", home, env={**ENV, "HOME": str(home), "MPLCONFIGDIR": str(tmp_path / "mpl")}),
             "home folder")
    assert _tree(home) == set()
    (tmp_path / "link").symlink_to(home)
    one_line(camtool("fit", SPHERE, "-o", tmp_path / "link"), "is a symlink")
    fifo_dir = tmp_path / "ff"
    fifo_dir.mkdir()
    os.mkfifo(fifo_dir / "p")
    one_line(camtool("fit", SPHERE, "-o", fifo_dir), "FIFO")
    assert _tree(home) == set()


@pytest.mark.parametrize("cmd", ["fit", "raster", "plan", "time"])
def test_stage_commands_respect_the_lock_of_a_running_camtool(tmp_path, cmd):
    out = tmp_path / "out"
    with safe_io.writing_into(out):  # as `camtool run` holds it
        one_line(camtool(cmd, SPHERE, "-o", out, *SMALL[:4]), "another camtool process")
    assert _tree(out) == {".camtool-lock"}
