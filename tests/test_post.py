"""camtool.program.post.write_programs: profiles from the job, check before placing, no partial output."""
from pathlib import Path

import re

import numpy as np
import pytest

from camtool.errors import BadInput, PlanInfeasible
from camtool.job import load_job
from camtool.run.post_inputs import write_job_programs
from camtool.robots import get_robot
from post_fixtures import smooth_trajectory, with_q


def rows_trajectory(robot, rows: int = 3, per_row: int = 40, free: int = 6, **kw):
    """A smooth trajectory (``smooth_trajectory``) with the zones of a raster job: approach,
    then per row a lead-in, work points and a lead-out, free motion between rows, depart.
    ``kw`` go to ``smooth_trajectory`` (unless given: a gentle motion, each joint at about 3 %
    of its range a second, 20 waypoints a second) and ``centre`` moves it to a posture (deg / mm; default per robot
    in ``CENTRES``)."""
    from dataclasses import replace

    from camtool.path.toolpath import ZONE_CODE

    centre = kw.pop("centre", CENTRES.get(robot.name))

    pattern = [ZONE_CODE["approach"]] * 2
    for r_ in range(rows):
        pattern += [ZONE_CODE["lead_in"]] * 2 + [ZONE_CODE["work"]] * per_row + [ZONE_CODE["lead_out"]] * 2
        pattern += [ZONE_CODE["self_motion"] if r_ < rows - 1 else ZONE_CODE["depart"]] * free
    kw.setdefault("duration_s", 0.05 * len(pattern))  # 20 waypoints a second, as the timing stage writes
    kw.setdefault("fraction", min(0.3, 0.005 * kw["duration_s"]))  # joints at about 3 % of their range a second
    tr = smooth_trajectory(robot, len(pattern), **kw)
    if centre is not None:  # move the motion to a posture away from singularities
        mid = (robot.limits.lower + robot.limits.upper) / 2
        tr = replace(tr, q=tr.q - mid + robot.q_from_edge(centre))
    return replace(tr, zone=np.array(pattern))


# postures (deg / mm) the gentle test motions move about: wrists bent, arms reaching forward
CENTRES = {"irb2400": [0.0, 20.0, 10.0, 0.0, 50.0, 0.0], "sia20": [0.0, 30.0, 0.0, -40.0, 0.0, 45.0, 0.0]}


def _job(tmp_path, robot="seed8", post="", extra=""):
    f = tmp_path / "job.toml"
    f.write_text(f'[workpiece]\nfile = "part.stl"\n[robot]\nname = "{robot}"\n{extra}[post]\n{post}')
    return load_job(f)


def test_all_three_formats_are_written_and_checked(tmp_path):
    r = get_robot("seed8")
    out = tmp_path / "out"
    files = write_job_programs(rows_trajectory(r), r, _job(tmp_path, post='program_name = "Sphere"\n'), out)
    assert sorted(f.name for f in files) == ["SPHERE.JBI", "Sphere.csv", "Sphere.mod", "Sphere.pgf"]
    assert all(f.parent == out and f.is_file() for f in files)
    left = sorted(p.name for p in out.iterdir() if p.name != ".camtool-programs.json")
    assert left == sorted(f.name for f in files)  # no temp folder left


def test_nothing_read_back_is_kept_after_the_post_stage(tmp_path):
    """The files parsed, the targets solved and the merge are dropped once the programs are placed (a dense
    job's are hundreds of MB that would stay alive to the end of the run)."""
    from camtool.program import candidates, targets
    from postprocessors.inform import parser as inform_parser
    from postprocessors.rapid import parser as rapid_parser

    r = get_robot("seed8")
    write_job_programs(rows_trajectory(r), r, _job(tmp_path), tmp_path / "out")
    assert not rapid_parser._PARSED and not rapid_parser._READ
    assert not inform_parser._PARSED and not inform_parser._READ
    assert not targets._SOLVED and not candidates._MERGED


def test_job_tool_and_csv_unit_reach_the_programs(tmp_path):
    r = get_robot("irb2400")
    job = _job(tmp_path, "irb2400", 'formats = ["rapid", "csv"]\ncsv_angle_unit = "rad"\n',
               '[tool]\nname = "spindle"\ntcp_xyz_mm = [0.0, 0.0, 120.0]\nmass_kg = 2.5\n')
    files = {f.suffix: f for f in write_job_programs(rows_trajectory(r), r, job, tmp_path / "o")}
    mod = files[".mod"].read_text()
    assert "PERS tooldata spindle:=[TRUE,[[0.000,0.000,120.000],[1.000000,0.000000,0.000000,0.000000]],[2.500," in mod
    assert ", spindle \\WObj:=camtool_wobj;" in mod
    assert files[".csv"].read_text().startswith("t_s,j1_rad,")


def test_profile_from_the_job_is_resolved_relative_to_the_job(tmp_path):
    r = get_robot("irb2400")
    (tmp_path / "cfg").mkdir()
    (tmp_path / "cfg" / "irc5.toml").write_text(
        'format = "rapid"\n[axes]\n' + "".join(f'j{i} = {{ axis = "rax_{i}", sign = -1 }}\n' for i in range(1, 7))
        + '[options]\nmax_zone = "z1"\n')
    job = _job(tmp_path, "irb2400", 'formats = ["rapid"]\nprofiles = { rapid = "cfg/irc5.toml" }\n')
    tr = rows_trajectory(r)
    files = write_job_programs(tr, r, job, tmp_path / "o")
    text = files[1].read_text()
    assert set(re.findall(r", (fine|z\d+), camtool_tool", text)) <= {"fine", "z0", "z1"}
    j1 = float(text.split("MoveAbsJ [[")[1].split(",")[0])
    assert j1 == pytest.approx(-np.degrees(tr.q[0, 0]), abs=1e-4)


def test_trajectory_outside_the_limits_is_refused_and_nothing_written(tmp_path):
    r = get_robot("irb2400")
    tr = smooth_trajectory(r, 20)
    q = tr.q.copy()
    q[7, 2] = np.radians(170.0)  # j3's serial range ends at 165 deg (the coupled axis 3 at 65)
    out = tmp_path / "o"
    with pytest.raises(PlanInfeasible, match=r"sample 7 .*j3 = 170.0000 deg"):
        write_job_programs(with_q(tr, q), r, _job(tmp_path, "irb2400", 'formats = ["rapid", "csv"]\n'), out)
    assert not out.exists() or not any(out.iterdir())


def test_failed_check_leaves_no_program(tmp_path):
    r = get_robot("irb2400")
    tr = smooth_trajectory(r, 20)
    t = tr.t_s.copy()
    t[10:] -= 0.5  # the step into sample 10 (0.42 s) now takes a negative time: impossible
    out = tmp_path / "o"
    with pytest.raises(PlanInfeasible) as exc:
        write_job_programs(with_q(tr, tr.q, t), r, _job(tmp_path, "irb2400", 'formats = ["rapid", "csv"]\n'), out)
    assert exc.value.exit_code == 3
    findings = exc.value.report["findings"]
    assert any("CAMTOOL.csv:12: move duration" in f and "not positive" in f for f in findings)
    # the RAPID program never runs faster than the robot allows, so it cannot follow the broken timing
    assert any("CAMTOOL.mod:" in f for f in findings)
    assert "program check finding(s), no program written" in str(exc.value)
    assert list(out.iterdir()) == []  # no program, no temporary folder


def test_output_folder_that_cannot_be_created(tmp_path):
    r = get_robot("irb2400")
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    with pytest.raises(BadInput, match=r"a_file/sub: cannot create the output folder"):
        write_job_programs(smooth_trajectory(r, 5), r, _job(tmp_path, "irb2400", 'formats = ["csv"]\n'), blocker / "sub")


def test_output_folder_that_is_not_writable(tmp_path):
    r = get_robot("irb2400")
    with pytest.raises(BadInput, match=r"/proc"):
        write_job_programs(smooth_trajectory(r, 5), r, _job(tmp_path, "irb2400", 'formats = ["csv"]\n'), Path("/proc"))


def test_missing_default_profile_is_bad_input(tmp_path):
    r = get_robot("irb2400_paper")
    with pytest.raises(BadInput, match=r"no inform profile for robot 'irb2400_paper'.*post.profiles.inform"):
        write_job_programs(smooth_trajectory(r, 5), r, _job(tmp_path, "irb2400_paper", 'formats = ["inform"]\n'),
                       tmp_path / "o")


def test_profile_with_unknown_joint_names_the_file_and_key(tmp_path):
    r = get_robot("irb2400")
    (tmp_path / "p.toml").write_text('format = "rapid"\n[axes]\nj1 = { axis = "rax_1" }\nelbow = { axis = "rax_3" }\n')
    job = _job(tmp_path, "irb2400", 'formats = ["rapid"]\nprofiles = { rapid = "p.toml" }\n')
    with pytest.raises(BadInput, match=r"p.toml: axes.elbow: robot irb2400 has no joint 'elbow'"):
        write_job_programs(smooth_trajectory(r, 5), r, job, tmp_path / "o")


def test_unknown_format_is_bad_input(tmp_path):
    r = get_robot("irb2400")
    with pytest.raises(BadInput, match="no post-processor 'gcode'"):
        write_job_programs(smooth_trajectory(r, 5), r, _job(tmp_path, "irb2400", 'formats = ["gcode"]\n'), tmp_path / "o")


def test_same_input_gives_identical_files(tmp_path):
    r = get_robot("seed8")
    tr = rows_trajectory(r)
    job = _job(tmp_path)
    a = {f.name: f.read_bytes() for f in write_job_programs(tr, r, job, tmp_path / "a")}
    b = {f.name: f.read_bytes() for f in write_job_programs(tr, r, job, tmp_path / "b")}
    assert a == b and len(a) == 4


def test_thin_waypoints_keeps_path_poses_and_drops_short_inserted_moves():
    from dataclasses import replace

    from camtool.program.post import thin_waypoints

    r = get_robot("seed8")
    tr = smooth_trajectory(r, 200)
    t = np.cumsum(np.r_[0.0, np.tile([0.05, 0.004, 0.004, 0.004, 0.004], 40)[:199]])
    pidx = np.where(np.arange(200) % 5 == 0, np.arange(200), -1)
    tr = replace(tr, t_s=t, path_index=pidx)
    thin = thin_waypoints(tr, 0.02)
    assert set(np.flatnonzero(pidx >= 0)) <= set(thin.path_index[thin.path_index >= 0])
    assert np.all(np.diff(thin.t_s) >= 0.02 - 1e-12)
    assert thin.t_s[0] == t[0] and thin.t_s[-1] == t[-1]
    assert thin_waypoints(tr, 0.0) is tr


def test_a_rerun_with_fewer_parts_leaves_no_stale_part(tmp_path):
    r = get_robot("seed8")
    out = tmp_path / "out"
    prof = tmp_path / "split.toml"
    src = Path(__file__).resolve().parents[1] / "camtool" / "program" / "profile_data" / "seed8_inform.toml"
    text = src.read_text()
    assert "lines_per_job" in text
    prof.write_text(re.sub(r"lines_per_job\s*=\s*\d+", "lines_per_job = 80", text))
    job = _job(tmp_path, post=f'formats = ["inform"]\nprofiles = {{inform = "{prof}"}}\n')
    many = write_job_programs(rows_trajectory(r, rows=6), r, job, out)
    assert len(many) > 2
    (out / "notes.txt").write_text("mine")  # a user's file is never touched
    few = write_job_programs(rows_trajectory(r, rows=2), r, job, out)
    left = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    assert left == sorted([f.name for f in few] + ["notes.txt"])


def test_post_has_no_format_of_its_own():
    """Every plugin, built-in or not, goes through the protocol: no format names in camtool.program.post."""
    import inspect

    import camtool.program.post

    src = inspect.getsource(camtool.program.post)
    for word in ('"csv"', '"rapid"', '"inform"', "format_of", "check_program"):
        assert word not in src


def test_a_plugin_takes_options_from_the_job(tmp_path, monkeypatch):
    from camtool.run.post_inputs import profile_for_job
    from camtool.program.registry import get_plugin

    r = get_robot("irb2400")
    job = _job(tmp_path, "irb2400", 'formats = ["csv"]\ncsv_angle_unit = "rad"\n')
    assert profile_for_job("csv", get_plugin("csv"), r, job).options["angle_unit"] == "rad"
    rapid = get_plugin("rapid")
    assert rapid.post_options(None) == {}  # the base's default: no options from the job
    monkeypatch.setattr(type(rapid), "post_options", lambda self, post: {"zone": "z50"})
    assert profile_for_job("rapid", rapid, r, job).options["zone"] == "z50"


def test_the_run_simulates_every_program_and_reports_it(tmp_path):
    """write_programs simulates RAPID and INFORM programs (not CSV) and, asked, reports the figures."""
    r = get_robot("seed8")
    report = {}
    files = write_job_programs(rows_trajectory(r), r, _job(tmp_path), tmp_path / "o", report=report)
    assert set(report) == {"rapid", "inform"} and len(files) == 4
    for fig in report.values():
        assert fig["rows"] == 3 and fig["exact_stops_on_surface"] == 0 and fig["part_switches_on_surface"] == 0
        assert fig["max_deviation_mm"] <= fig["path_tol_mm"] == 0.1
        assert abs(fig["duration_s"] / fig["planned_duration_s"] - 1) < 0.005
        assert fig["bytes"] > 0 and fig["write_s"] >= 0 and fig["simulate_s"] >= 0


def test_a_program_that_leaves_the_path_is_not_placed(tmp_path, monkeypatch):
    """The simulator's findings stop the run like a check's: a program the controller would
    run off the planned path is never placed."""
    import camtool.program.candidates as moves
    import camtool.program.post as post_mod

    r = get_robot("seed8")
    monkeypatch.setattr(moves, "MERGE_SHARE", 30.0)  # a writer that merges far beyond the tolerance
    monkeypatch.setattr(moves, "_MERGED", {})
    monkeypatch.setattr(post_mod, "CLOSER_ROUNDS", 0)  # and is not written again closer
    out = tmp_path / "o"
    with pytest.raises(PlanInfeasible, match=r"from the planned path \(tolerance 0.1 mm\)"):
        write_job_programs(rows_trajectory(r), r, _job(tmp_path, post='formats = ["rapid"]\n'), out)
    assert not any(p.suffix in (".mod", ".pgf") for p in out.iterdir())


def test_the_closer_rounds_bring_a_program_far_off_the_path_back_within_the_tolerance(tmp_path, monkeypatch):
    """A writer that merges 50 times beyond its share: its first program leaves the path by far more than
    the tolerance (the simulator, unchanged, measures it), and the closer rounds write the stretches it
    names closer, round after round, until the simulated program is within the aim; it is placed."""
    import camtool.program.candidates as moves
    import camtool.program.post as post_mod

    r = get_robot("seed8")
    monkeypatch.setattr(moves, "MERGE_SHARE", 30.0)
    monkeypatch.setattr(moves, "_MERGED", {})
    seen, real = [], post_mod.simulate_program

    def simulate(*a, **k):
        seen.append(real(*a, **k))
        return seen[-1]

    monkeypatch.setattr(post_mod, "simulate_program", simulate)
    report = {}
    files = write_job_programs(rows_trajectory(r), r, _job(tmp_path, post='formats = ["rapid"]\n'), tmp_path / "o",
                               report=report)
    assert sorted(f.name for f in files) == ["CAMTOOL.mod", "CAMTOOL.pgf"]
    assert seen[0].max_deviation_mm > 2 * 0.1 and 2 <= len(seen) <= 1 + post_mod.CLOSER_ROUNDS
    assert report["rapid"]["max_deviation_mm"] <= post_mod.AIM_SHARE * 0.1
    assert report["rapid"]["moves"] > seen[0].moves


def test_the_job_names_the_rows_and_dates_the_programs(tmp_path):
    import os

    from camtool.path.toolpath import Path as ToolPath

    r = get_robot("seed8")
    tr = rows_trajectory(r, rows=2)
    job = _job(tmp_path, post='formats = ["rapid", "inform"]\n')
    os.utime(job.path, (1_700_000_000, 1_700_000_000))  # 2023/11/14 22:13 UTC
    n = int(tr.path_index.max()) + 1
    seg = np.zeros(n, int)
    seg[len(seg) // 2:] = 7
    path = ToolPath(np.tile(np.eye(4), (n, 1, 1)), seg, np.zeros(n, int), np.zeros(n, int))
    files = {f.suffix: f for f in write_job_programs(tr, r, job, tmp_path / "o", path=path)}
    mod = files[".mod"].read_text()
    assert "! Job: job.toml; date 2023/11/14 22:13 UTC (options.date = job)." in mod
    assert "! Row 1 of 2: segment 0" in mod and "! Row 2 of 2: segment 7" in mod
    jbi = files[".JBI"].read_bytes().decode()
    assert "///DATE 2023/11/14 22:13\r\n///COMM camtool job.toml\r\n" in jbi
    again = {f.suffix: f.read_bytes() for f in write_job_programs(tr, r, job, tmp_path / "p", path=path)}
    assert again[".mod"] == files[".mod"].read_bytes() and again[".JBI"] == files[".JBI"].read_bytes()


def test_a_program_its_simulator_finds_off_the_path_is_written_again_closer(tmp_path, monkeypatch):
    """The writer merges moves within post.path_tol_mm; where the simulated program still leaves the
    planned path (a finding "from the planned path"), the format is written again with the stretch around
    the moves it names merged within a share of the tolerance (``ProcessInfo.closer_s``): more targets there,
    the same elsewhere, and only the last attempt's files are placed."""
    import camtool.program.post as post_mod

    calls, asked, named, real = [], [], [], post_mod.simulate_program
    write = post_mod._write_checked

    def spy(fmt, post, trajectory, robot, folders, process, writing, reference, world=None):
        asked.append(writing.closer_s)
        return write(fmt, post, trajectory, robot, folders, process, writing, reference, world)

    def simulate(plugin, file, robot, profile, trajectory, process, reference, world=None):
        sim = real(plugin, file, robot, profile, trajectory, process, reference, world)
        calls.append(file.with_suffix(".mod").read_text(encoding="latin-1").count("Move"))
        if len(calls) == 1:   # the first attempt: as if the middle move on work were 2 mm off
            mid = len(sim.deviation_s) // 2
            named.append(sim.deviation_s[mid - 1:mid + 2])
            sim.findings.append(f"{file}:9: the simulated TCP is 2.000 mm from the planned path "
                                f"(tolerance 1 mm) at t = {named[0][1][0]:.3f} s")
            sim.deviation_s = tuple((a, b, 2.0 if k == mid else d) for k, (a, b, d) in enumerate(sim.deviation_s))
        return sim

    monkeypatch.setattr(post_mod, "simulate_program", simulate)
    monkeypatch.setattr(post_mod, "_write_checked", spy)
    r = get_robot("seed8")
    job = _job(tmp_path, post='formats = ["rapid"]\npath_tol_mm = 1.0\n')   # a gentle motion: 1 mm merges
    files = write_job_programs(rows_trajectory(r), r, job, tmp_path / "o")
    assert len(calls) == 2 and calls[1] > calls[0]      # written twice, the second with more moves
    assert sorted(f.name for f in files) == ["CAMTOOL.mod", "CAMTOOL.pgf"]
    assert asked[0] == () and len(asked[1]) == 1
    before, _mid, after = named[0]
    assert asked[1][0] == pytest.approx((before[0], after[1], post_mod.AIM_SHARE * 1.0 / 2.0))


def test_closer_spans_take_the_moves_beside_and_tighten_where_named_again():
    """``closer_spans``: a move above the aim is taken with the moves just before and after it (contiguous
    ones only), within the aim over its deviation (at most CLOSER_SHARE) of the tolerance; named again, the
    union within that share of the share it had; moves within the aim add nothing."""
    from camtool.program.post import CLOSER_SHARE, closer_spans

    moves = ((0.0, 1.0, 0.05), (1.0, 2.0, 0.3), (2.0, 3.0, 0.05), (5.0, 6.0, 0.09), (6.0, 7.0, 0.01))
    got = closer_spans((), moves, 0.08)
    assert np.allclose(got, [(0.0, 3.0, 0.08 / 0.3), (5.0, 7.0, CLOSER_SHARE)])
    again = closer_spans(got, ((2.0, 3.0, 0.16), (8.0, 9.0, 0.01)), 0.08)
    assert np.allclose(again, [(0.0, 3.0, 0.08 / 0.3 * 0.5), (5.0, 7.0, CLOSER_SHARE)])
    assert closer_spans(got, moves[:1], 0.08) == got


def test_the_closer_rounds_stop_at_their_count_and_place_the_best_program_that_passed(monkeypatch, tmp_path):
    """``_closer_rounds``: a program within the tolerance but above the aim is written closer. Rounds that stop
    lowering the deviation end after CLOSER_PATIENCE of them, and the passing writing with the smallest deviation
    is written again and placed; rounds that keep lowering it end after CLOSER_ROUNDS. A program the rounds
    never bring within the tolerance is refused, the finding saying what was tried and what to change."""
    import camtool.program.post as post_mod
    from camtool.program.process import ProcessInfo

    def fake(fmt, post, trajectory, robot, folders, process, writing, reference, world=None):
        dev = deviation(len(asked), writing.closer_s)   # the writer is deterministic: by its spans, or by round
        asked.append(writing.closer_s)
        found = [f"x.mod:9: the simulated TCP is {dev:.3f} mm from the planned path (tolerance 0.1 mm)"] \
            if dev > 0.1 else []
        return [], found, {"max_deviation_mm": dev}, (), ((1.0, 2.0, dev),)

    monkeypatch.setattr(post_mod, "_write_checked", fake)
    post = type("Post", (), {"plugin": type("P", (), {"forget": lambda self: None})()})()

    def run():
        asked.clear()
        return post_mod._format_programs("rapid", post, None, None, (tmp_path, tmp_path), ProcessInfo(), None)

    asked = []
    deviation = lambda i, spans: 0.09 if spans == () else 0.3   # noqa: E731   above the aim, then off the path
    files, found, figures = run()
    assert found == [] and figures["max_deviation_mm"] == 0.09
    assert asked[:2] == [(), ((1.0, 2.0, 0.5),)] and asked[-1] == () and len(asked) == 2 + post_mod.CLOSER_PATIENCE
    deviation = lambda i, spans: 0.3   # noqa: E731   never mended
    files, found, figures = run()
    assert len(asked) == 1 + post_mod.CLOSER_PATIENCE and len(found) == 1
    assert f"written {post_mod.CLOSER_PATIENCE} time(s) closer to the plan there" in found[0]
    assert "post.path_tol_mm" in found[0]
    deviation = lambda i, spans: 0.099 - 0.001 * i   # noqa: E731   lowered a little every round, above the aim
    files, found, figures = run()
    assert found == [] and len(asked) == 1 + post_mod.CLOSER_ROUNDS
    assert figures["max_deviation_mm"] == pytest.approx(0.099 - 0.001 * post_mod.CLOSER_ROUNDS)
    seen: dict = {}   # best in the first round (a writing written again comes out as it did)
    deviation = lambda i, spans: seen.setdefault(spans, [0.095, 0.09, 0.092, 0.093][min(len(seen), 3)])  # noqa: E731
    files, found, figures = run()
    assert figures["max_deviation_mm"] == 0.09 and asked[-1] == asked[1] and len(asked) == 5


def test_joint_spans_grow_where_the_controller_still_cannot_follow():
    """The post stage's joint-move rounds: a new span is added as it is; one that meets a span already
    there (the joint moves did not suffice) takes their union widened by its length on either side."""
    from camtool.program.post import joint_spans

    assert joint_spans((), ((2.0, 2.5), (1.0, 1.2))) == ((1.0, 1.2), (2.0, 2.5))
    assert np.allclose(joint_spans(((1.0, 1.2),), ((1.1, 1.4),)), [(0.6, 1.8)])
    assert np.allclose(joint_spans(((0.1, 0.3),), ((0.2, 0.4),)), [(0.0, 0.7)])   # never before the start
    assert np.allclose(joint_spans(((1.0, 1.2), (2.0, 2.5)), ((1.2, 2.0),)), [(0.0, 4.0)])


def test_straight_moves_the_controller_cannot_follow_are_written_again_as_joint_moves(monkeypatch, tmp_path):
    """The post stage's rounds (``_joint_move_rounds``): each rewrite asks joint moves over the spans the
    last simulation named, a span named again grows, and the rounds stop once the program passes."""
    import camtool.program.post as post_mod
    from camtool.program.process import ProcessInfo

    named = [((1.0, 1.2),), ((1.1, 1.3),), ()]
    asked = []

    def fake(fmt, post, trajectory, robot, folders, process, writing, reference, world=None):
        asked.append(writing.joint_moves_s)
        left = named[len(asked) - 1]
        return [], (["x.JBI:9: r moves at 300 deg/s, above its limit 200 deg/s"] if left else []), None, left, ()

    monkeypatch.setattr(post_mod, "_write_checked", fake)

    class Plugin:
        def forget(self):
            pass

    post = type("Post", (), {"plugin": Plugin()})()
    files, found, _fig = post_mod._format_programs("inform", post, None, None, (tmp_path, tmp_path),
                                                   ProcessInfo(), None)
    assert found == [] and len(asked) == 3
    assert asked[0] == () and np.allclose(asked[1], [(1.0, 1.2)]) and np.allclose(asked[2], [(0.7, 1.6)])
    named[:] = [((1.0, 1.2),)] * 10   # never mended: JOINT_MOVE_ROUNDS rewrites, then the findings stand
    asked.clear()
    _files, found, _fig = post_mod._format_programs("inform", post, None, None, (tmp_path, tmp_path),
                                                    ProcessInfo(), None)
    assert found and len(asked) == 1 + post_mod.JOINT_MOVE_ROUNDS
