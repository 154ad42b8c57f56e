"""camtool.path.face_set: several faces in one path (order, join, per-face settings), saved and read back, and one
program for two faces of the half pipe."""
import json

import numpy as np
import pytest

from camtool.path.face_set import face_runs, joined, raster_changes, working_order
from camtool.settings import RasterSettings
from camtool.part.surface import Boundary, FaceSet, PlaneSurface, surface_from_dict
from camtool.path.toolpath import ZONE_CODE, Path

from conftest import SAMPLES, run_camtool


def _line_path(entry, exit_, segments=1):
    """A Path of two work poses per segment from ``entry`` to ``exit_`` (mm)."""
    pts = np.linspace(entry, exit_, 2 * segments)
    poses = np.repeat(np.eye(4)[None], len(pts), axis=0)
    poses[:, :3, 3] = pts
    seg = np.repeat(np.arange(segments), 2).astype(np.int32)
    return Path(poses, seg, np.ones(len(pts), np.int32), np.full(len(pts), ZONE_CODE["work"], np.int32))


def test_working_order_takes_the_shorter_air_moves():
    # face 0 ends at x = 100; face 2 starts there, face 1 starts where face 2 ends
    paths = [_line_path([0, 0, 0], [100, 0, 0]), _line_path([300, 0, 0], [400, 0, 0]),
             _line_path([100, 10, 0], [300, 10, 0])]
    assert working_order(paths) == [0, 2, 1]
    assert working_order(paths) == working_order(paths)  # deterministic


def test_two_opt_mends_a_greedy_tour():
    # nearest neighbour from face 0 goes to face 1 (10 mm), then must come back a long way
    entries = [[0, 0, 0], [0, 10, 0], [500, 0, 0], [0, -20, 0]]
    exits = [[0, 0, 0], [490, 0, 0], [0, -15, 0], [0, -20, 0]]
    paths = [_line_path(a, b) for a, b in zip(entries, exits)]
    order = working_order(paths)
    from camtool.path.face_set import air_mm

    greedy = [0, 1, 2, 3]
    assert air_mm(order, np.array(entries, float), np.array(exits, float)) <= \
        air_mm(greedy, np.array(entries, float), np.array(exits, float))


def test_joined_numbers_segments_on_and_marks_each_face():
    a, b = _line_path([0, 0, 0], [10, 0, 0], segments=2), _line_path([50, 0, 0], [60, 0, 0], segments=3)
    path = joined([a, b], [1, 0], (7, 3), RasterSettings.make(step_over_mm=4.0, pitch_mm=2.0))
    assert len(path) == len(a) + len(b)
    assert list(np.unique(path.segment)) == [0, 1, 2, 3, 4]
    assert [f for f, _ in face_runs(path)] == [3, 7]
    assert path.step_over_mm == 4.0 and path.pitch_mm == 2.0
    assert path.segment_text(0) == "face 3, segment 0" and a.segment_text(0) == "segment 0"  # for messages
    with pytest.raises(ValueError):
        Path(a.poses_mm, a.segment, a.point, a.zone, face=np.zeros(1, np.int32))


def test_raster_changes_are_the_fields_a_face_sets():
    job = {"step_over_mm": 10.0, "pitch_mm": 5.0}
    change = raster_changes(job, {"step_over_mm": 4.0, "angle_deg": 90.0})
    assert change["step_over_mm"] == 4.0 and change["angle_rad"] == pytest.approx(np.pi / 2)
    assert "pitch_mm" not in change
    assert raster_changes(job, {"step_over_mm": 10.0}) == {}


def test_a_face_set_round_trips_through_the_surface_format():
    sq = Boundary(np.array([[0, 0], [10, 0], [10, 10], [0, 10]], float))
    s1 = PlaneSurface(np.zeros(3), np.array([0, 0, 1.0]), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), sq)
    s2 = PlaneSurface(np.array([0, 0, 5.0]), np.array([0, 0, 1.0]), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), sq)
    fs = FaceSet((s1, s2), (0, 4), ({}, {"step_over_mm": 3.0}))
    back = surface_from_dict(json.loads(json.dumps(fs.to_dict())))
    assert isinstance(back, FaceSet) and back.indices == (0, 4) and back.raster_changes[1] == {"step_over_mm": 3.0}
    assert back.settings_for(1, RasterSettings.make()).step_over_mm == 3.0
    with pytest.raises(ValueError):
        FaceSet((s1,), (0,), ({},))  # one face is a surface, not a set


def test_two_faces_of_the_half_pipe_make_one_program(tmp_path):
    """The outside cylinder and the top end face in one RAPID program: rows named by face, one lifted move
    between the faces, and a section per face in report.json."""
    job_file = tmp_path / "pipe2.toml"
    text = (SAMPLES / "pipe_half.toml").read_text()
    text = text.replace('file = "pipe_half.stl"', f'file = "{(SAMPLES / "pipe_half.stl").as_posix()}"')
    text = text.replace("select = [0]", 'select = [0, 2]\nraster = {"2" = {step_over_mm = 8.0, pitch_mm = 4.0}}')
    text = text.replace("step_over_mm = 15.0", "step_over_mm = 30.0")
    text = text.replace('formats = ["rapid", "inform", "csv"]', 'formats = ["rapid"]')
    job_file.write_text(text)
    done = run_camtool("run", job_file, "-o", tmp_path / "out")  # as a user runs it
    assert done.returncode == 0, done.stderr
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    worked = report["faces"]["worked"]
    assert "face 0 (cylinder): " in done.stdout and "face 2 (plane): " in done.stdout  # a line per face
    assert [w["index"] for w in worked] == [0, 2]
    assert worked[1]["step_over_mm"] == 8.0 and worked[0]["step_over_mm"] == 30.0
    assert all(w["work_feed"]["work_share_within_1pct"] > 0.99 for w in worked)
    assert worked[0]["coverage"] > 0.995
    program = "".join(p.read_text() for p in (tmp_path / "out").glob("*.mod"))
    assert "face 0, segment 0" in program and f"face 2, segment {worked[1]['segment_range'][0]}" in program
    between = [c for c in report["lifted_connectors"] if c["segment"] == worked[1]["segment_range"][0]]
    assert between, "the move from one face to the next is a lifted connector"
    assert report["motion_check"]["ok"]
    # the motion check face by face: its worst figures over the face's segments, the run's worst among them
    motion = report["motion_check"]
    checked = [w["motion_check"] for w in worked]
    assert sum(c["samples"] for c in checked) == motion["samples"]
    assert max(c["work_deviation_mm"] for c in checked) == motion["work_deviation_mm"]
    assert min(c["min_clearance_mm"] for c in checked) == motion["min_clearance_mm"]
    assert all(not any(c["failing_samples"].values()) for c in checked)
    assert f"deviation {checked[0]['work_deviation_mm']:.3f} mm" in done.stdout
