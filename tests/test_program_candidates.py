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
