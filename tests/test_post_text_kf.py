"""Text in KRL and LS programs (issue #47 item 6): the hostile-string corpus of the RAPID and INFORM
tests through both dialects' sanitisers, hostile job names into whole programs, and `camtool
check` flagging code in a comment."""
import numpy as np
import pytest

from camtool.program.process import ProcessInfo
from camtool.program.profiles import load_profile
from camtool.robots import get_robot
from postprocessors.fanuc import FanucPost
from postprocessors.fanuc.dialect import ATTR_COMMENT_MAX
from postprocessors.fanuc.dialect import CODE_IN_COMMENT_RE as LS_CODE
from postprocessors.fanuc.dialect import comment_text as ls_comment
from postprocessors.krl import KrlPost
from postprocessors.krl.dialect import CODE_IN_COMMENT_RE as KRL_CODE
from postprocessors.krl.dialect import comment_text as krl_comment
from test_post import rows_trajectory
from test_post_text import HOSTILE

KRL_EXTRA = ["x\r\nEND\r\nDEF evil( )\r\n$OUT[1]=TRUE\r\nPTP {A1 0}", ";FOLD evil\n$TOOL={X 9}", "&ACCESS RVP",
             "LIN XP3 C_DIS", "%{PE}%R 8.3"]
LS_EXTRA = ["x ;\r\n  2:J P[1] 100% FINE    ;\r\n/POS", "CALL EVIL", "UTOOL_NUM=9", "PR[1]=P[2]", "!x ; DO[1]=ON",
            "/END", "'quoted' \"text\""]


@pytest.mark.parametrize("raw", HOSTILE + KRL_EXTRA + LS_EXTRA, ids=range(len(HOSTILE + KRL_EXTRA + LS_EXTRA)))
@pytest.mark.parametrize("sanitise,code,max_len", [(krl_comment, KRL_CODE, 80), (ls_comment, LS_CODE, 32)],
                         ids=["krl", "fanuc"])
def test_comment_text_is_one_safe_line(raw, sanitise, code, max_len):
    s = sanitise(raw)
    assert len(s) <= max_len
    assert all(" " <= c <= "~" for c in s)  # printable ASCII only: no line break of any kind
    assert not code.search(s), s  # no statement shape survives
    assert s == sanitise(s)  # idempotent


CENTRES = {"kr16": [0.0, -60.0, 100.0, 0.0, 50.0, 0.0], "m20ia": [0.0, 10.0, 20.0, 0.0, -50.0, 0.0]}


def _write(post, robot_name, fmt, tmp_path, job_name, labels=()):
    r = get_robot(robot_name)
    p = load_profile(None, robot_name, fmt, r)
    tr = rows_trajectory(r, rows=1, centre=CENTRES[robot_name])
    files = post.write(tr, r, p, tmp_path, ProcessInfo(job_name=job_name, row_labels=labels))
    return r, p, files


@pytest.mark.parametrize("job_name", [HOSTILE[0], HOSTILE[4], HOSTILE[8], KRL_EXTRA[0], "x" * 5_000_000])
def test_a_hostile_job_name_writes_a_clean_krl_program(tmp_path, job_name):
    r, p, files = _write(KrlPost(), "kr16", "krl", tmp_path, job_name, labels=(job_name,))
    text = files[0].read_bytes().decode("ascii")
    assert KrlPost().check(files[0], r, p) == []
    statements = [ln for ln in text.split("\r\n") if ln and not ln.startswith(";")]
    assert sum(ln.startswith("DEF ") for ln in statements) == 1 and statements.count("END") == 1
    assert not any("evil" in s.lower() for s in statements)
    assert all(len(ln) <= 250 for ln in text.split("\r\n"))


@pytest.mark.parametrize("job_name", [HOSTILE[0], HOSTILE[4], HOSTILE[8], LS_EXTRA[0], "x" * 5_000_000])
def test_a_hostile_job_name_writes_a_clean_ls_program(tmp_path, job_name):
    r, p, files = _write(FanucPost(), "m20ia", "fanuc", tmp_path, job_name, labels=(job_name,))
    text = files[0].read_bytes().decode("ascii")
    assert FanucPost().check(files[0], r, p) == []
    lines = text.split("\r\n")
    assert lines.count("/POS") == 1 and lines.count("/END") == 1 and not any("CALL" in ln for ln in lines)
    comment = next(ln for ln in lines if ln.startswith("COMMENT"))
    assert len(comment.split('"')[1]) <= ATTR_COMMENT_MAX


def test_check_flags_code_in_a_krl_comment(tmp_path):
    r, p, files = _write(KrlPost(), "kr16", "krl", tmp_path, "part.toml")
    raw = files[0].read_bytes()
    files[0].write_bytes(raw.replace(b"; Job: part.toml", b"; Job: x $OUT[1]=TRUE", 1))
    assert any("code in a comment" in f for f in KrlPost().check(files[0], r, p))


def test_check_flags_code_in_an_ls_remark(tmp_path):
    r, p, files = _write(FanucPost(), "m20ia", "fanuc", tmp_path, "part.toml")
    raw = files[0].read_bytes()
    files[0].write_bytes(raw.replace(b"!job part.toml ;", b"!job CALL EVIL ;", 1))
    assert any("code in a remark" in f for f in FanucPost().check(files[0], r, p))
