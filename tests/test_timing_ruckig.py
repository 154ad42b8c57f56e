"""method="ruckig": surface pieces are exact ruckig moves; share, limits, schedule, fallbacks, determinism."""
import numpy as np
import pytest
from ruckig import InputParameter, Ruckig
from ruckig import Trajectory as RuckigTrajectory

from camtool.program.post import thin_waypoints
from camtool.settings import TimingSettings
from camtool.timing import check_trajectory, time_trajectory, timing_report
from camtool.timing import ruckig_through
from camtool.timing.assemble import run_layout, tcp_positions_mm
from camtool.timing.quintic import MARGIN, piece_peaks
from camtool.timing.runs import time_runs
from camtool.timing.ruckig_through import CHECK_SHARE, JERK_FACTORS, REASONS, TIME_GRID_S, through_pieces
from camtool.path.toolpath import ZONE_CODE
from camtool.trajectory import Trajectory
from test_timing_fixtures import seed8, two_runs

ROBOT = seed8()
L = ROBOT.limits
JP, PATH = two_runs(ROBOT)  # 2 x 120 poses, 3 mm pitch: 30 ms pieces at 100 mm/s
RUCKIG = TimingSettings.make(method="ruckig", tcp_speed_mm_s=100.0)
TR = time_trajectory(JP, PATH, ROBOT, RUCKIG)
QT = time_trajectory(JP, PATH, ROBOT, TimingSettings.make(method="quintic", tcp_speed_mm_s=100.0))


def _report(tr):
    return timing_report(tr, ROBOT, tr.sampled)


def _row_index(tr, row):
    return int(np.flatnonzero(tr.path_index == JP.path_index[row])[0])


def _segment(tr, a, b):
    return Trajectory(tr.robot_name, tr.joint_names, tr.prismatic, tr.t_s[a:b + 1] - tr.t_s[a], tr.q[a:b + 1],
                      tr.qd[a:b + 1], tr.qdd[a:b + 1], tr.zone[a:b + 1], tr.path_index[a:b + 1])


def _ruckig_1dof(i, x0, x1, duration_s, factor):
    otg, inp, out = Ruckig(1), InputParameter(1), RuckigTrajectory(1)
    inp.max_velocity = [MARGIN * L.velocity[i]]
    inp.max_acceleration = [MARGIN * L.acceleration[i]]
    inp.max_jerk = [MARGIN * L.jerk[i] * factor]
    inp.current_position, inp.current_velocity, inp.current_acceleration = [x0[0]], [x0[1]], [x0[2]]
    inp.target_position, inp.target_velocity, inp.target_acceleration = [x1[0]], [x1[1]], [x1[2]]
    inp.minimum_duration = duration_s
    otg.calculate(inp, out)
    return out


def test_share_of_ruckig_pieces_and_report():
    rep = _report(TR)
    assert rep["surface_pieces"] == 2 * 119 == len(TR.piece_ruckig)
    # the pieces of the ramps at the run ends (no leads here) are the ones ruckig cannot always give
    assert rep["ruckig_piece_share"] >= 0.9 and rep["ruckig_work_piece_share"] >= 0.9
    fb = rep["ruckig_fallbacks"]
    assert fb["count"] == int((~TR.piece_ruckig).sum()) == sum(fb["by_reason"].values())
    assert set(fb["by_reason"]) <= set(REASONS)
    assert len(fb["first"]) == min(fb["count"], 20)
    q = _report(QT)
    assert q["ruckig_piece_share"] == 0.0 and q["ruckig_fallbacks"]["count"] == 0
    assert q["surface_pieces"] == rep["surface_pieces"]


def test_pieces_are_ruckig_moves():
    """Re-solve pieces with ruckig itself: its at_time and jerk match the Trajectory's Hermite pieces."""
    rows = TR.piece_row[TR.piece_ruckig][::23]
    assert len(rows) >= 8
    for row in rows:
        a, b = _row_index(TR, row), _row_index(TR, row + 1)
        assert b - a > 8  # written out at the jerk switches
        T = TR.t_s[b] - TR.t_s[a]
        seg = _segment(TR, a, b)
        t, q, v, acc, jerk = seg.sample(T / 37)
        inner = (t > 0) & (t < T) & (np.abs(t[:, None] - seg.t_s[None, :]).min(axis=1) > 1e-6)
        for i in range(ROBOT.dof):
            x0 = (TR.q[a, i], TR.qd[a, i], TR.qdd[a, i])
            x1 = (TR.q[b, i], TR.qd[b, i], TR.qdd[b, i])
            best = np.inf
            for f in JERK_FACTORS:
                rt = _ruckig_1dof(i, x0, x1, T, f)
                if abs(rt.duration - T) > 1e-8:
                    continue
                ref = np.array([rt.at_time(min(float(x), rt.duration))[:3] for x in t])[..., 0]
                prof = rt.profiles[0][0]
                k = np.clip(np.searchsorted(np.cumsum(prof.t), t, side="right"), 0, 6)
                jref = np.asarray(prof.j)[k]
                err = max(np.abs(ref[:, 0] - q[:, i]).max() / 1e-7, np.abs(ref[:, 1] - v[:, i]).max() / 1e-5,
                          np.abs(ref[:, 2] - acc[:, i]).max() / (1e-3 * L.acceleration[i]),
                          np.abs(jref - jerk[:, i])[inner].max() / (5e-3 * L.jerk[i]))
                best = min(best, err)
            assert best <= 1.0, (row, i, best)


def test_limits_exactly_within_share():
    assert check_trajectory(TR, ROBOT, dt_s=0.001) == []
    h = np.diff(TR.t_s)
    pk = piece_peaks(TR.q[:-1], TR.q[1:], TR.qd[:-1], TR.qd[1:], TR.qdd[:-1], TR.qdd[1:], h, L.lower, L.upper)
    assert not pk.position_break.any()
    assert (pk.jerk / L.jerk).max() <= CHECK_SHARE and (pk.acc / L.acceleration).max() <= CHECK_SHARE
    rep = _report(TR)
    assert 0.97 < rep["peak_joint_jerk_ratio"] <= CHECK_SHARE  # ruckig runs at its (98 %) jerk limit


def test_tcp_schedule_is_kept():
    """Every path pose is reached at the quintic (TCP schedule) time: no slow-down from ruckig here."""
    for row in range(len(JP.q)):
        assert TR.t_s[_row_index(TR, row)] == pytest.approx(QT.t_s[_row_index(QT, row)], abs=1e-6)
    assert len(TR.slowdowns) == len(QT.slowdowns)
    for x, y in zip(TR.slowdowns, QT.slowdowns):  # same stretches; times and ratios up to the 1 ns grid
        assert {k: v for k, v in x.items() if not isinstance(v, float)} == \
            {k: v for k, v in y.items() if not isinstance(v, float)}
        assert x["speed_ratio"] == pytest.approx(y["speed_ratio"], rel=1e-6)
    # poses and ruckig samples on the 2^-30 s grid (a fallback piece's own samples are stretched with it)
    fallback_rows = set(TR.piece_row[~TR.piece_ruckig].tolist())
    k = np.maximum.accumulate(np.where(TR.path_index >= 0, np.arange(len(TR.t_s)), 0))
    in_fallback = np.array([TR.path_index[i] < 0 and int(JP.path_index.tolist().index(TR.path_index[k[i]])) in
                            fallback_rows for i in range(len(TR.t_s))])
    surface = np.isin(TR.zone, [ZONE_CODE[z] for z in ("work", "lead_in", "lead_out")]) & ~in_fallback
    assert np.array_equal(np.round(TR.t_s[surface] / TIME_GRID_S) * TIME_GRID_S, TR.t_s[surface])
    assert _report(TR)["work_time_s"] == pytest.approx(_report(QT)["work_time_s"], abs=1e-6)


def test_longer_pieces_where_limits_force_them():
    layout = run_layout(JP, PATH)
    sidx = np.flatnonzero(layout.surface)
    first, last = layout.start[sidx], layout.end[sidx]
    step = np.linalg.norm(np.diff(tcp_positions_mm(JP, PATH, ROBOT)[sidx], axis=0), axis=1)
    runs = time_runs(JP.q[sidx], step, first, last, np.cumsum(first) - 1, JP.zone[sidx], L, 100.0)
    pieces = np.flatnonzero(~last[:-1])[:60]
    h = 0.3 * runs.h_s  # far too short: ruckig must lengthen the pieces
    res = through_pieces(L, JP.q[sidx], runs.qd, runs.qdd, h, pieces, share=MARGIN)
    assert res.used.mean() >= 0.95
    assert np.all(res.duration_s[res.used] > h[pieces][res.used])
    assert np.array_equal(np.round(res.duration_s / TIME_GRID_S) * TIME_GRID_S, res.duration_s)
    for n in np.flatnonzero(res.used)[::6]:  # each piece on its own, by the independent checker
        k = pieces[n]
        s = res.piece == n
        t = np.r_[0.0, res.t_s[s], res.duration_s[n]]
        st = [np.vstack([x[k], y[s], x[k + 1]]) for x, y in ((JP.q[sidx], res.q), (runs.qd, res.qd),
                                                              (runs.qdd, res.qdd))]
        m = len(t)
        piece = Trajectory("seed8", ROBOT.joint_names, ROBOT.prismatic, t, *st, np.zeros(m, int), np.full(m, -1))
        assert check_trajectory(piece, ROBOT, dt_s=2e-4) == []


def test_fallbacks_keep_quintic_and_are_reported(monkeypatch):
    monkeypatch.setattr(ruckig_through, "MIN_GAP_S", 0.01)  # switches can never be 10 ms apart
    tr = time_trajectory(JP, PATH, ROBOT, RUCKIG)
    assert check_trajectory(tr, ROBOT, 0.004) == []
    rep = _report(tr)
    assert rep["ruckig_piece_share"] < 0.2
    assert rep["ruckig_fallbacks"]["by_reason"].get("switch_times", 0) >= 0.8 * rep["surface_pieces"]
    fall = tr.piece_row[~tr.piece_ruckig]
    for row in fall[:5]:  # a fallback piece keeps the time law's own samples (those of method quintic)
        assert _row_index(tr, row + 1) - _row_index(tr, row) == _row_index(QT, row + 1) - _row_index(QT, row)
    mid = [r for r in fall if 30 <= r < 90][:3]  # at constant feed: none (the Hermite piece is exact)
    assert mid and all(_row_index(tr, r + 1) == _row_index(tr, r) + 1 for r in mid)


def test_deterministic():
    b = time_trajectory(JP, PATH, ROBOT, RUCKIG)
    for f in ("t_s", "q", "qd", "qdd", "zone", "path_index", "piece_row", "piece_ruckig", "piece_reason"):
        assert np.array_equal(getattr(TR, f), getattr(b, f))


def test_inserted_samples_and_thinning():
    """Samples inside pieces are inserted (path_index -1); post thinning keeps every pose at its time."""
    poses = TR.path_index >= 0
    assert poses.sum() == len(JP.q)
    surface_poses = np.isin(JP.zone, [ZONE_CODE["work"]]).sum()
    inserted_work = ((TR.zone == ZONE_CODE["work"]) & ~poses).sum()
    assert inserted_work <= (1 + 4 * ROBOT.dof) * surface_poses  # at most every jerk switch of every joint
    th = thin_waypoints(TR, 0.020)
    assert np.array_equal(th.t_s[th.path_index >= 0], TR.t_s[poses])
    work_th = (th.zone == ZONE_CODE["work"]).sum()
    assert work_th <= 2 * surface_poses


def test_free_moves_keep_the_irb2400_axis_3_within_its_speed():
    """A phase-synchronised free move turning j2 and j3 the same way: each joint alone may run at
    150 deg/s, but the controller's axis 3 (j2 + j3) may not either; the move is timed so that
    |q2' + q3'|, |q2'' + q3''| stay within axis 3's limits. Turning them opposite ways is not slowed."""
    from camtool.robots import get_robot
    from camtool.timing.ruckig_moves import AxisCoupling, RuckigMover, rest_to_rest_chain

    irb = get_robot("irb2400")
    mover = RuckigMover(irb.limits, coupling=AxisCoupling.of(irb))
    q0 = np.radians([0.0, 0.0, 0.0, 0.0, 45.0, 0.0])
    same = rest_to_rest_chain(mover, np.array([q0, q0 + np.radians([0, 40, 40, 0, 0, 0])]))
    t, q, qd, qdd = same[:4]
    axis3 = qd[:, 1] + qd[:, 2]
    assert np.degrees(np.abs(axis3).max()) <= 150.0 + 1e-6
    assert np.abs(qdd[:, 1] + qdd[:, 2]).max() <= irb.limits.acceleration[2] + 1e-6
    plain = rest_to_rest_chain(RuckigMover(irb.limits), np.array([q0, q0 + np.radians([0, 40, 40, 0, 0, 0])]))
    assert same[0][-1] > plain[0][-1] * 1.2      # slower than serial limits alone would allow
    opp = rest_to_rest_chain(mover, np.array([q0, q0 + np.radians([0, 40, -40, 0, 0, 0])]))
    ref = rest_to_rest_chain(RuckigMover(irb.limits), np.array([q0, q0 + np.radians([0, 40, -40, 0, 0, 0])]))
    assert abs(opp[0][-1] - ref[0][-1]) < 1e-9
    assert AxisCoupling.of(get_robot("sia20")) is None
