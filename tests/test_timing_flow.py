"""timing.zones = "flow": free chains pass their intermediate poses without stopping."""
import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.settings import TimingSettings
from camtool.timing import check_trajectory, time_trajectory
from test_timing_fixtures import seed8, transition_path

ROBOT = seed8()
N, K = 60, 6
JP, PATH = transition_path(ROBOT, N, K)
STOP = time_trajectory(JP, PATH, ROBOT, TimingSettings.make(zones="stop"))
FLOW = time_trajectory(JP, PATH, ROBOT, TimingSettings.make(zones="flow"))


@pytest.mark.parametrize("method", ["quintic", "ruckig"])
def test_flow_passes_the_checker(method):
    tr = FLOW if method == "quintic" else time_trajectory(JP, PATH, ROBOT,
                                                          TimingSettings.make(method=method, zones="flow"))
    assert check_trajectory(tr, ROBOT, dt_s=0.002) == []


def test_no_stop_at_intermediate_zone_poses_but_rest_at_run_ends():
    for row in range(N, N + K):
        k = np.flatnonzero(FLOW.path_index == JP.path_index[row])
        assert len(k) == 1 and np.array_equal(FLOW.q[k[0]], JP.q[row])
        assert np.abs(FLOW.qd[k[0]]).max() > 0
        s = np.flatnonzero(STOP.path_index == JP.path_index[row])[0]
        assert np.all(STOP.qd[s] == 0)
    for row in (0, N - 1, N + K, len(JP.q) - 1):
        k = np.flatnonzero(FLOW.path_index == JP.path_index[row])[0]
        assert np.all(FLOW.qd[k] == 0) and np.all(FLOW.qdd[k] == 0)


def test_flow_is_faster_than_stop():
    assert FLOW.duration_s < STOP.duration_s - 0.3


def test_flow_keeps_jumps_rest_to_rest():
    q = JP.q.copy()
    q[N + 2:, 3] += np.radians(25)  # a reconfiguration jump between self-motion poses 2 and 3
    from dataclasses import replace
    tr = time_trajectory(replace(JP, q=q), PATH, ROBOT, TimingSettings.make(zones="flow"))
    assert check_trajectory(tr, ROBOT, 0.004) == []
    for row in (N + 1, N + 2):
        k = np.flatnonzero(tr.path_index == JP.path_index[row])[0]
        assert np.all(tr.qd[k] == 0)


def test_flow_is_the_default_and_bad_value_rejected():
    d = time_trajectory(JP, PATH, ROBOT, TimingSettings.make())
    for f in ("t_s", "q", "qd", "qdd", "zone", "path_index"):
        assert np.array_equal(getattr(d, f), getattr(FLOW, f))
    with pytest.raises(BadInput):
        TimingSettings.make(zones="glide")


def test_inserted_corners_rest_and_keep_their_straight_edges():
    """An inserted free pose (path_index -1) where the joint direction turns is a rest pose; between
    two such corners the move stays on its straight joint-space edge (as it was collision-checked)."""
    from dataclasses import replace
    pidx = JP.path_index.copy()
    pidx[N + 1:N + 4] = -1  # self-motion poses 1..3 inserted (as a lift connector's)
    q = JP.q.copy()
    q[N + 2, 3] += np.radians(5)  # a 5 deg kink at pose 2 of the zone
    jp = replace(JP, path_index=pidx, q=q)
    tr = time_trajectory(jp, PATH, ROBOT, TimingSettings.make(zones="flow"))
    assert check_trajectory(tr, ROBOT, 0.004) == []
    rows = [np.flatnonzero(np.all(tr.q == q[r], axis=1))[0] for r in (N + 1, N + 2, N + 3)]
    assert all(np.all(tr.qd[k] == 0) for k in rows)
    a, b = rows[0], rows[1]
    d = (q[N + 2] - q[N + 1]) / np.linalg.norm(q[N + 2] - q[N + 1])
    off = tr.q[a:b + 1] - q[N + 1]
    assert np.abs(off - np.outer(off @ d, d)).max() < 1e-9


def test_flow_deterministic():
    b = time_trajectory(JP, PATH, ROBOT, TimingSettings.make(zones="flow"))
    for f in ("t_s", "q", "qd", "qdd", "zone", "path_index"):
        assert np.array_equal(getattr(FLOW, f), getattr(b, f))


def test_a_soft_group_with_uneven_curvature_runs_each_piece_as_fast_as_it_allows():
    """A chain whose middle is straight and whose ends turn: each piece at its own speed level is shorter
    than one plateau at the slowest piece's speed, and keeps every limit (the exact Hermite check)."""
    from camtool.timing.flow import _group
    from camtool.timing.pathlaw import PathSpline, speed_bounds, time_section
    t = np.linspace(0.0, 1.0, 13)
    qs = np.zeros((13, 8))
    qs[:, 0] = 400.0 * t                                  # the track runs straight through
    qs[:, 4] = 0.3 * np.where(t < 0.15, np.sin(t / 0.15 * np.pi), 0.0)  # a wrist bump near the start only
    qs[:, 5] = 0.2 * t
    u = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(qs, axis=0) / ROBOT.limits.velocity, axis=1))])
    spline = PathSpline(u, qs)
    bound, _, _ = speed_bounds(*spline.piece_bounds(), ROBOT.limits)
    assert bound.max() > 2 * bound.min()
    _, one_plateau, _ = time_section(spline, np.full(len(bound), bound.min()), ROBOT.limits, fill_s=0.01)
    t_s, q, qd, qdd, knot = _group(qs, ROBOT.limits, 0.01)
    assert t_s[-1] < 0.9 * one_plateau.t_s[-1]
    assert np.array_equal(q[knot >= 0], qs)
    assert np.all(qd[[0, -1]] == 0) and np.all(qdd[[0, -1]] == 0)
