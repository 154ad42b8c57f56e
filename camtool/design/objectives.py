"""The arm-design objectives: one planning run of the job per design.

A design sets some of the robot's named lengths (``[params]``, e.g. seed8's
L1 and L3). Its objectives are

- F1 ``length_mm``: the total arm length, the sum of |a| and |d| over the DH
  rows of the revolute joints plus |a| of prismatic ones (seed8:
  L1 + L2 + L3 + L4);
- F2 ``singularities``: the jumps the planner had to handle on the job's
  raster, ``len(events['reverse_plans']) + len(events['retracts'])``;
- F3 ``unreachable``: path poses out of reach. A design with any is INVALID
  (the constraint violation of the optimisers).

To keep one evaluation cheap:

- the raster is computed once per problem and reused (it does not depend on
  the arm); screening uses a coarser raster (step-over and pitch x
  ``coarse``);
- a quick reachability screen plans only the first and last pose of every
  run with the ``general`` method; if any is out of reach the design is
  invalid without a full planning run (``screened`` = True; its unreachable
  count is then a lower bound);
- results are cached per design rounded to the problem's resolution, in
  memory and optionally in a JSON file tied to a fingerprint of the job;
- designs are planned in parallel across processes (``jobs`` > 1).
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path as FsPath

import numpy as np

from .. import __version__
from ..errors import BadInput, PlanInfeasible
from ..job import Job, Section
from ..plan import plan_path
from ..plan.strategy import split_runs
from ..robots.library import robot_toml_data
from ..settings import PlannerSettings
from ..run.job_settings import home_q
from ..run.stages import path_for_job, robot_for_job, surface_for_job, workpiece_for_job
from ..path.toolpath import Path
from ..vary import parse_range
from .. import safe_io

CACHE_VERSION = 1


@dataclass(frozen=True)
class Variable:
    """One design variable: a robot [params] name and its range (mm)."""

    name: str
    lower_mm: float
    upper_mm: float


@dataclass(frozen=True)
class Evaluation:
    """The objectives of one design on one raster."""

    length_mm: float
    singularities: int
    unreachable: int
    screened: bool = False
    planner_runs: int = 0
    plan_s: float = 0.0

    @property
    def valid(self) -> bool:
        return self.unreachable == 0

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def parse_vary(text: str) -> Variable:
    """``NAME=LO:HI`` (mm) -> Variable; BadInput with one clear line otherwise."""
    name, lo, hi = parse_range(text, " in mm, e.g. L1=300:600")
    if lo <= 0:
        raise BadInput(f"--vary {text!r}: lengths must be > 0 mm")
    return Variable(name, lo, hi)


def robot_params(job: Job) -> dict[str, float]:
    """The job robot's named lengths (mm): the robot file's [params] overridden by the job."""

    data = robot_toml_data(job.robot.name, job.dir) or {}
    params = {k: float(v) for k, v in data.get("params", {}).items()}
    params.update({k: float(v) for k, v in job.robot.params.items()})
    return params


def check_variables(job: Job, variables: list[Variable]) -> dict[str, float]:
    """Check the variables against the robot's [params]; returns the robot's params."""
    params = robot_params(job)
    if not variables:
        raise BadInput("no design variable: give at least one --vary NAME=LO:HI")
    seen = set()
    for v in variables:
        if v.name not in params:
            have = ", ".join(params) or "none"
            raise BadInput(f"--vary {v.name}: robot {job.robot.name} has no parameter {v.name!r} (it has {have})")
        if v.name in seen:
            raise BadInput(f"--vary {v.name}: given twice")
        seen.add(v.name)
    return params


def job_with(job: Job, **changes) -> Job:
    """A copy of ``job`` with keys changed: ``job_with(job, raster={'pitch_mm': 20})``."""
    sections = dict(job.sections)
    for name, keys in changes.items():
        sections[name] = Section({**job.sections[name], **keys})
    return dataclasses.replace(job, sections=sections)


def coarse_job(job: Job, factor: float) -> Job:
    """The job with step-over and pitch multiplied by ``factor``."""
    if job.raster.step_over_mm == "auto":  # chosen from the process map by `camtool run` only
        raise BadInput(f'{job.path}: raster.step_over_mm = "auto" is chosen by `camtool run`; a design needs a '
                       "number of mm")
    return job_with(job, raster={"step_over_mm": job.raster.step_over_mm * factor,
                                 "pitch_mm": job.raster.pitch_mm * factor})


def screen_path(path: Path) -> Path:
    """The first and last pose of every run of ``path`` (the reachability screen)."""

    idx = sorted({k for a, b in split_runs(path) for k in (a, b)})
    return Path(path.poses_mm[idx], path.segment[idx], path.point[idx], path.zone[idx],
                path.free_spin, path.step_over_mm, path.pitch_mm)


def arm_length_mm(robot) -> float:
    """Total arm length: |a| + |d| of revolute DH rows plus |a| of prismatic rows (mm)."""
    return float(sum(abs(r.a_mm) + (0.0 if r.prismatic else abs(r.d_mm)) for r in robot.dh))


# -- one design, one process ------------------------------------------------------------

@dataclass(frozen=True)
class _Context:
    """What a worker needs: the job as plain data, the raster(s) and the variable names."""

    job_file: str
    job_data: dict
    path: Path
    screen: Path | None
    names: tuple[str, ...]


_CONTEXT: _Context | None = None


def _set_context(ctx: _Context) -> None:
    global _CONTEXT
    _CONTEXT = ctx


def _job_from(ctx: _Context, params: dict) -> Job:
    sections = {k: Section(v) for k, v in ctx.job_data.items()}
    sections["robot"] = Section({**sections["robot"], "params": params})
    return Job(FsPath(ctx.job_file), sections)


def evaluate_design(ctx: _Context, values) -> Evaluation:
    """Plan the context's raster with the arm of ``values``: screen first, then the full plan."""

    base = {k: float(v) for k, v in ctx.job_data["robot"]["params"].items()}
    params = {**base, **{n: float(v) for n, v in zip(ctx.names, values)}}
    job = _job_from(ctx, params)
    robot = robot_for_job(job)
    length = arm_length_mm(robot)
    planner = PlannerSettings.from_section(job.planner, home_q(job, robot))
    runs, t0 = 0, time.perf_counter()
    if ctx.screen is not None:
        runs += 1
        try:
            plan_path(ctx.screen, robot, planner.with_method("general"))
        except PlanInfeasible as exc:
            return Evaluation(length, 0, max(1, len(exc.report.get("unreachable", []))), True, runs,
                              time.perf_counter() - t0)
    runs += 1
    try:
        jp = plan_path(ctx.path, robot, planner)
    except PlanInfeasible as exc:
        return Evaluation(length, 0, max(1, len(exc.report.get("unreachable", []))), False, runs,
                          time.perf_counter() - t0)
    sing = len(jp.events["reverse_plans"]) + len(jp.events["retracts"])
    return Evaluation(length, sing, 0, False, runs, time.perf_counter() - t0)


def _worker_evaluate(values) -> Evaluation:
    return evaluate_design(_CONTEXT, values)


class DesignProblem:
    """The arm-design problem of one job: evaluate designs (cached, parallel).

    ``evaluate(X)`` returns ``(F, violation)`` with F = [length_mm,
    singularities] and violation = unreachable poses, for ``run_mopso`` and
    the NSGA-II wrapper. Counters: ``requested`` designs, ``planned`` designs
    (cache misses), ``planner_runs`` (screen and full plans), ``plan_s``.
    """

    def __init__(self, job: Job, variables: list[Variable], coarse: float = 4.0, jobs: int = 1,
                 resolution_mm: float = 1.0, screen: bool = True, cache_file: FsPath | None = None):
        if coarse < 1:
            raise BadInput(f"--coarse: expected a factor >= 1, found {coarse}")
        if jobs < 1:
            raise BadInput(f"-j: expected at least 1 process, found {jobs}")
        if resolution_mm <= 0:
            raise BadInput(f"--resolution-mm: expected a number > 0, found {resolution_mm}")
        self.params = check_variables(job, variables)
        self.job, self.variables, self.coarse = job, list(variables), float(coarse)
        self.names = tuple(v.name for v in variables)
        self.lower = np.array([v.lower_mm for v in variables])
        self.upper = np.array([v.upper_mm for v in variables])
        self.resolution_mm, self.jobs, self.use_screen = float(resolution_mm), int(jobs), screen
        self.surface = surface_for_job(job, workpiece_for_job(job))
        self.coarse_job = coarse_job(job, self.coarse)
        self.path = path_for_job(self.coarse_job, self.surface)
        self.full_path = None
        self.cache: dict[tuple, Evaluation] = {}
        self.cache_file = FsPath(cache_file) if cache_file else None
        self.requested = self.planned = self.planner_runs = 0
        self.plan_s = 0.0
        self._pool = None
        self._ctx = self._context(self.coarse_job, self.path)
        if self.cache_file is not None:
            self._load_cache()

    # -- plumbing ---------------------------------------------------------------------
    def _context(self, job: Job, path: Path) -> _Context:
        data = job.as_dict()
        data["robot"] = {**data["robot"], "params": dict(self.params)}
        return _Context(str(job.path), data, path, screen_path(path) if self.use_screen else None, self.names)

    def fingerprint(self) -> str:
        """A hash of everything an evaluation depends on (job, raster factor, variables)."""

        blob = json.dumps({"v": CACHE_VERSION, "camtool": __version__, "job": self.job.as_dict(),
                           "params": self.params, "coarse": self.coarse, "names": self.names,
                           "screen": self.use_screen}, sort_keys=True, default=str)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]

    def _load_cache(self) -> None:
        import os

        if not os.path.lexists(self.cache_file):
            return
        # opened once (a FIFO or device is one line), bounded depth, and its shape checked: never an internal error
        data = safe_io.load_json(safe_io.read_input_bytes(self.cache_file, "manifest"), self.cache_file)
        if not isinstance(data, dict) or data.get("fingerprint") != self.fingerprint():
            return  # another job or setting, or not a cache: start afresh (the file is rewritten by save_cache)
        entries = data.get("entries", {})
        if not isinstance(entries, dict):
            raise BadInput(f"{self.cache_file}: not a camtool design cache (entries is not a table)")
        try:
            for key, ev in entries.items():
                self.cache[tuple(float(x) for x in key.split(","))] = Evaluation(**ev)
        except (TypeError, ValueError, AttributeError) as exc:
            raise BadInput(f"{self.cache_file}: a damaged design cache entry ({type(exc).__name__}); "
                           "remove the file to start afresh") from None

    def save_cache(self) -> None:
        """Write the cache file (if any) through a temporary file."""
        if self.cache_file is None:
            return
        self.cache_file.parent.mkdir(parents=True, exist_ok=True)
        entries = {",".join(repr(x) for x in k): ev.as_dict() for k, ev in sorted(self.cache.items())}
        safe_io.write_file(self.cache_file.parent, self.cache_file.name,
                           json.dumps({"fingerprint": self.fingerprint(), "entries": entries}, indent=1))

    def key(self, x) -> tuple:
        """The cache key of a design: values rounded to the resolution (mm)."""
        r = self.resolution_mm
        return tuple(float(round(round(float(v) / r) * r, 6)) for v in x)

    def _map(self, designs: list[tuple]) -> list[Evaluation]:
        if self.jobs == 1 or len(designs) == 1:
            return [evaluate_design(self._ctx, d) for d in designs]
        if self._pool is None:
            self._pool = ProcessPoolExecutor(self.jobs, initializer=_set_context, initargs=(self._ctx,))
        return list(self._pool.map(_worker_evaluate, designs))

    def close(self) -> None:
        """Shut the worker processes down (the cache file is written too)."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
        self.save_cache()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # -- evaluation ---------------------------------------------------------------------
    def evaluate_many(self, X) -> list[Evaluation]:
        """Evaluations of the designs in the rows of X (coarse raster, cached)."""
        keys = [self.key(x) for x in np.atleast_2d(np.asarray(X, float))]
        self.requested += len(keys)
        todo = list(dict.fromkeys(k for k in keys if k not in self.cache))
        for k, ev in zip(todo, self._map(todo)):
            self.cache[k] = ev
            self.planned += 1
            self.planner_runs += ev.planner_runs
            self.plan_s += ev.plan_s
        return [self.cache[k] for k in keys]

    def evaluate(self, X) -> tuple[np.ndarray, np.ndarray]:
        """(F, violation) of the rows of X: F = [length_mm, singularities], violation = unreachable."""
        evs = self.evaluate_many(X)
        F = np.array([[e.length_mm, e.singularities] for e in evs], float).reshape(-1, 2)
        return F, np.array([e.unreachable for e in evs], float)

    def evaluate_full(self, x) -> Evaluation:
        """One design on the job's FULL-resolution raster (not cached, counted)."""
        if self.full_path is None:
            self.full_path = path_for_job(self.job, self.surface)
            self._full_ctx = self._context(self.job, self.full_path)
        ev = evaluate_design(self._full_ctx, self.key(x))
        self.planner_runs += ev.planner_runs
        self.plan_s += ev.plan_s
        return ev

    def reference(self) -> np.ndarray:
        """The job's current values of the design variables (seed8 defaults: the paper's choice)."""
        return np.array([self.params[n] for n in self.names])
