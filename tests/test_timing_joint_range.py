"""Issue #48: a run whose spline leaves a joint's range between its poses is a plan that cannot be timed (exit 3,
the joint and the rows named), not an internal error (exit 1)."""
import numpy as np
import pytest

from camtool.errors import PlanInfeasible
from camtool.path.toolpath import ZONE_CODE
from camtool.robots import get_robot
from camtool.timing.runs import time_runs


def test_a_spline_leaving_the_joint_range_is_infeasible_naming_the_joint():
    limits = get_robot("seed8").limits
    n = 8
    q = np.tile((limits.lower + limits.upper) / 2, (n, 1))
    top = limits.upper[2]
    q[:, 2] = top - np.array([0.4, 0.1, 0.0, 0.0, 0.0, 0.0, 0.1, 0.4])  # joint 3 runs along its upper limit
    first, last = np.zeros(n, bool), np.zeros(n, bool)
    first[0], last[-1] = True, True
    with pytest.raises(PlanInfeasible, match=r"run of surface rows 0\.\.7: .*joint 3 by") as info:
        time_runs(q, np.full(n - 1, 5.0), first, last, np.zeros(n, int), np.full(n, ZONE_CODE["work"]), limits, 100.0)
    assert info.value.exit_code == 3 and info.value.report["timing_failed"] == {"rows": [0, 7], "joint": 3}
