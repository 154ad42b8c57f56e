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
from camtool.path.toolpath import ZONE_CODE
from camtool.plan.spline_bow import WORK_STEP_MM, SplineDepthSettings, add_spline_poses, spline_depths_mm
from camtool.plan.strategy import ik_settings
from camtool.run.job_settings import JobSettings
from camtool.run.stages import path_for_job, robot_for_job, surface_for_job, workpiece_for_job
from camtool.timing import time_trajectory
from camtool.timing.assemble import run_layout, tcp_positions_mm
from camtool.timing.feed import tcp_positions_world
from camtool.timing.pathlaw import PathSpline, speed_bounds
from camtool.timing.runs import path_parameter
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
    frame = _plate_frame(settings, robot, job)
    inv = np.linalg.inv(frame)

    def world_distance(P):
        return signed_distance(np.atleast_2d(P) @ inv[:3, :3].T + inv[:3, 3])

    local = cleared_leads(two_row_path(), signed_distance, lead_mm=15.0)
    path = Path(np.einsum("ij,njk->nik", frame, local.poses_mm), local.segment, local.point, local.zone)
    return settings, robot, path, world_distance, plan_path(path, robot, settings.planner)


def _plate_frame(settings, robot, job=None) -> np.ndarray:
    """The frame of the plate sample's first work pose: local x along its tool x, local z off the plate."""
    job = load_job(SAMPLES / "irb2400_plate.toml") if job is None else job
    T0 = path_for_job(job, surface_for_job(job, workpiece_for_job(job))).poses_mm[0]
    frame = np.eye(4)
    frame[:3, 0], frame[:3, 2] = T0[:3, 0], -T0[:3, 2]
    frame[:3, 1] = np.cross(frame[:3, 2], frame[:3, 0])
    frame[:3, 3] = T0[:3, 3]
    return frame


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


CREST_DEG = 6.0        # each facet of the roof falls this steeply from its crest
CREST_X_MM = 50.0      # where the crest runs (across the row)
NORMAL_SIGMA_MM = 6.0  # the tool axes: the facet normals blended over this (as a free-form face's smoothed normals)


def _roof_distance(P):
    """mm in front of the roof z <= -tan(CREST_DEG) |x - CREST_X_MM| (+), inside it (-): the larger of the two facet
    planes' signed distances (exact inside and over each facet)."""
    P = np.atleast_2d(P)
    t = np.tan(np.radians(CREST_DEG))
    d1 = (P[:, 2] + t * (P[:, 0] - CREST_X_MM)) / np.hypot(1.0, t)
    d2 = (P[:, 2] - t * (P[:, 0] - CREST_X_MM)) / np.hypot(1.0, t)
    return np.maximum(d1, d2)


def _roof_path(pitch_mm: float) -> Path:
    """One row along x over the roof's crest, its poses on the facets every ``pitch_mm`` (as the sag puts a mesh's
    midposes on its facets), two lead poses either end, tool z against the blended normal."""
    x = np.arange(-10.0, 110.0 + 1e-9, pitch_mm)
    t = np.tan(np.radians(CREST_DEG))
    z = -t * np.abs(x - CREST_X_MM)
    w = np.tanh((x - CREST_X_MM) / NORMAL_SIGMA_MM)            # -1 .. 1 across the crest
    n = np.stack([w * t, np.zeros_like(x), np.ones_like(x)], 1)  # the facets' normals (-t, 0, 1), (t, 0, 1), blended
    n /= np.linalg.norm(n, axis=1)[:, None]
    poses = np.tile(np.eye(4), (len(x), 1, 1))
    zt = -n
    xt = np.cross([0.0, 1.0, 0.0], zt)
    xt /= np.linalg.norm(xt, axis=1)[:, None]
    poses[:, :3, 0], poses[:, :3, 1], poses[:, :3, 2] = xt, np.cross(zt, xt), zt
    poses[:, :3, 3] = np.stack([x, np.zeros_like(x), z], 1)
    zone = np.full(len(x), ZONE_CODE["work"], np.int32)
    zone[x < 0.0] = ZONE_CODE["lead_in"]
    zone[x > 100.0] = ZONE_CODE["lead_out"]
    return Path(poses, np.zeros(len(x), np.int32), np.zeros(len(x), np.int32), zone)


def _work_feed_bound(joint_path, path, robot, feed_mm_s: float) -> float:
    """The highest constant feed (mm/s) the time law's spline of the row allows on its work (pathlaw.speed_bounds)."""
    q = np.asarray(joint_path.q, float)
    pos = tcp_positions_mm(joint_path, path, robot)
    (a, b), = [r for r in run_layout(joint_path, path).runs() if r[1] > r[0]]
    s = path_parameter(q[a:b + 1], np.linalg.norm(np.diff(pos[a:b + 1], axis=0), axis=1), robot.limits, feed_mm_s)
    bound, _, _ = speed_bounds(*PathSpline(s, q[a:b + 1]).piece_bounds(), robot.limits)
    z = np.asarray(joint_path.zone)[a:b + 1]
    return float(bound[(z[:-1] == ZONE_CODE["work"]) & (z[1:] == ZONE_CODE["work"])].min())


def test_steps_on_facets_over_a_crest_are_not_halved_below_the_floor_and_the_row_keeps_its_feed(lifted):
    """Poses 1.25 mm apart on two facets meeting at a crest (a CAD mesh's face after the sag's midposes) under a part
    that every step's spline goes into (the roof raised 1 mm: a crest the spline cuts however short its steps):
    the work steps are halved down to ``WORK_STEP_MM`` / 2 and no further (the leads' steps still are), and the
    feed the row's spline allows stays at a third of the planned row's (halved all the way: an eighth)."""
    settings, robot, _, _, _ = lifted
    frame = _plate_frame(settings, robot)
    inv = np.linalg.inv(frame)
    local = _roof_path(1.25)
    path = Path(np.einsum("ij,njk->nik", frame, local.poses_mm), local.segment, local.point, local.zone)

    def raised(P):
        return _roof_distance(np.atleast_2d(P) @ inv[:3, :3].T + inv[:3, 3]) - 1.0

    jp = plan_path(path, robot, settings.planner)
    feed = settings.timing.tcp_speed_mm_s
    solver = CwlnSolver(robot, ik_settings(settings.planner), free_spin=path.free_spin)
    depth = SplineDepthSettings(depth_tol_mm=settings.planner.chord_tol_mm, feed_mm_s=feed)
    out = add_spline_poses(jp, path, robot, solver, depth, raised)
    step = np.linalg.norm(np.diff(tcp_positions_mm(out, path, robot), axis=0), axis=1)
    z = np.asarray(out.zone)
    work = (z[:-1] == ZONE_CODE["work"]) & (z[1:] == ZONE_CODE["work"])
    assert out.events["spline_steps"]["rounds"] == 4                 # still deeper than the tolerance: measured
    assert step[work].min() >= 0.5 * WORK_STEP_MM - 1e-6 and step[~work].min() < 0.1
    assert np.array_equal(out.q[out.path_index >= 0], jp.q)
    before, after = _work_feed_bound(jp, path, robot, feed), _work_feed_bound(out, path, robot, feed)
    assert after >= before / 3
