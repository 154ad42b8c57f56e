"""The figures of a run that passed its motion check: feed.png, the joint plots and the redundancy map.

They need only the timed trajectories, so the raster task draws them alongside the
post stage (``camtool.alongside``) and report.html takes the redundancy map from here.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from .report import plot_joints
from .report_html import redundancy_figure
from .timing import plot_feed_png, sampled_for


@dataclass(frozen=True)
class FigureInputs:
    """What the figures are drawn from; ``dt_s`` is the timing check's sampling step."""

    trajectories: dict          # method -> Trajectory; the first is the run's own
    robot: object
    path: object
    joint_path: object
    outdir: Path
    dt_s: float
    title: str = ""
    world: object = None        # the job's CollisionWorld: the redundancy map's collision layer


@dataclass(frozen=True)
class RunFigures:
    """The files drawn, the redundancy map (or None) for report.html, and the wall / CPU seconds per figure
    stage where they were drawn (report.json's ``stage_seconds_alongside``)."""

    feed_png: Path
    joint_plots: tuple
    redundancy: tuple           # (RedundancyMap or None, [its PNG])
    seconds: dict
    cpu_seconds: dict


def draw_run_figures(inputs: FigureInputs) -> RunFigures:
    """Draw feed.png, the joint plots (every trajectory) and the redundancy map of ``inputs``."""
    seconds, cpu = {}, {}
    mark = [time.perf_counter(), time.process_time()]

    def lap(name):
        now = (time.perf_counter(), time.process_time())
        seconds[name], cpu[name] = round(now[0] - mark[0], 3), round(now[1] - mark[1], 3)
        mark[:] = now

    own = next(iter(inputs.trajectories.values()))
    feed_png = plot_feed_png(own, sampled_for(own, inputs.robot, inputs.dt_s),
                             Path(inputs.outdir) / "plots" / "feed.png", title=inputs.title)
    joint_plots = tuple(plot_joints(inputs.trajectories, inputs.robot, Path(inputs.outdir) / "plots"))
    lap("plots")
    redundancy = redundancy_figure(inputs.outdir, inputs.robot, inputs.path, inputs.joint_path, world=inputs.world)
    lap("redundancy_map")
    return RunFigures(feed_png, joint_plots, redundancy, seconds, cpu)
