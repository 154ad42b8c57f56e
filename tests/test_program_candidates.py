"""camtool.program.candidates: each step from a trajectory's waypoints to the merged targets."""
import numpy as np
import pytest

from camtool.program.candidates import (AddPlannedPoints, Candidates, CandidateStep, MarkAnchors, MergeChords,
                                        anchors, candidate_steps, merged_candidates, runs)
from camtool.program.plan import profile_tool
from camtool.program.process import ProcessInfo
from camtool.program.profiles import load_profile
from camtool.robots import get_robot
from camtool.path.toolpath import ZONE_CODE
from test_post import rows_trajectory

WORK = ZONE_CODE["work"]


@pytest.fixture(scope="module")
def start():
    r = get_robot("irb2400")
    r = r.with_placement(tool_T_mm=profile_tool(load_profile(None, "irb2400", "rapid", r)))
    tr = rows_trajectory(r, rows=2)
    return tr, r, Candidates.from_trajectory(tr, r, ProcessInfo(), linear=True)


@pytest.mark.parametrize("step", [AddPlannedPoints(), MarkAnchors(), MergeChords(), candidate_steps()],
                         ids=lambda s: type(s).__name__)
def test_every_step_keeps_the_trajectory_and_its_order(start, step):
    tr, _r, c = start
    assert isinstance(step, CandidateStep)
    out = step.apply(MarkAnchors().apply(c))
    assert np.all(np.diff(out.st["t"]) >= 0) and len(out) >= len(c)
    old = out.origin >= 0   # every trajectory waypoint is still there, in order, with its values
    assert np.array_equal(out.origin[old], np.arange(len(tr.t_s)))
    assert np.allclose(out.st["q"][old], tr.q) and np.allclose(out.st["t"][old], tr.t_s)
    assert out.keep[0] and out.keep[-1]


def test_anchors_are_the_ends_and_every_work_row_end(start):
    _tr, _r, c = start
    out = MarkAnchors().apply(c)
    first, last = runs(c.st["zone"] == WORK)
    assert out.keep[first].all() and out.keep[last].all() and out.keep[[0, -1]].all()
    assert np.array_equal(anchors(c.st["zone"]) & ~out.keep, np.zeros(len(c), bool))


def test_merging_keeps_few_targets_within_the_tolerance(start):
    _tr, _r, c = start
    before = MarkAnchors().apply(AddPlannedPoints().apply(c))
    out = MergeChords().apply(before)
    assert before.keep.sum() < out.keep.sum() < len(out)          # some waypoints merged away, anchors kept
    k = np.flatnonzero(~out.keep)
    idx = np.flatnonzero(out.keep)
    seg = np.searchsorted(idx, k, side="right") - 1
    assert out.ratio_exact(idx[seg], idx[seg + 1], k).max() <= 1.0 + 1e-9   # every skipped waypoint within


def test_planned_points_only_where_a_joint_chord_bows(start):
    _tr, _r, c = start
    out = AddPlannedPoints().apply(c)
    added = out.origin < 0
    assert not out.keep.any()
    # a straight process move is its own chord: points are added only off the straight stretches
    assert not np.any(out.st["in_proc"][added] & np.r_[out.st["in_proc"][1:], False][added])


def test_the_merge_is_shared_by_the_formats_of_one_run(start):
    tr, r, _c = start
    a = merged_candidates(tr, r, ProcessInfo(), linear=True)
    assert merged_candidates(tr, r, ProcessInfo(), linear=True) is a
    assert merged_candidates(tr, r, ProcessInfo(path_tol_mm=0.2), linear=True) is not a


def test_waypoint_arrays_made_in_blocks_are_each_waypoints_own(start, monkeypatch):
    """Poses, Jacobians and dexterity a block of waypoints at a time: the same arrays as all at once."""
    import camtool.program.candidates as candidates

    tr, r, whole = start
    monkeypatch.setattr(candidates, "STATE_BLOCK_ROWS", 5)
    blocks = Candidates.from_trajectory(tr, r, ProcessInfo(), linear=True)
    assert len(whole) > 20 and whole.st.keys() == blocks.st.keys()
    for k in whole.st:
        assert np.array_equal(whole.st[k], blocks.st[k]), k


def _sia20():
    r = get_robot("sia20")
    return r.with_placement(tool_T_mm=profile_tool(load_profile(None, "sia20", "inform", r)))


def test_jacobian6_is_the_pose_derivative():
    """Kinematics.jacobian6 against central differences of Kinematics.pose (position and rotation vector)."""
    from scipy.spatial.transform import Rotation

    from camtool.program.kinematics import Kinematics

    kin = Kinematics(_sia20())
    q = np.array([[0.3, 0.5, -0.4, -1.1, 0.7, 0.9, -0.2]])
    J = kin.jacobian6(q)[0]
    h = 1e-6
    for i in range(7):
        dq = np.zeros((1, 7))
        dq[0, i] = h
        (p1, R1), (p0, R0) = kin.pose(q + dq), kin.pose(q - dq)
        assert np.allclose(J[:3, i], (p1 - p0)[0] / (2 * h), atol=1e-4)
        assert np.allclose(J[3:, i], Rotation.from_matrix(R1[0] @ R0[0].T).as_rotvec() / (2 * h), atol=1e-7)


def _held_case(q_k, delta_rad):
    """A straight move whose middle waypoint has the SIA20D's E axis ``delta_rad`` off the linear
    interpolation of its ends' E (the ends' other joints do not matter to the measure)."""
    from camtool.program.kinematics import Kinematics

    kin = Kinematics(_sia20())
    q = np.repeat(np.asarray(q_k, float)[None], 3, 0)
    q[0, 2] += delta_rad + 0.1   # E at the ends: the middle's plus delta on average
    q[2, 2] += delta_rad - 0.1
    P = kin.pose(q[1:2])[0][0]
    d = np.array([3.0, -4.0, 1.0])
    return kin, q, np.stack([P - d, P, P + d])


def test_held_joint_chords_predict_the_controllers_joint_solution():
    """HeldJointChords' first-order move of the solved joints against an independent Newton solve (the
    program simulator's ``_ik_batch``) of the same pose with E held at its interpolated value."""
    from camtool.program.candidates import HELD_JOINT_GUARD, HeldJointChords
    from camtool.program.targets import _Chain, _ik_batch

    q_k = np.array([0.3, 0.5, -0.4, -1.1, 0.7, 0.9, -0.2])
    held = np.zeros(7, bool)
    held[2] = True
    for delta in (np.radians(0.2), np.radians(1.0)):
        kin, q, P = _held_case(q_k, delta)
        ratio = HeldJointChords(kin, q, P, held)(np.array([0]), np.array([2]), np.array([1]))[0]
        chain = _Chain(_sia20())
        Pk, Rk = chain.fk(q_k[None])
        guess = q_k.copy()
        guess[2] += delta
        solved, ep, _eo = _ik_batch(chain, Pk, Rk, guess[None], ~held)
        assert ep[0] < 1e-4 and abs(solved[0, 2] - q_k[2] - delta) < 1e-12
        moved = np.abs(solved[0] - q_k)[~held].max()
        assert ratio * HELD_JOINT_GUARD == pytest.approx(moved, rel=0.05)


def test_held_joint_chords_refuse_a_straight_move_past_the_wrist_singularity():
    """With the wrist nearly straight (B = 0.05 deg) a tenth of a degree of E turns R and T by far more
    than the guard; at a well-conditioned wrist the same E offset is well within it."""
    from camtool.program.candidates import HeldJointChords

    held = np.zeros(7, bool)
    held[2] = True
    near = np.array([0.3, 0.5, -0.4, -1.1, 0.7, np.radians(0.05), -0.2])
    far = near.copy()
    far[5] = 0.9
    kin, q, P = _held_case(near, np.radians(0.1))
    assert HeldJointChords(kin, q, P, held)(np.array([0]), np.array([2]), np.array([1]))[0] > 5
    kin, q, P = _held_case(far, np.radians(0.1))
    assert HeldJointChords(kin, q, P, held)(np.array([0]), np.array([2]), np.array([1]))[0] < 0.2


def test_held_joint_chords_make_each_waypoints_jacobian_once_and_answer_as_a_fresh_measure():
    """Douglas-Peucker asks about the same waypoints again and again: HeldJointChords makes each one's
    Jacobian once (counted through the kinematics), and every answer is bit for bit a fresh instance's."""
    from camtool.program.candidates import HeldJointChords
    from camtool.program.kinematics import Kinematics

    kin = Kinematics(_sia20())
    rng = np.random.default_rng(7)
    q = np.array([0.3, 0.5, -0.4, -1.1, 0.7, 0.9, -0.2]) + rng.normal(0.0, 0.05, (40, 7))
    P = kin.pose(q)[0]
    held = np.zeros(7, bool)
    held[2] = True
    rows = []

    class Counting(Kinematics):
        def jacobian6(self, qs):
            rows.append(len(qs))
            return super().jacobian6(qs)

    cached = HeldJointChords(Counting(_sia20()), q, P, held)
    queries = [(0, 39, np.arange(1, 39)), (0, 20, np.arange(1, 20)), (20, 39, np.arange(21, 39)),
               (5, 15, np.arange(6, 15))]
    for a, b, k in queries:
        got = cached(np.full(len(k), a), np.full(len(k), b), k)
        fresh = HeldJointChords(kin, q, P, held)(np.full(len(k), a), np.full(len(k), b), k)
        assert np.array_equal(got, fresh) and np.all(np.isfinite(got))
    assert sum(rows) == 38                   # waypoints 1..38, each once


def test_stated_joints_are_the_axes_beside_the_six_the_controller_solves():
    from camtool.program.convention import stated_joints

    r = get_robot("sia20")
    assert stated_joints(load_profile(None, "sia20", "inform", r), r, [f"RB1:{i}" for i in range(1, 7)]) == (2,)
    r = get_robot("irb2400")
    assert stated_joints(load_profile(None, "irb2400", "rapid", r), r, [f"rax_{i}" for i in range(1, 7)]) == ()
    r = get_robot("seed8")
    names = r.joint_names
    got = stated_joints(load_profile(None, "seed8", "rapid", r), r, [f"rax_{i}" for i in range(1, 7)])
    assert [names[i] for i in got] == ["track", "j4"]


def test_spans_the_post_stage_asks_joint_moves_for_are_no_straight_moves():
    from camtool.program.candidates import SPAN_SLACK_S, in_spans

    t = 10.0 + np.arange(0, 1.0, 0.05)   # the plan's clock need not start at 0: spans count from t[0]
    inside = in_spans(t, ((0.2, 0.3),))
    assert np.array_equal(np.flatnonzero(inside), [4, 5, 6])
    assert not in_spans(t, ((0.2 + 2 * SPAN_SLACK_S, 0.25 - 2 * SPAN_SLACK_S),)).any()
    assert not in_spans(t, ()).any()


def test_span_shares_are_the_smallest_share_of_the_spans_holding_each_time():
    from camtool.program.candidates import span_shares

    t = 10.0 + np.arange(0, 1.0, 0.05)   # spans count from t[0], as the joint-move spans
    got = span_shares(t, ((0.2, 0.3, 0.5), (0.25, 0.4, 0.25)))
    assert np.allclose(got[[3, 4, 6, 8, 9]], [1.0, 0.5, 0.25, 0.25, 1.0])
    assert np.array_equal(span_shares(t, ()), np.ones(len(t)))


def test_a_span_the_post_stage_writes_closer_keeps_its_skipped_waypoints_within_its_share(start):
    """``ProcessInfo.closer_s``: inside a (start, end, share) span the straight moves skip only waypoints
    within MERGE_SHARE x share of the tolerance of their line (each waypoint's TCP by the robot's own
    forward kinematics, not the merge's), and keep more targets there; outside it, the moves skip
    waypoints farther than that (the span is what made the difference)."""
    from camtool.program.candidates import MERGE_SHARE

    tr, r, _c = start
    first, last = runs(np.asarray(tr.zone) == WORK)
    t0 = tr.t_s[0]
    span = (tr.t_s[first[1]] - t0, tr.t_s[last[1]] - t0, 0.25)   # the second row, within a quarter
    loose = merged_candidates(tr, r, ProcessInfo(path_tol_mm=1.0), linear=True)   # a gentle motion: 1 mm merges
    close = merged_candidates(tr, r, ProcessInfo(path_tol_mm=1.0, closer_s=(span,)), linear=True)

    def worst_skipped(c, lo, hi):
        """The largest distance (mm) of a skipped waypoint of a straight move inside [lo, hi] from its line."""
        idx = np.flatnonzero(c.keep)
        worst = 0.0
        for a, b in zip(idx[:-1], idx[1:]):
            inside = lo <= c.st["t"][a] - t0 and c.st["t"][b] - t0 <= hi
            if not (inside and c.st["in_proc"][a] and c.st["in_proc"][b]):
                continue
            Pa, Pb = (r.fk_tcp(c.st["q"][i])[:3, 3] for i in (a, b))
            for k in range(a + 1, b):
                Pk = r.fk_tcp(c.st["q"][k])[:3, 3]
                s = np.clip(np.dot(Pk - Pa, Pb - Pa) / np.dot(Pb - Pa, Pb - Pa), 0.0, 1.0)
                worst = max(worst, float(np.linalg.norm(Pa + s * (Pb - Pa) - Pk)))
        return worst

    limit = MERGE_SHARE * 0.25 * 1.0
    assert worst_skipped(close, span[0], span[1]) <= limit + 1e-6
    assert worst_skipped(loose, span[0], span[1]) > limit
    held = lambda c, lo, hi: int(np.sum(c.keep & (c.st["t"] - t0 >= lo) & (c.st["t"] - t0 <= hi)))  # noqa: E731
    assert held(close, span[0], span[1]) > held(loose, span[0], span[1])
    row0 = (tr.t_s[first[0]] - t0, tr.t_s[last[0]] - t0)   # the first row, outside the span, as it was
    assert held(close, *row0) == held(loose, *row0)
