"""One arm-design study: optimise (MOPSO or NSGA-II), choose, verify, compare.

Choice rule: among the designs found valid on the coarse raster with the
fewest singularities (normally 0), try them shortest first (ties: in design
order) on the job's FULL-resolution raster; the first with 0 unreachable
points and 0 singularities there is chosen. If none of the first
``max_checks`` passes, the verified design with 0 unreachable points and the
fewest singularities is taken; if none is reachable, there is no choice.
The front itself comes from the coarse raster: the shortest 0-singularity
member of the front is the first candidate, and the following ones are the
next-shortest valid designs the swarm met.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path as FsPath

import numpy as np

from .mopso import MopsoSettings, run_mopso
from .objectives import DesignProblem, Evaluation
from .. import safe_io


@dataclass
class DesignStudy:
    """Everything the CLI prints and plots."""

    method: str
    names: tuple
    lower: np.ndarray
    upper: np.ndarray
    narrowed_lower: np.ndarray | None
    narrowed_upper: np.ndarray | None
    X: np.ndarray
    F: np.ndarray
    violation: np.ndarray
    step: np.ndarray
    front_X: np.ndarray
    front_F: np.ndarray
    chosen_X: np.ndarray | None = None
    chosen_full: Evaluation | None = None
    chosen_coarse: Evaluation | None = None
    checks: list = field(default_factory=list)
    reference_X: np.ndarray | None = None
    reference_coarse: Evaluation | None = None
    reference_full: Evaluation | None = None
    evaluations: int = 0
    wall_s: float = 0.0

    @property
    def invalid_X(self) -> np.ndarray:
        bad = self.X[self.violation > 0]
        return np.unique(bad, axis=0) if len(bad) else bad


def choose_design(problem: DesignProblem, X, F, violation, max_checks: int = 8):
    """Apply the choice rule (module doc); returns (x, full Evaluation, checks list)."""
    ok = np.asarray(violation) == 0
    if not ok.any():
        return None, None, []
    Xv, Fv = np.asarray(X)[ok], np.asarray(F)[ok]
    _, first = np.unique(Xv, axis=0, return_index=True)
    Xv, Fv = Xv[first], Fv[first]
    order = np.lexsort((*Xv.T[::-1], Fv[:, 0], Fv[:, 1]))
    checks = []
    for k in order[:max_checks]:
        ev = problem.evaluate_full(Xv[k])
        checks.append((Xv[k].copy(), ev))
        if ev.valid and ev.singularities == 0:
            return Xv[k].copy(), ev, checks
    reachable = [(ev.singularities, ev.length_mm, i) for i, (x, ev) in enumerate(checks) if ev.valid]
    if not reachable:
        return None, None, checks
    i = min(reachable)[2]
    return checks[i][0], checks[i][1], checks


def design_arm(problem: DesignProblem, method: str = "mopso", settings: MopsoSettings = MopsoSettings(),
               seed: int = 0, max_checks: int = 8, on_iteration=None) -> DesignStudy:
    """Run the study on ``problem`` (see module doc); deterministic for a given seed."""
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    if method == "mopso":
        r = run_mopso(problem.evaluate, problem.lower, problem.upper, settings, rng,
                      resolution=problem.resolution_mm, on_iteration=on_iteration)
        study = DesignStudy("mopso", problem.names, problem.lower, problem.upper, r.narrowed_lower,
                            r.narrowed_upper, r.X, r.F, r.violation, r.step, r.front_X, r.front_F,
                            evaluations=r.evaluations)
    elif method == "nsga2":
        from .nsga2 import run_nsga2

        r = run_nsga2(problem.evaluate, problem.lower, problem.upper, settings.budget, settings.particles,
                      seed, resolution=problem.resolution_mm)
        study = DesignStudy("nsga2", problem.names, problem.lower, problem.upper, None, None, r.X, r.F,
                            r.violation, np.ones(len(r.F), int), r.front_X, r.front_F, evaluations=r.evaluations)
    else:
        raise ValueError(f"unknown method {method!r}")
    x, ev, checks = choose_design(problem, study.X, study.F, study.violation, max_checks)
    study.chosen_X, study.chosen_full, study.checks = x, ev, checks
    if x is not None:
        study.chosen_coarse = problem.evaluate_many([x])[0]
    ref = problem.reference()
    study.reference_X = ref
    study.reference_coarse = problem.evaluate_many([ref])[0]
    study.reference_full = problem.evaluate_full(ref)
    study.wall_s = time.perf_counter() - t0
    return study


def write_chosen_job(problem: DesignProblem, x, file: FsPath) -> FsPath:
    """A copy of the job with robot.params set to design ``x`` and every file name absolute."""
    import tomli_w

    job = problem.job
    data = job.as_dict()
    data["workpiece"]["file"] = str(job.resolve(data["workpiece"]["file"]).resolve())
    from ..robots import BUILTIN_ROBOTS

    if data["robot"]["name"] not in BUILTIN_ROBOTS:
        data["robot"]["name"] = str(job.resolve(data["robot"]["name"]).resolve())
    data["post"]["profiles"] = {k: str(job.resolve(v).resolve()) for k, v in data["post"]["profiles"].items()}
    params = {**job.robot.params, **{n: round(float(v), 6) for n, v in zip(problem.names, x)}}
    data["robot"]["params"] = params
    file = FsPath(file)
    file.parent.mkdir(parents=True, exist_ok=True)
    header = (f"# Written by `camtool design`: {safe_io.comment_text(job.path.name)} with the chosen arm "
              + ", ".join(f"{n} = {params[n]:g} mm" for n in problem.names) + "\n")
    safe_io.write_file(file.parent, file.name, header + tomli_w.dumps(data))
    return file


def write_chosen_robot(problem: DesignProblem, x, file: FsPath) -> FsPath | None:
    """The robot's DH TOML with [params] set to the chosen design (None for URDF robots)."""
    import tomli_w

    from ..robots.library import robot_toml_data

    job = problem.job
    data = robot_toml_data(job.robot.name, job.dir)
    if data is None:
        return None
    data["params"] = {**problem.params, **{n: round(float(v), 6) for n, v in zip(problem.names, x)}}
    file = FsPath(file)
    file.parent.mkdir(parents=True, exist_ok=True)
    safe_io.write_file(file.parent, file.name, tomli_w.dumps(data))
    return file
