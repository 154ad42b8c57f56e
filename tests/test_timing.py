"""time_trajectory: limits, TCP speed, slow-downs, waypoints, both methods, determinism."""
import numpy as np
import pytest

from camtool.errors import BadInput, PlanInfeasible
from camtool.settings import TimingSettings
from camtool.timing import check_trajectory, time_trajectory, timing_report
from camtool.path.toolpath import ZONE_CODE
from test_timing_fixtures import retract_path, seed8, tcp_speed_mm_s, two_runs

ROBOT = seed8()
JP, PATH = two_runs(ROBOT)
WORK = ZONE_CODE["work"]


@pytest.fixture(scope="module", params=["quintic", "ruckig"])
def timed(request):
    return request.param, time_trajectory(JP, PATH, ROBOT, TimingSettings.make(method=request.param,
                                                                               tcp_speed_mm_s=100.0))


def test_within_limits_by_independent_check(timed):
    _, tr = timed
    assert check_trajectory(tr, ROBOT, dt_s=0.004) == []
    rep = timing_report(tr, ROBOT, tr.sampled)
    for key in ("peak_joint_speed_ratio", "peak_joint_acc_ratio", "peak_joint_jerk_ratio"):
        assert 0 < rep[key] <= 1.0
    assert 0 < rep["work_time_s"] < rep["cycle_time_s"] == pytest.approx(tr.duration_s)


def test_tcp_speed_is_the_set_speed_in_mid_run(timed):
    _, tr = timed
    t, q, *_ = tr.sample(0.004)
    zone = tr.zone[np.clip(np.searchsorted(tr.t_s, t, side="right") - 1, 0, len(tr.t_s) - 1)]
    v = tcp_speed_mm_s(ROBOT, t, q)
    checked = 0
    work = zone[:-1] == WORK
    edges = np.flatnonzero(np.diff(np.r_[0, work.astype(int), 0]))
    for a, b in zip(edges[::2], edges[1::2]):  # central 40 % of each work run
        lo, hi = a + int(0.3 * (b - a)), b - int(0.3 * (b - a))
        assert np.median(v[lo:hi]) == pytest.approx(100.0, rel=0.005)
        assert np.all(np.abs(v[lo:hi] - 100.0) < 3.0)
        checked += hi - lo
    assert checked > 300


def test_waypoints_are_passed_exactly(timed):
    _, tr = timed
    for row in range(len(JP.q)):
        k = np.flatnonzero(tr.path_index == JP.path_index[row])
        assert len(k) == 1
        assert np.array_equal(tr.q[k[0]], JP.q[row])
    # the Hermite piece that starts at a waypoint starts at its q (sampling from t_s[0] hits it)
    _, qs, *_ = tr.sample(tr.duration_s / 1.0)
    assert np.array_equal(qs[0], tr.q[0]) and np.allclose(qs[-1], tr.q[-1], atol=1e-12)
    assert np.all(np.diff(tr.t_s) > 0)


def test_rest_at_run_boundaries(timed):
    _, tr = timed
    for row in (0, 119, 122, 241):  # first/last work pose of each segment
        k = np.flatnonzero(tr.path_index == row)[0]
        assert np.all(tr.qd[k] == 0) and np.all(tr.qdd[k] == 0)
    free = tr.zone == ZONE_CODE["self_motion"]
    assert free.sum() > 10  # the self-motion move is sampled densely


def test_fast_job_is_slowed_down_and_reported():
    """Too fast for the limits: each row at its highest constant feed (slow_scope row), the binding joint named."""
    tr = time_trajectory(JP, PATH, ROBOT, TimingSettings.make(tcp_speed_mm_s=1500.0))
    assert check_trajectory(tr, ROBOT, 0.004) == []
    assert len(tr.slowdowns) == 2 and all(0.3 < s["speed_ratio"] < 0.99 for s in tr.slowdowns)
    rep = timing_report(tr, ROBOT, tr.sampled)
    assert rep["slowdowns"] == [dict(s) for s in tr.slowdowns]
    peaks = [rep[f"peak_joint_{k}_ratio"] for k in ("speed", "acc", "jerk")]
    assert 0.9 < max(peaks) <= 1.0  # the binding limit is used, not exceeded
    for s in tr.slowdowns:
        assert 0 <= s["first_row"] < s["last_row"] < len(JP.q) and 0 < s["speed_ratio"] < 1
        assert s["joint"] in ROBOT.joint_names and s["feed_mm_s"] == pytest.approx(1500.0 * s["speed_ratio"])


def test_slow_job_needs_no_mid_run_slowdown():
    tr = time_trajectory(JP, PATH, ROBOT, TimingSettings.make(tcp_speed_mm_s=50.0))
    assert [s for s in tr.slowdowns if not s["at_run_end"]] == []


def test_deterministic():
    a = time_trajectory(JP, PATH, ROBOT, TimingSettings.make(method="quintic"))
    b = time_trajectory(JP, PATH, ROBOT, TimingSettings.make(method="quintic"))
    for f in ("t_s", "q", "qd", "qdd", "zone", "path_index"):
        assert np.array_equal(getattr(a, f), getattr(b, f))
    assert a.slowdowns == b.slowdowns


def test_inserted_retract_poses():
    n = 60
    jp2, path2, out = retract_path(ROBOT, n)
    qa = jp2.q[:n]
    tr = time_trajectory(jp2, path2, ROBOT, TimingSettings.make())
    assert check_trajectory(tr, ROBOT, 0.004) == []
    ret = tr.zone == ZONE_CODE["retract"]
    assert ret.sum() > 10 and np.all(tr.path_index[ret] == -1)
    # the retract step moves the track only (straight joint-space line, phase-synchronised)
    k0 = np.flatnonzero(tr.path_index == n - 1)[0]
    k1 = np.flatnonzero(np.all(tr.q == out, axis=1))[0]
    assert np.allclose(tr.q[k0:k1 + 1, 1:], qa[-1][1:], atol=1e-9)


@pytest.mark.parametrize("keys", [{"method": "spline"}, {"tcp_speed_mm_s": 0}, {"check_dt_ms": 0},
                                  {"zones": "glide"}])
def test_bad_settings_are_the_schemas_job(keys):
    with pytest.raises(BadInput, match="timing"):
        TimingSettings.make(**keys)


def test_bad_joint_path():
    q = JP.q.copy()
    q[5, 3] = np.radians(175)
    from dataclasses import replace
    with pytest.raises(PlanInfeasible, match="j4"):
        time_trajectory(replace(JP, q=q), PATH, ROBOT, TimingSettings.make())
    q = JP.q.copy()  # the JointPath made read-only the array it was given
    q[5, 3] = np.nan
    with pytest.raises(PlanInfeasible, match="row 5"):
        time_trajectory(replace(JP, q=q), PATH, ROBOT, TimingSettings.make())
    with pytest.raises(BadInput, match="shape"):
        time_trajectory(replace(JP, q=JP.q[:, :7]), PATH, ROBOT, TimingSettings.make())


def test_each_run_is_timed_once_lead_sizing_then_timing():
    from camtool.timing import lead_needed_mm
    from camtool.timing import pathlaw

    settings = TimingSettings.make(method="quintic", tcp_speed_mm_s=90.0)
    fresh = time_trajectory(JP, PATH, ROBOT, settings)        # every run planned now, none kept
    assert pathlaw._RUN_MEMO is None
    with pathlaw.remembered_runs():
        need = lead_needed_mm(JP, PATH, ROBOT, settings)      # plans the runs ...
        planned = len(pathlaw._RUN_MEMO)
        assert planned == len(need["per_run"]) > 0
        with pathlaw.remembered_runs():                       # an inner scope shares the outer's laws
            again = time_trajectory(JP, PATH, ROBOT, settings)    # ... and timing takes their laws
        assert len(pathlaw._RUN_MEMO) == planned
        _, smp, _ = next(iter(pathlaw._RUN_MEMO.values()))
    assert pathlaw._RUN_MEMO is None                          # let go with the scope
    for f in ("t_s", "q", "qd", "qdd", "zone", "path_index"):
        assert np.array_equal(getattr(fresh, f), getattr(again, f))
    with pytest.raises(ValueError):                           # kept laws cannot be changed by a caller
        smp.q[0, 0] = 1.0
