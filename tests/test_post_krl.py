"""KUKA KRL writer, reader and checker (issue #47): .src + .dat, PTP to E6AXIS off the surface,
LIN / CIRC to E6POS on it, $VEL.CP in m/s, C_DIS / C_PTP, $BASE / $TOOL, names, splitting,
the checker's findings."""
import re

import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.program.process import ProcessInfo
from camtool.program.profiles import load_profile
from camtool.robots import get_robot
from postprocessors.krl import KrlPost
from postprocessors.krl.dialect import abc_deg, cptp_percent, cptp_radius, krl_name, matrix_abc
from test_post import rows_trajectory


def on_the_path(q_read, tr, tol_deg):
    """Every target lies on the planned motion (the trajectory's quintic pieces, sampled every
    millisecond) to ``tol_deg`` in every joint: a time-free test, since whole-percent PTP speeds
    put a target early or late by a share of its move (the program's total time is tested apart)."""
    from camtool.program.candidates import hermite

    t = np.arange(tr.t_s[0], tr.t_s[-1], 1e-3)
    k = np.clip(np.searchsorted(tr.t_s, t, side="right") - 1, 0, len(tr.t_s) - 2)
    plan = hermite(tr.t_s, tr.q, tr.qd, tr.qdd, k, t)
    gap = np.array([np.abs(plan - q).max(axis=1).min() for q in q_read])
    assert np.degrees(gap).max() < tol_deg, np.flatnonzero(np.degrees(gap) >= tol_deg)[:5]

POST = KrlPost()
CENTRE = [0.0, -60.0, 100.0, 0.0, 50.0, 0.0]   # A5 bent: away from the wrist singularity


def _setup(**options):
    r = get_robot("kr16")
    p = load_profile(None, "kr16", "krl", r)
    return r, (p.with_changes(options=options) if options else p)


def _write(tmp_path, rows=3, process=None, **options):
    r, p = _setup(**options)
    tr = rows_trajectory(r, rows=rows, centre=CENTRE)
    files = POST.write(tr, r, p, tmp_path, process=process or ProcessInfo())
    return r, p, tr, files


def test_round_trip_on_the_plan(tmp_path):
    """A .src and its .dat; fewer moves than waypoints; every target on the planned motion when
    the program reaches it (PTP axis values to 1e-4 deg, E6POS through the inverse kinematics);
    the program's clock within 0.5 % of the plan's."""
    r, p, tr, files = _write(tmp_path)
    assert [f.name for f in files] == ["CAMTOOL.src", "CAMTOOL.dat"]
    dur, q = POST.read(files[0], r, p)
    assert 10 < len(q) < len(tr.q) and np.isnan(dur[0])
    on_the_path(q, tr, 1e-2)   # CP targets: 1e-3 mm / 1e-4 deg written, solved back to joints
    assert abs(np.nansum(dur) - tr.duration_s) < 0.005 * tr.duration_s
    assert POST.check(files[0], r, p) == []
    prog = POST.read_program(files[0], r, p)
    assert {"J", "L", "C"} <= set(prog.kind) and prog.kind[0] == "J"


def test_layout(tmp_path):
    process = ProcessInfo(job_name="part.toml", job_time="2024/05/06 07:08", row_labels=("segment 4",) * 3)
    r, p, tr, files = _write(tmp_path, process=process, process_output=7)
    src = files[0].read_bytes().decode("ascii")
    dat = files[1].read_bytes().decode("ascii")
    assert "\r\n" in src and src.count("\n") == src.count("\r\n")   # Windows text files
    lines = src.split("\r\n")[:-1]
    assert lines[0] == "DEF CAMTOOL( )" and lines[-1] == "END"
    assert dat.startswith("DEFDAT CAMTOOL\r\n") and dat.endswith("ENDDAT\r\n")
    assert "; Job: part.toml; date 2024/05/06 07:08 UTC" in lines
    assert "BAS(#INITMOV,0)" in lines and "$ORI_TYPE=#VAR" in lines and "$CIRC_TYPE=#BASE" in lines
    assert any(re.fullmatch(r"\$BASE=\{X -?\d+\.\d{3},Y -?\d+\.\d{3},Z -?\d+\.\d{3},A -?\d+\.\d{4},B -?\d+\.\d{4},"
                            r"C -?\d+\.\d{4}\}", ln) for ln in lines)
    moves = [ln for ln in lines if re.match(r"(PTP|LIN|CIRC) ", ln)]
    assert moves[0] == "PTP XP1" and not re.search(r"C_(DIS|PTP)", moves[-1])   # exact at both ends
    assert all(re.fullmatch(r"(PTP XP\d+( C_PTP( C_DIS)?)?|LIN XP\d+( C_DIS)?|CIRC XA\d+, XP\d+( C_DIS)?)", m)
               for m in moves)
    # every $VEL.CP is in m/s, every $VEL_AXIS a whole %
    assert all(0 < float(v) < 0.5 for v in re.findall(r"^\$VEL\.CP=(\S+)$", src, re.M))
    assert all(1 <= int(v) <= 100 for v in re.findall(r"^\$VEL_AXIS\[\d\]=(\d+)$", src, re.M))
    # PTP targets are E6AXIS, CP targets E6POS, neither with Status and Turn
    decls = re.findall(r"^DECL (E6AXIS|E6POS) (X[PA]\d+)=\{([^}]*)\}\r$", dat, re.M)
    assert decls and all(" S " not in b and not re.search(r"\b[ST] ", b) for _t, _n, b in decls)
    assert all(b.startswith("A1 ") for t, _n, b in decls if t == "E6AXIS")
    assert all(b.startswith("X ") for t, _n, b in decls if t == "E6POS")
    # rows named where they start and end, the output switched around them
    on = [i for i, ln in enumerate(lines) if ln == "$OUT[7]=TRUE"]
    off = [i for i, ln in enumerate(lines) if ln == "$OUT[7]=FALSE"]
    assert len(on) == len(off) == 3 and lines[on[0] - 1] == "; Row 1 of 3: segment 4"
    assert lines[off[0] + 1] == "; End of row 1"


def test_base_and_tool_are_the_job_s(tmp_path):
    """$BASE is the work object in $ROBROOT, $TOOL the job's TCP in $FLANGE (camtool's flange on
    the kr16); LIN targets are the TCP in $BASE: base @ target is the TCP the plan reaches."""
    from camtool.transforms import matrix_from_xyz_rpy

    r, p = _setup()
    p = p.with_changes(wobj={"xyz_mm": [1200.0, -50.0, 400.0], "rpy_deg": [10.0, -20.0, 30.0]},
                       tool={"tcp_xyz_mm": [0.0, 20.0, 150.0], "tcp_rpy_deg": [0.0, 15.0, 0.0]})
    tr = rows_trajectory(r, rows=2, centre=CENTRE)
    files = POST.write(tr, r, p, tmp_path)
    src = files[0].read_text()
    base = re.search(r"\$BASE=\{([^}]*)\}", src).group(1)
    v = dict((k, float(x)) for k, x in (f.split() for f in base.split(",")))
    B = np.eye(4)
    B[:3, :3], B[:3, 3] = matrix_abc([v["A"], v["B"], v["C"]])[0], [v["X"], v["Y"], v["Z"]]
    assert np.allclose(B, matrix_from_xyz_rpy([1200.0, -50.0, 400.0], [10.0, -20.0, 30.0]), atol=1e-3)
    prog = POST.read_program(files[0], r, p)
    assert np.allclose(prog.tool_T_mm, matrix_from_xyz_rpy([0.0, 20.0, 150.0], [0.0, 15.0, 0.0]), atol=1e-4)
    dur, q = POST.read(files[0], r, p)
    rt = r.with_placement(tool_T_mm=prog.tool_T_mm)
    cart = np.flatnonzero(prog.kind != "J")
    P = np.array([rt.fk_tcp(x)[:3, 3] for x in q[cart]])
    assert np.abs(P - prog.pose[cart, :3, 3]).max() < 2e-3


def test_abc_is_z_then_y_then_x():
    R = matrix_abc([30.0, 20.0, 10.0])[0]
    c, s = np.cos, np.sin
    a, b, g = np.radians([30.0, 20.0, 10.0])
    Rz = np.array([[c(a), -s(a), 0], [s(a), c(a), 0], [0, 0, 1]])
    Ry = np.array([[c(b), 0, s(b)], [0, 1, 0], [-s(b), 0, c(b)]])
    Rx = np.array([[1, 0, 0], [0, c(g), -s(g)], [0, s(g), c(g)]])
    assert np.allclose(R, Rz @ Ry @ Rx) and np.allclose(abc_deg(R)[0], [30.0, 20.0, 10.0])


def test_cptp_is_a_share_of_half_the_motion():
    assert cptp_percent(5.0, 100.0) == 10 and cptp_radius(10, 100.0) == pytest.approx(5.0)
    assert cptp_percent(80.0, 100.0) == 100 and cptp_percent(0.01, 100.0) == 1
    assert cptp_radius(cptp_percent(7.3, 60.0), 60.0) <= 7.3   # never more rounding than planned


def test_names_are_krl_names(tmp_path, caplog):
    assert krl_name("part-1 final")[0] == "PART_1_FINAL"
    assert krl_name("1abc")[0] == "P1ABC" and krl_name("lin")[0] == "LIN_1"
    assert len(krl_name("x" * 60)[0]) == 24
    r, p = _setup()
    p = p.with_changes(program_name="a very long program name indeed")
    files = POST.write(rows_trajectory(r, rows=1, centre=CENTRE), r, p, tmp_path)
    assert files[0].name == "A_VERY_LONG_PROGRAM_.src" and "not valid" in caplog.text


def test_long_program_is_split_off_the_surface(tmp_path):
    r, p, tr, files = _write(tmp_path, lines_per_file=30)
    names = [f.name for f in files]
    assert names[:2] == ["CAMTOOL.src", "CAMTOOL.dat"] and "CAMTOOL_001.src" in names and "CAMTOOL_002.dat" in names
    main = files[0].read_text()
    assert "CAMTOOL_001( )" in main and "CAMTOOL_002( )" in main and "\nPTP " not in main
    assert POST.check(files[0], r, p) == []
    prog = POST.read_program(files[0], r, p)
    assert len(set(prog.part)) >= 2 and np.all(np.diff(prog.part) >= 0)
    ends = np.flatnonzero(np.diff(prog.part)) 
    assert (prog.blend_mm[ends] == 0).all()   # a module ends with an exact stop
    dur, q = POST.read(files[0], r, p)
    assert abs(np.nansum(dur) - tr.duration_s) < 0.005 * tr.duration_s


def test_same_trajectory_gives_identical_bytes(tmp_path):
    process = ProcessInfo(job_time="2024/01/02 03:04")
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    r, p, tr, a = _write(tmp_path / "a", process=process)
    b = POST.write(tr, r, p, tmp_path / "b", process=process)
    assert [x.read_bytes() for x in a] == [y.read_bytes() for y in b]


def _broken(tmp_path, edit, file=0):
    r, p, tr, files = _write(tmp_path, rows=1)
    raw = files[file].read_bytes().decode("ascii")
    files[file].write_bytes(edit(raw).encode("latin-1"))
    return POST.check(files[0], r, p)


@pytest.mark.parametrize("edit,expect", [
    (lambda s: s[:s.rindex("END")], "does not end with END"),
    (lambda s: s.replace("PTP XP1\r\n", "LIN XP3\r\n", 1), "must be a PTP"),
    (lambda s: s.replace("DEF CAMTOOL( )", "DEF OTHER( )"), "is in a file named"),
    (lambda s: s.replace("$VEL_AXIS[3]=10\r\n", "", 1), "before $VEL_AXIS"),
    (lambda s: s.replace("$VEL.CP=", "$VEL.CP=nan", 1), "must be a number"),
    (lambda s: s.replace("; Job:", "; Job: LIN {X 1} $OUT[3]=TRUE", 1), "code in a comment"),
    (lambda s: s.replace("$ADVANCE=3", "$ADVANCE=3\r\nHALT", 1), "unrecognised statement"),
    (lambda s: s.replace("; Job:", "; " + "x" * 300, 1), "longer than"),
    (lambda s: s.replace("\r\n", "\n", 3), "mixed line ends"),
])
def test_check_finds_broken_src(tmp_path, edit, expect):
    found = _broken(tmp_path, edit)
    assert any(expect in f for f in found), found


@pytest.mark.parametrize("edit,expect", [
    (lambda s: s[:s.rindex("ENDDAT")], "does not end with ENDDAT"),
    (lambda s: re.sub(r"DECL E6POS XP3=\{[^}]*\}\r\n", "", s), "XP3 is not declared"),
    (lambda s: s.replace("A1 ", "A1 1e999", 1), "finite number"),
    (lambda s: s.replace(",A6 ", ",A9 ", 1), "an E6AXIS needs"),
])
def test_check_finds_broken_dat(tmp_path, edit, expect):
    found = _broken(tmp_path, edit, file=1)
    assert any(expect in f for f in found), found


def test_check_of_a_dat_checks_its_src(tmp_path):
    r, p, tr, files = _write(tmp_path, rows=1)
    assert POST.check(files[1], r, p) == []


def test_a_target_beyond_the_limits_is_a_finding(tmp_path):
    r, p, tr, files = _write(tmp_path, rows=1)
    dat = files[1].read_text().replace("DECL E6AXIS XP1={A1 ", "DECL E6AXIS XP1={A1 190.0,A0 ", 1)
    dat = re.sub(r"A0 [-\d.]+,", "", dat)
    files[1].write_text(dat.replace("\n", "\r\n").replace("\r\r\n", "\r\n"))
    found = POST.check(files[0], r, p)
    assert any("a1 = 190.0000 deg outside the limits" in f for f in found), found


@pytest.mark.parametrize("change,expect", [
    (dict(axes={"a1": {"axis": "A7", "max_speed": 156.0}}), "expected one of A1..A6"),
    (dict(axes={"a1": {"axis": "A1"}}), "max_speed: missing"),
    (dict(options={"cdis_mm": [5.0, 1.0]}), "cdis_mm"),
    (dict(options={"approach_vel_axis": 0}), "approach_vel_axis"),
])
def test_bad_profiles_are_refused(tmp_path, change, expect):
    r = get_robot("kr16")
    text = (load_profile(None, "kr16", "krl", r).source)
    body = open(text).read()
    if "axes" in change:
        (j, spec), = change["axes"].items()
        items = ", ".join(f'{k} = {v!r}'.replace("'", '"') for k, v in spec.items())
        body = re.sub(rf"^{j} = .*$", f'{j} = {{ {items}, unit = "deg" }}', body, flags=re.M)
    else:
        (k, v), = change["options"].items()
        body = re.sub(rf"^{k} = .*$", f"{k} = {v}", body, flags=re.M)
    f = tmp_path / "p.toml"
    f.write_text(body)
    with pytest.raises(BadInput, match=expect):
        load_profile(f, "kr16", "krl", r)


def test_a_called_module_that_is_a_fifo_is_a_finding_not_a_hang(tmp_path):
    import os

    r, p, tr, files = _write(tmp_path, lines_per_file=30)
    part = tmp_path / "CAMTOOL_002.src"
    part.unlink()
    os.mkfifo(part)
    found = POST.check(files[0], r, p)
    assert found and any("CAMTOOL_002" in f for f in found)
