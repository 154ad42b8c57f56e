"""Plugin protocol and discovery: built-ins via entry points, a third-party package from outside."""
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from camtool.errors import BadInput
from postprocessors.base import PostProcessor, chunks, describe_plugins, discover, get_plugin, sanitise_name

PKG = Path(__file__).parent / "plugin_pkg"


def test_builtins_are_discovered_through_entry_points():
    found = discover()
    for name, ext in (("rapid", ".mod"), ("inform", ".JBI"), ("csv", ".csv")):
        info = found[name]
        assert info.error == ""
        assert info.source == "camtool"  # from camtool's own pyproject entry points
        assert info.plugin.extension == ext
        assert isinstance(info.plugin, PostProcessor)
        for opt, spec in info.plugin.options_schema.items():
            typ, default, doc = spec
            assert isinstance(default, typ) and doc


def test_unknown_format_names_the_installed_ones():
    with pytest.raises(BadInput, match=r"no post-processor 'kuka'.*rapid"):
        get_plugin("kuka")


def test_describe_lists_options():
    rows = {r["name"]: r for r in describe_plugins()}
    assert rows["rapid"]["options"]["lines_per_module"]["default"] == 5000
    assert rows["inform"]["options"]["lines_per_job"]["type"] == "int"


@pytest.mark.parametrize("raw,kw,expected", [
    ("My Part ü", dict(max_len=32), "My_Part__"),
    ("9lives", dict(max_len=32), "p9lives"),
    ("MODULE", dict(max_len=32, reserved=frozenset({"MODULE"})), "MODULE_1"),
    ("long job name", dict(max_len=8, upper=True), "LONG_JOB"),
])
def test_sanitise_name(raw, kw, expected, caplog):
    name, note = sanitise_name(raw, **kw)
    assert name == expected
    assert raw in note and expected in note
    assert any(expected in r.getMessage() for r in caplog.records)


def test_valid_name_is_kept_without_note():
    assert sanitise_name("Part_001", max_len=32) == ("Part_001", "")


def test_chunks_cover_the_range():
    parts = chunks(12, 5)
    assert [list(r) for r in parts] == [[0, 1, 2, 3, 4], [5, 6, 7, 8, 9], [10, 11]]


def test_third_party_plugin_installed_with_pip_is_listed(tmp_path):
    src = tmp_path / "src"
    shutil.copytree(PKG, src)  # build in a copy: no build droppings in the repository
    target = tmp_path / "site"
    pip = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation",
                          "--no-index", "--target", str(target), str(src)], capture_output=True, text=True)
    assert pip.returncode == 0, pip.stderr
    env = {**os.environ, "PYTHONPATH": str(target)}
    out = subprocess.run([sys.executable, "-m", "camtool.cli", "posts", "--json"], capture_output=True,
                         text=True, env=env)
    assert out.returncode == 0, out.stderr
    rows = {r["name"]: r for r in json.loads(out.stdout)}
    assert rows["demo"]["source"] == "camtool-demo-post"
    assert rows["demo"]["extension"] == ".txt"
    assert rows["demo"]["options"]["separator"]["default"] == " "
    assert {"rapid", "inform", "csv"} <= set(rows)
    # and without the package on the path it is not there
    out2 = subprocess.run([sys.executable, "-m", "camtool.cli", "posts", "--json"], capture_output=True, text=True)
    assert "demo" not in {r["name"] for r in json.loads(out2.stdout)}


def test_third_party_plugin_runs_through_write_programs(tmp_path):
    """The installed demo plugin writes a program through camtool.post in a fresh process."""
    src = tmp_path / "src"
    shutil.copytree(PKG, src)
    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation",
                    "--no-index", "--target", str(target), str(src)], check=True, capture_output=True)
    script = f"""
import sys; sys.path.insert(0, {str(Path(__file__).parent)!r})
from pathlib import Path
from camtool.job import load_job
from camtool.post import write_programs
from camtool.robots import get_robot
from post_fixtures import smooth_trajectory
job_file = Path({str(tmp_path)!r}) / "job.toml"
job_file.write_text('[workpiece]\\nfile = "x.stl"\\n[robot]\\nname = "irb2400"\\n[post]\\nformats = ["demo"]\\nprogram_name = "DEMO"\\n')
r = get_robot("irb2400")
print([p.name for p in write_programs(smooth_trajectory(r, 20), r, load_job(job_file), Path({str(tmp_path / 'out')!r}))])
"""
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": str(target)})
    assert out.returncode == 0, out.stderr
    assert "['DEMO.txt']" in out.stdout
    assert len((tmp_path / "out" / "DEMO.txt").read_text().splitlines()) == 20
