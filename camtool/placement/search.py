"""``camtool place``: search the workpiece placement that the robot reaches best.

    job -> robot, workpiece, surface, path (once, at the job's placement)
        -> raster screen over the user's bounds (every placement: the path moved rigidly)
        -> local refinement round the best
        -> full closed-form check (every pose) of the best few, their work feed by the time law; reranked
        -> full planning and timing of the best few (the real pipeline on the placed job)
        -> the chosen placement, the ranked list, placed_job.toml, the feasible-region PNG
        (none plans: the same again with the part's roll and pitch, its tilt on the fixture: ``tilt.py``)

The screen and the cost are in ``screen.py``; the plot in ``plots.py``.
Everything is deterministic for a seed, whatever the number of processes:
each placement's screen is a pure function of its offset, the refinement
draws from ``numpy.random.default_rng(seed)`` in the parent process, and the
planner takes its own seed from the job.
"""
from __future__ import annotations

import dataclasses
import math
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path as FsPath

import numpy as np

from ..collision.spec import obstacle_specs
from ..errors import BadInput, PlanInfeasible
from ..job import Job, Section
from ..run.job_settings import JobSettings
from ..vary import parse_range
from ..run.stages import path_for_job, robot_for_job, surface_for_job, time_for_job, workpiece_for_job
from .kinematics import screen_model
from .margins import reach_margins
from .part_clear import PartClearance
from .screen import AXES, UNITS, PathGeometry, ScreenResult, ScreenSettings, placement_matrix, screen_batch
from .tilt import MAX_TILT_DEG, TILT_AXES, TiltSettings, is_tilted, placed_pose
from .. import safe_io

DEFAULT_VARY = ("x=-300:300", "y=-300:300", "z=-300:300")
DEFAULT_STEP = {"x": 25.0, "y": 25.0, "z": 25.0, "yaw": 5.0, "roll": 5.0, "pitch": 5.0}
RESOLUTION = {"x": 1.0, "y": 1.0, "z": 1.0, "yaw": 0.5, "roll": 0.5, "pitch": 0.5}   # placements rounded to this (mm, deg)
GRID_MAX = 1000          # grid placements screened at most
REFINE_TOP = 5           # best placements refined round
REFINE_ROUNDS = 3        # each halves the step
REFINE_RANDOM = 4        # random neighbours per placement and round (seeded)
CHUNK = 24               # placements per process task
FULL_CHECKS = 12         # best placements checked on every pose (their feed timed) before the best of them are planned
PROBE_SHARE = 8          # a failed tilt stage probes the tilts beyond its bound on 1/8 of the upright grid
KEEP_USER_WITHIN = 0.01  # your placement stays when it plans and costs at most 1 % more than the best


@dataclass(frozen=True)
class Variable:
    """One placement variable: x, y, z (mm, world frame), yaw (deg about world z) or the tilt's roll and pitch
    (deg about world x and y, ``tilt.py``), as an offset range."""

    name: str
    lower: float
    upper: float

    @property
    def unit(self) -> str:
        return UNITS[self.name]

    @property
    def axis(self) -> int:
        return AXES.index(self.name)


def parse_vary(text: str) -> Variable:
    """``NAME=LO:HI`` with NAME one of x, y, z (mm), yaw, roll or pitch (deg) -> Variable; BadInput otherwise."""
    name, lo, hi = parse_range(text, ", e.g. z=-300:100 (mm) or yaw=-30:30 (deg)", lambda n: UNITS.get(n, "mm"))
    if name not in AXES:
        raise BadInput(f"--vary {text!r}: unknown variable {name!r}; use x, y, z (mm), yaw, roll or pitch (deg)")
    if name == "yaw" and hi - lo > 360.0:
        raise BadInput(f"--vary {text!r}: a yaw range wider than 360 deg repeats itself")
    if name in TILT_AXES and max(abs(lo), abs(hi)) > 90.0:
        raise BadInput(f"--vary {text!r}: a {name} beyond +-90 deg turns the part away from the robot")
    return Variable(name, lo, hi)


def check_variables(variables) -> list[Variable]:
    seen = set()
    for v in variables:
        if v.name in seen:
            raise BadInput(f"--vary {v.name}: given twice")
        seen.add(v.name)
    return sorted(variables, key=lambda v: v.axis)


# --------------------------------------------------------------------------- the placed job


def placement_of(job: Job, offset, tilt_centre_mm=None) -> tuple[list[float], list[float]]:
    """(cell.workpiece_xyz_mm, cell.workpiece_rpy_deg) of ``job`` moved by ``offset`` (dx, dy, dz, dyaw[, droll,
    dpitch]); a tilt turns the part about ``tilt_centre_mm`` (``tilt.py``: the path's work centre)."""
    if is_tilted(offset):
        D = placement_matrix(offset, job.cell.workpiece_xyz_mm, tilt_centre_mm)
        return placed_pose(job.cell.workpiece_xyz_mm, job.cell.workpiece_rpy_deg, D)
    xyz = [float(a) + float(d) for a, d in zip(job.cell.workpiece_xyz_mm, offset[:3])]
    r, p, y = (float(a) for a in job.cell.workpiece_rpy_deg)
    yaw = (y + float(offset[3]) + 180.0) % 360.0 - 180.0
    return [round(v, 6) for v in xyz], [r, p, round(yaw, 6)]


def placed_job(job: Job, offset, tilt_centre_mm=None) -> Job:
    """A copy of ``job`` with the workpiece placement moved by ``offset``."""
    xyz, rpy = placement_of(job, offset, tilt_centre_mm)
    sections = dict(job.sections)
    sections["cell"] = Section({**job.sections["cell"], "workpiece_xyz_mm": xyz, "workpiece_rpy_deg": rpy})
    return dataclasses.replace(job, sections=sections)


def write_placed_job(job: Job, offset, file: FsPath, overrides=None, note: str = "", tilt_centre_mm=None) -> FsPath:
    """The job with the moved placement, as TOML; `camtool run FILE` runs it.

    With ``overrides`` (the ``--set`` texts the job was loaded with, possibly
    empty) the file holds the keys of the job file as written plus the
    overrides, so every other key keeps its schema default as the original job
    does; without, every key is written out. File names become absolute.
    """

    import tomli_w

    from ..job import parse_override
    from ..robots import BUILTIN_ROBOTS

    xyz, rpy = placement_of(job, offset, tilt_centre_mm)
    if overrides is None:
        data = placed_job(job, offset, tilt_centre_mm).as_dict()
    else:
        data = safe_io.load_toml(job.path, "job")  # one checked read, never the name by a plain open
        for text in overrides:
            section, key, value = parse_override(text)
            data.setdefault(section, {})[key] = value
        data.setdefault("cell", {})
        data["cell"]["workpiece_xyz_mm"], data["cell"]["workpiece_rpy_deg"] = xyz, rpy
    wp = data.get("workpiece", {})
    if wp.get("file"):
        wp["file"] = str(job.resolve(wp["file"]).resolve())
    rob = data.get("robot", {})
    if rob.get("name") and rob["name"] not in BUILTIN_ROBOTS:
        rob["name"] = str(job.resolve(rob["name"]).resolve())
    post = data.get("post", {})
    if post.get("profiles"):
        post["profiles"] = {k: str(job.resolve(v).resolve()) for k, v in post["profiles"].items()}
    file = FsPath(file)
    file.parent.mkdir(parents=True, exist_ok=True)
    header = (f"# Written by `camtool place`: {safe_io.comment_text(job.path.name)} with the workpiece at cell.workpiece_xyz_mm = "
              f"{[round(v, 3) for v in xyz]}, cell.workpiece_rpy_deg = {[round(v, 3) for v in rpy]}"
              f" (moved by {format_offset(offset)}){note}\n")
    safe_io.write_file(file.parent, file.name, header + tomli_w.dumps(data))
    return file


def format_offset(offset) -> str:
    dx, dy, dz, dyaw = offset[:4]
    s = f"dx {dx:+g} mm, dy {dy:+g} mm, dz {dz:+g} mm"
    s += f", yaw {dyaw:+g} deg" if dyaw else ""
    return s + (f", tilted roll {offset[4]:+g} deg, pitch {offset[5]:+g} deg" if is_tilted(offset) else "")


# --------------------------------------------------------------------------- worker context


@dataclass(frozen=True)
class _Context:
    """What a process needs: the job (to build the robot), the path geometry and the settings."""

    job: Job
    free_spin: bool
    geom: PathGeometry
    settings: ScreenSettings


_CTX: dict = {}


def _set_context(ctx: _Context) -> None:
    _CTX["ctx"] = ctx
    robot = robot_for_job(ctx.job)
    _CTX["model"] = screen_model(robot, JobSettings.from_job(ctx.job, robot), ctx.free_spin)


def _screen_chunk(offsets, full: bool) -> list[ScreenResult]:
    ctx = _CTX["ctx"]
    return screen_batch(_CTX["model"], ctx.geom, offsets, ctx.settings, full=full)


def _verify(offset) -> dict:
    ctx = _CTX["ctx"]
    return verify_placement(ctx.job, offset, ctx.settings, ctx.geom.tilt_centre_mm)


def verify_placement(job: Job, offset, settings: ScreenSettings, tilt_centre_mm=None) -> dict:
    """The real pipeline on the placed job (fit, raster, plan, time, the independent limit check): what
    `camtool run` does before its motion check and the post stage.

    Returns ``ok`` (0 unreachable poses, the timed trajectory within limits),
    the cycle time and the planned run's margins (``reach_margins``) with
    their penalty (``plan_penalty``); the cost is set by the search
    (``PlacementProblem.planned_cost``).
    """
    from ..run import stages
    from ..timing import feed_profile, feed_statistics, limit_findings, sampled_for
    from ..timing.pathlaw import remembered_runs

    t0 = time.perf_counter()
    pj = placed_job(job, offset, tilt_centre_mm)
    robot = robot_for_job(pj)
    st = JobSettings.from_job(pj, robot)
    wp = workpiece_for_job(pj)
    try:
        surface = surface_for_job(pj, wp)
        path = path_for_job(pj, surface)
    except BadInput as exc:   # the part rastered again at another placement (a tilt: a world-dependent raster)
        if not any(float(v) for v in offset):
            raise
        return {"offset": [float(v) for v in offset], "poses": 0, "ok": False, "unreachable": 0, "cost": math.inf,
                "reason": f"the placed job is refused: {exc}", "seconds": round(time.perf_counter() - t0, 3)}
    part_for_checks = stages.part_for_checks     # as the raster task plans
    part = part_for_checks(st, wp, surface) if part_for_checks is not None else wp
    out = {"offset": [float(v) for v in offset], "poses": len(path)}
    try:
        with remembered_runs():   # as the raster task plans and times
            path, jp = stages.plan_with_sized_leads(st, surface, path, robot, part)
            tr = time_for_job(st, jp, path, robot)
    except PlanInfeasible as exc:
        out.update(ok=False, unreachable=len(exc.report.get("unreachable", [])), reason=str(exc), cost=math.inf,
                   seconds=round(time.perf_counter() - t0, 3))
        return out
    findings = limit_findings(tr, robot, st.timing.check_dt_s)
    m = reach_margins(path, jp, robot, orientation_mm=st.planner.orientation_weight_mm,
                      track_scale_mm=st.planner.track_scale_mm)
    jm = m["joint_limit"]["min_share"] if m["joint_limit"] else None
    used = m["reach"]["max_used_pct"] / 100.0 if m["reach"] else None
    dex = m["manipulability"]["dexterity_min"] if m["manipulability"] else None
    pen = settings.penalty(jm, used, dex)
    ok = not findings
    feed = float(getattr(tr, "tcp_speed_mm_s", 0.0) or 0.0)
    if ok and feed > 0:   # the work feed the timed run holds, as report.json's work_feed
        wf = feed_statistics(feed_profile(tr, sampled_for(tr, robot, st.timing.check_dt_s)), feed)
        if wf.get("median_work_feed_mm_s") is not None:
            out.update(feed_mm_s=round(float(wf["median_work_feed_mm_s"]), 3),
                       feed_min_mm_s=round(float(wf["min_work_feed_mm_s"]), 3),
                       feed_share=round(float(wf["median_work_feed_mm_s"]) / feed, 5))
    out.update(ok=ok, unreachable=0, cycle_s=round(tr.duration_s, 3),
               reverse_plans=len(jp.events.get("reverse_plans", [])), retracts=len(jp.events.get("retracts", [])),
               limit_findings=len(findings), margins=m, plan_penalty=round(pen, 5), cost=math.inf,
               seconds=round(time.perf_counter() - t0, 3))
    if findings:
        out["reason"] = f"the timed trajectory breaks {len(findings)} limit(s); first: {findings[0]}"
    return out


# --------------------------------------------------------------------------- the search


def rank_key(r: ScreenResult):
    """Feasible first by cost (then the smaller move); infeasible by how far they got and how much fails."""
    move = float(np.linalg.norm(r.offset[:3])) + sum(abs(a) for a in r.offset[3:])
    if r.feasible:
        return (0, round(r.cost, 6), round(move, 6), r.offset)
    stage = {"full": 1, "ik": 2, "bound": 3, "part": 4}[r.stage]
    return (stage, r.unreachable / max(r.checked, 1), round(r.reach_used, 6), round(move, 6), r.offset)


def grid_values(variables: list[Variable], max_points: int = GRID_MAX) -> list[np.ndarray]:
    """Per variable, evenly spaced values over its range: DEFAULT_STEP, coarsened so the grid has at most
    ``max_points`` placements (at least 3 values per variable)."""
    n = np.array([int(math.ceil((v.upper - v.lower) / DEFAULT_STEP[v.name])) + 1 for v in variables], float)
    while np.prod(n) > max_points and np.any(n > 3):
        f = (np.prod(n) / max_points) ** (1.0 / len(n))
        n = np.maximum(3, np.floor(n / max(f, 1.0001)))
    return [np.unique(_snap(v.name, np.linspace(v.lower, v.upper, int(k)))) for v, k in zip(variables, n)]


def _snap(name: str, x):
    """Values rounded to the search resolution (RESOLUTION: 1 mm, 0.5 deg)."""
    r = RESOLUTION[name]
    return np.round(np.asarray(x, float) / r) * r + 0.0


def zero_offset(variables: list[Variable]) -> tuple:
    """The job's own placement: (0, 0, 0, 0), or (0, 0, 0, 0, 0, 0) when the part's tilt is searched."""
    return (0.0,) * (6 if any(v.name in TILT_AXES for v in variables) else 4)


def _full_offset(variables: list[Variable], x) -> tuple:
    off = list(zero_offset(variables))
    for v, val in zip(variables, x):
        off[v.axis] = round(float(np.clip(_snap(v.name, val), v.lower, v.upper)), 6)
    return tuple(off)


@dataclass
class PlacementStudy:
    """Everything ``camtool place`` prints, plots and writes."""

    job: Job
    robot_name: str
    families: str
    variables: list
    grid: list
    results: dict = field(default_factory=dict)        # offset -> ScreenResult (every placement screened)
    grid_offsets: list = field(default_factory=list)
    user: ScreenResult | None = None
    finalists: list = field(default_factory=list)      # ScreenResult, full screen, in rank order
    verified: dict = field(default_factory=dict)       # offset -> verify_placement dict
    chosen: tuple | None = None
    n_poses: int = 0
    n_ik_poses: int = 0
    screen_s: float = 0.0
    verify_s: float = 0.0
    wall_s: float = 0.0
    processes: int = 1
    tilt_centre_mm: np.ndarray | None = None           # the tilt's pivot (tilt.work_centre)
    upright: dict | None = None                        # the search before the tilt, when it found none
    beyond: dict | None = None                         # the tilt found none: the wider tilt's screen (_beyond)

    @property
    def zero(self) -> tuple:
        """The job's own placement's offset."""
        return zero_offset(self.variables)

    @property
    def grid_step(self) -> np.ndarray:
        return np.array([(g[1] - g[0]) if len(g) > 1 else (v.upper - v.lower)
                         for g, v in zip(self.grid, self.variables)])

    def ranked(self, top: int = 10) -> list[ScreenResult]:
        """The best screened placements (feasible ones by cost), at most ``top``, each at least one grid step
        (in some variable) from every better one; the chosen and planned placements are always listed."""
        must = [r for r in sorted(self.results.values(), key=rank_key) if r.offset in self.verified
                and r.offset != zero_offset(self.variables)]
        rest = distinct(sorted(self.results.values(), key=rank_key), self.variables, self.grid_step, top, must)
        return sorted(rest, key=rank_key)[:max(top, len(must))]

    @property
    def feasible_count(self) -> int:
        return sum(r.feasible for r in self.results.values())


class PlacementProblem:
    """The placement search of one job (module doc); ``with`` closes its worker processes."""

    def __init__(self, job: Job, variables: list[Variable], jobs: int = 1, settings: ScreenSettings | None = None,
                 tilt: TiltSettings = TiltSettings()):
        if job.task.kind != "raster":
            raise BadInput(f"{job.path}: task.kind = {job.task.kind!r}: camtool place searches the placement of "
                           "raster jobs only")
        if jobs < 1:
            raise BadInput(f"-j: expected at least 1 process, found {jobs}")
        self.job, self.variables, self.jobs, self.tilt = job, check_variables(variables), int(jobs), tilt
        self.robot = robot_for_job(job)
        st = JobSettings.from_job(job, self.robot)
        if st.planner.method == "arm-angle-sqp":
            raise BadInput(f"{job.path}: planner.method = 'arm-angle-sqp' does not plan raster jobs")
        self.settings = settings or ScreenSettings(orientation_mm=st.planner.orientation_weight_mm,
                                                   track_scale_mm=st.planner.track_scale_mm,
                                                   tcp_speed_mm_s=st.timing.tcp_speed_mm_s)
        self.workpiece = workpiece_for_job(job)
        self.surface = surface_for_job(job, self.workpiece)
        self.path = path_for_job(job, self.surface)
        self.model = screen_model(self.robot, st, self.path.free_spin)
        if self.model is None:
            raise BadInput(f"robot {self.robot.name}: camtool place screens with closed-form IK families (SRS 7R "
                           "arm, a linear track + SRS arm, or a 6R spherical wrist); this robot has none")
        self.geom = PathGeometry.build(self.path, self.model, self.robot, job.cell.workpiece_xyz_mm, self.settings)
        self._ctx = _Context(job, self.path.free_spin, self.geom, self.settings)
        self.part_clear = PartClearance(self.workpiece, st.cell, obstacle_specs(job.cell.obstacles), self._moved)
        self._pool = None

    # -- plumbing --------------------------------------------------------------------------
    def _pool_get(self):
        if self._pool is None:
            self._pool = ProcessPoolExecutor(self.jobs, initializer=_set_context, initargs=(self._ctx,))
        return self._pool

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _moved(self, offset) -> np.ndarray:
        """The world transform of a placement offset (the part's move from the job's placement)."""
        return placement_matrix(offset, self.geom.pivot_mm, self.geom.tilt_centre_mm)

    def screen(self, offsets, full: bool = False) -> list[ScreenResult]:
        """Screen placements (in order), in ``jobs`` processes when there are many; the part kept clear of the
        cell's world-fixed obstacles and floor (``part_clear``)."""
        offsets = [tuple(o) for o in offsets]
        if not offsets:
            return []
        if self.jobs == 1 or len(offsets) <= CHUNK // 2 and not full:
            return self.part_clear.refuse(screen_batch(self.model, self.geom, offsets, self.settings, full=full))
        size = 1 if full else CHUNK
        chunks = [offsets[a:a + size] for a in range(0, len(offsets), size)]
        out = []
        for part in self._pool_get().map(_screen_chunk, chunks, [full] * len(chunks)):
            out.extend(part)
        return self.part_clear.refuse(out)

    def verify(self, offsets) -> list[dict]:
        """The real pipeline on each placed job (``verify_placement``), in ``jobs`` processes."""
        offsets = [tuple(o) for o in offsets]
        if self.jobs == 1 or len(offsets) == 1:
            return [verify_placement(self.job, o, self.settings, self.geom.tilt_centre_mm) for o in offsets]
        return list(self._pool_get().map(_verify, offsets))

    # -- the search ----------------------------------------------------------------------------
    def run(self, seed: int = 0, verify: int = 3, max_checks: int = 9, grid_max: int = GRID_MAX,
            on_progress=None) -> PlacementStudy:
        """Screen the grid, refine, check and verify the best (module doc); when nothing plans with the part as it
        stands, the same with its tilt (``tilt.py``)."""
        t0 = time.perf_counter()
        say = on_progress or (lambda msg: None)
        V = self.variables
        study = self._search(V, grid_values(V, grid_max), seed, verify, max_checks, say)
        if study.chosen is None and self.tilt.enabled and not any(v.name in TILT_AXES for v in V):
            study = self._tilted(study, seed, verify, max_checks, say)
        study.wall_s = time.perf_counter() - t0
        return study

    def _tilted(self, upright: PlacementStudy, seed: int, verify: int, max_checks: int, say) -> PlacementStudy:
        """The search again with the part's roll and pitch (``TiltSettings``): the upright search's grid at every
        tilt of the coarse tilt grid, refined round the best; the job's own placement is not planned twice."""
        t = self.tilt
        values = np.unique(_snap("roll", t.values_deg()))
        V = self.variables + [Variable(a, -t.max_deg, t.max_deg) for a in TILT_AXES]
        say(f"no placement plans with the part as it stands: tilting it (roll, pitch within +-{t.max_deg:g} deg)")
        known = upright.verified.get(zero_offset(self.variables))
        study = self._search(V, list(upright.grid) + [values, values], seed, verify, max_checks, say, known)
        best = sorted(upright.results.values(), key=rank_key)[0]
        study.upright = {"placements": len(upright.results), "feasible": upright.feasible_count,
                         "planned": len(upright.verified), "best": best.as_dict(), "seconds": round(upright.wall_s, 3)}
        study.screen_s += upright.screen_s
        study.verify_s += upright.verify_s
        if study.chosen is None and t.max_deg < MAX_TILT_DEG:
            study.beyond = self._beyond(V, grid_values(self.variables, max(8, len(upright.grid_offsets) // PROBE_SHARE)))
        return study

    def _beyond(self, V: list[Variable], grid: list[np.ndarray]) -> dict | None:
        """What a wider tilt would do: the coarse tilts out to +-90 deg (``TiltSettings(90)``) beyond the bound,
        screened on a coarser grid (1 / PROBE_SHARE of the upright one); the best that passes the screen (not
        planned), or None."""
        t = self.tilt
        values = TiltSettings(MAX_TILT_DEG).values_deg()
        tilts = [(r, p) for r in values for p in values if max(abs(r), abs(p)) > t.max_deg + 1e-9]
        mesh = np.meshgrid(*grid, indexing="ij")
        offs = []
        for x in zip(*(m.ravel() for m in mesh)):
            base = list(_full_offset(V, list(x) + [0.0, 0.0]))   # the tilt set past V's bound below
            offs += [tuple(base[:4] + [float(r), float(p)]) for r, p in tilts]
        ok = sorted((r for r in self.screen(offs) if r.feasible), key=rank_key)
        if not ok:
            return {"max_deg": MAX_TILT_DEG, "screened": len(offs), "offset": None}
        o = ok[0].offset
        return {"max_deg": float(max(abs(o[4]), abs(o[5]))), "screened": len(offs), "offset": list(o),
                "passing": len(ok)}

    def _search(self, V: list[Variable], grid: list[np.ndarray], seed: int, verify: int, max_checks: int, say,
                known: dict | None = None) -> PlacementStudy:
        """One search over the variables ``V`` from the grid ``grid`` (module doc); ``known``: the job's own
        placement, already planned."""
        t0 = time.perf_counter()
        study = PlacementStudy(self.job, self.robot.name, self.model.families, V, grid, n_poses=len(self.path),
                               n_ik_poses=len(self.geom.sub), processes=self.jobs,
                               tilt_centre_mm=self.geom.tilt_centre_mm)
        mesh = np.meshgrid(*grid, indexing="ij")
        grid_offsets = [_full_offset(V, x) for x in zip(*(m.ravel() for m in mesh))]
        user = zero_offset(V)
        todo = list(dict.fromkeys([user, *grid_offsets]))
        for r in self.screen(todo):
            study.results[r.offset] = r
        study.grid_offsets = grid_offsets
        study.user = study.results[user]
        if known is not None:
            study.verified[user] = {**known, "offset": list(user)}
        say(f"screened {len(todo)} grid placements: {study.feasible_count} feasible")
        self._refine(study, np.random.default_rng(seed), say)
        study.screen_s = time.perf_counter() - t0
        self._plan_best(study, verify, max_checks, say)
        study.wall_s = time.perf_counter() - t0
        return study

    def _refine(self, study: PlacementStudy, rng, say) -> None:
        """Local refinement round the best: axis neighbours and seeded random ones, the step halving."""
        V = study.variables
        step = study.grid_step
        for rnd in range(REFINE_ROUNDS):
            step = step / 2.0
            tops = self._tops(study, REFINE_TOP)
            cand = []
            for r in tops:
                x = np.array([r.offset[v.axis] for v in V])
                for k in range(len(V)):
                    for sgn in (-1.0, 1.0):
                        y = x.copy()
                        y[k] += sgn * step[k]
                        cand.append(y)
                for _ in range(REFINE_RANDOM):
                    cand.append(x + step * rng.uniform(-1.0, 1.0, len(V)))
            offs = [_full_offset(V, y) for y in cand]
            offs = [o for o in dict.fromkeys(offs) if o not in study.results]
            for r in self.screen(offs):
                study.results[r.offset] = r
            say(f"refinement {rnd + 1}: {len(offs)} placements, {study.feasible_count} feasible in all")

    def _plan_best(self, study: PlacementStudy, verify: int, max_checks: int, say) -> None:
        """The best few: closed-form check of every pose, then the real pipeline; the chosen placement."""
        t1 = time.perf_counter()
        V = study.variables
        user = zero_offset(V)
        feasible = [r for r in sorted(study.results.values(), key=rank_key) if r.feasible]
        picked = distinct(feasible, V, study.grid_step / 2.0, max(max_checks, FULL_CHECKS))
        full = self.screen([r.offset for r in picked], full=True)   # every pose, the feed by the time law
        for r in full:
            study.results[r.offset] = r
        passed = sorted((r for r in full if r.feasible), key=rank_key)[:max_checks]
        say(f"checked {len(picked)} of the best placements on every pose: {len(passed)} to plan")
        for a in range(0, len(passed), max(verify, 1)):
            group = passed[a:a + max(verify, 1)]
            study.finalists += group
            batch = [r.offset for r in group] + ([user] if user not in study.verified else [])
            for o, v in zip(batch, self.verify(batch)):
                study.verified[o] = self.planned_cost(study, o, v)
            n_ok = sum(v["ok"] for o, v in study.verified.items() if o != user)
            say(f"planned {len(study.verified)}: {n_ok} plan with 0 unreachable poses")
            if n_ok:
                break
        if user not in study.verified:  # nothing passed the screen: still plan the user's placement
            study.verified[user] = self.planned_cost(study, user, self.verify([user])[0])
        ok = [(v["cost"], o) for o, v in study.verified.items() if v["ok"]]
        study.chosen = min(ok)[1] if ok else None
        mine = study.verified.get(user)
        if ok and mine is not None and mine["ok"] and mine["cost"] <= min(ok)[0] * (1.0 + KEEP_USER_WITHIN):
            study.chosen = user  # not worth moving the part for
        study.verify_s = time.perf_counter() - t1

    def planned_cost(self, study: PlacementStudy, offset, v: dict) -> dict:
        """The planned cost of a placement: cycle time x (1 + the placement's margin penalty) x (1 + move term)
        x (1 + the feed term of the planned run's median work feed).

        The penalty is the screen's on every pose (the placement's own margins: the
        best closed-form solution per pose); where the screen did not pass (the
        user's placement may plan although the screen is stricter), the planned
        run's. ``inf`` when the plan failed.
        """
        v = dict(v)
        if not v["ok"]:
            return v
        r = study.results.get(tuple(offset))
        if r is not None and r.feasible and not r.full_checked:
            r = study.results[tuple(offset)] = self.screen([tuple(offset)], full=True)[0]
        if r is not None and r.feasible:
            v["penalty"], v["penalty_from"] = round(r.penalty, 5), "screen"
        else:
            v["penalty"], v["penalty_from"] = v["plan_penalty"], "plan"
        v["cost"] = round(self.settings.cost(v["cycle_s"], v["penalty"], offset, v.get("feed_share")), 3)
        return v

    def _tops(self, study: PlacementStudy, n: int) -> list[ScreenResult]:
        """The n best placements to refine round (feasible first; the least infeasible when none is)."""
        return sorted(study.results.values(), key=rank_key)[:n]



def distinct(ranked: list[ScreenResult], variables, min_step, n: int, kept=()) -> list[ScreenResult]:
    """Up to n placements in rank order (after ``kept``), each at least ``min_step`` away in some variable from
    every one kept before it."""
    kept = list(kept)

    def x(r):
        return np.array([r.offset[v.axis] for v in variables])
    for r in ranked:
        if len(kept) >= n:
            break
        if r in kept:
            continue
        if all(np.any(np.abs(x(r) - x(k)) >= np.asarray(min_step) - 1e-9) for k in kept):
            kept.append(r)
    return kept


def place_job(job: Job, variables: list[Variable], jobs: int = 1, seed: int = 0, verify: int = 3,
              max_checks: int = 9, grid_max: int = GRID_MAX, on_progress=None,
              tilt: TiltSettings = TiltSettings()) -> PlacementStudy:
    """Search ``job``'s workpiece placement over ``variables`` (module doc)."""
    with PlacementProblem(job, variables, jobs, tilt=tilt) as problem:
        return problem.run(seed, verify, max_checks, grid_max, on_progress)
