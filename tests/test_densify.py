"""Batched densify (plan/densify.py): the same inserts as splitting each step recursively, one at a time."""
import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from camtool.job import load_job
from camtool.plan.cwln import CwlnSolver
from camtool.plan.densify import MAX_SPLITS, slerp_midposes, densify_work
from camtool.plan.strategy import ik_settings
from camtool.run.job_settings import JobSettings
from camtool.run.stages import path_for_job, plan_for_job, robot_for_job, surface_for_job, workpiece_for_job
from camtool.path.toolpath import SURFACE_CODES, ZONE_CODE

from conftest import SAMPLES


def test_batched_slerp_midposes_are_scipys_slerp_halfway_pose_by_pose():
    A = Rotation.random(50, random_state=1).as_matrix()
    B = Rotation.random(50, random_state=2).as_matrix()
    Ta, Tb = np.tile(np.eye(4), (50, 1, 1)), np.tile(np.eye(4), (50, 1, 1))
    Ta[:, :3, :3], Tb[:, :3, :3] = A, B
    Ta[:, :3, 3], Tb[:, :3, 3] = np.arange(150).reshape(50, 3), -np.arange(150).reshape(50, 3)
    mid = slerp_midposes(Ta, Tb)
    for k in range(50):
        R = Slerp([0.0, 1.0], Rotation.from_matrix([A[k], B[k]]))(0.5).as_matrix()
        assert np.array_equal(mid[k, :3, :3], R)
        assert np.array_equal(mid[k, :3, 3], 0.5 * (Ta[k, :3, 3] + Tb[k, :3, 3]))


def _split_one(solver, Ta, qa, Tb, qb, tol, depth):
    """The reference: one step halved recursively (the algorithm before batching)."""
    q_mid = 0.5 * (qa + qb)
    T_mid = slerp_midposes(Ta[None], Tb[None])[0]
    if depth >= MAX_SPLITS or np.linalg.norm(solver.tcp_pose(q_mid)[:3, 3] - T_mid[:3, 3]) <= tol:
        return []
    res = solver.solve(T_mid, q_mid, clamp=False)
    if not res.converged or np.any(res.q < solver.lo) or np.any(res.q > solver.hi):
        return []
    return (_split_one(solver, Ta, qa, T_mid, res.q, tol, depth + 1) + [res.q]
            + _split_one(solver, T_mid, res.q, Tb, qb, tol, depth + 1))


def test_batched_densify_inserts_what_the_recursive_split_inserts():
    job = load_job(SAMPLES / "sphere.toml", ["raster.step_over_mm=40", "raster.pitch_mm=40", "planner.chord_tol_mm=10"])
    robot = robot_for_job(job)
    settings = JobSettings.from_job(job, robot)
    path = path_for_job(job, surface_for_job(job, workpiece_for_job(job)))
    jp = plan_for_job(settings, path, robot)  # barely densified at a 10 mm tolerance
    keep = jp.path_index >= 0  # without the rows inserted there
    jp = type(jp)(**{f: (getattr(jp, f)[keep] if f != "events" else {}) for f in jp.__dataclass_fields__})
    solver = CwlnSolver(robot, ik_settings(settings.planner), free_spin=path.free_spin)
    tol = 0.05
    dense = densify_work(jp, path, robot, solver, tol)
    base_inv = np.linalg.inv(robot.base_T_mm)
    on = np.isin(jp.zone, SURFACE_CODES + (ZONE_CODE["self_motion"],)) & (jp.path_index >= 0)
    expected = []
    for r in np.flatnonzero(on[:-1] & on[1:] & (np.diff(jp.path_index) == 1)):
        Ta, Tb = (base_inv @ path.poses_mm[jp.path_index[i]] for i in (r, r + 1))
        expected += [(r, q) for q in _split_one(solver, Ta, jp.q[r], Tb, jp.q[r + 1], tol, 0)]
    assert len(expected) > 0 and dense.events["densified_steps"]["rows"] == len(expected)
    got = dense.q[dense.path_index < 0]
    assert np.allclose(got, np.array([q for _, q in expected]), atol=1e-9)
    # every original row is kept in order, each inserted row right after its step's first row
    assert np.array_equal(dense.q[dense.path_index >= 0], jp.q[jp.path_index >= 0])
    rows_before = np.flatnonzero(dense.path_index >= 0)
    assert len(rows_before) == len(jp.q)


def test_a_row_inserted_between_work_and_a_lead_is_the_leads():
    """The work ends at its last work pose: a midpose densify adds on the step to a lead-out (or from a lead-in)
    lies on the lead's tangent, off the surface past a convex rim, and takes the lead's zone, as the sag's does
    (labelled work, the Vito door's read 0.1-1.2 mm off the surface on work and the motion check refused it)."""
    job = load_job(SAMPLES / "sphere.toml", ["raster.step_over_mm=40", "raster.pitch_mm=40", "planner.chord_tol_mm=10"])
    robot = robot_for_job(job)
    settings = JobSettings.from_job(job, robot)
    path = path_for_job(job, surface_for_job(job, workpiece_for_job(job)))
    jp = plan_for_job(settings, path, robot)
    keep = jp.path_index >= 0
    jp = type(jp)(**{f: (getattr(jp, f)[keep] if f != "events" else {}) for f in jp.__dataclass_fields__})
    solver = CwlnSolver(robot, ik_settings(settings.planner), free_spin=path.free_spin)
    dense = densify_work(jp, path, robot, solver, 0.01)
    inserted = np.flatnonzero(dense.path_index < 0)
    original = np.flatnonzero(dense.path_index >= 0)
    after = original[np.searchsorted(original, inserted)]          # each inserted row's step's end row
    before = original[np.searchsorted(original, inserted) - 1]     # and its first row
    work, lead_out = ZONE_CODE["work"], ZONE_CODE["lead_out"]
    into_lead = (dense.zone[before] == work) & (dense.zone[after] == lead_out)
    assert into_lead.sum() > 0, "no row inserted between work and a lead-out: the test lost its subject"
    assert (dense.zone[inserted[into_lead]] == lead_out).all()
    between_work = (dense.zone[before] == work) & (dense.zone[after] == work)
    assert (dense.zone[inserted[between_work]] == work).all()
