"""A reach hint that names no placement names ``camtool place`` and its tilt (issue #46).

The hint's screen (``nearest_feasible_shift``) moves the part and turns it about z only; ``camtool place`` also
tilts it on its fixture (``--tilt-max-deg``). Where the hint finds no placement, or none it finds plans, the
refusal's one line says so, with the tilt's bound as place has it."""
import pytest

from camtool.commands.place import command as place_command
from camtool.run import reach_hint


def _tilt_default_deg() -> float:
    (opt,) = [p for p in place_command.params if "--tilt-max-deg" in p.opts]
    return float(opt.default)


def test_no_placement_found_names_place_and_its_tilt(monkeypatch):
    """The screen finds nothing at any margin: every margin is asked (the margin-free one last), no placement is
    returned, and the refusal's clause names place, --vary and --tilt-max-deg with place's own default."""
    asked = []
    monkeypatch.setattr(reach_hint, "nearest_feasible_shift", lambda job, st, robot, path, search: asked.append(
        (search.reach_margin, search.joint_margin)))
    assert reach_hint.planned_shift(None, None, None, None) is None
    assert asked == [*reach_hint.HINT_MARGINS, reach_hint.LAST_MARGINS]
    line = reach_hint.NOWHERE.format(mm=600.0)
    assert "\n" not in line and line.startswith("no placement within 600 mm")
    assert "camtool place" in line and "--vary" in line and "--tilt-max-deg" in line
    assert f"{_tilt_default_deg():g} deg unless given" in line


@pytest.mark.parametrize("planned", [False, True])
def test_a_shift_that_does_not_plan_names_place_and_its_tilt(monkeypatch, planned):
    """A placement the screen finds but that does not plan: no placement printed, place and its tilt named;
    one that plans is printed as before, without place."""
    def shift(job, st, robot, path, search):
        x = 1000.0 + 100.0 * search.reach_margin     # each margin its own placement
        return {"already_reachable": False, "workpiece_xyz_mm": [x, 0.0, 0.0], "workpiece_rpy_deg": [0.0, 0.0, 0.0],
                "message": f"set cell.workpiece_xyz_mm = [{x:g}, 0, 0]: {reach_hint.SCREENED}"}

    monkeypatch.setattr(reach_hint, "nearest_feasible_shift", shift)
    monkeypatch.setattr(reach_hint, "placed", lambda job, s: s)
    monkeypatch.setattr(reach_hint, "why_not_planned", lambda s: None if planned else "timing: too fast")
    out = reach_hint.planned_shift(None, None, None, None)
    assert out["planned"] is planned
    if planned:
        assert reach_hint.PLANNED in out["message"] and "camtool place" not in out["message"]
    else:
        msg = out["message"]
        assert "cell.workpiece_xyz_mm" not in msg and "\n" not in msg
        assert f"none of the {len(reach_hint.HINT_MARGINS)} nearest placements" in msg
        assert reach_hint.PLACE in msg and "--tilt-max-deg" in msg
