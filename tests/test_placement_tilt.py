"""The part tilted on its fixture (``camtool.placement.tilt``) and kept clear of the cell (``part_clear``).

The generated part: a 200 mm square plate 900 mm in front of the IRB2400 at 1 m height, its normal 45 deg
above the horizontal, facing away from the robot, the workpiece frame's origin on the robot's axis 1. Its
closed-form reason: a turn about axis 1 (the only turn the upright search has, ``--vary yaw``) changes j1 and
nothing else, so what fails at yaw 0 fails at every yaw; at yaw 0 every closed-form solution of every pose (checked by
forward kinematics) bends j5 past the polisher's free bend (where it meets link_4) or leaves a joint's limits.
Pitched towards the robot, every pose has a solution inside them.
"""
import math

import numpy as np
import pytest
import trimesh

from camtool.errors import BadInput
from camtool.job import load_job
from camtool.placement.kinematics import screen_model
from camtool.placement.part_clear import PartClearance
from camtool.placement.screen import placement_matrix
from camtool.placement.search import PlacementProblem, Variable, placed_job, placement_of
from camtool.placement.tilt import TiltSettings, tilt_matrix
from camtool.run.job_settings import JobSettings
from camtool.run.stages import robot_for_job, workpiece_for_job
from camtool.transforms import matrix_from_xyz_rpy

CENTRE = np.array([900.0, 0.0, 1000.0])
JOB = """[workpiece]
file = "{file}"
units = "mm"
[fit]
model = "plane"
[raster]
step_over_mm = 50.0
pitch_mm = 25.0
lead_mm = 15.0
tool_x_world = [0.0, 0.0, 1.0]
[robot]
name = "irb2400"
[cell]
workpiece_xyz_mm = [0.0, 0.0, 0.0]
{cell}
[tool]
name = "polisher"
tcp_xyz_mm = [0.0, 0.0, 150.0]
[post]
formats = ["csv"]
"""


def plate_job(tmp_path, elevation_deg: float, cell: str = ""):
    """A job of the 200 mm plate at CENTRE whose normal lies ``elevation_deg`` above the horizontal, facing +x."""
    e = math.radians(elevation_deg)
    n = np.array([math.cos(e), 0.0, math.sin(e)])
    u = np.array([0.0, 1.0, 0.0])
    v = np.cross(n, u)
    g = np.linspace(-100.0, 100.0, 5)
    V = np.array([CENTRE + a * u + b * v for a in g for b in g])
    F = [[i * 5 + j, (i + 1) * 5 + j, (i + 1) * 5 + j + 1] for i in range(4) for j in range(4)]
    F += [[i * 5 + j, (i + 1) * 5 + j + 1, i * 5 + j + 1] for i in range(4) for j in range(4)]
    m = trimesh.Trimesh(V, np.array(F), process=False)
    if m.face_normals.mean(axis=0) @ n < 0:
        m.faces = m.faces[:, ::-1]
    m.export(tmp_path / "plate.stl")
    (tmp_path / "plate.toml").write_text(JOB.format(file=tmp_path / "plate.stl", cell=cell))
    return load_job(tmp_path / "plate.toml", [])


def _centre_pose(problem) -> np.ndarray:
    """The work pose nearest the plate's centre (world)."""
    P = problem.path.poses_mm
    return P[int(np.argmin(np.linalg.norm(P[:, :3, 3] - CENTRE, axis=1)))]


def _poses_out_of_bend(problem, D: np.ndarray) -> int:
    """How many of the path's poses, moved by D, have no closed-form solution (each checked by forward
    kinematics) with every joint inside its limits and j5 inside the free bend of the tool before link_4."""
    robot = problem.robot
    model = screen_model(robot, JobSettings.from_job(problem.job, robot))
    T = np.linalg.inv(robot.base_T_mm) @ D @ problem.path.poses_mm
    cands = model.candidates(T)
    out = 0
    for k in range(len(T)):
        ok = False
        for q in cands[:, k][np.isfinite(cands[:, k]).all(axis=1)]:
            assert np.abs(robot.fk_tcp(q) - T[k]).max() < 1e-6            # the solutions are solutions
            ok |= bool(robot.within_limits(q) and model.lower[4] <= q[4] <= model.upper[4])
        out += not ok
    return out


def test_tilt_matrix_and_the_placed_job_in_closed_form(tmp_path):
    job = plate_job(tmp_path, 45.0)
    c = np.array([900.0, 10.0, 1000.0])
    off = (5.0, -7.0, 20.0, 30.0, 10.0, -20.0)
    a, b, y = (math.radians(v) for v in (10.0, -20.0, 30.0))
    Rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    Ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    Rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    T = tilt_matrix(10.0, -20.0, c)
    assert np.allclose(T[:3, :3], Ry @ Rx) and np.allclose(T[:3, 3] + T[:3, :3] @ c, c)   # the centre stays
    D = placement_matrix(off, [0.0, 0.0, 0.0], c)
    p = np.array([1000.0, -50.0, 900.0])
    assert np.allclose(D[:3, :3] @ p + D[:3, 3], Rz @ (Ry @ Rx @ (p - c) + c) + [5.0, -7.0, 20.0])
    xyz, rpy = placement_of(job, off, c)
    assert np.allclose(matrix_from_xyz_rpy(xyz, rpy), D, atol=1e-5)
    moved = placed_job(job, off, c)
    assert np.allclose(matrix_from_xyz_rpy(moved.cell.workpiece_xyz_mm, moved.cell.workpiece_rpy_deg), D, atol=1e-5)
    # no tilt: the same numbers as the upright search's offsets, to the bit
    assert placement_of(job, (5.0, -7.0, 20.0, 30.0, 0.0, 0.0), c) == placement_of(job, (5.0, -7.0, 20.0, 30.0))


def test_tilt_settings():
    assert TiltSettings().values_deg().tolist() == [-30.0, -15.0, 0.0, 15.0, 30.0]
    assert TiltSettings(90.0).values_deg().tolist() == [-90.0, -60.0, -30.0, 0.0, 30.0, 60.0, 90.0]
    assert TiltSettings(10.0).values_deg().tolist() == [-10.0, 0.0, 10.0]
    assert not TiltSettings(0.0).enabled
    for bad in (-1.0, 91.0, float("nan")):
        with pytest.raises(BadInput, match="tilt-max-deg"):
            TiltSettings(bad)


def test_only_a_tilted_placement_reaches_the_plate(tmp_path):
    job = plate_job(tmp_path, 45.0)
    with PlacementProblem(job, [Variable("yaw", -90.0, 90.0)], tilt=TiltSettings(30.0)) as problem:
        # the closed-form reason: at yaw 0 no pose has a solution with j5 inside the free bend ...
        assert _poses_out_of_bend(problem, np.eye(4)) == len(problem.path)
        # ... and a turn about axis 1 (the workpiece frame's origin is on it) only adds to j1
        robot = problem.robot
        model = screen_model(robot, JobSettings.from_job(job, robot))
        T0 = np.linalg.inv(robot.base_T_mm) @ _centre_pose(problem)
        T1 = np.linalg.inv(robot.base_T_mm) @ placement_matrix((0, 0, 0, 37.0), [0, 0, 0]) @ _centre_pose(problem)
        q0, q1 = (np.sort(model.candidates(T[None])[:, 0, 4]) for T in (T0, T1))
        assert np.allclose(q0, q1, equal_nan=True)
        study = problem.run(seed=0, verify=2, max_checks=3)
        assert _poses_out_of_bend(problem, placement_matrix(study.chosen, [0, 0, 0], study.tilt_centre_mm)) == 0
    assert study.upright is not None and study.upright["feasible"] == 0      # none upright, at any yaw
    assert study.chosen is not None and len(study.chosen) == 6
    roll, pitch = study.chosen[4:]
    assert (roll, pitch) != (0.0, 0.0) and max(abs(roll), abs(pitch)) <= 30.0
    assert study.verified[study.chosen]["ok"] and study.verified[study.chosen]["unreachable"] == 0
    # the placed job's plate (its own mesh, placed by the written rpy) has the tilted normal
    xyz, rpy = placement_of(job, study.chosen, study.tilt_centre_mm)
    wp = workpiece_for_job(placed_job(job, study.chosen, study.tilt_centre_mm))
    mesh_n = trimesh.Trimesh(wp.vertices_mm, wp.faces).face_normals.mean(axis=0)
    e = math.radians(45.0)
    R = matrix_from_xyz_rpy([0, 0, 0], rpy)[:3, :3]
    assert np.allclose(mesh_n / np.linalg.norm(mesh_n), R @ [math.cos(e), 0.0, math.sin(e)], atol=1e-6)


def test_a_part_that_needs_no_tilt_keeps_its_upright_placement(tmp_path):
    job = plate_job(tmp_path, 75.0)    # 75 deg up: the robot reaches it as it stands
    studies = []
    for tilt in (TiltSettings(30.0), TiltSettings(0.0)):
        with PlacementProblem(job, [Variable("yaw", -90.0, 90.0)], tilt=tilt) as problem:
            studies.append(problem.run(seed=0, verify=2, max_checks=3))
    a, b = studies
    assert a.upright is None and a.chosen is not None and len(a.chosen) == 4
    def planned(study):   # every figure of the planned placements but their wall-clock seconds
        return {o: {k: x for k, x in v.items() if k != "seconds"} for o, v in study.verified.items()}
    assert a.chosen == b.chosen and planned(a) == planned(b)
    assert [r.as_dict() for r in a.results.values()] == [r.as_dict() for r in b.results.values()]


def test_the_part_is_kept_clear_of_a_world_table(tmp_path):
    """A table in the world frame 50 mm under the plate's lowest point: moved down or tilted into it, the part is
    refused; the distances are the closed form's (the plate's lowest vertex above the table's top)."""
    top = 1000.0 - 100.0 * math.cos(math.radians(75.0)) - 50.0
    cell = (f'[[cell.obstacles]]\nname = "table"\nbox_mm = [400.0, 400.0, 40.0]\nxyz_mm = [900.0, 0.0, {top - 20.0}]\n'
            'frame = "world"\n')
    job = plate_job(tmp_path, 75.0, "clearance_mm = 5.0\n" + cell)
    robot = robot_for_job(job)
    st = JobSettings.from_job(job, robot)
    from camtool.collision.spec import obstacle_specs

    wp = workpiece_for_job(job)
    c = np.array([900.0, 0.0, 1000.0])
    pc = PartClearance(wp, st.cell, obstacle_specs(job.cell.obstacles), lambda o: placement_matrix(o, [0, 0, 0], c))
    for off in [(0, 0, 0, 0), (0, 0, -40, 0), (0, 0, -60, 0), (0, 0, 0, 0, 0, 20.0), (0, 0, 0, 0, 0, -20.0)]:
        D = placement_matrix(off, [0, 0, 0], c)
        low = float((wp.vertices_mm @ D[:3, :3].T + D[:3, 3])[:, 2].min())
        d = pc.distances(D)[0]
        assert d == pytest.approx(low - top, abs=1e-3) if low > top else d <= 1e-6
    from camtool.placement.screen import ScreenResult

    rs = [ScreenResult(o, True, "ok", 0, 1, 0.5, cost=1.0) for o in [(0, 0, 0, 0), (0, 0, -47, 0), (0, 0, -40, 0)]]
    out = pc.refuse(rs)
    assert [r.stage for r in out] == ["ok", "part", "ok"]     # 3 mm above the table < 5 mm clearance; 10 mm is fine


def test_place_refuses_naming_the_nearest_and_what_a_wider_tilt_would_do(tmp_path):
    """The plate 30 deg up: no tilt within +-30 deg plans (its closed-form reason as above, pitched 30 deg it
    still bends j5 past the free bend); the refusal names the nearest miss and the tilt that passes the screen."""
    job = plate_job(tmp_path, 30.0)
    problem = PlacementProblem(job, [Variable("yaw", -90.0, 90.0)])
    c = problem.geom.tilt_centre_mm
    for pitch in (-30.0, 0.0, 30.0):
        assert _poses_out_of_bend(problem, placement_matrix((0, 0, 0, 0, 0, pitch), [0, 0, 0], c)) > 0
    assert _poses_out_of_bend(problem, placement_matrix((0, 0, 0, 0, 0, -60.0), [0, 0, 0], c)) == 0
    problem.close()
    code, err = _cli(["place", str(job.path), "--vary", "yaw=-90:90", "--max-checks", "2", "-o",
                            str(tmp_path / "out")])
    assert code == 3
    line = err.strip().splitlines()[-1]
    assert "a tilt within +-30 deg" in line and "nearest:" in line and "(--tilt-max-deg 60)" in line
    code, err = _cli(["place", str(job.path), "--tilt-max-deg", "-1", "-o", str(tmp_path / "o2")])
    assert code == 2 and err.strip() == "camtool: error: --tilt-max-deg: expected an angle in [0, 90] deg, found -1"
    code, err = _cli(["place", str(job.path), "--vary", "roll=-100:0", "-o", str(tmp_path / "o3")])
    assert code == 2 and "beyond +-90 deg" in err and len(err.strip().splitlines()) == 1


def _cli(args):
    """(exit code, stderr) of ``camtool ARGS`` run as a user runs it."""
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "camtool.cli", *args], capture_output=True, text=True, timeout=600)
    return r.returncode, r.stderr
