"""The timed spline kept out of the part (camtool.plan.spline_bow): a row whose lead-out is lifted steeply clear of a
rise just past its end (test_lead_clearance's part: the plane z = 0 rising at 45 deg beyond x = 103 mm), planned for
the IRB2400 and timed as a run does; its spline, measured against the part's closed-form distance."""
import numpy as np
import pytest

from camtool.job import load_job
from camtool.path.lead_clearance import cleared_leads
from camtool.path.toolpath import SURFACE_CODES, Path
from camtool.plan import plan_path
from camtool.plan.cwln import CwlnSolver
from camtool.plan.spline_bow import SplineDepthSettings, add_spline_poses, spline_depths_mm
from camtool.plan.strategy import ik_settings
from camtool.run.job_settings import JobSettings
from camtool.run.stages import path_for_job, robot_for_job, surface_for_job, workpiece_for_job
from camtool.timing import time_trajectory
from camtool.timing.feed import tcp_positions_world
from camtool.trajectory import sample_trajectory

from conftest import SAMPLES
from test_lead_clearance import signed_distance, two_row_path


@pytest.fixture(scope="module")
def lifted():
    """(settings, robot, the lifted path in the IRB2400's cell, the part's signed distance there, its plan): the two
    rows of test_lead_clearance laid on the plate sample's first work pose, rows along its tool x."""
    job = load_job(SAMPLES / "irb2400_plate.toml")
    robot = robot_for_job(job)
    settings = JobSettings.from_job(job, robot)
    T0 = path_for_job(job, surface_for_job(job, workpiece_for_job(job))).poses_mm[0]
    frame = np.eye(4)                                   # local x along the plate's tool x, local z off the plate
    frame[:3, 0], frame[:3, 2] = T0[:3, 0], -T0[:3, 2]
    frame[:3, 1] = np.cross(frame[:3, 2], frame[:3, 0])
    frame[:3, 3] = T0[:3, 3]
    inv = np.linalg.inv(frame)

    def world_distance(P):
        return signed_distance(np.atleast_2d(P) @ inv[:3, :3].T + inv[:3, 3])

    local = cleared_leads(two_row_path(), signed_distance, lead_mm=15.0)
    path = Path(np.einsum("ij,njk->nik", frame, local.poses_mm), local.segment, local.point, local.zone)
    return settings, robot, path, world_distance, plan_path(path, robot, settings.planner)


def _timed_depth_mm(joint_path, path, robot, settings, distance) -> float:
    """How deep the timed trajectory's TCP goes into the part on the surface zones (4 ms samples)."""
    tr = time_trajectory(joint_path, path, robot, settings.timing)
    smp = sample_trajectory(tr, 0.004)
    k = np.clip(np.searchsorted(tr.t_s, smp.t_s, side="right") - 1, 0, len(tr.t_s) - 2)
    on = np.isin(tr.zone[k], SURFACE_CODES) & np.isin(tr.zone[k + 1], SURFACE_CODES)
    return float(-distance(tcp_positions_world(robot, smp.q[on])).min())


def test_a_spline_that_bows_into_the_part_beside_a_lifted_lead_gets_poses_until_it_stays_out(lifted):
    settings, robot, path, distance, jp = lifted
    tol = settings.planner.chord_tol_mm
    depth = SplineDepthSettings(depth_tol_mm=tol, feed_mm_s=settings.timing.tcp_speed_mm_s)
    rows, before = spline_depths_mm(jp, path, robot, depth.feed_mm_s, distance)
    assert before.max() > 2 * tol                                   # the spline overshoots the lift's bend
    assert _timed_depth_mm(jp, path, robot, settings, distance) > 2 * tol   # and so does the timed motion
    solver = CwlnSolver(robot, ik_settings(settings.planner), free_spin=path.free_spin)
    out = add_spline_poses(jp, path, robot, solver, depth, distance)
    ev = out.events["spline_steps"]
    assert ev["rows"] > 0 and ev["max_depth_mm"] <= tol
    assert np.array_equal(out.q[out.path_index >= 0], jp.q)        # the planned poses stay, in order
    # the time stage's own trajectory of the new plan, against the part's closed form
    assert _timed_depth_mm(out, path, robot, settings, distance) <= tol + 0.005


def test_a_spline_in_front_of_the_part_is_left_as_it_is(lifted):
    settings, robot, path, distance, jp = lifted
    solver = CwlnSolver(robot, ik_settings(settings.planner), free_spin=path.free_spin)
    depth = SplineDepthSettings(depth_tol_mm=settings.planner.chord_tol_mm, feed_mm_s=settings.timing.tcp_speed_mm_s)
    far = add_spline_poses(jp, path, robot, solver, depth, lambda P: distance(P) + 1.0)   # the part 1 mm lower
    assert far.events["spline_steps"]["rows"] == 0 and np.array_equal(far.q, jp.q)
