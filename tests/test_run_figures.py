"""The run's figures (camtool.report.figures): the same files drawn alongside (forked) as in this process."""
import functools

import numpy as np
import pytest

from camtool.alongside import Standby
from camtool.collision.stage import collision_world
from camtool.job import load_job
from camtool.report.figures import (
    FigureInputs,
    MapInputs,
    draw_redundancy_map,
    draw_run_figures,
    import_figure_libraries,
)
from camtool.run.job_settings import JobSettings
from camtool.run.stages import (
    part_for_checks,
    path_for_job,
    plan_and_time,
    robot_for_job,
    surface_for_job,
    workpiece_for_job,
)

from conftest import SAMPLES


@pytest.fixture(scope="module")
def coarse_sample():
    """The sample at a coarse raster (a few seconds to plan): its figure inputs, without the folder."""
    job = load_job(SAMPLES / "sphere.toml", ["raster.step_over_mm=60", "raster.pitch_mm=8"])
    robot = robot_for_job(job)
    wp = workpiece_for_job(job)
    surface = surface_for_job(job, wp)
    settings = JobSettings.from_job(job, robot)
    path = path_for_job(job, surface)
    jp, tr = plan_and_time(settings, path, robot, workpiece=part_for_checks(settings, wp, surface))
    return lambda out: (FigureInputs({"seed": tr}, robot, out, settings.timing.check_dt_s, "sphere.toml"),
                        MapInputs(robot, path, jp, out, collision_world(settings, robot)))


def _drawn(inputs, forked):
    """(RunFigures, DrawnMap), each drawn by a Standby (forked or in this process)."""
    plots, mapping = inputs
    with Standby(import_figure_libraries, forked=forked) as a, Standby(import_figure_libraries, forked=forked) as b:
        return (a.start(functools.partial(draw_run_figures, plots)).result(),
                b.start(functools.partial(draw_redundancy_map, mapping)).result())


@pytest.mark.parametrize("forked", [True, False])
def test_every_figure_is_drawn(coarse_sample, tmp_path, forked):
    drawn, mapped = _drawn(coarse_sample(tmp_path), forked)
    names = sorted(p.name for p in (tmp_path / "plots").iterdir())
    assert names == ["feed.png", "joint_acceleration.png", "joint_angle.png", "joint_speed.png",
                     "redundancy_map.png"]
    assert drawn.feed_png == tmp_path / "plots" / "feed.png" and len(drawn.joint_plots) == 3
    assert mapped.redundancy[0] is not None and mapped.redundancy[1] == [tmp_path / "plots" / "redundancy_map.png"]
    assert set(drawn.seconds) == {"plots"} and set(mapped.seconds) == {"redundancy_map"}
    assert all(v >= 0 for v in (*drawn.seconds.values(), *mapped.cpu_seconds.values()))


def test_drawn_alongside_or_here_the_files_and_the_map_are_the_same(coarse_sample, tmp_path):
    _, forked = _drawn(coarse_sample(tmp_path / "a"), True)
    _, here = _drawn(coarse_sample(tmp_path / "b"), False)
    for name in ("feed.png", "joint_angle.png", "joint_speed.png", "joint_acceleration.png", "redundancy_map.png"):
        assert (tmp_path / "a" / "plots" / name).read_bytes() == (tmp_path / "b" / "plots" / name).read_bytes(), name
    a, b = forked.redundancy[0], here.redundancy[0]
    assert np.array_equal(a.code, b.code) and np.array_equal(a.margin, b.margin, equal_nan=True)
