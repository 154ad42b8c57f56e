"""A hostile cell, second round (issue #49): plugins are imported only when asked for and in time, allowed
by distribution, a name two packages claim is refused; batch jobs keep their result apart from stdout and
never outlive their batch; hot-folder names that collide get a suffix."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from camtool.program import registry
from camtool.program.plugin import PostProcessor

from conftest import ROOT, SAMPLES

ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


class _Kuka(PostProcessor):
    name = "kuka"
    extension = ".kuka"


def _ep(name, load, dist):
    return SimpleNamespace(name=name, value=f"{dist}:{name}", dist=SimpleNamespace(name=dist), load=load)


@pytest.fixture
def eps(monkeypatch):
    def install(*items):
        monkeypatch.setattr(registry, "entry_points", lambda **kw: list(items))
        registry.clear_cache()
    yield install
    registry.clear_cache()


def test_a_plugin_name_alone_does_not_allow_an_impostor(eps, monkeypatch):
    imported = []
    eps(_ep("kuka", lambda: imported.append("impostor") or _Kuka, "aaa-kuka"),
        _ep("kuka2", lambda: _Kuka, "camtool-kuka"))
    monkeypatch.setenv(registry.ALLOW_ENV, "kuka")
    registry.clear_cache()
    assert "kuka" not in registry.discover() and imported == []
    monkeypatch.setenv(registry.ALLOW_ENV, "camtool-kuka:kuka2")
    registry.clear_cache()
    assert set(registry.discover()) - set(registry.BUILTINS) == {"kuka2"}


def test_a_name_two_packages_claim_is_refused_for_both(eps):
    eps(_ep("kuka", lambda: _Kuka, "aaa-kuka"), _ep("kuka", lambda: _Kuka, "camtool-kuka"))
    assert "kuka" not in registry.discover()
    errors = [c.error for c in registry.clashes()]
    assert len(errors) == 2 and all("aaa-kuka, camtool-kuka" in e for e in errors)


def test_a_plugin_is_imported_only_when_its_format_is_asked_for_and_in_time(eps, monkeypatch):
    imported = []

    def hangs():
        imported.append(1)
        time.sleep(30)

    eps(_ep("slow", hangs, "slow-post"))
    monkeypatch.setenv(registry.TIMEOUT_ENV, "0.5")
    from camtool.program.check_program import format_of

    assert format_of(Path("NEW.mod")) == "rapid" and imported == []   # a built-in's file: no plugin imported
    assert registry.get_plugin("rapid").name == "rapid" and imported == []
    t = time.monotonic()
    with pytest.raises(Exception, match="did not finish within 0.5 s"):
        registry.get_plugin("slow")
    assert time.monotonic() - t < 5


# ---------------------------------------------------------------- batch jobs

def test_the_result_channel_is_apart_from_stdout(tmp_path):
    """The child's JSON reaches the parent on its own pipe, whatever the job prints on stdout."""
    code = ("import os, sys; from camtool.console import take_result_channel, echo_json\n"
            "take_result_channel(); print('noise'); echo_json({'ok': 1}); print('more noise')\n")
    r_fd, w_fd = os.pipe()
    proc = subprocess.Popen([sys.executable, "-c", code], env={**ENV, "CAMTOOL_RESULT_FD": str(w_fd)},
                            pass_fds=(w_fd,), stdout=subprocess.PIPE, text=True)
    os.close(w_fd)
    out, _ = proc.communicate(timeout=30)
    with os.fdopen(r_fd, "rb") as f:
        result = f.read()
    assert json.loads(result) == {"ok": 1}
    assert "noise" in out and "ok" not in out


def test_the_batch_runner_reads_the_result_pipe_not_stdout(tmp_path, monkeypatch):
    from camtool.batch import runner

    folder = tmp_path / "out" / "job"
    script = ("import os, json\nprint('plugin noise at import')\n"
              "fd = int(os.environ['CAMTOOL_RESULT_FD'])\n"
              "os.write(fd, json.dumps({'programs': [], 'plots': [], 'points_total': 7}).encode())\n")
    monkeypatch.setattr(runner, "job_command", lambda spec: [sys.executable, "-c", script])
    spec = runner.JobSpec(job=str(SAMPLES / "sphere.toml"), name="job", outdir=str(folder), overrides=(),
                          timeout_s=60, fingerprint="x")
    res = runner.run_one(spec)
    assert res.status == "ok" and res.points == 7, res
    assert "plugin noise at import" in (folder / "camtool.log").read_text()


def test_a_job_dies_with_its_batch_even_on_sigkill(tmp_path):
    """PR_SET_PDEATHSIG: the job process is killed when the process that started it is."""
    pidfile = tmp_path / "pid"
    code = f"""
import subprocess, sys, time
from camtool.alongside import die_with_parent
p = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"], preexec_fn=die_with_parent,
                     start_new_session=True)
open({str(pidfile)!r}, "w").write(str(p.pid))
time.sleep(60)
"""
    parent = subprocess.Popen([sys.executable, "-c", code], env=ENV)
    for _ in range(200):
        if pidfile.exists() and pidfile.read_text():
            break
        time.sleep(0.05)
    child = int(pidfile.read_text())
    parent.send_signal(signal.SIGKILL)
    parent.wait(timeout=10)
    for _ in range(100):
        try:
            os.kill(child, 0)
        except ProcessLookupError:
            break
        time.sleep(0.05)
    else:
        os.kill(child, signal.SIGKILL)
        pytest.fail("the job outlived its batch")


def test_sighup_is_handled_like_sigterm():
    from camtool.commands.options import sigterm_as_interrupt

    with sigterm_as_interrupt():
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGHUP)
            time.sleep(1)


# ---------------------------------------------------------------- hot-folder names

def test_hot_folder_names_that_collide_across_rounds_get_a_suffix(tmp_path):
    import json as _json

    from camtool.batch.watch import Watcher, output_names

    indir, out = tmp_path / "in", tmp_path / "out"
    indir.mkdir()
    out.mkdir()
    first, second = indir / "a b.stl", indir / "a_b.stl"
    (out / "summary.json").write_text(_json.dumps({"camtool": "x", "jobs": [
        {"name": "a_b.stl", "outdir": str(out / "a_b.stl"), "source": str(first), "status": "ok"}]}))
    w = Watcher(indir, out, tmp_path / "t.toml", {})
    again = w._unclaimed(output_names([first]))
    assert again == {first: "a_b.stl"}                      # its own folder, rerun in place
    later = w._unclaimed(output_names([second]))
    assert later[second].startswith("a_b.stl-") and len(later[second]) == len("a_b.stl-") + 8
    w._sources["b.stl"] = {"source": str(indir / "b.stl")}   # claimed earlier in this session
    assert w._unclaimed({indir / "sub" / "b.stl": "b.stl"})[indir / "sub" / "b.stl"] != "b.stl"
