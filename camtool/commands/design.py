"""``camtool design``: choose a parametric arm's link lengths for a job (two-step MOPSO)."""
from __future__ import annotations

import time
from pathlib import Path

import click

from ..console import echo_json, progress_enabled
from ..errors import BadInput, PlanInfeasible
from .. import safe_io
from ..job import load_job

DEFAULT_VARY = ("L1=300:600", "L3=300:500")
PAPER_CHOICE = {"L1": 480.0, "L3": 418.0}  # Sun et al. 2023, section 2.2


def _design_dict(names, x) -> dict:
    return {n: round(float(v), 3) for n, v in zip(names, x)}


def _eval_dict(ev) -> dict | None:
    return None if ev is None else {"length_mm": round(ev.length_mm, 3), "singularities": ev.singularities,
                                    "unreachable": ev.unreachable, "valid": ev.valid}


@click.command("design")
@click.argument("job_file", metavar="JOB", type=click.Path(path_type=Path))
@click.option("--vary", "vary", multiple=True, metavar="NAME=LO:HI",
              help="A robot length to optimise and its range in mm (repeatable; default L1=300:600 and L3=300:500).")
@click.option("--particles", type=int, default=12, show_default=True, help="Swarm size (NSGA-II: population).")
@click.option("--iters", type=int, default=5, show_default=True, help="Step-2 (optimise) iterations.")
@click.option("--explore-iters", type=int, default=3, show_default=True, help="Step-1 (explore) iterations.")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed: the same seed gives the same run.")
@click.option("-j", "--jobs", type=int, default=1, show_default=True, help="Processes that plan designs in parallel.")
@click.option("--method", type=click.Choice(["mopso", "nsga2"]), default="mopso", show_default=True,
              help="mopso = the paper's two-step MOPSO; nsga2 = pymoo's NSGA-II at the same evaluation budget.")
@click.option("--coarse", type=float, default=4.0, show_default=True,
              help="Screening raster: step-over and pitch times this factor.")
@click.option("--resolution-mm", type=float, default=1.0, show_default=True,
              help="Designs are rounded to this (mm); the cache key.")
@click.option("--max-checks", type=int, default=8, show_default=True,
              help="Candidates verified on the full-resolution raster before giving up on 0 singularities.")
@click.option("--cache", "cache_file", type=click.Path(path_type=Path), default=None, metavar="FILE.json",
              help="Keep evaluations in this file and reuse them in later runs of the same job and settings.")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="Override a job-file key, e.g. --set planner.reverse_samples=20 (repeatable).")
@click.option("-o", "--outdir", type=click.Path(path_type=Path), default=None,
              help="Output folder (default: out/<job file name>_design).")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
def command(job_file: Path, vary: tuple[str, ...], particles: int, iters: int, explore_iters: int, seed: int,
            jobs: int, method: str, coarse: float, resolution_mm: float, max_checks: int, cache_file: Path | None,
            overrides: tuple[str, ...], outdir: Path | None, as_json: bool) -> None:
    """Choose the link lengths of JOB's parametric arm (e.g. seed8's L1, L3).

    Objectives: F1 total arm length (mm) and F2 singularities (reverse plans +
    retracts) the planner meets on a coarse raster; a design with unreachable
    points is invalid. Step 1 explores with invalid designs as repelling
    obstacles and narrows the ranges; step 2 optimises inside them. The
    chosen design is the shortest 0-singularity design that also plans with
    0 unreachable points and 0 singularities on the FULL raster.

    Writes OUTDIR/design_space.png, OUTDIR/pareto_front.png, OUTDIR/design.html (both, interactive),
    OUTDIR/design.json,
    OUTDIR/chosen_job.toml (`camtool run` accepts it) and OUTDIR/chosen_robot.toml.
    Exit 3 when no valid design was found.
    """
    from ..design import DesignProblem, MopsoSettings, design_arm, parse_vary
    from ..design.plots import plot_design_html, plot_design_space, plot_front
    from ..design.study import write_chosen_job, write_chosen_robot
    from ..report.run_report import write_json_atomic

    if particles < 2:
        raise BadInput(f"--particles: expected at least 2, found {particles}")
    if iters < 0 or explore_iters < 0:
        raise BadInput("--iters and --explore-iters: expected numbers >= 0")
    if max_checks < 1:
        raise BadInput(f"--max-checks: expected at least 1, found {max_checks}")
    if method == "nsga2":
        from ..design.nsga2 import pymoo_available

        if not pymoo_available():
            raise BadInput("--method nsga2 needs pymoo: pip install 'camtool[design]'")
    variables = [parse_vary(v) for v in (vary or DEFAULT_VARY)]
    job = load_job(job_file, list(overrides))
    outdir = outdir or Path("out") / f"{job_file.stem}_design"
    safe_io.check_outdir(outdir)  # not / or home, no links, no foreign files
    settings = MopsoSettings(particles=particles, explore_iters=explore_iters, optimise_iters=iters)
    t0 = time.perf_counter()
    live = progress_enabled() and not as_json

    def on_iteration(step, t, n_archive):
        if live:
            click.echo(f"  step {step} iteration {t}: archive {n_archive}  {time.perf_counter() - t0:6.1f} s",
                       err=True)

    with DesignProblem(job, variables, coarse=coarse, jobs=jobs, resolution_mm=resolution_mm,
                       cache_file=cache_file) as problem:
        study = design_arm(problem, method, settings, seed, max_checks, on_iteration)
    wall_s = time.perf_counter() - t0
    names = problem.names
    outdir.mkdir(parents=True, exist_ok=True)
    files = [plot_design_space(study, outdir / "design_space.png"), plot_front(study, outdir / "pareto_front.png"),
             plot_design_html(study, outdir / "design.html")]
    summary = {
        "job": str(job_file), "robot": job.robot.name, "method": method, "seed": seed,
        "variables": {v.name: [v.lower_mm, v.upper_mm] for v in variables},
        "coarse_factor": coarse, "coarse_raster_poses": len(problem.path),
        "full_raster_poses": len(problem.full_path) if problem.full_path is not None else None,
        "narrowed": None if study.narrowed_lower is None else
        {n: [round(float(a), 3), round(float(b), 3)] for n, a, b in zip(names, study.narrowed_lower,
                                                                     study.narrowed_upper)},
        "front": [{**_design_dict(names, x), "length_mm": round(float(f[0]), 3), "singularities": int(f[1])}
                  for x, f in zip(study.front_X, study.front_F)],
        "invalid_designs": int(len(study.invalid_X)),
        "chosen": None if study.chosen_X is None else {
            "design": _design_dict(names, study.chosen_X), "coarse": _eval_dict(study.chosen_coarse),
            "full": _eval_dict(study.chosen_full)},
        "checked_full": [{"design": _design_dict(names, x), **_eval_dict(ev)} for x, ev in study.checks],
        "reference": {"design": _design_dict(names, study.reference_X), "coarse": _eval_dict(study.reference_coarse),
                      "full": _eval_dict(study.reference_full)},
        "evaluations": study.evaluations, "designs_requested": problem.requested,
        "designs_planned": problem.planned, "cache_hits": problem.requested - problem.planned,
        "planner_runs": problem.planner_runs,
        "plan_s": round(problem.plan_s, 3), "wall_s": round(wall_s, 3), "processes": jobs,
    }
    if study.chosen_X is not None:
        files.append(write_chosen_job(problem, study.chosen_X, outdir / "chosen_job.toml"))
        robot_file = write_chosen_robot(problem, study.chosen_X, outdir / "chosen_robot.toml")
        if robot_file is not None:
            files.append(robot_file)
    summary["files"] = [str(f) for f in files] + [str(outdir / "design.json")]
    write_json_atomic(summary, outdir / "design.json")
    if as_json:
        echo_json(summary)
    else:
        _print_summary(summary, names, study)
    if study.chosen_X is None:
        raise PlanInfeasible("no design reaches every point of the full raster; widen the --vary ranges "
                             "or give more particles / iterations (see design.json)")


def _fmt(design: dict) -> str:
    return ", ".join(f"{k} = {v:g}" for k, v in design.items())


def _fmt_eval(ev: dict | None) -> str:
    if ev is None:
        return "-"
    if not ev["valid"]:
        return f"INVALID ({ev['unreachable']} unreachable)"
    return f"length {ev['length_mm']:g} mm, {ev['singularities']} singularities, 0 unreachable"


def _print_summary(s: dict, names, study) -> None:
    click.echo(f"{s['robot']} / {s['method']}: {len(names)} variables, coarse raster {s['coarse_raster_poses']} "
               f"poses (x{s['coarse_factor']:g}), full raster {s['full_raster_poses']} poses")
    click.echo("ranges mm        " + ", ".join(f"{n} ({a:g}, {b:g})" for n, (a, b) in s["variables"].items()))
    if s["narrowed"] is not None:
        click.echo("narrowed mm      " + ", ".join(f"{n} ({a:g}, {b:g})" for n, (a, b) in s["narrowed"].items()))
    click.echo(f"invalid designs  {s['invalid_designs']}")
    click.echo(f"Pareto front     {len(s['front'])} designs (coarse raster)")
    if s["front"]:
        click.echo("  " + "  ".join(f"{n:>8}" for n in names) + "  length_mm  singularities")
    for row in s["front"]:
        click.echo("  " + "  ".join(f"{row[n]:8g}" for n in names) + f"  {row['length_mm']:9g}  {row['singularities']:13d}")
    if s["chosen"] is not None:
        c = s["chosen"]
        click.echo(f"chosen           {_fmt(c['design'])}: full raster {_fmt_eval(c['full'])}")
    else:
        click.echo("chosen           none: no candidate reached every point of the full raster")
    r = s["reference"]
    paper = s["robot"] == "seed8" and all(r["design"].get(k) == v for k, v in PAPER_CHOICE.items())
    label = "the job's arm = the paper's choice" if paper else "the job's arm"
    click.echo(f"reference        {_fmt(r['design'])} ({label}): full raster {_fmt_eval(r['full'])}; "
               f"coarse {_fmt_eval(r['coarse'])}")
    click.echo(f"evaluations      {s['evaluations']} by the optimiser; {s['designs_requested']} requested in all, "
               f"{s['designs_planned']} designs planned, {s['cache_hits']} cache hits")
    click.echo(f"planner runs     {s['planner_runs']} ({s['plan_s']:.1f} s planning) in {s['wall_s']:.1f} s wall, "
               f"{s['processes']} process(es)")
    for f in s["files"]:
        click.echo(f"wrote {f}")
