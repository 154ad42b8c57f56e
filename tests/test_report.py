"""camtool.report.run_report on hand-made paths, joint paths and trajectories: metrics, JSON, CSV and plots."""
import csv
import json
import struct

import numpy as np
import pytest

from camtool.report.run_report import (
    adjacent_work_steps,
    plan_metrics,
    plot_joints,
    plot_unreachable,
    write_json_atomic,
    write_points_csv,
)
from camtool.robots import get_robot
from camtool.path.toolpath import ZONE_CODE, Path
from camtool.trajectory import JointPath, Trajectory
from camtool.transforms import matrix_from_xyz_rpy

Z = ZONE_CODE
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def png_size(file):
    """(width, height) from a PNG's IHDR chunk."""
    data = file.read_bytes()
    assert data[:8] == PNG_SIGNATURE and data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def straight_path(zones):
    """Poses 10 mm apart along world x at y = 50, z = 300, tool z down."""
    n = len(zones)
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, :3] = np.diag([1.0, -1.0, -1.0])
    poses[:, :3, 3] = np.column_stack([10.0 * np.arange(n), np.full(n, 50.0), np.full(n, 300.0)])
    point = np.array([j + 1 if z == Z["work"] else 0 for j, z in enumerate(zones)])
    return Path(poses, np.zeros(n, int), point, np.array(zones, dtype=np.int8))


def joint_path(q, path_index, zones, pos_err=None, ori_err=None, events=None, **flags):
    n = len(q)
    f = {k: np.asarray(flags.get(k, np.zeros(n, bool)), bool) for k in ("jump", "reverse_planned", "retract",
                                                                         "singular")}
    return JointPath(np.asarray(q, float), np.asarray(path_index), np.asarray(zones, dtype=np.int8),
                     np.zeros(n) if pos_err is None else np.asarray(pos_err, float),
                     np.zeros(n) if ori_err is None else np.asarray(ori_err, float),
                     f["jump"], f["reverse_planned"], f["retract"], f["singular"],
                     np.asarray(flags.get("reached", np.ones(n, bool)), bool), events or {})


def sia20_case():
    """Eight path poses planned as nine rows (one inserted retract row), sia20 (7 revolute joints).

    Joint steps into each row (rad), and whether they count as on-surface steps:
      1 work<-approach 0.1        no (from approach)
      2 work<-work     1.0 & 0.95 yes: a jump at 50 deg (two joints, one step)
      3 self<-work     2.0        no
      4 work<-self     1.5        no
      5 work<-work     0.2        yes, small
      6 retract row    1.5        no (inserted, path_index -1)
      7 work<-retract  1.0        no
      8 work<-work     0.9        yes: a jump at 50 deg (51.6 deg)
    """
    W, A, S, R = Z["work"], Z["approach"], Z["self_motion"], Z["retract"]
    path_zones = [A, W, W, S, W, W, W, W]
    rows = [(0, A, {}), (1, W, {0: 0.1}), (2, W, {2: 1.0, 5: 0.95}), (3, S, {1: 2.0}), (4, W, {6: -1.5}),
            (5, W, {0: 0.2}), (-1, R, {1: 1.5}), (6, W, {1: -1.0}), (7, W, {3: 0.9})]
    q = [np.array([0.1, 0.2, 0.0, -1.0, 0.3, 0.5, 0.0])]
    for _, _, step in rows[1:]:
        nxt = q[-1].copy()
        for j, d in step.items():
            nxt[j] += d
        q.append(nxt)
    pos_err = np.array([5.0, 1e-5, 2e-5, 7.0, 3e-4, 1e-5, 9.0, 0.0, 1e-5])   # only work rows count
    ori_err = np.array([0.5, 1e-6, 4e-6, 0.7, 1e-6, 2e-6, 0.9, 0.0, 1e-6])
    idx = [r[0] for r in rows]
    zones = [r[1] for r in rows]
    events = {"reverse_plans": [{"index": 4, "segment": 0, "point": 5, "attempt": 1}],
              "retracts": [{"index": 6}, {"index": 7}], "gradient_projections": np.int64(3),
              "start_configuration": "searched", "start_margin": 0.123456, "ik_seeds": "random",
              "reverse_plan_seconds": 0.25, "plan_seconds": 2.0}
    jp = joint_path(q, idx, zones, pos_err, ori_err, events,
                    retract=[z == R for z in zones], jump=[False, False, True] + [False] * 5 + [True],
                    reverse_planned=[False] * 4 + [True] + [False] * 4)
    return straight_path(path_zones), jp


# -- plan_metrics ----------------------------------------------------------------------
def test_adjacent_work_steps_mask():
    _, jp = sia20_case()
    assert adjacent_work_steps(jp).tolist() == [False, True, False, False, True, False, False, True]


def test_plan_metrics_counts_jumps_between_adjacent_work_poses_only():
    robot = get_robot("sia20")
    path, jp = sia20_case()
    m = plan_metrics(path, jp, robot, "seed", 50.0, 100.0)
    assert m["robot"] == "sia20" and m["method"] == "seed"
    assert m["points_total"] == 8 and m["points_work"] == 6
    assert m["on_surface_jumps"] == 2
    assert m["max_joint_step_work_deg"] == pytest.approx(np.degrees(1.0), abs=1e-6)
    assert m["max_track_step_work_mm"] == 0.0
    assert m["max_position_error_mm"] == pytest.approx(3e-4)
    assert m["max_orientation_error_deg"] == pytest.approx(np.degrees(4e-6))
    assert m["reverse_plans"] == 1 and m["reverse_plan_events"][0]["index"] == 4
    assert m["retracts"] == 2 and m["singular_points"] == [{"index": 6}, {"index": 7}]
    assert m["gradient_projections"] == 3 and type(m["gradient_projections"]) is int
    assert m["start_configuration"] == "searched" and m["ik_seeds"] == "random"
    assert m["start_margin"] == 0.1235
    assert m["plan_seconds"] == 2.0 and m["points_per_second"] == 4.0
    assert m["reverse_plan_seconds"] == 0.25
    json.dumps(m)  # plain Python values only


@pytest.mark.parametrize("thr_deg, jumps", [(50.0, 2), (54.0, 1), (57.0, 1), (58.0, 0), (5.0, 3)])
def test_plan_metrics_jump_threshold(thr_deg, jumps):
    # on-surface steps: 57.3 deg, 11.5 deg, 51.6 deg
    path, jp = sia20_case()
    assert plan_metrics(path, jp, get_robot("sia20"), "general", thr_deg, 100.0)["on_surface_jumps"] == jumps


def test_plan_metrics_track_steps_in_mm():
    robot = get_robot("seed8")
    W = Z["work"]
    q = np.zeros((4, 8))
    q[:, 0] = [0.0, 150.0, 160.0, 160.0]      # track: 150 mm, then 10 mm
    q[:, 2] = [0.0, 0.1, 0.1, 0.3]            # a revolute joint: 0.2 rad at most
    jp = joint_path(q, [0, 1, 2, 3], [W] * 4, events={})
    path = straight_path([W] * 4)
    m = plan_metrics(path, jp, robot, "seed", 50.0, 100.0)
    assert m["on_surface_jumps"] == 1
    assert m["max_track_step_work_mm"] == pytest.approx(150.0)
    assert m["max_joint_step_work_deg"] == pytest.approx(np.degrees(0.2), abs=1e-6)
    assert plan_metrics(path, jp, robot, "seed", 50.0, 200.0)["on_surface_jumps"] == 0
    assert m["reverse_plans"] == 0 and m["retracts"] == 0 and m["points_per_second"] is None
    assert m["start_margin"] is None


def test_plan_metrics_without_adjacent_work_steps():
    W, S = Z["work"], Z["self_motion"]
    q = np.zeros((3, 7))
    q[1, 0] = q[2, 0] = 2.0
    jp = joint_path(q, [0, 1, 2], [W, S, W])
    m = plan_metrics(straight_path([W, S, W]), jp, get_robot("sia20"), "seed", 50.0, 100.0)
    assert m["on_surface_jumps"] == 0 and m["max_joint_step_work_deg"] == 0.0


# -- write_json_atomic -----------------------------------------------------------------
def test_write_json_atomic_converts_numpy_and_leaves_no_temp_file(tmp_path):
    f = tmp_path / "out" / "nested" / "report.json"  # the folder is created
    obj = {"i": np.int64(7), "f": np.float32(0.5), "b": np.bool_(True), "arr": np.arange(6).reshape(2, 3),
           "farr": np.array([0.25, 1.5]), "list": [np.int32(1), np.float64(2.5)], "s": "text", "none": None,
           "nested": {"q": np.zeros(2)}}
    write_json_atomic(obj, f)
    assert sorted(p.name for p in f.parent.iterdir()) == ["report.json"]
    text = f.read_text()
    assert text.endswith("\n")
    back = json.loads(text)
    assert back == {"i": 7, "f": 0.5, "b": True, "arr": [[0, 1, 2], [3, 4, 5]], "farr": [0.25, 1.5],
                    "list": [1, 2.5], "s": "text", "none": None, "nested": {"q": [0.0, 0.0]}}
    assert type(back["i"]) is int and type(back["b"]) is bool


def test_write_json_atomic_replaces_an_existing_file(tmp_path):
    f = tmp_path / "report.json"
    f.write_text('{"old": true, "long": "' + "x" * 1000 + '"}\n')
    write_json_atomic({"new": 1}, f)
    assert json.loads(f.read_text()) == {"new": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["report.json"]


def test_write_json_atomic_failure_keeps_the_old_file(tmp_path):
    f = tmp_path / "report.json"
    write_json_atomic({"run": 1}, f)
    with pytest.raises(TypeError):
        write_json_atomic({"bad": object()}, f)
    assert json.loads(f.read_text()) == {"run": 1}  # never half-written


def test_write_json_atomic_failure_leaves_no_temp_file(tmp_path):
    with pytest.raises(TypeError):
        write_json_atomic({"bad": object()}, tmp_path / "report.json")
    assert list(tmp_path.iterdir()) == []


def test_write_json_atomic_output_is_strict_json(tmp_path):
    f = tmp_path / "report.json"
    write_json_atomic({"max_position_error_mm": np.float64("nan")}, f)

    def reject(name):
        raise ValueError(name)
    json.loads(f.read_text(), parse_constant=reject)


# -- points.csv --------------------------------------------------------------------------
def test_points_csv_rows_columns_and_values(tmp_path):
    base = matrix_from_xyz_rpy([1000.0, -200.0, 50.0], [0, 0, 90])
    robot = get_robot("sia20").with_placement(base_T_mm=base, tool_T_mm=matrix_from_xyz_rpy([0, 0, 100], [0, 0, 0]))
    path, jp = sia20_case()
    f = tmp_path / "points.csv"
    write_points_csv(path, jp, robot, f)
    rows = list(csv.reader(f.open()))
    header, body = rows[0], rows[1:]
    joints = [f"{n}_deg" for n in robot.joint_names]
    assert header == ["row", "path_index", "segment", "point", "zone", "x_mm", "y_mm", "z_mm", *joints,
                      "position_error_mm", "orientation_error_deg", "max_joint_step_deg", "jump",
                      "reverse_planned", "retract", "singular", "reached"]
    assert len(body) == len(jp.q) == 9
    assert all(len(r) == len(header) for r in body)
    col = {name: i for i, name in enumerate(header)}
    for k, r in enumerate(body):
        assert int(r[col["row"]]) == k
        assert int(r[col["path_index"]]) == jp.path_index[k]
        assert np.allclose([float(r[col[j]]) for j in joints], np.degrees(jp.q[k]), atol=1e-5)
        assert float(r[col["position_error_mm"]]) == pytest.approx(jp.position_error_mm[k], rel=1e-3)
        assert float(r[col["orientation_error_deg"]]) == pytest.approx(np.degrees(jp.orientation_error_rad[k]),
                                                                       rel=1e-3)
    assert [r[col["zone"]] for r in body] == ["approach", "work", "work", "self_motion", "work", "work",
                                              "retract", "work", "work"]
    # path rows take the path's TCP position; the inserted row its forward kinematics in the world frame
    xyz = np.array([[float(v) for v in r[col["x_mm"]:col["z_mm"] + 1]] for r in body])
    on_path = jp.path_index >= 0
    assert np.allclose(xyz[on_path], path.poses_mm[jp.path_index[on_path], :3, 3], atol=1e-4)
    assert np.allclose(xyz[6], (base @ robot.fk_tcp(jp.q[6]))[:3, 3], atol=1e-4)
    assert not np.allclose(xyz[6], robot.fk_tcp(jp.q[6])[:3, 3], atol=1.0)  # the base placement counts
    assert [int(r[col["segment"]]) for r in body][6] == -1 and int(body[6][col["point"]]) == 0
    assert [int(r[col["point"]]) for r in body][:3] == [0, 2, 3]
    steps = [float(r[col["max_joint_step_deg"]]) for r in body]
    expected = np.r_[0.0, np.degrees(np.abs(np.diff(jp.q, axis=0)).max(axis=1))]
    assert np.allclose(steps, expected, atol=1e-4)
    for flag in ("jump", "reverse_planned", "retract", "singular", "reached"):
        assert [int(r[col[flag]]) for r in body] == getattr(jp, flag).astype(int).tolist(), flag


def test_points_csv_track_column_in_mm(tmp_path):
    robot = get_robot("seed8")
    W = Z["work"]
    q = np.zeros((2, 8))
    q[1, 0] = 123.0
    q[1, 1] = 0.5
    f = tmp_path / "points.csv"
    write_points_csv(straight_path([W, W]), joint_path(q, [0, 1], [W, W]), robot, f)
    rows = list(csv.DictReader(f.open()))
    assert len(rows) == 2
    track, j1 = (f"{robot.joint_names[0]}_mm", f"{robot.joint_names[1]}_deg")
    assert float(rows[1][track]) == pytest.approx(123.0)
    assert float(rows[1][j1]) == pytest.approx(np.degrees(0.5), abs=1e-5)
    # the largest revolute step ignores the 123 mm track move
    assert float(rows[1]["max_joint_step_deg"]) == pytest.approx(np.degrees(0.5), abs=1e-4)


# -- plots -------------------------------------------------------------------------------
def small_trajectory(robot, phase=0.0):
    t = np.linspace(0.0, 2.0, 6)
    amp = np.where(robot.prismatic, 200.0, 0.5)
    q = amp * np.sin(t[:, None] + phase + np.arange(robot.dof))
    qd = amp * np.cos(t[:, None] + phase + np.arange(robot.dof))
    qdd = -q
    n = len(t)
    return Trajectory(robot.name, robot.joint_names, robot.prismatic, t, q, qd, qdd, np.zeros(n, int),
                      np.arange(n))


@pytest.mark.parametrize("name", ["sia20", "seed8"])
def test_plot_joints_writes_three_pngs(tmp_path, name):
    robot = get_robot(name)
    out = tmp_path / "plots"
    files = plot_joints({"seed": small_trajectory(robot)}, robot, out, dt_s=0.05)
    assert [f.name for f in files] == ["joint_angle.png", "joint_speed.png", "joint_acceleration.png"]
    assert sorted(p.name for p in out.iterdir()) == sorted(f.name for f in files)
    for f in files:
        assert png_size(f) == (630, 540)  # 7 x 6 in at 90 dpi


def test_plot_joints_compare_has_one_column_per_trajectory(tmp_path):
    robot = get_robot("seed8")
    files = plot_joints({"seed": small_trajectory(robot), "general": small_trajectory(robot, 0.5)}, robot,
                        tmp_path, dt_s=0.05)
    assert len(files) == 3
    for f in files:
        assert png_size(f) == (1260, 540)


def test_plot_unreachable_writes_a_png(tmp_path):
    W = Z["work"]
    path = straight_path([W] * 10)
    f = tmp_path / "plots" / "deeper" / "unreachable.png"
    out = plot_unreachable(path, [{"index": 2}, {"index": 7}], f)
    assert out == f and f.is_file()
    assert png_size(f) == (1080, 450)  # 12 x 5 in at 90 dpi
    assert list(f.parent.iterdir()) == [f]
