"""--allow-partial leaves out the poses where the motion check finds the arm in the part (camtool.run.check_left_out,
issue #46): the waypoints of each failing sample taken to the raster's poses, and a generated part end to end."""
import json

import numpy as np
import trimesh

from camtool.path.toolpath import ZONE_CODE, Path
from camtool.run.check_left_out import CHECK_LEFT_OUT_ROUNDS, CheckLeftOut, failing_path_poses

from conftest import run_camtool

W, LI, LO, SM = (ZONE_CODE[z] for z in ("work", "lead_in", "lead_out", "self_motion"))


def _path(zones, segments) -> Path:
    n = len(zones)
    return Path(np.tile(np.eye(4), (n, 1, 1)), np.array(segments), np.arange(n), np.array(zones))


def test_a_failing_sample_is_placed_between_the_path_poses_round_its_waypoints():
    # program waypoints: path poses 0, 1, (inserted), 2, (inserted), (inserted), 5
    pidx = [0, 1, -1, 2, -1, -1, 5]
    got = failing_path_poses(pidx, [("penetration", "tool", 1, 2),      # between pose 1 and the inserted one
                                    ("penetration", "tool", 2, 2),      # at the inserted one: poses 1 .. 2
                                    ("clearance", "wrist", 4, 5),       # between two inserted: poses 2 .. 5
                                    ("deviation", "tcp", 6, 6)])        # at pose 5
    assert got == [("clearance", "wrist", 2, 5), ("deviation", "tcp", 5, 5),
                   ("penetration", "tool", 1, 2)]


def test_poses_left_out_grow_along_their_run_and_a_connector_leaves_out_the_runs_ends():
    # two runs of 6 surface poses (lead, 4 work, lead) joined by two self-motion poses
    zones = [LI, W, W, W, W, LO, SM, SM, LI, W, W, W, W, LO]
    path = _path(zones, [0] * 6 + [0, 1] + [1] * 6)
    left = CheckLeftOut().grown(path, path, None, [("penetration", "forearm (j4-j5)", 3, 3)], "first")
    assert left.indices == [3] and left.rounds == 1
    # a finding in the connector (path poses 6 .. 7): the last pose of run 0 and the first of run 1, in round 2
    # 2 poses deep (2 ** 1: the pose and its neighbour along the run)
    left = left.grown(path, path, None, [("clearance", "tool", 6, 7)], "second")
    assert left.indices == [3, 4, 5, 8, 9] and left.rounds == 2
    # round 3 leaves each found place out 2 ** 2 = 4 poses deep either way along its run, never past it
    again = left.grown(path, path, None, [("penetration", "forearm (j4-j5)", 3, 3)], "third")
    assert again.indices == [0, 1, 2, 3, 4, 5, 8, 9] and again.firsts == ("first", "second", "third")
    # a programmed partial path: its poses are the raster's ``index``
    sub = _path([W, W, LO], [0, 0, 0])
    assert CheckLeftOut().grown(path, sub, np.array([9, 10, 11]), [("penetration", "tool", 1, 1)], "x").indices == [10]
    # nothing new, or out of rounds: None (the failure is the run's)
    assert again.grown(path, path, None, [("penetration", "tool", 2, 2)], "nothing new") is None
    spent = CheckLeftOut(rounds=CHECK_LEFT_OUT_ROUNDS)
    assert spent.grown(path, path, None, [("penetration", "tool", 10, 10)], "out of rounds") is None
    f = left.figures(path)
    assert f["rows"] == [0, 1] and f["work_poses"] == 3 and f["by_kind"]["clearance"]["bodies"] == ["tool"]
    assert f["by_kind"]["penetration"] == {"poses": 1, "work_poses": 1, "rows": [0], "bodies": ["forearm (j4-j5)"]}
    assert left.line(path) == ("3 work poses on rows 0-1 left out where the motion check failed: forearm in the "
                               "part; tool too near the part (2 re-plans)")


def _plate_under_a_roof(folder) -> None:
    """A 200 x 200 mm plate and, 150 mm in front of it (on the tool's side), a 70 x 240 mm roof over its upper
    rows: the tool and the wrist must pass through the roof to work them."""
    def sheet(x0, x1, y0, y1, z, n):
        X, Y = np.meshgrid(np.linspace(x0, x1, n), np.linspace(y0, y1, n), indexing="ij")
        V = np.c_[X.ravel(), Y.ravel(), np.full(X.size, z)]
        a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
        F = np.r_[np.c_[a, a + n, a + n + 1], np.c_[a, a + n + 1, a + 1]]
        return trimesh.Trimesh(V, F, process=False)

    trimesh.util.concatenate([sheet(-100, 100, -100, 100, 0.0, 11),
                              sheet(ROOF_LOW_MM - 900.0, 160, -120, 120, ROOF_Z_MM, 5)]).export(folder / "part.stl")
    (folder / "job.toml").write_text(f"""
[workpiece]
file = "part.stl"
units = "mm"
[fit]
model = "plane"
[raster]
step_over_mm = 40.0
pitch_mm = 25.0
lead_mm = 15.0
clearance_mm = 5.0
tool_x_world = [0.0, 0.0, 1.0]
[robot]
name = "irb2400"
[cell]
workpiece_xyz_mm = [{PLATE_X_MM}, 0.0, 900.0]
workpiece_rpy_deg = [0.0, -90.0, 0.0]
[tool]
name = "polisher"
tcp_xyz_mm = [0.0, 0.0, 120.0]
[post]
formats = ["csv"]
program_name = "ROOF"
""")


ROOF_Z_MM = 150.0          # the roof's height over the plate (the plate's local z: towards the robot)
PLATE_X_MM = 1000.0        # the plate's world x; local x is world z (up), from 800 to 1000 mm
ROOF_LOW_MM = 990.0        # the roof's lower edge, world z (its upper one: 1060 mm)


def test_allow_partial_leaves_out_the_rows_under_a_roof_and_programs_the_rest(tmp_path):
    _plate_under_a_roof(tmp_path)
    strict = run_camtool("run", tmp_path / "job.toml", "-q", "-o", tmp_path / "strict")
    assert strict.returncode == 3, strict.stderr
    line = strict.stderr.strip().splitlines()[-1]
    assert "the motion check failed" in line and "body: " in line and "segment" in line
    assert not (tmp_path / "strict" / "ROOF.csv").exists()

    r = run_camtool("run", tmp_path / "job.toml", "--allow-partial", "-o", tmp_path / "partial")
    assert r.returncode == 0, r.stderr
    report = json.loads((tmp_path / "partial" / "report.json").read_text())
    assert report["status"] == "ok" and report["motion_check"]["ok"] and (tmp_path / "partial" / "ROOF.csv").exists()
    left = report["partial"]["check_left_out"]
    assert left["by_kind"]["penetration"]["bodies"] and left["rounds"] >= 1
    assert left["summary"] in r.stdout and "planned again with" in r.stderr
    # the closed form: on a tool axis along +x the wrist's capsule (check.link_radius_mm round the axis from the
    # flange back) lies within its radius of the roof's lower edge on every row above ROOF_LOW_MM - radius: those
    # rows are left out whole; the rows below them keep their work, but for the end the lift to the next row leaves
    radius = report["motion_check"]["settings"]["link_radius_mm"]
    points = np.genfromtxt(tmp_path / "partial" / "points.csv", delimiter=",", names=True, dtype=None,
                           encoding="utf-8")
    work = points[points["zone"] == "work"]
    assert work.size and (work["z_mm"] < ROOF_LOW_MM - radius).all()
    p = report["partial"]
    assert p["work_poses_kept"] + left["work_poses"] <= p["work_poses_total"] and 0 < p["work_kept_pct"] < 100
    # the five rows (40 mm apart from 820 mm up): the two lowest, 130 mm and more below the roof, are kept whole
    kept = work[work["path_index"] >= 0]
    low = [np.count_nonzero(np.abs(kept["z_mm"] - z) < 1.0) for z in (820.0, 860.0)]
    assert low[0] == low[1] == p["work_poses_total"] // 5 and left["rows"][-1] == 4
