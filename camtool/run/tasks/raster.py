"""The main seed's task (``task.kind = "raster"``): a surface raster planned for a redundant arm.

    workpiece -> fit -> raster -> plan (+ home moves) -> time -> check -> post -> report
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Callable

from ...alongside import Standby, timed
from ...collision.stage import collision_world
from ...errors import BadInput, PlanInfeasible
from ...report.faces import faces_worked
from ...part.faces import faces_report
from ...job import Job
from ..part_stages import JobPart, faces_settings
from ...process.outputs import process_outputs
from ...process.dwell import check_target_inputs, retime_for_target, target_removal
from ...process.stepover import auto_step_over
from ...path.raster import raster_path
from ...report.html import figure_sections
from ...motion.geometry import import_part_libraries
from ...report.figures import (
    FigureInputs,
    MapInputs,
    draw_joint_plots,
    draw_redundancy_map,
    draw_run_figures,
    import_figure_libraries,
    sweep_ahead,
)
from ...placement.partial import partial_path, partial_summary, reachable_stretches
from ..check_left_out import CheckLeftOut
from ...plan.kernel import load_compiled
from ..reach_hint import NOWHERE, planned_shift
from ...placement.shift import ShiftSearch
from ..job_settings import JobSettings
from ...part.surface import FaceSet
from ...timing import sampled_for
from ...timing.pathlaw import remembered_runs
from ..stages import (RunResult, StageLog, clearance_part, finish_run, leads_into_part, motion_check, shaped_for_part,
                      motion_check_part, part_for_checks, plan_and_time, plan_with_sized_leads, post_checked, report_failure, report_unreachable,
                      run_report, time_for_job, with_scan_verdict)


_log = logging.getLogger("camtool.run")


def check_several_faces(job: Job, settings: JobSettings) -> None:
    """BadInput for what a job of several faces does not do yet: a target removal map, an automatic step-over,
    a partial plan (each is one surface's)."""
    process = settings.process
    what = ("process.target_removal_file" if process is not None and process.enabled and process.target_removal_file
            else 'raster.step_over_mm = "auto"' if settings.raster.step_over_auto
            else "task.allow_partial" if job.task.allow_partial else None)
    if what:
        raise BadInput(f"{job.path}: {what} works one face; faces.select = {job.faces.select!r} selects several: "
                       "select one face, or drop the key")


PARTIAL_LIFT_ROUNDS = 5   # a partial plan leaves out the stretch ends it cannot lift off at, then plans again


def partial_plan_path(path, exc: PlanInfeasible, unliftable=(), check_left_out=()):
    """(the reachable stretches as a Path, each of its poses' index in ``path``, report figures) for
    ``task.allow_partial``, the ``unliftable`` path indices left out too, and those ``check_left_out`` (where the
    motion check failed); PlanInfeasible if none."""
    bad = [u["index"] for u in exc.report.get("unreachable", [])]
    bad += sorted((set(int(i) for i in unliftable) | set(int(i) for i in check_left_out)) - set(bad))
    stretches = reachable_stretches(path, bad)
    if not stretches:
        raise exc
    sub, index = partial_path(path, stretches, bad)
    figures = {**partial_summary(path, stretches), "left_out_path_indices": bad,
               "stretch_list": [s.as_dict() for s in stretches]}
    if unliftable:
        figures["unliftable_ends_left_out"] = sorted(int(i) for i in unliftable)
    return sub, index, figures


def plan_partial(settings: JobSettings, path, exc: PlanInfeasible, robot, part, surface, replan=None):
    """(partial path, joint path, trajectory, figures, each partial pose's index in ``path``, the unliftable path
    indices left out): the reachable stretches planned and timed; ``replan`` (a ``_Replan``): planned again with
    its poses left out for the motion check, from its unliftable ends. A stretch cut
    at the edge of reach ends where the arm may not lift off (a lift past a joint limit, into a link): at each
    connector that cannot be lifted (``lift_reconfigurations``' ``unliftable_path_indices``: the end of one
    run, the start of the next) the poses of both sides are left out as the unreachable ones are, 1, 2, 4, ...
    of them in turn (the edge of reach may lie several poses in), and the rest planned again,
    ``PARTIAL_LIFT_ROUNDS`` times at most."""
    unliftable = _trimmed(exc.report.get("unliftable_path_indices", ()), len(path), 1)   # every pose reached
    left = ()
    if replan is not None:
        unliftable, left = set(replan.unliftable), replan.left.indices
    for round_ in range(PARTIAL_LIFT_ROUNDS + 1):
        sub, index, figures = partial_plan_path(path, exc, unliftable, left)
        try:
            joint_path, trajectory = plan_and_time(settings, sub, robot, workpiece=part, surface=surface,
                                                   every_failure=True)
            return sub, joint_path, trajectory, figures, index, frozenset(unliftable)
        except PlanInfeasible as again:
            ends = again.report.get("unliftable_path_indices")
            if not ends or round_ == PARTIAL_LIFT_ROUNDS:
                raise
            unliftable |= _trimmed([int(index[i]) for i in ends], len(path), 2 ** (round_ + 1))


def _trimmed(pairs, n: int, depth: int) -> set[int]:
    """The path indices ``depth`` poses deep into each side of each (end of a run, start of the next) pair."""
    out: set[int] = set()
    for a, b in zip(pairs[::2], pairs[1::2]):
        out |= set(range(max(int(a) - depth + 1, 0), int(a) + 1)) | set(range(int(b), min(int(b) + depth, n)))
    return out


class MapAhead:
    """The redundancy map made ahead, in a process on standby (``hand_on``): its cells swept as soon as
    the raster is made (while the path is planned), the map drawn as soon as the plan is known (while
    the trajectory is timed). ``result()``: its ``DrawnMap``, or None when it was not drawn ahead (then
    report.html draws it)."""

    def __init__(self, standby: Standby, robot, outdir: Path, world):
        self._standby, self._robot, self._outdir, self._world = standby, robot, outdir, world
        self._state = "waiting"   # -> "swept" -> "started" -> (done) | "withdrawn"

    def rastered(self, path) -> None:
        """Sweep the map's cells of the raster (``run_figures.sweep_ahead``); the map takes them where the
        planned path keeps its work poses (the leads sized for the ramps move only the leads)."""
        if self._state == "waiting":
            self._standby.start(partial(sweep_ahead, MapInputs(self._robot, path, None, self._outdir, self._world)))
            self._state = "swept"

    def planned(self, path, joint_path) -> None:
        """Draw the map of this plan (once; a later plan withdraws it: that map would be of another path)."""
        if self._state in ("waiting", "swept"):
            draw = partial(draw_redundancy_map, MapInputs(self._robot, path, joint_path, self._outdir, self._world))
            (self._standby.start if self._state == "waiting" else self._standby.then)(draw)
            self._state = "started"
        else:
            self.withdraw()

    def withdraw(self) -> None:
        """Kill the map drawn ahead (a failing plan draws its own, failing poses marked)."""
        self._standby.cancel()
        self._state = "withdrawn"

    def result(self):
        return self._standby.result() if self._state == "started" else None


class Ahead:
    """What the run hands its helpers as soon as it has it: the raster and the plan to the redundancy map
    (``MapAhead``); the timed trajectory to the motion check and the joint plots (each ``timed`` callable
    is called as ``(path, trajectory)``), before the time stage's own 4 ms check, while this process makes
    it. ``timed_trajectory``: the one handed (None before, or with nothing to hand it to)."""

    def __init__(self, mapping: MapAhead, timed: tuple[Callable, ...] = ()):
        self.mapping, self._timed = mapping, timed
        self.timed_trajectory = None

    def timed(self, path, trajectory) -> None:
        """Hand ``trajectory`` (of ``path``) on, once."""
        if self._timed and self.timed_trajectory is None:
            for hand in self._timed:
                hand(path, trajectory)
            self.timed_trajectory = trajectory


@dataclass(frozen=True)
class RasterRun:
    """What a raster run is given: the job and its settings, the robot, the output folder, the stage log,
    whether the other planner is compared, the part (``part_stages.JobPart``), and the motion check's finding
    for which the leads were planned again (None on a first run)."""

    job: Job
    settings: JobSettings
    robot: object
    outdir: Path
    log: StageLog
    compare: bool
    part: JobPart
    leads_retried: str | None = None
    again: "_Replan | None" = None   # planned again with poses left out for the motion check (allow_partial)

    def figure_inputs(self, trajectories: dict) -> FigureInputs:
        """What the figures of these trajectories are drawn from."""
        return FigureInputs(trajectories, self.robot, self.outdir, self.settings.timing.check_dt_s, self.job.path.name)


@dataclass(frozen=True)
class Rastered:
    """The part stages' and the raster stage's output: the workpiece as loaded, the surface (several faces when a
    ``FaceSet``), the path, and the automatic step-over's choice (None without one)."""

    wp: object
    surface: object
    path: object
    step_choice: dict | None
    axis_tilt: dict | None = None   # the tool axes tilted clear of the part (``shaped_for_part``), or None

    @property
    def several(self) -> bool:
        """faces.select names several faces: one program for them all."""
        return isinstance(self.surface, FaceSet)


@dataclass(frozen=True)
class _Replan:
    """Where a raster run planned again with poses left out for the motion check (``check_left_out``) starts:
    the path its poses are indexed in (as the first plan rastered it), that plan's refusal (its unreachable
    poses; an empty one when every pose was reached), the stretch ends left out as unliftable, and the poses
    left out for the check so far."""

    path: object
    refusal: PlanInfeasible
    unliftable: frozenset
    left: CheckLeftOut


@dataclass(frozen=True)
class _Origin:
    """What a plan was made of: the raster path, the programmed path's index in it (None: the raster itself),
    the first plan's refusal (None: every pose reached) and the unliftable ends left out."""

    path: object
    index: object = None
    refusal: PlanInfeasible | None = None
    unliftable: frozenset = frozenset()


def planned_and_timed(r: RasterRun, made: Rastered, part, ahead: Ahead | None = None):
    """(path, joint path, trajectory, partial figures or None, ``_Origin``): the plan and time stages of a raster
    job.

    ``ahead.mapping.planned(path, joint_path)`` is told the plan before the time stage, ``ahead.timed(path,
    trajectory)`` the trajectory before the time stage's 4 ms check (not a partial plan's).
    Leads grow to what the ramps need (``plan_with_sized_leads``; each run's time law is planned once,
    ``remembered_runs``); with ``task.allow_partial`` the reachable stretches are planned when some poses
    are not. An unreachable plan writes its report (and the nearest shift that would fit) and is raised.
    ``made.wp`` the workpiece as loaded, ``part`` what the checks measure against (``part_for_checks``).
    ``r.again``: planned again, straight to the partial plan with the poses it leaves out."""
    job, settings, robot, log = r.job, r.settings, r.robot, r.log
    path, stretches = made.path, None
    tell = ahead.mapping.planned if ahead is not None else (lambda path_, joint_path_: None)
    if r.again is not None:
        return _planned_again(r, made, part, tell)
    origin = _Origin(path)
    with remembered_runs():  # lead sizing plans each run's time law; the time stage takes it
        try:
            try:
                with log.clock("plan"):
                    path, joint_path = plan_with_sized_leads(settings, made.surface, path, robot, workpiece=part)
                tell(path, joint_path)
                with log.clock("time"):
                    trajectory = time_for_job(settings, joint_path, path, robot,
                                              before_check=None if ahead is None else partial(ahead.timed, path))
                if joint_path.events.get("leads", {}).get("lead_mm_used", settings.raster.lead_mm) != settings.raster.lead_mm:
                    log.done("raster", path)  # rastered again with the leads the ramps need
                origin = _Origin(path)
            except PlanInfeasible as exc:
                if not (job.task.allow_partial and (exc.report.get("unreachable")
                                                    or exc.report.get("unliftable_path_indices"))):
                    raise
                sub, joint_path, trajectory, stretches, index, unliftable = plan_partial(
                    settings, path, exc, robot, part, made.surface)
                origin = _Origin(path, index, exc, unliftable)
                path = sub
                tell(path, joint_path)
                log.done("raster", path)  # the part of the raster that is programmed
        except PlanInfeasible as exc:
            if ahead is not None:
                ahead.mapping.withdraw()   # the report draws the map with the failing poses
            shift = None
            if exc.report.get("unreachable") or exc.report.get("timing_failed"):  # where the part would fit and plan
                shift = planned_shift(job, settings, robot, path)  # printed only if it plans and times
            report_unreachable(exc, path, robot, job, r.outdir, made.wp, made.surface, shift=shift,
                               world=collision_world(settings, robot))
            if shift is not None and not shift["already_reachable"]:
                raise PlanInfeasible(f"{exc}; {shift['message']}", report=exc.report) from None
            if shift is None and exc.report.get("unreachable"):
                raise PlanInfeasible(f"{exc}; {NOWHERE.format(mm=ShiftSearch().max_mm)}", report=exc.report) from None
            raise
    return path, joint_path, trajectory, stretches, origin


def _planned_again(r: RasterRun, made: Rastered, part, tell):
    """``planned_and_timed`` of a run planned again with poses left out for the motion check (``r.again``): the
    partial plan of the first plan's path, from its unreachable poses and unliftable ends; a refusal is the run's
    (report.json names what was left out)."""
    again = r.again
    try:
        with remembered_runs(), r.log.clock("plan"):
            sub, joint_path, trajectory, stretches, index, unliftable = plan_partial(
                r.settings, again.path, again.refusal, r.robot, part, made.surface, replan=again)
    except PlanInfeasible as exc:
        report_unreachable(exc, again.path, r.robot, r.job, r.outdir, made.wp, made.surface,
                           world=collision_world(r.settings, r.robot))
        why = "no stretch is left to program" if exc is again.refusal else str(exc)   # (partial_plan_path)
        raise PlanInfeasible(f"{why}; planned again with {again.left.line(again.path)}", report=exc.report) from None
    tell(sub, joint_path)
    r.log.done("raster", sub)  # the part of the raster that is programmed
    return sub, joint_path, trajectory, stretches, _Origin(again.path, index, again.refusal, unliftable)


def run(job: Job, settings: JobSettings, robot, outdir: Path, log: StageLog, compare: bool = False, *,
        part: JobPart) -> RunResult:
    """Run a raster job; programs, report.json, points.csv and plots go into ``outdir``. ``part``: its
    workpiece and surface (``part_stages.JobPart``)."""
    if settings.planner.method == "arm-angle-sqp":
        raise BadInput(f"{job.path}: planner.method: 'arm-angle-sqp' plans task.kind = 'sequential_reach', "
                       f"not {job.task.kind!r} jobs")
    given = RasterRun(job, settings, robot, Path(outdir), log, compare, part)
    try:
        return _left_out_rounds(given)
    except _LeadsIntoPart as first:
        # first make the motion work: leads lifted clear of the row's tangent, planned again (a neighbouring
        # face that goes on tangentially, a dome on a cylinder); its failure, if it fails too, is the run's
        _log.warning("camtool: the motion check found the tool in the part in a lead (%s); planned again with the "
                     "leads lifted clear of the rows' tangents (raster.lead_path = \"tangent\")", first.finding)
        tangent = replace(settings, raster=replace(settings.raster, lead_path="tangent"))
        return _left_out_rounds(replace(given, settings=tangent, leads_retried=first.finding))


def _left_out_rounds(r: RasterRun) -> RunResult:
    """``_helped_run``; with ``task.allow_partial``, planned again while the motion check fails at poses the partial
    plan can leave out (``check_left_out``: ``CHECK_LEFT_OUT_ROUNDS`` at most; the last failure is the run's)."""
    while True:
        try:
            return _helped_run(r)
        except _CheckLeftOutAgain as failed:
            again = failed.again
            _log.warning("camtool: the motion check failed (%s); planned again with %s (--allow-partial)",
                         again.left.firsts[-1], again.left.line(again.path))
            r = replace(r, again=again)


def _helped_run(r: RasterRun) -> RunResult:
    """``_run`` with its helpers forked, and closed with it."""
    # forked now, while this process plans on one CPU: the figures' and the check's libraries are imported
    # there; the redundancy map's cells are swept and the check's part is made while the path is planned, the
    # map drawn while the trajectory is timed, off the end of the run where the check, the figures and the post
    # stage share the CPUs. numba's compiled code is loaded before the map's and the check's processes fork:
    # its set-up (a quarter of a second) is not paid again there (the map's Jacobians, the check's grid loops)
    with Standby(import_figure_libraries, hand_on=True, nice=5) as figures:
        load_compiled()
        r.log.lap("kernels")
        with Standby(import_figure_libraries, hand_on=True, nice=10) as mapping, \
                Standby(import_part_libraries, hand_on=True) as checking:
            return _run(r, _Helpers(mapping, figures, checking))


class _LeadsIntoPart(Exception):
    """The motion check found the tool in the part in a lead that runs on a segmented face's surface
    continued (``stages.leads_into_part``): the run plans again with the leads lifted clear."""

    def __init__(self, finding: str):
        super().__init__(finding)
        self.finding = finding


@dataclass(frozen=True)
class _Helpers:
    """The processes on standby for a raster run: the redundancy map, the plots and the motion check's."""

    mapping: Standby
    figures: Standby
    checking: Standby

    def rastered(self, settings: JobSettings, wp, path, surface) -> Standby:
        """The motion check's process, told the raster: it builds the part the check measures against from the
        raster's work poses while the run plans, then checks the trajectory it is handed (``then``)."""
        return self.checking.start(partial(_check_part, settings, wp, path, surface))


@dataclass(frozen=True)
class _Alongside:
    """The helpers at work once the raster is made: the motion check's process (told the raster), the figures',
    the map made ahead, and the collision world."""

    checking: Standby
    figures: Standby
    mapping: MapAhead
    world: object


@dataclass(frozen=True)
class _Planned:
    """The plan and time stages' output: the path programmed, its joint path and trajectory, the partial plan's
    figures (None: all planned), the target removal's dwell, the part the checks measure against, and whether
    the helpers were handed the trajectory by the time stage (before its 4 ms check)."""

    path: object
    joint_path: object
    trajectory: object
    partial_figures: dict | None
    dwell: object
    part: object
    handed_ahead: bool
    origin: _Origin | None = None


def _check_part(settings: JobSettings, wp, path, surface, _prepared=None):
    """The motion check's part (``stages.motion_check_part``), made ahead."""
    return motion_check_part(settings, wp, path, surface)


def _timed_check(settings: JobSettings, trajectory, robot, wp, path, surface, part, locate: bool = False):
    """``stages.motion_check`` on the part made ahead, with its (wall, CPU) seconds; ``locate``: a failure names
    the path poses of its samples (``task.allow_partial``)."""
    return timed(partial(motion_check, settings, trajectory, robot, wp, path, surface, part=part, locate=locate))


def _drawn_map(ahead: MapAhead):
    """The map drawn ahead as report.html takes it, or None (drawn there)."""
    drawn = ahead.result()
    return None if drawn is None else drawn.redundancy


def _run(r: RasterRun, helpers: _Helpers) -> RunResult:
    """``run`` with its helpers on standby (``camtool.alongside.Standby``): raster, plan and time, the other
    planner compared, the figures started, post (once the motion check has passed), report."""
    world = collision_world(r.settings, r.robot)
    ahead = MapAhead(helpers.mapping, r.robot, r.outdir, world)
    r, made = _rastered(r)
    ahead.rastered(made.path)
    along = _Alongside(helpers.rastered(r.settings, made.wp, made.path, made.surface), helpers.figures, ahead, world)
    planned = _planned(r, made, along)
    trajectories, compared = _compared(r, planned, made.surface)
    if not planned.handed_ahead or r.compare:
        along.figures.start(partial(draw_run_figures, r.figure_inputs(trajectories)))
    else:   # the joint plots are under way (``plots``): feed.png, from the trajectory sampled by the 4 ms check
        along.figures.then(partial(draw_run_figures, r.figure_inputs(trajectories)))
    # the check and the figures run while the programs are written (cancelled on an error: run)
    programs, simulated, html_figures = _posted(r, made, along, planned)
    report = _run_report(r, made, planned, simulated)
    process, process_files = process_outputs(r.job, r.settings, planned.trajectory, r.robot,
                                             made.surface, r.outdir, dwell=planned.dwell,
                                             extra=None if made.step_choice is None
                                             else {"step_over_auto": made.step_choice})
    if process is not None:
        report["process_map"] = process
    if compared is not None:
        report["compare"] = compared
    return finish_run(r.log, programs, report, planned.path, planned.joint_path, r.robot, trajectories, r.outdir,
                      extra_files=tuple(process_files), world=world, figures=along.figures, mapping=ahead,
                      html_figures=html_figures)


def _rastered(r: RasterRun) -> tuple[RasterRun, Rastered]:
    """The workpiece, fit and raster stages; the run with its settings' step-over chosen (``raster.step_over_mm =
    "auto"``). A job of several faces, or a target removal map it cannot meet, fails before planning."""
    job, log = r.job, r.log
    wp = log.done("workpiece", r.part.workpiece())
    surface = log.done("fit", r.part.surface())
    if isinstance(surface, FaceSet):  # faces.select names several faces: one program for them all
        check_several_faces(job, r.settings)
    check_target_inputs(job, r.settings.process, surface)  # a target removal map it cannot meet: before planning
    settings, step_choice = auto_step_over(r.settings, surface)  # raster.step_over_mm = "auto"
    path, tilt = shaped_for_part(settings, surface, raster_path(surface, settings.raster),
                                 clearance_part(settings, wp, surface), r.robot)
    path = log.done("raster", path)
    return replace(r, settings=settings), Rastered(wp, surface, path, step_choice, tilt)


def _hand_check(r: RasterRun, made: Rastered, checking: Standby, path, trajectory) -> None:
    """Hand ``trajectory`` (of ``path``) to the independent motion check, alongside the rest of the run."""
    checking.then(partial(_timed_check, with_scan_verdict(r.settings, made.wp), trajectory, r.robot, made.wp, path,
                          made.surface, locate=r.job.task.allow_partial))


def _hand_plots(r: RasterRun, figures: Standby, path, trajectory) -> None:
    """Start the joint plots of ``trajectory``: they need no more than the trajectory (feed.png: after the time)."""
    figures.start(partial(draw_joint_plots, r.figure_inputs({r.settings.planner.method: trajectory})))


def _planned(r: RasterRun, made: Rastered, along: _Alongside) -> _Planned:
    """The plan and time stages, the trajectory handed to the motion check (and the joint plots) as soon as it
    is timed, or once timed again for a target removal map."""
    check = partial(_hand_check, r, made, along.checking)
    plots = partial(_hand_plots, r, along.figures)
    # a target removal map times the trajectory again: then the helpers take that one, after the time stage
    handed = Ahead(along.mapping, () if target_removal(r.settings) else (check,) + (() if r.compare else (plots,)))
    part = part_for_checks(r.settings, made.wp, made.surface)
    path, joint_path, trajectory, partial_figures, origin = planned_and_timed(r, made, part, handed)
    r.log.done("plan", joint_path)
    retimed, dwell = retime_for_target(r.job, r.settings, made.surface, path, joint_path, r.robot)  # a target map
    trajectory = trajectory if retimed is None else retimed
    r.log.done("time", trajectory)
    # the post stage places no program before the motion check passed
    if handed.timed_trajectory is None:
        check(path, trajectory)
    elif handed.timed_trajectory is not trajectory:
        raise RuntimeError("the helpers were handed another trajectory than the one programmed")
    return _Planned(path, joint_path, trajectory, partial_figures, dwell, part, handed.timed_trajectory is not None,
                    origin)


def _compared(r: RasterRun, planned: _Planned, surface) -> tuple[dict, dict | None]:
    """(the trajectories by planner method, the other planner's figures or None): with ``compare``, the path
    planned and timed by the other method too, on the same ``surface`` as the first (its failure is a figure)."""
    settings = r.settings
    trajectories = {settings.planner.method: planned.trajectory}
    if not r.compare:
        return trajectories, None
    other = "general" if settings.planner.method == "seed" else "seed"
    try:
        jp2, tr2 = plan_and_time(settings, planned.path, r.robot, other, workpiece=planned.part, surface=surface)
        trajectories[other] = tr2
        compared = run_report(planned.path, jp2, tr2, r.robot, r.job, other)
    except PlanInfeasible as exc:
        compared = {"method": other, "status": "infeasible", "reason": str(exc)}
    r.log.lap("compare")
    return trajectories, compared


def _posted(r: RasterRun, made: Rastered, along: _Alongside, planned: _Planned):
    """(programs, the programs' simulation figures, report.html's figures or None): the post stage, which places
    the programs only once the motion check has passed; a motion-check finding is the run's failure, as when
    the check ran first."""
    log, path, joint_path, trajectory = r.log, planned.path, planned.joint_path, planned.trajectory
    rendered = {}

    def motion_checked():   # the programs are placed only once the motion check has passed
        log.lap("post")
        drawn_map = _drawn_map(along.mapping)
        if drawn_map is not None:   # report.html's figures need no verdict: rendered while the check finishes
            rendered["html"] = figure_sections({"tcp_speed_mm_s": getattr(trajectory, "tcp_speed_mm_s", 0.0)},
                                               r.robot, workpiece=made.wp, surface=made.surface, path=path,
                                               joint_path=joint_path, trajectory=trajectory, world=along.world,
                                               redundancy=drawn_map[0])
            log.lap("report_html")
        figures_, (wall, cpu) = along.checking.result()
        log.alongside_seconds["check"], log.alongside_cpu_seconds["check"] = wall, cpu
        return log.done("check", figures_)

    simulated: dict = {}
    try:
        programs = log.done("post", post_checked(trajectory, r.robot, r.job, r.outdir, path=path, report=simulated,
                                                 before_placing=motion_checked))
    except PlanInfeasible:
        failed = along.checking.failure()   # a motion-check finding is the run's, as when the check ran first
        if not isinstance(failed, PlanInfeasible):
            raise
        along.figures.failure()   # the plots finish: none half-written
        failing = failed.report.pop("failing_path_poses", None)   # with task.allow_partial (``check_left_out``)
        if r.leads_retried is None and leads_into_part(r.settings, failed):
            raise _LeadsIntoPart(str(failed.report["motion_check"]["findings"][0])) from None
        again = _left_out_again(r, planned, failed, failing)
        if again is not None:
            raise _CheckLeftOutAgain(again) from None
        if r.again is not None:   # what the partial plan left out before this check failed too
            failed.report["check_left_out"] = r.again.left.figures(r.again.path)
            failed = PlanInfeasible(f"{failed}; planned again with {r.again.left.line(r.again.path)}",
                                    report=failed.report)
        report_failure(failed, path, joint_path, r.robot, r.job, r.outdir, made.wp, made.surface, world=along.world,
                       redundancy=_drawn_map(along.mapping))
        raise failed from None
    return programs, simulated, rendered.get("html")


def _left_out_again(r: RasterRun, planned: _Planned, failed: PlanInfeasible, failing) -> "_Replan | None":
    """With ``task.allow_partial``, what the run plans again from after its motion check failed at ``failing``
    (``check_left_out.failing_path_poses``): the poses there left out as well; None when none more would be
    (nothing located, out of rounds: the failure is the run's)."""
    origin = planned.origin
    if not (r.job.task.allow_partial and failing and origin is not None):
        return None
    left = r.again.left if r.again is not None else CheckLeftOut()
    first = str(failed.report["motion_check"]["findings"][0])
    grown = left.grown(origin.path, planned.path, origin.index, [tuple(f) for f in failing], first)
    if grown is None:
        return None
    refusal = origin.refusal if origin.refusal is not None else PlanInfeasible("every pose reached", report={})
    return _Replan(origin.path, refusal, origin.unliftable, grown)


class _CheckLeftOutAgain(Exception):
    """The motion check failed at poses a partial plan can leave out (``task.allow_partial``): the run plans
    again from ``again`` (a ``_Replan``)."""

    def __init__(self, again: _Replan):
        super().__init__(again.left.firsts[-1])
        self.again = again


def _plan_events(joint_path) -> dict:
    """The plan's events report.json names: free moves, lifted connectors, leads sized, smoothed runs."""
    events, out = joint_path.events, {}
    if "free_moves" in events:
        out["free_moves"] = events["free_moves"]
    out["lifted_connectors"] = events.get("lifted_connectors", [])
    if "leads" in events:
        out["leads"] = events["leads"]
    out["smoothed_runs"] = events.get("smoothed_runs", [])
    return out


def _run_report(r: RasterRun, made: Rastered, planned: _Planned, simulated: dict) -> dict:
    """report.json's figures of a programmed run up to its status: the run's, the plan's events, the leads
    retried, the partial plan, the motion check, the programs simulated, the faces."""
    motion = r.log.outputs["check"]
    report = run_report(planned.path, planned.joint_path, planned.trajectory, r.robot, r.job,
                        r.settings.planner.method)
    report.update(_plan_events(planned.joint_path))
    if r.leads_retried is not None:
        report["leads_retried"] = {"lead_path": "tangent", "because": r.leads_retried}
    if planned.partial_figures is not None:
        report["partial"] = planned.partial_figures
        if r.again is not None:   # what was left out where the motion check failed, and a line that says so
            report["partial"]["check_left_out"] = {**r.again.left.figures(r.again.path),
                                                   "summary": r.again.left.line(r.again.path)}
    report["motion_check"] = motion
    report["programs_simulated"] = simulated
    tilt = (planned.joint_path.events.get("leads") or {}).get("axis_tilt", made.axis_tilt)
    if tilt is not None:   # the tool axes tilted clear of the part (free-form faces of a mesh)
        report["axis_tilt"] = tilt
    faces_of_job = faces_settings(r.job)
    if faces_of_job.segmented:   # the faces of the part and which the job works (the fit stage's segmentation)
        faces = faces_report(faces_of_job, made.wp)
        if made.several:  # each face worked, in working order: coverage and feed
            faces["worked"] = faces_worked(made.surface, planned.path, planned.trajectory,
                                           sampled_for(planned.trajectory, r.robot, r.settings.timing.check_dt_s),
                                           motion)
        r.log.outputs["faces"] = faces
        report["faces"] = {k: v for k, v in faces.items() if k != "labels"}
    report["limits_ok"] = True  # post_checked passed the independent check
    report["status"] = "ok"
    return report
