"""Safe motion end to end: the independent motion check runs inside `camtool run` and decides."""
import json

import numpy as np

from camtool.job import load_job
from camtool.plan.cwln import CwlnSolver, IkSettings
from camtool.plan.densify import densify_work
from camtool.run.job_settings import JobSettings
from camtool.run.stages import path_for_job, plan_for_job, robot_for_job, surface_for_job, workpiece_for_job
from camtool.path.toolpath import WORK

from conftest import SAMPLES, run_camtool

COARSE = ["--set", "raster.step_over_mm=40", "--set", "raster.pitch_mm=8", "--set", 'post.formats=["csv"]']


# the forced-reconfiguration job's motion check: tests/test_connectors.py (one plan for both)


def test_a_raster_too_coarse_for_the_controller_is_refused_with_the_place(tmp_path):
    """40 mm pitch: the joint-linear motion between program points leaves the sphere by more than 0.1 mm."""
    r = run_camtool("run", SAMPLES / "sphere.toml", "-o", tmp_path, "--set", "raster.step_over_mm=40",
                    "--set", "raster.pitch_mm=40", "--set", "planner.chord_tol_mm=10", "--set",
                    'post.formats=["csv"]', "-q")
    assert r.returncode == 3
    line = r.stderr.strip().splitlines()[-1]
    assert "motion check failed" in line and "segment" in line and " t = " in line
    assert not list(tmp_path.glob("*.csv")) or [p.name for p in tmp_path.glob("*.csv")] == ["points.csv"]
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["status"] == "unsafe" and report["motion_check"]["ok"] is False


def test_densified_work_steps_keep_the_chord_on_the_line():
    job = load_job(SAMPLES / "sphere.toml", ["raster.step_over_mm=40", "raster.pitch_mm=40"])
    robot = robot_for_job(job)
    settings = JobSettings.from_job(job, robot)
    path = path_for_job(job, surface_for_job(job, workpiece_for_job(job)))
    jp = plan_for_job(settings, path, robot)          # default chord_tol_mm = 0.05: steps get split
    # #24: on the sphere the steps are split on the surface arc first (plan/sag.py), densify keeps the rest
    assert jp.events["sag_steps"]["rows"] > 0
    solver = CwlnSolver(robot, IkSettings())
    inserted = (jp.path_index < 0) & (jp.zone == WORK)
    assert inserted.any()
    # every inserted pose lies on the sphere through its two path poses, not on their chord (to 0.02 mm)
    base_inv = np.linalg.inv(robot.base_T_mm)
    for r in np.flatnonzero(inserted)[:20]:
        a = r - 1
        while jp.path_index[a] < 0:
            a -= 1
        b = r + 1
        while jp.path_index[b] < 0:
            b += 1
        pa, pb = path.poses_mm[jp.path_index[a]][:3, 3], path.poses_mm[jp.path_index[b]][:3, 3]
        x = (robot.base_T_mm @ solver.tcp_pose(jp.q[r]))[:3, 3]
        assert abs(np.linalg.norm(x - [1000.0, 0.0, 100.0]) - np.linalg.norm(pa - [1000.0, 0.0, 100.0])) < 0.02
        assert np.linalg.norm(np.cross(x - pa, pb - pa)) / np.linalg.norm(pb - pa) > 0.01 or \
            np.linalg.norm(pb - pa) < 5.0
    # and densifying again finds nothing left to split
    again = densify_work(jp, path, robot, solver, 0.05)
    assert again.events["densified_steps"]["steps"] <= jp.events["densified_steps"]["steps"]
    del base_inv


def test_allow_partial_programs_the_reachable_part_with_its_coverage(tmp_path):
    """The sphere 250 mm farther out: some rows are out of reach of seed8; --allow-partial works the rest."""
    args = ["run", SAMPLES / "sphere.toml", "--set", "cell.workpiece_xyz_mm=[1250.0, 0.0, 100.0]",
            "--set", "raster.step_over_mm=20", "--set", 'post.formats=["csv"]', "-q"]
    r = run_camtool(*args, "-o", tmp_path / "strict")
    assert r.returncode == 3 and "out of reach" in r.stderr and "move the workpiece by" in r.stderr
    assert not (tmp_path / "strict" / "SPHERE.csv").exists()
    r = run_camtool(*args, "--allow-partial", "-o", tmp_path / "partial")
    assert r.returncode == 0, r.stderr
    report = json.loads((tmp_path / "partial" / "report.json").read_text())
    p = report["partial"]
    assert 50.0 < p["work_kept_pct"] < 100.0 and p["left_out_path_indices"]
    assert report["motion_check"]["ok"] and (tmp_path / "partial" / "SPHERE.csv").exists()


def test_allow_partial_leaves_out_the_stretch_ends_the_arm_cannot_lift_off_at(tmp_path):
    """The IRB2400's plate 300 mm lower: its lower rows are out of reach (axis 3, j2 + j3, past 65 deg), and where
    the reachable rows end no lift stays within that limit. --allow-partial was refused ("reconfiguration before
    segment 1: at 100 mm above the surface irb2400 controller axis rax_3 = 67.9 deg is beyond its limits"; issue
    #46's real shell and folded sheet so too); it now leaves those stretch ends out as well and programs the rest."""
    r = run_camtool("run", SAMPLES / "irb2400_plate.toml", "--set", "cell.workpiece_xyz_mm=[1000.0, 0.0, 600.0]",
                    "--set", 'post.formats=["csv"]', "--allow-partial", "-q", "-o", tmp_path)
    assert r.returncode == 0, r.stderr
    report = json.loads((tmp_path / "report.json").read_text())
    p = report["partial"]
    ends = p["unliftable_ends_left_out"]
    assert ends and set(ends) <= set(p["left_out_path_indices"]) and 0.0 < p["work_kept_pct"] < 100.0
    assert report["limits_ok"] and report["motion_check"]["ok"] and report["lifted_connectors"] is not None
    assert (tmp_path / "PLATE2400.csv").exists()
