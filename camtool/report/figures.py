"""The figures of a run that passed its motion check: feed.png, the joint plots and the redundancy map.

The redundancy map's cells need only the path's work poses, so the raster task sweeps
them while the path is planned (``sweep_ahead``) and draws the map with the plan while
the trajectory is timed; feed.png and the joint plots need the timed trajectories and are
drawn while the programs are written. Both run in processes made ready ahead
(``camtool.alongside.Standby``, ``import_figure_libraries``); report.html takes the map
from here.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from ..errors import BadInput
from .run_report import import_plotting, plot_joints
from .html import redundancy_figure
from ..timing import plot_feed_png, sampled_for


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


@dataclass(frozen=True)
class JointPlots:
    """The joint plots drawn (``draw_joint_plots``) and the wall / CPU seconds of drawing them."""

    files: tuple
    seconds: float
    cpu_seconds: float


def draw_joint_plots(inputs: FigureInputs, _prepared=None) -> JointPlots:
    """Draw the joint plots (every trajectory) of ``inputs``: they need the timed trajectories alone, so the
    raster task hands them over before the time stage's 4 ms check (``draw_run_figures`` then adds feed.png)."""
    wall, cpu = _clock()
    files = tuple(plot_joints(inputs.trajectories, inputs.robot, Path(inputs.outdir) / "plots"))
    now = _clock()
    return JointPlots(files, now[0] - wall, now[1] - cpu)


def draw_run_figures(inputs: FigureInputs, joint_plots: JointPlots | None = None) -> RunFigures:
    """Draw feed.png and the joint plots (every trajectory) of ``inputs``; ``joint_plots``: the ones drawn
    already (``draw_joint_plots``), then feed.png alone."""
    wall, cpu = _clock()
    own = next(iter(inputs.trajectories.values()))
    feed_png = plot_feed_png(own, sampled_for(own, inputs.robot, inputs.dt_s),
                             Path(inputs.outdir) / "plots" / "feed.png", title=inputs.title)
    now = _clock()
    joint_plots = joint_plots if joint_plots is not None else draw_joint_plots(inputs)
    return RunFigures(feed_png, joint_plots.files, {"plots": round(now[0] - wall + joint_plots.seconds, 3)},
                      {"plots": round(now[1] - cpu + joint_plots.cpu_seconds, 3)})


@dataclass(frozen=True)
class SweptMap:
    """``redundancy_map.sweep_map``'s cells of a path (None: that robot is not mapped) and the wall / CPU
    seconds of sweeping them."""

    sweep: object
    seconds: dict
    cpu_seconds: dict


def sweep_ahead(inputs: MapInputs, _prepared=None) -> SweptMap:
    """The redundancy map's cells of ``inputs.path`` (the raster, before it is planned): the map's heavy
    part, done while the run plans; ``draw_redundancy_map`` takes them where the planned path has the
    same work poses. ``_prepared``: what the process did ahead (``camtool.alongside.Standby``, hand_on)."""
    from .redundancy_map import redundancy_kind, sweep_map

    wall, cpu = _clock()
    sweep = None
    if len(inputs.path) and redundancy_kind(inputs.robot) is not None:
        try:
            sweep = sweep_map(inputs.path, inputs.robot, world=inputs.world)
        except BadInput:
            sweep = None
    now = _clock()
    return SweptMap(sweep, {"redundancy_sweep": round(now[0] - wall, 3)},
                    {"redundancy_sweep": round(now[1] - cpu, 3)})


def draw_redundancy_map(inputs: MapInputs, swept: SweptMap | None = None) -> DrawnMap:
    """Draw the redundancy map of ``inputs`` (``OUTDIR/plots/redundancy_map.png``), from ``swept``'s cells
    where they are this path's (``sweep_ahead``)."""
    wall, cpu = _clock()
    redundancy = redundancy_figure(inputs.outdir, inputs.robot, inputs.path, inputs.joint_path, world=inputs.world,
                                   sweep=None if swept is None else swept.sweep)
    now = _clock()
    seconds, cpu_seconds = ({}, {}) if swept is None else (dict(swept.seconds), dict(swept.cpu_seconds))
    seconds["redundancy_map"], cpu_seconds["redundancy_map"] = round(now[0] - wall, 3), round(now[1] - cpu, 3)
    return DrawnMap(redundancy, seconds, cpu_seconds)
