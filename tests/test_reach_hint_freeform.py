"""Issue #48 on a real scanned free-form part: every placement a reach hint prints plans when tried.

The part is a real depth-camera scan nobody here made: the dome-shaped bowl of ros-industrial-consortium's
scan_n_plan_workshop (benchmarks/parts/freeform/snp_dome_scan.ply, Apache-2.0, 0.46 m across; LICENSES.md
there), taken as the raw cloud of its 3627 points (the scan branch of ``fit.model = "freeform"``: outliers,
noise filter, normals estimated). The IRB2400 cannot reach it 1.75 m away; the hint names a placement, and the job
moved there is read, fitted, rastered, planned and timed again from its own file and passes."""
from pathlib import Path

import numpy as np
import pytest
import trimesh

from camtool.job import load_job
from camtool.run import reach_hint
from camtool.run.job_settings import JobSettings
from camtool.run.stages import path_for_job, robot_for_job, surface_for_job, workpiece_for_job

DOME = Path(__file__).resolve().parents[1] / "benchmarks" / "parts" / "freeform" / "snp_dome_scan.ply"
JOB = """
[workpiece]
file = "dome_cloud.ply"
units = "mm"

[fit]
model = "freeform"

[raster]
step_over_mm = 40.0
pitch_mm = 20.0
lead_mm = 15.0
contour = "off"
tool_x_world = [0.0, 0.0, 1.0]

[robot]
name = "irb2400"

[cell]
workpiece_xyz_mm = [1750.0, 0.0, 1000.0]
workpiece_rpy_deg = [0.0, 90.0, 0.0]   # the bowl's inside towards the robot (-x)

[tool]
name = "sander"
tcp_xyz_mm = [0.0, 0.0, 150.0]
mass_kg = 2.0

[post]
formats = ["csv"]
"""


@pytest.fixture(scope="module")
def far_dome(tmp_path_factory):
    """The scanned dome as a raw cloud (mm, centred), out of reach: job, robot, settings, path."""
    folder = tmp_path_factory.mktemp("dome")
    scan = trimesh.load(str(DOME), force="mesh", process=False)
    pts = np.asarray(scan.vertices, float) * 1000.0
    trimesh.PointCloud(pts - pts.mean(axis=0)).export(folder / "dome_cloud.ply")
    (folder / "job.toml").write_text(JOB)
    job = load_job(folder / "job.toml")
    robot = robot_for_job(job)
    wp = workpiece_for_job(job)
    assert wp.faces is None   # the scan branch: a cloud, no triangles
    return job, robot, JobSettings.from_job(job, robot), wp, path_for_job(job, surface_for_job(job, wp))


def test_the_hint_on_a_scan_plans_where_it_points(far_dome):
    job, robot, st, wp, path = far_dome
    shift = reach_hint.planned_shift(job, st, robot, path)
    assert shift is not None and not shift["already_reachable"]   # the screen finds poses out of reach here
    assert shift["planned"], shift.get("not_planned")
    xyz = shift["workpiece_xyz_mm"]
    assert f"cell.workpiece_xyz_mm = [{', '.join(f'{v:g}' for v in xyz)}]" in shift["message"]
    assert np.linalg.norm(np.subtract(xyz, job.cell.workpiece_xyz_mm)) > 100.0   # it moved the part
    moved = reach_hint.placed(job, shift)
    assert moved.cell.workpiece_xyz_mm == xyz
    # tried again from the job, as a user pastes the hint: read, fitted, rastered, planned and timed there
    assert reach_hint.why_not_planned(moved) is None
