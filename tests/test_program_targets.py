"""The targets' joint values (camtool.program.targets): a Yaskawa job written without pulse factors
(every target a ///RECTAN position with its ///RCONF) is solved back to the planned joints, and a
program read twice (its check, then its simulation) is solved once."""
import numpy as np

from camtool.program import targets
from camtool.program.process import ProcessInfo
from camtool.robots import get_robot
from camtool.program.profiles import load_profile
from postprocessors.yaskawa_inform import InformPost
from test_post import rows_trajectory


def _rectan_job(tmp_path):
    """The SIA20 (no pulse factors known: camtool writes positions, never made-up pulses)."""
    r = get_robot("sia20")
    p = load_profile(None, "sia20", "inform", r, InformPost())     # the shipped profile: no pulses
    tr = rows_trajectory(r, rows=2)
    files = InformPost().write(tr, r, p, tmp_path, process=ProcessInfo())
    return r, p, tr, InformPost().read_program(files[0], r, p)


def test_positions_without_pulses_solve_back_to_the_plan(tmp_path):
    r, p, tr, prog = _rectan_job(tmp_path)
    assert targets.cartesian_targets(prog).all()          # no joint target at all
    q = targets.target_joints(prog, r, p)
    assert np.isfinite(q).all()
    # each target is one of the trajectory's configurations (the written waypoints)
    d = np.abs(q[:, None, :] - np.asarray(tr.q)[None, :, :]).max(axis=2).min(axis=1)
    assert d.max() < 1e-4


def test_a_program_read_twice_is_solved_once(tmp_path, monkeypatch):
    r, p, tr, prog = _rectan_job(tmp_path)
    targets._SOLVED.clear()
    calls = []
    real = targets._solve_targets
    monkeypatch.setattr(targets, "_solve_targets", lambda *a: calls.append(1) or real(*a))
    first = targets.target_joints(prog, r, p)
    first[:] = np.nan                                      # the caller's copy, not the memo's
    second = targets.target_joints(prog, r, p)
    assert len(calls) == 1 and np.isfinite(second).all()
    tool = np.eye(4)
    tool[2, 3] = 50.0
    other = r.with_placement(tool_T_mm=tool)
    targets.target_joints(prog, other, p)                  # another tool: solved again
    assert len(calls) == 2
