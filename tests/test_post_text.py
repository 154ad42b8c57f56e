"""Text in programs (issue #28 item 2): every comment, header, job and file name a program
carries is sanitised per dialect, and `camtool check` flags code in comments."""
import re

import numpy as np
import pytest

from camtool.program.process import ProcessInfo
from camtool.program.profiles import load_profile
from camtool.robots import get_robot
from post_fixtures import profile_for_tests, smooth_trajectory
from postprocessors.inform import InformPost
from postprocessors.inform.dialect import CODE_IN_COMMENT_RE as INFORM_CODE
from postprocessors.inform.dialect import comment_text as inform_comment
from postprocessors.rapid import RapidPost
from postprocessors.rapid.dialect import CODE_IN_COMMENT_RE as RAPID_CODE
from postprocessors.rapid.dialect import comment_text as rapid_comment

HOSTILE = [
    "job\nENDPROC\nPROC evil()\n  SetDO doBad, 1;\nENDPROC\nPROC main()",
    "x\rMODULE Evil\r",
    'quote " and \' and \\ backslash',
    "tab\tbell\x07nul\x00esc\x1b[31m del\x7f",
    "плита.toml",
    "日本語のジョブ",
    "a := b; %\"evil\"%;",
    "MoveL [[0,0,0],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v10, fine, tool0;",
    "MOVJ C00000 VJ=10.00 PL=0\r\nCALL JOB:EVIL\r\nEND",
    "DOUT OT#(1) ON",
    "\u2028line separator\u2029paragraph\x85next line",
    "x" * 5_000_000,
]


@pytest.mark.parametrize("raw", HOSTILE, ids=range(len(HOSTILE)))
@pytest.mark.parametrize("sanitise,code,max_len", [(rapid_comment, RAPID_CODE, 80), (inform_comment, INFORM_CODE, 32)],
                         ids=["rapid", "inform"])
def test_comment_text_is_one_safe_line(raw, sanitise, code, max_len):
    s = sanitise(raw)
    assert len(s) <= max_len
    assert all(" " <= c <= "~" for c in s)  # printable ASCII only: no line break of any kind
    assert not code.search(s), s  # no statement shape survives
    assert s == sanitise(s)  # idempotent: a sanitised text stays as it is


def test_long_text_is_truncated_visibly():
    assert rapid_comment("y" * 5_000_000).endswith("...")


def _write(post, robot_name, fmt, tmp_path, job_name):
    r = get_robot(robot_name)
    p = profile_for_tests(robot_name, fmt, r, tmp_path)  # sia20 INFORM: with test pulse factors
    if fmt == "inform":   # joint moves: the fixture's sinusoid passes the SIA20D's straight-arm singularity
        p = p.with_changes(options={"motion": "joint"})
    files = post.write(smooth_trajectory(r, 20), r, p, tmp_path, ProcessInfo(job_name=job_name))
    return r, p, files


@pytest.mark.parametrize("job_name", [HOSTILE[0], HOSTILE[4], HOSTILE[8], "x" * 5_000_000])
def test_a_hostile_job_name_writes_a_clean_rapid_program(tmp_path, job_name):
    r, p, files = _write(RapidPost(), "irb2400", "rapid", tmp_path, job_name)
    text = files[1].read_bytes().decode("ascii")  # ASCII: a non-Latin-1 name cannot fail to encode
    assert RapidPost().check(files[0], r, p) == []
    statements = [ln.strip() for ln in text.splitlines() if not ln.strip().startswith("!")]
    assert sum(s.startswith("PROC ") for s in statements) == 1 and statements.count("ENDPROC") == 1
    assert not any("evil" in s.lower() or "doBad" in s for s in statements)
    job_line = next(ln for ln in text.splitlines() if ln.strip().startswith("! Job:"))
    assert len(job_line) < 160


@pytest.mark.parametrize("job_name", [HOSTILE[0], HOSTILE[4], HOSTILE[8]])
def test_a_hostile_job_name_writes_a_clean_inform_job(tmp_path, job_name):
    r, p, files = _write(InformPost(), "sia20", "inform", tmp_path, job_name)
    raw = files[0].read_bytes()
    raw.decode("ascii")
    assert InformPost().check(files[0], r, p) == []
    lines = raw.decode("ascii").split("\r\n")
    assert lines.count("END") == 1 and not any(ln.startswith("CALL") for ln in lines)


def test_check_flags_code_in_a_rapid_comment(tmp_path):
    r, p, files = _write(RapidPost(), "irb2400", "rapid", tmp_path, "part.toml")
    text = files[1].read_text()
    files[1].write_text(text.replace("! Job: part.toml", "! Job: x ENDPROC PROC evil()", 1))
    found = RapidPost().check(files[0], r, p)
    assert any("code in a comment" in f for f in found)


def test_check_flags_code_in_an_inform_comment(tmp_path):
    r, p, files = _write(InformPost(), "sia20", "inform", tmp_path, "part.toml")
    raw = files[0].read_bytes()
    files[0].write_bytes(raw.replace(b"\r\nNOP\r\n", b"\r\nNOP\r\n'CALL JOB:EVIL\r\n", 1))
    found = InformPost().check(files[0], r, p)
    assert any("code in a comment" in f for f in found)


def test_module_dir_cannot_break_out_of_its_string(tmp_path):
    from camtool.errors import BadInput

    r = get_robot("seed8")
    p = load_profile(None, "seed8", "rapid", r).with_changes(options={"module_dir": 'HOME:";\nPROC x()'})
    with pytest.raises(BadInput, match="module_dir"):
        RapidPost().write(smooth_trajectory(r, 5), r, p, tmp_path)
