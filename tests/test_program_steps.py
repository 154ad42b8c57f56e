"""The program steps (camtool.program.steps): one contract run over every step, and what
each step does."""
import numpy as np
import pytest

from camtool.program.kinematics import Kinematics
from camtool.program.plan import plan_moves, profile_tool
from camtool.program.process import ProcessInfo
from camtool.program.profiles import load_profile
from camtool.program.steps import (CompoundStep, ExactStops, FitArcs, JoinNullLinear, MoveStep, context_for,
                                   move_lengths_ok, program_steps)
from camtool.robots import get_robot
from test_post import rows_trajectory

LEVELS = (0.3, 1.0, 5.0, 10.0)
STEPS = [ExactStops(), ExactStops(min_level_on_surface=1, max_level=2), JoinNullLinear(),
         FitArcs(max_sweep_deg=120.0), FitArcs(max_sweep_deg=10.0),
         program_steps(arcs_max_sweep_deg=120.0), CompoundStep(())]


@pytest.fixture(scope="module")
def planned():
    r = get_robot("irb2400")
    p = load_profile(None, "irb2400", "rapid", r)
    r = r.with_placement(tool_T_mm=profile_tool(p))
    tr = rows_trajectory(r, rows=2)
    process = ProcessInfo()
    plan = plan_moves(tr, r, process, linear=True, levels_mm=LEVELS, min_level_on_surface=0)
    return plan, context_for(tr, r, process, plan, LEVELS, 0), r


@pytest.mark.parametrize("step", STEPS, ids=lambda s: type(s).__name__)
def test_every_step_keeps_the_contract(planned, step):
    plan, ctx, _r = planned
    assert isinstance(step, MoveStep)
    out = step.apply(plan, ctx)
    n = len(out)
    assert 2 <= n <= len(plan)
    for name in ("wp", "kind", "t", "level", "row", "row_start", "row_end", "free", "P", "R", "q"):
        assert len(getattr(out, name)) == n, name
    assert np.allclose(out.P[[0, -1]], plan.P[[0, -1]]) and out.level[0] == -1 and out.level[-1] == -1
    assert np.all(np.diff(out.t) >= 0)
    assert out.row_start.sum() == plan.row_start.sum() and out.row_end.sum() == plan.row_end.sum()
    # every row's first and last target stays, with its marks
    for mark in ("row_start", "row_end"):
        assert np.allclose(out.P[getattr(out, mark)], plan.P[getattr(plan, mark)])
    assert set(np.unique(out.kind)) <= {"J", "L", "C"}
    circ = out.kind == "C"
    if circ.any():
        assert np.isfinite(out.via_P[circ]).all() and np.isfinite(out.via_q[circ]).all()
        assert move_lengths_ok(out)
    assert np.all(out.level >= -1) and np.all(out.level < len(LEVELS))


def test_fit_arcs_merges_rows_on_circles(planned):
    plan, ctx, _r = planned
    out = FitArcs(max_sweep_deg=120.0).apply(plan, ctx)
    assert (out.kind == "C").sum() >= 1 and len(out) < len(plan)
    assert len(FitArcs(max_sweep_deg=120.0).apply(out, ctx)) == len(out)  # nothing left to merge


def test_fit_arcs_keeps_each_arc_within_its_sweep(planned):
    from camtool.program.arcs import circle_through

    plan, ctx, _r = planned
    for limit in (120.0, 10.0):
        out = FitArcs(max_sweep_deg=limit).apply(plan, ctx)
        k = np.flatnonzero(out.kind == "C")
        if len(k):
            *_x, sweep, ok = circle_through(out.P[k - 1], out.via_P[k], out.P[k])
            assert ok.all() and np.degrees(sweep).max() <= limit + 1e-9


def test_join_null_linear_makes_a_linear_move_that_goes_nowhere_a_joint_move(planned):
    from dataclasses import replace

    plan, ctx, _r = planned
    i = int(np.flatnonzero(plan.kind == "L")[0])
    P = plan.P.copy()
    P[i] = P[i - 1]
    out = JoinNullLinear().apply(replace(plan, P=P), ctx)
    assert out.kind[i] == "J" and (out.kind == "L").sum() == (plan.kind == "L").sum() - 1


def test_no_circular_move_through_a_point_next_to_its_chord():
    """A circle point within MIN_ARC_BOW_MM of its chord could read back as three points on one
    line once written to 0.001 mm: such targets stay linear moves."""
    from camtool.program.steps import MIN_ARC_BOW_MM, _on_circle

    P0, P1 = np.array([0.0, 0.0, 0.0]), np.array([100.0, 0.0, 0.0])
    X = np.array([[25.0, 0.0, 0.0], [50.0, 0.5 * MIN_ARC_BOW_MM, 0.0], [75.0, 0.0, 0.0]])
    assert not _on_circle(P0, X[1], P1, X, 1.0)[0]
    X[1, 1] = 2.0   # a real bow: a circle
    r = 0.5 * (50.0 ** 2 + 2.0 ** 2) / 2.0
    X[[0, 2], 1] = np.sqrt(r ** 2 - 25.0 ** 2) - (r - 2.0)
    assert _on_circle(P0, X[1], P1, X, 1e-6)[0]


def test_exact_stops_only_where_one_is_meant(planned):
    from dataclasses import replace

    plan, ctx, _r = planned
    loose = replace(plan, level=np.full(len(plan), -1))          # a stop at every target
    out = ExactStops(min_level_on_surface=1).apply(loose, ctx)
    stops = np.flatnonzero(out.level == -1)
    touches = np.flatnonzero(plan.row_start & plan.row_end)
    assert set(stops) == {0, len(plan) - 1, *touches}            # no retract in this plan
    assert np.all(out.level[(plan.row >= 0) & (out.level >= 0)] >= 1)
    capped = ExactStops(max_level=0).apply(replace(plan, level=np.full(len(plan), 3)), ctx)
    assert np.all(capped.level[1:-1] <= 0)


def _ctx(P, mid=None, t=None):
    from camtool.program.steps import StepContext

    P = np.asarray(P, float)
    return StepContext(waypoint_P=P, waypoint_R=np.repeat(np.eye(3)[None], len(P), 0), path_tol_mm=0.1,
                       ori_tol_deg=1.0, waypoint_mid_P=np.zeros((0, 3)) if mid is None else np.asarray(mid, float),
                       waypoint_t=np.zeros(0) if t is None else np.asarray(t, float))


def test_an_arc_through_a_kink_leaves_the_chords_by_its_sagitta():
    """Issue #46's hood: three waypoints 5 mm apart that kink by 1.3 mm lie exactly on a circle (R 9.5 mm),
    whose arcs leave the chords between them by R (1 - cos(half the angle between them)): the arc is
    refused at 0.04 mm, taken at the larger sagitta (closed form), and taken at 0.04 mm where the planned
    motion itself bows along the circle between the waypoints."""
    from camtool.program.arcs import arc_point, circle_through
    from camtool.program.steps import _arc_follows_plan

    P = np.array([[0.0, 0.0, 0.0], [4.72, -1.43, 0.0], [9.55, -0.34, 0.0]])
    c, rad, n, r0, sweep, _ok = circle_through(P[:1], P[1:2], P[2:])
    angle = np.array([np.arccos(np.dot(P[i] - c[0], P[i + 1] - c[0]) / rad[0] ** 2) for i in range(2)])
    sag = rad[0] * (1 - np.cos(angle / 2))
    assert 0.2 < sag.max() < 0.4
    w = np.arange(3)
    assert not _arc_follows_plan(P[0], P[1], P[2], w, _ctx(P), 0.04)
    assert not _arc_follows_plan(P[0], P[1], P[2], w, _ctx(P), 0.98 * sag.max())
    assert _arc_follows_plan(P[0], P[1], P[2], w, _ctx(P), 1.02 * sag.max())
    s_mid = np.array([angle[0] / 2, angle[0] + angle[1] / 2]) / sweep[0]
    on_arc = arc_point(np.repeat(c, 2, 0), np.repeat(n, 2, 0), np.repeat(r0, 2, 0), np.repeat(sweep, 2), s_mid)
    assert _arc_follows_plan(P[0], P[1], P[2], w, _ctx(P, mid=on_arc), 0.04)


def test_an_arc_on_a_fine_circle_is_kept():
    """Waypoints 5 mm apart on a circle of R 200 mm: sagitta 25 / (8 R) = 0.016 mm, within 0.04 mm."""
    from camtool.program.steps import _arc_follows_plan

    R = 200.0
    th = np.arange(9) * 5.0 / R
    P = np.stack([R * np.sin(th), R * (1 - np.cos(th)), np.zeros_like(th)], axis=1)
    assert _arc_follows_plan(P[0], P[4], P[8], np.arange(9), _ctx(P), 0.04)
    assert not _arc_follows_plan(P[0], P[4], P[8], np.arange(9), _ctx(P), 0.5 * 25 / (8 * R))


def test_an_arc_ending_between_waypoints_is_checked_by_their_times():
    """A target added on the planned motion (wp -1) beside a corner: the waypoints between the arc's ends'
    times are checked, so a circle bowing off a straight stretch is refused (the SIA20D plate at 40 mm)."""
    from camtool.program.steps import _waypoints_between

    t = np.arange(10) * 0.05
    P = np.stack([np.arange(10) * 5.0, np.zeros(10), np.zeros(10)], axis=1)
    ctx = _ctx(P, t=t)
    plan = type("P", (), {})()
    plan.wp, plan.t = np.array([2, -1]), np.array([0.1, 0.33])
    assert np.array_equal(_waypoints_between(plan, 0, 1, ctx), [2, 3, 4, 5, 6])
    plan.wp = np.array([2, 6])
    assert np.array_equal(_waypoints_between(plan, 0, 1, ctx), [2, 3, 4, 5, 6])
    plan.wp = np.array([2, -1])
    assert len(_waypoints_between(plan, 0, 1, _ctx(P))) == 0   # no times: nothing to check by


def test_arcs_in_a_span_written_closer_keep_to_its_share(planned):
    """``StepContext.closer_s`` (``ProcessInfo.closer_s``): inside a span the post stage writes closer to the
    plan an arc must hold the waypoints within its share of ARC_SHARE x the tolerance (each waypoint's distance
    from the written circle, by the circle's own centre and radius); outside it, arcs are as before."""
    from dataclasses import replace

    from camtool.program.arcs import circle_through
    from camtool.program.steps import ARC_SHARE

    plan, ctx, _r = planned
    free = FitArcs(max_sweep_deg=120.0).apply(plan, ctx)
    rows = [plan.t[plan.row == k] - plan.t[0] for k in range(plan.rows)]
    span = (rows[0][0], rows[0][-1], 0.02)   # the first row within 2 % of the tolerance

    def arcs(out):
        """(start time, worst waypoint distance from its circle, mm) of each circular move."""
        got = []
        for k in np.flatnonzero(out.kind == "C"):
            c, rad, n, _r0, _sw, _ok = circle_through(out.P[k - 1][None], out.via_P[k][None], out.P[k][None])
            X = ctx.waypoint_P[out.wp[k - 1]:out.wp[k] + 1] - c[0]
            h = X @ n[0]
            dist = np.hypot(h, np.linalg.norm(X - h[:, None] * n[0], axis=1) - rad[0])
            got.append((out.t[k - 1] - plan.t[0], dist.max()))
        return got

    close = FitArcs(max_sweep_deg=120.0).apply(plan, replace(ctx, closer_s=(span,)))
    in_row0 = lambda a: span[0] - 1e-9 <= a[0] <= span[1]   # noqa: E731
    assert any(in_row0(a) and a[1] > ARC_SHARE * 0.1 * 0.02 for a in arcs(free))   # the span made a difference
    assert all(a[1] <= ARC_SHARE * 0.1 * 0.02 + 1e-9 for a in arcs(close) if in_row0(a))
    assert [a for a in arcs(close) if not in_row0(a)] == [a for a in arcs(free) if not in_row0(a)]


def test_fit_arcs_kept_tests_give_the_fresh_plan(planned):
    """The arc fit keeps its tests from one writing to the next (``steps.FITTED``): a second writing, the same or
    with a span written closer (the post stage's next round), is the plan fitted from nothing, to the bit."""
    from dataclasses import fields, replace

    from camtool.program.steps import FITTED, forget_fitted

    plan, ctx, _r = planned
    rows = [plan.t[plan.row == k] for k in range(plan.rows)]
    closer = replace(ctx, closer_s=((rows[0][0], rows[0][-1], 0.02),))

    def fresh(c):
        forget_fitted()
        return FitArcs(max_sweep_deg=120.0).apply(plan, c)

    for first, again in ((ctx, ctx), (ctx, closer), (closer, ctx)):
        expected = fresh(again)
        FitArcs(max_sweep_deg=120.0).apply(plan, first)
        assert len(FITTED) > 0
        got = FitArcs(max_sweep_deg=120.0).apply(plan, again)
        for f in fields(got):
            a, b = getattr(got, f.name), getattr(expected, f.name)
            assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f") if isinstance(a, np.ndarray) else a == b, f.name
    assert (fresh(closer).kind == "C").sum() != (fresh(ctx).kind == "C").sum() or \
        not np.array_equal(fresh(closer).P, fresh(ctx).P)   # the span changes the fit: the keys tell them apart
    forget_fitted()
