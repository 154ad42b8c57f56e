"""The figures of a run that passed its motion check: feed.png, the joint plots and the redundancy map.

The redundancy map needs only the planned path, so the raster task draws it while the
trajectory is timed; feed.png and the joint plots need the timed trajectories and are
drawn while the programs are written. Both run in processes made ready ahead
(``camtool.alongside.Standby``, ``import_figure_libraries``); report.html takes the map
from here.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from .report import import_plotting, plot_joints
from .report_html import redundancy_figure
from .timing import plot_feed_png, sampled_for


@dataclass(frozen=True)
class FigureInputs:
    """What feed.png and the joint plots are drawn from; ``dt_s`` is the timing check's sampling step."""

    trajectories: dict          # method -> Trajectory; the first is the run's own
    robot: object
    outdir: Path
    dt_s: float
    title: str = ""


@dataclass(frozen=True)
class MapInputs:
    """What the redundancy map is drawn from: the planned path and its joint path."""

    robot: object
    path: object
    joint_path: object
    outdir: Path
    world: object = None        # the job's CollisionWorld: the map's collision layer


@dataclass(frozen=True)
class RunFigures:
    """The files drawn and the wall / CPU seconds of drawing them (report.json's ``stage_seconds_alongside``)."""

    feed_png: Path
    joint_plots: tuple
    seconds: dict
    cpu_seconds: dict


@dataclass(frozen=True)
class DrawnMap:
    """``redundancy_figure``'s (map or None, [its PNG]) and the wall / CPU seconds of drawing it."""

    redundancy: tuple
    seconds: dict
    cpu_seconds: dict


def import_figure_libraries() -> None:
    """Import matplotlib (a second or more): a process made ready ahead of the figures
    (``camtool.alongside.Standby``) does it while the run still plans."""
    import_plotting()


def _clock() -> tuple[float, float]:
    return time.perf_counter(), time.process_time()


def draw_run_figures(inputs: FigureInputs) -> RunFigures:
    """Draw feed.png and the joint plots (every trajectory) of ``inputs``."""
    wall, cpu = _clock()
    own = next(iter(inputs.trajectories.values()))
    feed_png = plot_feed_png(own, sampled_for(own, inputs.robot, inputs.dt_s),
                             Path(inputs.outdir) / "plots" / "feed.png", title=inputs.title)
    joint_plots = tuple(plot_joints(inputs.trajectories, inputs.robot, Path(inputs.outdir) / "plots"))
    now = _clock()
    return RunFigures(feed_png, joint_plots, {"plots": round(now[0] - wall, 3)}, {"plots": round(now[1] - cpu, 3)})


def draw_redundancy_map(inputs: MapInputs) -> DrawnMap:
    """Draw the redundancy map of ``inputs`` (``OUTDIR/plots/redundancy_map.png``)."""
    wall, cpu = _clock()
    redundancy = redundancy_figure(inputs.outdir, inputs.robot, inputs.path, inputs.joint_path, world=inputs.world)
    now = _clock()
    return DrawnMap(redundancy, {"redundancy_map": round(now[0] - wall, 3)},
                    {"redundancy_map": round(now[1] - cpu, 3)})
