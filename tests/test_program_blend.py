"""camtool.program.blend: corners blended within the tolerance, rows marked."""
import numpy as np
import pytest

from camtool.program.blend import BLEND_SHARE, BlendCorners
from camtool.program.candidates import merged_candidates
from camtool.program.plan import part_names, profile_tool, row_markers, stop_at_part_ends
from camtool.program.process import ProcessInfo
from camtool.program.profiles import load_profile
from camtool.robots import get_robot
from test_post import rows_trajectory

LEVELS = (0.3, 1.0, 5.0, 10.0)


@pytest.fixture(scope="module")
def merged():
    r = get_robot("irb2400")
    r = r.with_placement(tool_T_mm=profile_tool(load_profile(None, "irb2400", "rapid", r)))
    return merged_candidates(rows_trajectory(r, rows=2), r, ProcessInfo(), linear=True)


def test_targets_rows_and_kinds(merged):
    plan = BlendCorners(LEVELS).plan(merged)
    assert len(plan) == int(merged.keep.sum())
    assert plan.rows == 2 and plan.row_start.sum() == 2 and plan.row_end.sum() == 2
    assert np.all(plan.free == (plan.row < 0)) and set(np.unique(plan.kind)) <= {"J", "L"}
    assert plan.kind[0] == "J" and np.all(np.diff(plan.t) >= 0)
    assert np.all(plan.level[1:-1] >= -1) and np.all(plan.level < len(LEVELS))


def test_surface_corners_get_at_least_the_level_asked(merged):
    for asked in (0, 2):
        plan = BlendCorners(LEVELS, asked).plan(merged)
        inner = np.flatnonzero(plan.row >= 0)[1:-1]
        assert np.all(plan.level[inner] >= asked)


def test_blending_never_adds_deviation_beyond_the_tolerance(merged):
    plan = BlendCorners(LEVELS).plan(merged)
    tol = merged.process.path_tol_mm
    assert np.all(plan.deviation_mm[plan.row >= 0] <= tol + 1e-9) and BLEND_SHARE <= 1.0


def test_a_level_no_corner_can_get_does_not_grow_the_plan_without_bound(merged):
    """10 mm on the surface is more than these corners allow: the shorter moves stop growing (it
    doubled every round, 511,806 targets from 94); the simulator then finds what the corner cuts."""
    from camtool.program.blend import MAX_GROWTH

    plan = BlendCorners(LEVELS, 3).plan(merged)
    assert len(plan) <= 2 * MAX_GROWTH * int(merged.keep.sum()) + 2


def test_row_markers_pair_each_rows_first_and_last_move(merged):
    """camtool.program.plan.row_markers: the start lines at each row's first move (with its label, None past the
    labels given), the end lines at its last; rows counted from 1 in order."""
    plan = BlendCorners(LEVELS).plan(merged)
    before, after = row_markers(plan, ProcessInfo(row_labels=("first",)), lambda r, label: [f"start {r} {label}"],
                                lambda r: [f"end {r}"])
    assert sorted(before) == np.flatnonzero(plan.row_start).tolist()
    assert sorted(after) == np.flatnonzero(plan.row_end).tolist()
    assert [before[i] for i in sorted(before)] == [["start 1 first"], ["start 2 None"]]
    assert [after[i] for i in sorted(after)] == [["end 1"], ["end 2"]]
    assert all(plan.row[i] == int(before[i][0].split()[1]) - 1 for i in before)


def test_stop_at_part_ends_stops_every_part_but_the_last(merged):
    plan = BlendCorners(LEVELS, 1).plan(merged)
    n = len(plan)
    parts = [range(0, n // 3), range(n // 3, n // 2), range(n // 2, n)]
    own = plan.level.copy()
    level = stop_at_part_ends(plan.level, parts)
    assert level[n // 3 - 1] == -1 and level[n // 2 - 1] == -1
    untouched = np.setdiff1d(np.arange(n), [n // 3 - 1, n // 2 - 1])
    assert np.array_equal(level[untouched], plan.level[untouched])
    assert np.array_equal(plan.level, own)          # the plan's own levels stay


def test_part_names_fit_the_controllers_length_and_count_from_one():
    assert part_names("PLATE", 3, 8) == ["PLATE_1", "PLATE_2", "PLATE_3"]
    names = part_names("LONGNAME", 12, 8)        # the name is cut to make room for the suffix
    assert names[0] == "LONGNA_1" and names[-1] == "LONGN_12"
    assert all(len(n) <= 8 for n in names) and len(set(names)) == 12
