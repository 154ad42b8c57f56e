"""Constant feed on work: ramps in the leads, slowed rows / stretches, short leads, feed report, time law."""
from dataclasses import replace

import numpy as np
import pytest
from ruckig import InputParameter, Ruckig
from ruckig import Trajectory as RuckigTrajectory

from camtool.settings import TimingSettings
from camtool.timing import (check_trajectory, feed_profile, lead_bound_mm, lead_needed_mm, plot_feed_png,
                            tcp_positions_world, time_trajectory, timing_report)
from camtool.timing.pathlaw import PathSpline, plan_section, sample_section, scurve, speed_bounds
from camtool.timing.quintic import MARGIN
from camtool.path.toolpath import ZONE_CODE
from camtool.transforms import matrix_from_xyz_rpy
from test_timing_fixtures import joint_path_and_path, seed8, two_runs

ROBOT = seed8()
N = 120


def with_leads(lead=5, bump_deg=0.0):
    """two_runs (3 mm pitch) with ``lead`` poses of lead-in and lead-out per run; optionally a bump of
    ``bump_deg`` in j5 in the middle of the first row (a kink no interpolation can run at the feed)."""
    jp, _ = two_runs(ROBOT, n=N)
    zone, q = np.array(jp.zone), jp.q.copy()
    for a in (0, N + 2):
        zone[a:a + lead], zone[a + N - lead:a + N] = ZONE_CODE["lead_in"], ZONE_CODE["lead_out"]
    if bump_deg:
        k = np.arange(N)
        q[:N, 4] += np.radians(bump_deg) * np.exp(-0.5 * ((k - 60) / 1.5) ** 2)
    return joint_path_and_path(ROBOT, q, zone, np.array([0] * (N + 1) + [1] * (N + 1)))


LEADS = with_leads()
BUMP = with_leads(bump_deg=1.0)


def _report(tr):
    assert check_trajectory(tr, ROBOT, 0.004) == []
    return timing_report(tr, ROBOT, tr.sampled)


def test_work_at_the_feed_when_the_leads_hold_the_ramps():
    tr = time_trajectory(*LEADS, ROBOT, TimingSettings.make(tcp_speed_mm_s=100.0))
    rep = _report(tr)
    f = rep["work_feed"]
    assert f["work_share_within_1pct"] == 1.0 and abs(f["min_work_feed_mm_s"] - 100.0) < 0.1
    assert rep["slowdowns"] == [] and rep["short_leads"] == []
    assert rep["feed_policy"] == "constant" and rep["slow_scope"] == "row"
    # the TCP is at the feed at the first work pose: the ramp lies in the lead-in
    prof = feed_profile(tr, tr.sampled)
    first_work = np.flatnonzero(prof.work)[0]
    assert abs(prof.feed_mm_s[first_work] - 100.0) < 0.5
    # and the leads need no more than they have (15 mm)
    need = lead_needed_mm(*LEADS, ROBOT, TimingSettings.make())
    assert 5.0 < need["lead_in_mm"] < 15.0 and 5.0 < need["lead_out_mm"] < 15.0
    assert len(need["per_run"]) == 2


def test_short_leads_are_reported_with_the_length_needed():
    jp, path = with_leads(lead=1)  # 3 mm leads
    tr = time_trajectory(jp, path, ROBOT, TimingSettings.make())
    rep = _report(tr)
    short = rep["short_leads"]
    assert {(s["run"], s["side"]) for s in short} == {(0, "lead_in"), (0, "lead_out"), (1, "lead_in"),
                                                     (1, "lead_out")}
    need = lead_needed_mm(jp, path, ROBOT, TimingSettings.make())
    for s in short:
        assert s["lead_mm"] < 3.5 < s["needed_mm"] <= need[f"{s['side']}_mm"] + 1e-3
    assert rep["work_feed"]["work_share_within_1pct"] < 0.99  # the ramps run into the work
    # the conservative bound from the joint rates alone is of the same size
    rates = np.abs(np.diff(jp.q[:10], axis=0)).max(axis=0) / 3.0
    bound = lead_bound_mm(ROBOT.limits, 100.0, 1.2 * rates)
    assert 0.5 * need["lead_in_mm"] < bound < 3 * need["lead_in_mm"]


def test_row_scope_slows_the_whole_row_and_names_the_joint():
    tr = time_trajectory(*BUMP, ROBOT, TimingSettings.make())
    rep = _report(tr)
    (s,) = rep["slowdowns"]
    assert s["run"] == 0 and s["first_row"] == 5 and s["last_row"] == N - 6  # the first and last work pose
    assert s["joint"] == "j5" and s["limit"] == "jerk" and 0.3 < s["speed_ratio"] < 0.9
    assert s["feed_mm_s"] == pytest.approx(100.0 * s["speed_ratio"])
    prof = feed_profile(tr, tr.sampled)
    t0, t1 = s["t_start_s"], s["t_end_s"]
    mid = prof.work & (prof.t_s[:-1] > t0 + 0.25 * (t1 - t0)) & (prof.t_s[1:] < t0 + 0.4 * (t1 - t0))
    assert mid.sum() > 20 and np.allclose(prof.feed_mm_s[mid], s["feed_mm_s"], rtol=0.01)
    # the second row runs at the feed
    second = prof.work & (prof.t_s[:-1] > t1 + 1.0)
    assert np.median(prof.feed_mm_s[second]) == pytest.approx(100.0, rel=1e-3)


def test_stretch_scope_slows_only_the_stretch():
    row = time_trajectory(*BUMP, ROBOT, TimingSettings.make())
    tr = time_trajectory(*BUMP, ROBOT, TimingSettings.make(slow_scope="stretch"))
    rep = _report(tr)
    (s,) = rep["slowdowns"]
    assert 40 < s["first_row"] < 60 < s["last_row"] < 80 and s["joint"] == "j5"
    assert s["feed_mm_s"] == pytest.approx(row.slowdowns[0]["feed_mm_s"])  # the same highest constant feed
    assert rep["work_feed"]["work_share_within_1pct"] > 0.85
    assert tr.duration_s < row.duration_s - 2.0
    mx = time_trajectory(*BUMP, ROBOT, TimingSettings.make(feed="max"))
    assert check_trajectory(mx, ROBOT, 0.004) == [] and mx.duration_s <= tr.duration_s + 0.05


def test_fast_feed_every_row_at_its_own_constant_feed():
    jp, path = two_runs(ROBOT)
    tr = time_trajectory(jp, path, ROBOT, TimingSettings.make(tcp_speed_mm_s=1500.0))
    rep = _report(tr)
    assert [(s["first_row"], s["last_row"]) for s in rep["slowdowns"]] == [(0, 119), (122, 241)]
    for s in rep["slowdowns"]:
        assert s["joint"] in ROBOT.joint_names and s["limit"] in ("speed", "acceleration", "jerk", "ramps")
    assert max(rep[f"peak_joint_{k}_ratio"] for k in ("speed", "acc", "jerk")) > 0.95


def test_feed_report_and_png(tmp_path):
    tr = time_trajectory(*LEADS, ROBOT, TimingSettings.make())
    rep = _report(tr)
    f = rep["work_feed"]
    assert set(f) == {"commanded_feed_mm_s", "work_length_mm", "work_share_within_1pct", "work_share_within_2pct",
                      "min_work_feed_mm_s", "median_work_feed_mm_s", "max_work_feed_mm_s"}
    assert f["work_length_mm"] == pytest.approx(2 * (N - 11) * 3.0, rel=0.01)
    png = plot_feed_png(tr, tr.sampled, tmp_path / "plots" / "feed.png", title="leads")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10000


def test_vectorised_fk_matches_pinocchio():
    robot = ROBOT.with_placement(matrix_from_xyz_rpy([100, -50, 30], [5, 10, 20]),
                                 matrix_from_xyz_rpy([0, 0, 150], [0, 20, 0]))
    L = robot.limits
    q = L.lower + (L.upper - L.lower) * np.random.default_rng(3).random((50, robot.dof))
    ref = np.array([(robot.base_T_mm @ robot.fk_tcp(x))[:3, 3] for x in q])
    assert np.abs(tcp_positions_world(robot, q) - ref).max() < 1e-9
    no_dh = replace(robot, dh=())  # the Pinocchio loop
    assert np.abs(tcp_positions_world(no_dh, q[:5]) - ref[:5]).max() < 1e-9


def test_rest_to_rest_line_is_near_ruckig_time_optimal():
    """One joint, a straight line: the time law's S-curves against ruckig's time-optimal profile (98 %)."""
    L = ROBOT.limits
    q0 = np.zeros(8)
    q1 = q0.copy()
    q1[4] = 1.0
    spline = PathSpline(np.array([0.0, 1.0]), np.vstack([q0, q1]))
    bound, joint, kind = speed_bounds(*spline.piece_bounds(), L)
    assert joint[0] == 4 and kind[0] == 0 and bound[0] == pytest.approx(MARGIN * L.velocity[4])
    plan = plan_section(spline, bound, L)
    otg, inp, out = Ruckig(1), InputParameter(1), RuckigTrajectory(1)
    inp.max_velocity, inp.max_acceleration = [MARGIN * L.velocity[4]], [MARGIN * L.acceleration[4]]
    inp.max_jerk = [MARGIN * L.jerk[4]]
    inp.current_position, inp.target_position = [0.0], [1.0]
    otg.calculate(inp, out)
    assert out.duration <= plan.duration <= 1.03 * out.duration
    smp = sample_section(spline, plan)
    assert smp.q[-1, 4] == 1.0 and np.all(smp.qd[[0, -1]] == 0)
    phases, T, D = scurve(0.0, 2.0, 10.0, 20.0)  # dv J < A^2: jerk phases only
    assert T == pytest.approx(2 * np.sqrt(2.0 / 20.0)) and D == pytest.approx(T)  # mean speed 1


def test_lead_lengths_skip_a_run_the_time_law_cannot_take():
    """A run whose spline leaves the joint range has no lead figure (``time_trajectory`` names that run);
    ``lead_needed_mm`` answers for the others instead of failing."""
    from camtool.timing.runs import run_leads
    jp, path = LEADS
    q = jp.q.copy()
    q[50:53, 3] = ROBOT.limits.upper[3]                    # three poses on j4's limit with a sharp bend:
    q[51, 3] = ROBOT.limits.upper[3] - 1e-9                 # the cubic through them overshoots the limit
    q[49, 3] = q[53, 3] = ROBOT.limits.upper[3] - 0.3
    zone = np.array(jp.zone)
    step = np.full(N - 1, 3.0)
    assert run_leads(q[:N], step, zone[:N], ROBOT.limits, 100.0) == {}
    need = lead_needed_mm(replace(jp, q=q), path, ROBOT, TimingSettings.make())
    assert [r["run"] for r in need["per_run"]] == [1]


def test_feed_plot_envelope_keeps_every_low_and_high():
    from camtool.timing.feed import display_envelope

    x = np.arange(100_000) / 1000.0
    v = np.full(100_000, 100.0)
    v[12_345], v[70_000] = 37.0, 140.0
    v[50_000:50_010] = np.nan
    xe, ve = display_envelope(x, v, bins=1000)
    assert len(xe) == len(ve) == 2000
    assert np.nanmin(ve) == 37.0 and np.nanmax(ve) == 140.0
    assert xe[0] >= x[0] and xe[-1] <= x[-1] and np.all(np.diff(xe) >= 0)
    xs, vs = display_envelope(x[:500], v[:500], bins=1000)  # short profiles as they are
    assert np.array_equal(vs, v[:500])
