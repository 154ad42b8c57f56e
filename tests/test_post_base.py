"""Plugin base and registry: built-ins registered in code, a third-party package from outside."""
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from camtool.errors import BadInput
from camtool.program.plugin import PostProcessor
from camtool.program.registry import describe_plugins, discover, get_plugin
from camtool.program.text import chunks, sanitise_name

PKG = Path(__file__).parent / "plugin_pkg"


def test_builtins_are_registered_in_code():
    found = discover()
    for name, ext in (("rapid", ".mod"), ("inform", ".JBI"), ("csv", ".csv")):
        info = found[name]
        assert info.error == ""
        assert info.source == "camtool" and info.builtin  # registered in camtool.program.registry
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
    """The installed demo plugin writes a program through camtool.program.post in a fresh process."""
    src = tmp_path / "src"
    shutil.copytree(PKG, src)
    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation",
                    "--no-index", "--target", str(target), str(src)], check=True, capture_output=True)
    script = f"""
import sys; sys.path.insert(0, {str(Path(__file__).parent)!r})
from pathlib import Path
from camtool.job import load_job
from camtool.run.post_inputs import write_job_programs
from camtool.robots import get_robot
from post_fixtures import smooth_trajectory
job_file = Path({str(tmp_path)!r}) / "job.toml"
job_file.write_text('[workpiece]\\nfile = "x.stl"\\n[robot]\\nname = "irb2400"\\n[post]\\nformats = ["demo"]\\nprogram_name = "DEMO"\\n')
r = get_robot("irb2400")
print([p.name for p in write_job_programs(smooth_trajectory(r, 20), r, load_job(job_file), Path({str(tmp_path / 'out')!r}))])
"""
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": str(target)})
    assert out.returncode == 0, out.stderr
    assert "['DEMO.txt']" in out.stdout
    assert len((tmp_path / "out" / "DEMO.txt").read_text().splitlines()) == 20


def test_discovery_scans_the_entry_points_once_and_can_be_cleared(monkeypatch, tmp_path):
    import camtool.program.registry as base
    from camtool.job import load_job
    from camtool.run.post_inputs import write_job_programs
    from camtool.robots import get_robot
    from test_post import rows_trajectory

    scans = []
    real = base.entry_points
    monkeypatch.setattr(base, "entry_points", lambda **kw: scans.append(kw) or real(**kw))
    base.clear_cache()
    try:
        job_file = tmp_path / "job.toml"
        job_file.write_text('[workpiece]\nfile = "x.stl"\n[robot]\nname = "seed8"\n[post]\n')
        r = get_robot("seed8")
        write_job_programs(rows_trajectory(r), r, load_job(job_file), tmp_path / "out")  # 3 formats
        describe_plugins()
        get_plugin("csv")
        assert len(scans) == 1
        found = discover()
        found.pop("rapid")  # callers get their own dict: the cache is not changed
        assert "rapid" in discover()
        base.clear_cache()
        discover()
        assert len(scans) == 2
    finally:
        base.clear_cache()


def test_describe_says_which_check_a_plugin_has():
    rows = {r["name"]: r for r in describe_plugins()}
    assert {rows[n]["check"] for n in ("rapid", "inform", "csv")} == {"own"}


def test_dead_helper_is_gone():
    import postprocessors.base as base
    assert not hasattr(base, "joint_values_native")


class _NoCheckPost(PostProcessor):
    """A plugin without ``check``: one line per waypoint, ``t q1 q2 ...``; ``spoil`` breaks row 3."""

    name = "nocheck"
    extension = ".txt"
    requires_profile = False
    options_schema = {}

    def __init__(self, spoil=None):
        self.spoil = spoil

    def write(self, trajectory, robot, profile, outdir, process):
        rows = [[float(t), *map(float, q)] for t, q in zip(trajectory.t_s, trajectory.q)]
        if self.spoil is not None:
            rows[3][1] = self.spoil
        path = Path(outdir) / "P.txt"
        path.write_text("\n".join(" ".join(repr(v) for v in row) for row in rows) + "\n")
        return [path]

    def read(self, path, robot, profile):
        import numpy as np
        data = np.loadtxt(path, ndmin=2)
        return np.concatenate([[np.nan], np.diff(data[:, 0])]), data[:, 1:]


@pytest.mark.parametrize("spoil,message", [(None, None), (float("nan"), "move 4: j1: value is not a finite number"),
                                           (9.0, "move 4: j1 = 515.6620 deg outside the limits")])
def test_a_plugin_without_check_is_read_back_and_checked(spoil, message, monkeypatch, tmp_path):
    import camtool.run.post_inputs as post
    from camtool.errors import PlanInfeasible
    from camtool.job import load_job
    from camtool.run.post_inputs import write_job_programs
    from camtool.robots import get_robot
    from post_fixtures import smooth_trajectory

    plugin = _NoCheckPost(spoil)
    real = post.get_plugin
    monkeypatch.setattr(post, "get_plugin", lambda name: plugin if name == "nocheck" else real(name))
    job_file = tmp_path / "job.toml"
    job_file.write_text('[workpiece]\nfile = "x.stl"\n[robot]\nname = "irb2400"\n[post]\nformats = ["nocheck"]\n')
    r = get_robot("irb2400")
    out = tmp_path / "out"
    if message is None:
        assert [f.name for f in write_job_programs(smooth_trajectory(r, 20), r, load_job(job_file), out)] == ["P.txt"]
        return
    with pytest.raises(PlanInfeasible) as exc:
        write_job_programs(smooth_trajectory(r, 20), r, load_job(job_file), out)
    assert any(message in f and str(out) in f for f in exc.value.report["findings"]), exc.value.report
    assert not (out / "P.txt").exists()


def test_read_back_check_reports_a_reader_that_fails(tmp_path):
    from camtool.robots import get_robot
    from camtool.program.check import check_file

    f = tmp_path / "P.txt"
    f.write_text("not numbers\n")
    found = check_file(_NoCheckPost(), f, get_robot("irb2400"), None)
    assert len(found) == 1 and "'nocheck' cannot read it back (ValueError" in found[0]


def test_a_packaged_post_delegates_to_its_modules():
    """PackagedPost: a plugin that names its dialect, writer, parser and checker modules gets
    validate_profile, write, read, read_program and check from them, and counts as simulated and
    self-checking; the built-ins are such plugins."""
    from types import SimpleNamespace

    from camtool.program.plugin import PackagedPost
    from camtool.program.registry import get_plugin

    calls = []
    mod = SimpleNamespace(validate_profile=lambda p, r: calls.append("validate"),
                          write=lambda *a: calls.append("write") or [],
                          read=lambda *a: calls.append("read") or (None, None),
                          read_program=lambda *a: calls.append("read_program"),
                          check=lambda *a: calls.append("check") or [])

    class Toy(PackagedPost):
        name, extension = "toy", ".toy"
        dialect = writer = parser = checker = mod

    t = Toy()
    t.validate_profile(None, None)
    t.write(None, None, None, None, None)
    t.read(None, None, None)
    t.read_program(None, None, None)
    t.check(None, None, None)
    assert calls == ["validate", "write", "read", "read_program", "check"]
    assert t.simulated and t.own_check
    assert all(isinstance(get_plugin(n), PackagedPost) for n in ("rapid", "inform"))
