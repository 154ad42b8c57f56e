"""The program simulator: a program re-executed as the controller interpolates it, against the plan."""
import json
import re

import numpy as np
import pytest
from click.testing import CliRunner

from camtool.cli import cli
from camtool.program.profiles import load_profile
from camtool.robots import get_robot
from camtool.simulate import (Reference, move_durations, reference_from_trajectory, simulate, target_joints)
from postprocessors.abb_rapid import RapidPost
from post_fixtures import profile_for_tests
from camtool.program.process import ProcessInfo
from camtool.program.moves import ProgramMoves, empty_moves
from postprocessors.yaskawa_inform import InformPost
from test_post import rows_trajectory


def _program(fmt, robot_name, tmp_path, rows=2, **options):
    r = get_robot(robot_name)
    p = profile_for_tests(robot_name, fmt, r, tmp_path)
    if options:
        p = p.with_changes(options=options)
    post = RapidPost() if fmt == "rapid" else InformPost()
    tr = rows_trajectory(r, rows=rows)
    files = post.write(tr, r, p, tmp_path, process=ProcessInfo())
    return r, p, post, tr, files


@pytest.mark.parametrize("fmt,robot_name", [("rapid", "seed8"), ("rapid", "irb2400"), ("inform", "seed8"),
                                            ("inform", "sia20")])
def test_a_written_program_follows_its_plan(fmt, robot_name, tmp_path):
    r, p, post, tr, files = _program(fmt, robot_name, tmp_path)
    prog = post.read_program(files[0], r, p)
    rep = simulate(prog, r, reference_from_trajectory(tr, r, 100.0), path_tol_mm=0.1, profile=p)
    assert rep.findings == []
    assert rep.rows == 2 and rep.exact_stops_on_surface == 0 and rep.part_switches_on_surface == 0
    assert rep.max_deviation_mm < 0.1
    assert abs(rep.duration_s - tr.duration_s) < 0.005 * tr.duration_s
    assert rep.limit_violations == 0 and rep.speed_violations == 0
    assert np.diff(np.r_[0.0, np.linspace(0, rep.duration_s, rep.samples)]).max() <= 0.004 + 1e-9
    assert rep.moves_on_work > 0 and rep.work_length_mm > 0 and rep.feed["mean_mm_s"] > 0


def test_an_exact_stop_on_the_surface_is_a_finding(tmp_path):
    r, p, post, tr, files = _program("rapid", "seed8", tmp_path)
    text = files[1].read_text()
    lines = text.splitlines()
    start = next(i for i, ln in enumerate(lines) if "! Row 1 of" in ln)
    k = next(i for i in range(start + 3, len(lines)) if "MoveAbsJ" in lines[i])
    lines[k] = re.sub(r", z\d+, ", ", fine, ", lines[k])
    files[1].write_text("\n".join(lines) + "\n")
    rep = simulate(post.read_program(files[0], r, p), r, reference_from_trajectory(tr, r), path_tol_mm=0.1)
    assert rep.exact_stops_on_surface == 1
    assert any(f"CAMTOOL.mod:{k + 1}: exact stop on the surface" in f for f in rep.findings)


def test_a_moved_target_is_a_deviation(tmp_path):
    r, p, post, tr, files = _program("inform", "seed8", tmp_path)
    text = files[0].read_bytes().decode()
    lines = text.split("\r\n")
    # a work target of row 1: move its track position by 2 mm (409.6 pulses)
    row = next(i for i, ln in enumerate(lines) if ln.startswith("'ROW 1/"))
    mv = next(ln for ln in lines[row + 3:] if ln.startswith("MOVJ"))
    idx = mv.split()[2]  # BCnnnnn
    bc = next(i for i, ln in enumerate(lines) if ln.startswith(idx + "="))
    lines[bc] = f"{idx}={int(lines[bc].split('=')[1]) + 410}"
    files[0].write_bytes("\r\n".join(lines).encode())
    rep = simulate(post.read_program(files[0], r, p), r, reference_from_trajectory(tr, r), path_tol_mm=0.1)
    assert rep.max_deviation_mm > 1.0
    assert any("from the planned path (tolerance 0.1 mm)" in f for f in rep.findings)


def test_program_time_is_compared_with_the_plan(tmp_path):
    r, p, post, tr, files = _program("rapid", "seed8", tmp_path)
    prog = post.read_program(files[0], r, p)
    prog.duration_s[5:] *= 1.02  # 2 % slower from the 6th move on
    rep = simulate(prog, r, reference_from_trajectory(tr, r), path_tol_mm=None)
    assert any("the program takes" in f and "allowed 0.5 %" in f for f in rep.findings)


def _two_moves(r, q0, q1, q2, t1, t2, blend_mm, kind="J"):
    kw = empty_moves(3, r.dof)
    kw["q"] = np.array([q0, q1, q2], float)
    kw["duration_s"] = np.array([np.nan, t1, t2])
    kw["blend_mm"] = np.array([0.0, blend_mm, 0.0])
    return ProgramMoves(**kw, where=["x:1", "x:2", "x:3"])


def test_a_zone_is_a_parabolic_blend_and_fine_a_stop(tmp_path):
    """Joint speed in a corner goes linearly from the incoming to the outgoing move's (no
    overshoot); with fine the path goes through the target."""
    r = get_robot("irb2400")
    mid = (r.limits.lower + r.limits.upper) / 2
    q0, q1, q2 = mid, mid + np.radians([20, 0, 0, 0, 0, 0]), mid + np.radians([20, 10, 0, 0, 0, 0])
    for blend in (0.0, 50.0):
        prog = _two_moves(r, q0, q1, q2, 1.0, 1.0, blend)
        rep = simulate(prog, r)
        assert rep.speed_violations == 0 and rep.duration_s == pytest.approx(2.0)
        assert rep.exact_stops == (3 if blend == 0 else 2)


def test_circular_moves_follow_the_circle():
    """A MoveC-like move: the TCP on the circle through start, circle point and target."""
    from camtool.program.arcs import arc_point as _arc_point, circle_through as _arc

    P0 = np.array([[100.0, 0.0, 0.0]])
    Pv = np.array([[0.0, 100.0, 0.0]])
    P1 = np.array([[-100.0, 0.0, 0.0]])
    c, rad, n, r0, sweep, ok = _arc(P0, Pv, P1)
    assert ok[0] and np.allclose(c, 0) and rad[0] == pytest.approx(100.0) and sweep[0] == pytest.approx(np.pi)
    pts = _arc_point(np.repeat(c, 5, 0), np.repeat(n, 5, 0), np.repeat(r0, 5, 0), np.repeat(sweep, 5, 0),
                     np.linspace(0, 1, 5))
    assert np.allclose(np.linalg.norm(pts, axis=1), 100.0)
    assert np.allclose(pts[2], [0.0, 100.0, 0.0], atol=1e-9)  # through the circle point


def test_cartesian_targets_are_solved_in_the_asked_configuration(tmp_path):
    r, p, post, tr, files = _program("rapid", "irb2400", tmp_path)
    prog = post.read_program(files[0], r, p)
    q = target_joints(prog, r, p)
    cart = prog.kind == "L"
    assert cart.any() and np.isfinite(q).all()
    P = np.array([r.fk_tcp(qq)[:3, 3] for qq in q[cart]])
    assert np.abs(P - prog.pose[cart, :3, 3]).max() < 1e-3
    dur = move_durations(prog, r, q)
    assert np.isnan(dur[0]) and np.all(dur[1:] > 0)


def test_reference_breaks_between_rows():
    r = get_robot("seed8")
    tr = rows_trajectory(r, rows=3)
    ref = reference_from_trajectory(tr, r)
    assert isinstance(ref, Reference) and ref.rows == 3
    assert ref.breaks.sum() == 3  # one polyline per row (with its leads)


def test_cli_check_simulate_against_the_csv(tmp_path):
    from camtool.program.profiles import Profile
    from camtool.program.profiles import default_options
    from postprocessors.csv_joint import CsvPost

    r, p, post, tr, files = _program("rapid", "irb2400", tmp_path)
    csv = CsvPost().write(tr, r, Profile("<t>", "csv", options=default_options("csv")), tmp_path)[0]
    res = CliRunner().invoke(cli, ["check", str(files[0]), "--robot", "irb2400", "--simulate", "--against",
                                   str(csv), "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    sim = out["simulation"]
    assert sim["rows"] == 2 and sim["max_deviation_mm"] < 0.1 and sim["exact_stops_on_surface"] == 0
    res = CliRunner().invoke(cli, ["check", str(files[0]), "--robot", "irb2400", "--simulate"])
    assert res.exit_code == 0 and "simulated" in res.stderr and "work: 2 rows" in res.stderr


def test_cli_check_needs_a_robot_or_a_job(tmp_path):
    r, p, post, tr, files = _program("rapid", "seed8", tmp_path)
    res = CliRunner().invoke(cli, ["check", str(files[0])])
    assert res.exit_code == 2 and "--robot NAME, or --job JOB" in res.output


def test_the_simulated_program_is_measured_against_the_cell(tmp_path):
    """With the job's collision world, the simulator runs every body pair on the program as the
    controller runs it: a clear cell passes with its figures, a ball on the tool's way is a finding
    naming the two bodies and the program line."""
    from camtool.collision import CellSettings, CollisionWorld
    from camtool.collision.shapes import WORLD, Body

    r, p, post, tr, files = _program("rapid", "seed8", tmp_path)
    prog = post.read_program(files[0], r, p)
    ref = reference_from_trajectory(tr, r, 100.0)
    rep = simulate(prog, r, ref, path_tol_mm=0.1, profile=p, world=CollisionWorld(r, CellSettings()))
    assert rep.findings == [] and rep.cell["collisions"] == 0 and rep.cell["evaluations"] > 0
    T = np.eye(4)
    T[:3, 3] = (np.asarray(r.base_T_mm) @ r.fk(tr.q[len(tr.q) // 2]))[:3, 3]   # where the flange passes mid-program
    ball = Body("ball", "obstacle", WORLD, "sphere", (30.0,), T)
    rep = simulate(prog, r, ref, path_tol_mm=0.1, profile=p, world=CollisionWorld(r, CellSettings(obstacles=(ball,))))
    line = next(f for f in rep.findings if "ball" in f)
    assert "overlap by" in line and "as the controller runs it" in line and rep.cell["collisions"] >= 1
    assert re.search(r"\.mod|line|move", line, re.I)


@pytest.mark.parametrize("fmt,robot_name", [("rapid", "seed8"), ("rapid", "irb2400"), ("inform", "sia20")])
def test_blocks_of_samples_give_the_same_simulation(fmt, robot_name, tmp_path, monkeypatch):
    """The simulator interpolates (corners, Cartesian Newton) and measures (speeds, TCP, deviation) in
    blocks of samples: blocks far smaller than the program give the same samples and figures as one."""
    import camtool.simulate as sim
    import camtool.simulate.interpolation as itp
    import camtool.simulate.measures as ms

    r, p, post, tr, files = _program(fmt, robot_name, tmp_path)
    prog = post.read_program(files[0], r, p)
    prog.duration_s[len(prog) // 2:] *= 0.05   # too fast from the middle on: speed and time findings too
    seen = []
    monkeypatch.setattr(sim, "interpolate", lambda *a: seen.append(itp.interpolate(*a)) or seen[-1])

    def run(block):
        monkeypatch.setattr(itp, "SIM_BLOCK_SAMPLES", block)
        monkeypatch.setattr(ms, "BLOCK_SAMPLES", block)
        return simulate(prog, r, reference_from_trajectory(tr, r, 100.0), path_tol_mm=0.1, profile=p).as_dict()

    whole = run(10**9)
    blocks = run(7)
    assert whole["samples"] > 50 * 7 and whole["findings"]
    assert whole["speed_violations"] > 0 or not (prog.kind == "J").all()  # a MoveL keeps its TCP speed
    assert blocks == whole
    assert np.array_equal(seen[0].q, seen[1].q) and np.array_equal(seen[0].m, seen[1].m)


def test_the_moves_the_controller_cannot_follow_are_named_by_their_span():
    """Three joint moves, the middle one too fast for axis 1 (60 deg in 0.2 s: 300 deg/s, limit 150):
    exactly that move's (start, end) is named, and a program within the limits names none."""
    r = get_robot("irb2400")
    mid = (r.limits.lower + r.limits.upper) / 2
    kw = empty_moves(4, r.dof)
    kw["q"] = np.array([mid, mid + np.radians([10, 0, 0, 0, 0, 0]), mid + np.radians([70, 0, 0, 0, 0, 0]),
                        mid + np.radians([80, 0, 0, 0, 0, 0])])
    kw["duration_s"] = np.array([np.nan, 1.0, 0.2, 1.0])
    kw["blend_mm"] = np.zeros(4)
    prog = ProgramMoves(**kw, where=["x:1", "x:2", "x:3", "x:4"])
    assert np.degrees(r.limits.velocity[0]) < 300.0
    rep = simulate(prog, r)
    assert rep.speed_violations > 0
    assert np.allclose(rep.unfollowed_s, [(1.0, 1.2)])
    assert "unfollowed_s" not in rep.as_dict()
    kw["duration_s"] = np.array([np.nan, 1.0, 2.0, 1.0])
    assert simulate(ProgramMoves(**kw, where=["x:1", "x:2", "x:3", "x:4"]), r).unfollowed_s == ()


def test_each_move_on_work_has_its_own_deviation_and_time_span(tmp_path):
    """``SimReport.deviation_s``: a target moved 2 mm off the plan makes the moves into and out of it the
    farthest (their largest deviation is the report's maximum, and the finding's time lies in one of them);
    the spans are the moves' own (each starting where the move before it ends, as written), every other
    move within the tolerance."""
    r, p, post, tr, files = _program("inform", "seed8", tmp_path)
    lines = files[0].read_bytes().decode().split("\r\n")
    row = next(i for i, ln in enumerate(lines) if ln.startswith("'ROW 1/"))
    mv = next(ln for ln in lines[row + 3:] if ln.startswith("MOVJ"))
    bc = next(i for i, ln in enumerate(lines) if ln.startswith(mv.split()[2] + "="))
    lines[bc] = f"{mv.split()[2]}={int(lines[bc].split('=')[1]) + 410}"   # 2 mm along the track
    files[0].write_bytes("\r\n".join(lines).encode())
    prog = post.read_program(files[0], r, p)
    rep = simulate(prog, r, reference_from_trajectory(tr, r), path_tol_mm=0.1)
    dev = np.array(rep.deviation_s)
    assert len(dev) >= rep.moves_on_work and "deviation_s" not in rep.as_dict()
    assert np.all(dev[:, 1] > dev[:, 0]) and np.all(np.diff(dev[:, 0]) > 0)
    assert dev[:, 2].max() == rep.max_deviation_mm > 1.0
    off = np.flatnonzero(dev[:, 2] > 0.1)
    assert 0 < len(off) < len(dev) / 4 and np.all(np.diff(off) == 1)   # one stretch of moves, around the target
    t_found = float(re.search(r"at t = ([0-9.]+) s", next(f for f in rep.findings if "planned path" in f)).group(1))
    assert any(a - 1e-3 <= t_found <= b + 1e-3 for a, b, _d in dev[off])
    dur = move_durations(prog, r, target_joints(prog, r, p))
    ends = np.cumsum(np.where(np.isfinite(dur), dur, 0.0))
    assert np.all(np.isclose(dev[:, 1][:, None], ends[None]).any(axis=1))   # each span ends where a move does
    moved = next(k for k, w in enumerate(prog.where) if w.endswith(f":{lines.index(mv) + 1}"))
    into = np.flatnonzero(np.isclose(dev[:, 1], ends[moved]))
    assert len(into) == 1 and into[0] in off   # the move into the moved target is off the path


def test_the_reference_runs_through_the_planners_own_waypoints_on_work():
    """A waypoint the planner adds on work (path_index -1: a chord sag's midpose on the surface) is part of the
    planned path: the reference's polyline passes through its TCP."""
    from dataclasses import replace
    from camtool.timing.feed import tcp_positions_world
    r = get_robot("seed8")
    tr = rows_trajectory(r, rows=1)
    pidx = np.asarray(tr.path_index).copy()
    work = np.flatnonzero(np.asarray(tr.zone) == 0)
    k = int(work[len(work) // 2])
    pidx[k] = -1
    ref = reference_from_trajectory(replace(tr, path_index=pidx), r)
    tcp = tcp_positions_world(r, np.asarray(tr.q)[k:k + 1])[0] - r.base_T_mm[:3, 3]
    tcp = tcp @ r.base_T_mm[:3, :3]
    assert np.min(np.linalg.norm(ref.points - tcp, axis=1)) < 1e-6
