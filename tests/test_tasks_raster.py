"""The raster task's map drawn ahead (camtool.run.tasks.raster.MapAhead): started once, withdrawn on a re-plan."""
import functools

from camtool.report.figures import MapInputs, draw_redundancy_map
from camtool.run.tasks.raster import MapAhead


class _Recorder:
    """Stands in for a Standby: records what it was handed and whether it was cancelled."""

    def __init__(self):
        self.started, self.cancelled = [], False

    def start(self, fn):
        self.started.append(fn)
        return self

    def cancel(self):
        self.cancelled = True

    def result(self):
        return ("drawn", self.started[-1])


def test_the_plan_is_handed_over_once_as_the_map_inputs():
    standby = _Recorder()
    ahead = MapAhead(standby, "robot", "out", "world")
    ahead.planned("path", "joint path")
    (fn,) = standby.started
    assert isinstance(fn, functools.partial) and fn.func is draw_redundancy_map
    assert fn.args == (MapInputs("robot", "path", "joint path", "out", "world"),)
    assert ahead.result() == ("drawn", fn) and not standby.cancelled


def test_a_second_plan_withdraws_the_map_and_report_html_draws_it():
    standby = _Recorder()
    ahead = MapAhead(standby, "robot", "out", None)
    ahead.planned("path", "joint path")
    ahead.planned("stretches", "their joint path")   # task.allow_partial planned again: another path
    assert len(standby.started) == 1 and standby.cancelled and ahead.result() is None


def test_a_failed_plan_withdraws_it_before_the_failure_report():
    standby = _Recorder()
    ahead = MapAhead(standby, "robot", "out", None)
    ahead.withdraw()
    assert standby.cancelled and ahead.result() is None and not standby.started
