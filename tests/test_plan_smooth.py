"""Null-space smoothing of surface runs (camtool.plan.smooth)."""
import numpy as np
import pytest

from camtool.job import load_job
from camtool.plan import plan_path
from camtool.plan.cwln import CwlnSolver
from camtool.plan.smooth import SmoothSettings, derivatives, divided_difference, run_ratios, smooth_runs
from camtool.plan.strategy import ik_settings
from camtool.run.job_settings import JobSettings
from camtool.run.stages import path_for_job, robot_for_job, surface_for_job, workpiece_for_job
from camtool.path.toolpath import row_segments, run_bounds
from camtool.transforms import rotation_angle_rad

from conftest import ROOT


def test_divided_differences_are_exact_on_polynomials_on_an_uneven_grid():
    s = np.cumsum(np.r_[0.0, np.random.default_rng(0).uniform(0.5, 2.0, 12)])
    q = 2.0 * s ** 3 - s ** 2 + 3.0 * s
    assert np.allclose(divided_difference(s, 3) @ q, 12.0)                      # q''' = 12
    second = divided_difference(s, 2) @ (s ** 2)
    assert np.allclose(second, 2.0)                                              # (s^2)'' = 2
    assert np.allclose(divided_difference(s, 1) @ s, 1.0)


def test_the_ratios_by_sequential_differences_are_the_matrix_formulas():
    """run_ratios builds no matrix; its numbers are the divided-difference matrices' on an uneven grid."""
    from camtool.robots import get_robot
    robot = get_robot("seed8")
    rng = np.random.default_rng(25)
    s = np.cumsum(np.r_[0.0, rng.uniform(0.2, 3.0, 40)])
    q = np.cumsum(rng.normal(0.0, 0.01, (41, 8)), axis=0)
    d = derivatives(q, s, 3)
    for k in range(4):
        assert np.allclose(d[k], divided_difference(s, k) @ q, rtol=1e-12, atol=0)
    feed = 100.0
    jerk, acc = run_ratios(q, s, robot, feed)
    lim = robot.limits
    assert np.allclose(jerk, np.abs(divided_difference(s, 3) @ q).max(axis=0) * feed ** 3 / lim.jerk,
                       rtol=1e-12, atol=0)
    assert np.allclose(acc, np.abs(divided_difference(s, 2) @ q).max(axis=0) * feed ** 2 / lim.acceleration,
                       rtol=1e-12, atol=0)
    for n in (1, 2, 3):  # too few poses for a third (n <= 3) or a second difference (n <= 2): 0
        jerk, acc = run_ratios(q[:n], s[:n], robot, feed)
        assert np.array_equal(jerk, np.zeros(8))
        assert np.array_equal(acc, np.zeros(8)) or n == 3


@pytest.fixture(scope="module")
def sample_plan():
    job = load_job(ROOT / "samples" / "sphere.toml")
    robot = robot_for_job(job)
    path = path_for_job(job, surface_for_job(job, workpiece_for_job(job)))
    settings = JobSettings.from_job(job, robot)
    planned = plan_path(path, robot, settings.planner)
    solver = CwlnSolver(robot, ik_settings(settings.planner), free_spin=path.free_spin)
    smooth = SmoothSettings(feed_mm_s=settings.timing.tcp_speed_mm_s)
    return robot, path, planned, smooth_runs(planned, path, robot, solver, smooth), smooth


def _runs(jp, path):
    seg = row_segments(jp.path_index, jp.zone, path.segment)
    _, start, end = run_bounds(jp.zone, seg)
    return list(zip(np.flatnonzero(start), np.flatnonzero(end)))


def _s_mm(path, rows, jp):
    p = path.poses_mm[jp.path_index[rows], :3, 3]
    return np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))]


def test_kinked_rows_of_the_sample_are_smoothed_below_the_limits_at_the_feed(sample_plan):
    """The sample's rows whose track stops at its clamping buffer needed 2-6x j5's jerk limit at 100 mm/s;
    smoothed, every run needs less than 85 % of every limit, and every pose is still on its target."""
    robot, path, planned, smoothed, st = sample_plan
    done = smoothed.events["smoothed_runs"]
    assert len(done) >= 5
    assert all(d["worst_ratio_before"] > 1.5 and d["worst_ratio_after"] <= 1.0 for d in done)
    base_inv = np.linalg.inv(robot.base_T_mm)
    for a, b in _runs(smoothed, path):
        rows = np.arange(a, b + 1)
        jerk, acc = run_ratios(smoothed.q[rows], _s_mm(path, rows, smoothed), robot, st.feed_mm_s)
        assert jerk.max() <= st.jerk_ratio and acc.max() <= st.accel_ratio, (a, b)
    for d in done:
        first, last = d["path_index"]
        assert np.all(path.segment[first:last + 1] == d["segment"])
        for r in np.flatnonzero((smoothed.path_index >= first) & (smoothed.path_index <= last)):
            q = smoothed.q[r]
            T = base_inv @ path.poses_mm[smoothed.path_index[r]]
            Tq = robot.fk_tcp(q)
            assert np.linalg.norm(Tq[:3, 3] - T[:3, 3]) <= 1e-4
            assert rotation_angle_rad(Tq, T) <= np.radians(1e-4) + 1e-12
            assert robot.within_limits(q)
            assert smoothed.position_error_mm[r] <= 1e-4


def test_rows_that_run_at_the_feed_are_left_as_planned(sample_plan):
    robot, path, planned, smoothed, st = sample_plan
    changed = {tuple(d["path_index"]) for d in smoothed.events["smoothed_runs"]}
    untouched = [(a, b) for a, b in _runs(planned, path)
                 if (planned.path_index[a], planned.path_index[b]) not in changed]
    assert len(untouched) > 50
    for a, b in untouched:
        assert np.array_equal(planned.q[a:b + 1], smoothed.q[a:b + 1])
    # the joint path is a new box; the planner's stays as it was
    assert not np.array_equal(planned.q, smoothed.q)


def test_smoothing_is_deterministic(sample_plan):
    robot, path, planned, smoothed, st = sample_plan
    solver = CwlnSolver(robot, ik_settings(JobSettings.from_job(load_job(ROOT / "samples" / "sphere.toml"),
                                                                 robot).planner), free_spin=path.free_spin)
    again = smooth_runs(planned, path, robot, solver, st)
    assert np.array_equal(again.q, smoothed.q)


def test_the_spline_through_smoothed_poses_must_stay_inside_the_joint_limits():
    from camtool.plan.smooth import spline_within_limits
    from camtool.robots import get_robot
    robot = get_robot("seed8")
    s = np.arange(9) * 5.0
    q = np.zeros((9, 8))
    q[:, 1] = np.linspace(0.0, 0.5, 9)
    assert spline_within_limits(q, s, robot)
    top = robot.limits.upper[5]
    q[:, 5] = top - np.array([0.4, 0.2, 0.05, 0.0, 0.0, 0.0, 0.05, 0.2, 0.4])  # flat on the limit, bending
    assert np.all(q[:, 5] <= top)                                            # every pose inside ...
    assert not spline_within_limits(q, s, robot)                             # ... the spline overshoots


def _kkt_case(n=8, seed=4):
    from camtool.robots import get_robot

    robot = get_robot("seed8")
    rng = np.random.default_rng(seed)
    s = np.cumsum(rng.uniform(4.0, 6.0, n))
    q = rng.uniform(-0.5, 0.5, (n, robot.dof))
    J = rng.normal(size=(n, 6, robot.dof))
    e = rng.normal(scale=0.1, size=(n, 6))
    scale = np.where(robot.prismatic, 500.0, 1.0)
    w3, w2 = np.ones((n - 3, robot.dof)), np.ones((n - 2, robot.dof))
    return robot, q, e, J, divided_difference(s, 3), divided_difference(s, 2), scale, w3, w2


def test_kkt_step_meets_the_linearised_task():
    from camtool.plan.smooth import _kkt_step

    robot, q, e, J, D3, D2, scale, w3, w2 = _kkt_case()
    dq = _kkt_step(q, e, J, D3, D2, robot, SmoothSettings(100.0), q.min(0) - 10.0, q.max(0) + 10.0, scale, w3, w2)
    assert np.allclose(np.einsum("krj,kj->kr", J, dq), e, atol=1e-8)   # J dq = e at every pose, exactly


def test_kkt_step_with_more_joints_held_than_free_is_not_handed_to_superlu(capfd, monkeypatch):
    """Every joint held at a limit (a zero-width box, every pose outside it): a pose's 6 task rows and its 8 held
    joints are dependent, the KKT system singular. Issue #46: SuperLU, handed such a system on the noether panel
    with seed8, printed BLAS's "DGEMV parameter number 2 had an illegal value" on stderr before raising; it is
    no longer asked (one solve, the unconstrained one, then None)."""
    import camtool.plan.smooth as smooth

    calls = []
    real = smooth.spla.spsolve
    monkeypatch.setattr(smooth.spla, "spsolve", lambda K, b: calls.append(K.shape) or real(K, b))
    robot, q, e, J, D3, D2, scale, w3, w2 = _kkt_case()
    n, dof = q.shape
    assert smooth._kkt_step(q, e, J, D3, D2, robot, SmoothSettings(100.0), q.mean(0), q.mean(0), scale, w3,
                            w2) is None
    assert calls == [(n * dof + n * 6,) * 2]
    assert capfd.readouterr().err == ""
