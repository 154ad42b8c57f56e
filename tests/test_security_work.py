"""A hostile cell, second round (issue #49): no input makes the work unbounded; each case ends within 10 s."""
from __future__ import annotations

import os
import subprocess
import sys
import time

from conftest import ROOT, SAMPLES

ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def camtool(*args, timeout=60, cwd=None):
    return subprocess.run([sys.executable, "-m", "camtool.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env=ENV, cwd=cwd)


def test_the_rapid_number_pattern_is_linear_on_200000_digits():
    from postprocessors.rapid import dialect as D

    head = "    MoveAbsJ [[0,0,0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100"
    for line in (head + " \\T:=" + "1" * 200_000 + " x", head + " " * 200_000 + "x"):
        t = time.monotonic()
        assert D.MOVE_RE.match(line) is None
        assert time.monotonic() - t < 1.0
    ok = D.MOVE_RE.match(head + " \\T:=1.5e-3, z1, tool0 \\WObj:=wobj0;")
    assert ok and ok["t"] == "1.5e-3" and ok["wobj"] == "wobj0"


def test_check_of_a_rapid_line_of_200000_digits_ends_at_once(tmp_path):
    mod = tmp_path / "BIG.mod"
    mod.write_text("MODULE BIG\n  PROC main()\n    MoveAbsJ [[0,0,0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100 \\T:="
                   + "1" * 200_000 + " x\n  ENDPROC\nENDMODULE\n")
    t = time.monotonic()
    r = camtool("check", mod, "--robot", "irb2400", timeout=60)
    assert "internal error" not in r.stderr and "Traceback" not in r.stderr
    assert time.monotonic() - t < 30


def test_the_krl_and_fanuc_number_patterns_are_linear():
    import re

    from postprocessors.fanuc import dialect as F
    from postprocessors.krl import dialect as K

    for num in (K.NUM, F.NUM):
        t = time.monotonic()
        assert re.fullmatch(num + ",", "1" * 200_000) is None
        assert time.monotonic() - t < 1.0


JBI = ("/JOB\r\n//NAME {n}\r\n//POS\r\n///NPOS 0,0,0,0,0,0\r\n//INST\r\n///DATE 2020/01/01 00:00\r\n"
       "///ATTR SC,RW\r\n///GROUP1 RB1\r\nNOP\r\n")


def test_an_inform_job_of_100000_calls_is_one_line(tmp_path):
    (tmp_path / "BIG.JBI").write_bytes((JBI.format(n="BIG") + "CALL JOB:NEW\r\n" * 100_000 + "END\r\n").encode())
    (tmp_path / "NEW.JBI").write_bytes((JBI.format(n="NEW") + "END\r\n").encode())
    t = time.monotonic()
    r = camtool("check", tmp_path / "BIG.JBI", "--robot", "sia20", timeout=60)
    assert r.returncode == 2 and "CALL JOB" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert time.monotonic() - t < 30


def test_a_called_job_is_parsed_once_however_often_it_is_called(tmp_path, monkeypatch):
    import postprocessors.inform.parser as P

    (tmp_path / "MID.JBI").write_bytes((JBI.format(n="MID") + "CALL JOB:NEW\r\n" * 500 + "END\r\n").encode())
    (tmp_path / "NEW.JBI").write_bytes((JBI.format(n="NEW") + "END\r\n").encode())
    reads = []
    orig = P.read_bytes
    monkeypatch.setattr(P, "read_bytes", lambda p: reads.append(p) or orig(p))
    P.forget()
    files = P.job_files(tmp_path / "MID.JBI")
    assert len(files) == 501 and len(reads) == 2


def test_a_raster_just_under_the_memory_cap_is_refused_before_any_work(tmp_path):
    t = time.monotonic()
    r = camtool("raster", SAMPLES / "sphere.toml", "-o", tmp_path / "out", "--set", "raster.pitch_mm=0.1",
                "--set", "raster.step_over_mm=0.5", timeout=120)
    assert r.returncode == 2 and "raster.max_poses" in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert time.monotonic() - t < 60
