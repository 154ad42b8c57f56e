"""``camtool place``: where to put the workpiece so that the robot reaches all of it, with margin."""
from __future__ import annotations

import math
import time
from pathlib import Path

import click

from ..console import echo_json, progress_enabled
from ..errors import BadInput, PlanInfeasible
from .. import safe_io
from ..job import load_job


def _offset_dict(o) -> dict:
    d = {"dx_mm": round(o[0], 3), "dy_mm": round(o[1], 3), "dz_mm": round(o[2], 3), "dyaw_deg": round(o[3], 3)}
    if len(o) > 4:   # the tilt stage's (``placement.tilt``)
        d.update(droll_deg=round(o[4], 3), dpitch_deg=round(o[5], 3))
    return d


def _verified_dict(v: dict | None) -> dict | None:
    if v is None:
        return None
    keep = ("ok", "unreachable", "cycle_s", "reverse_plans", "retracts", "limit_findings", "penalty", "penalty_from",
            "plan_penalty", "cost", "reason", "margins", "seconds", "feed_mm_s", "feed_min_mm_s", "feed_share")
    out = {k: v[k] for k in keep if k in v}
    if not math.isfinite(out.get("cost", 0.0)):
        out["cost"] = None
    return out


def _entry(study, job, r, rank=None) -> dict:
    from ..placement.search import placement_of

    xyz, rpy = placement_of(job, r.offset, study.tilt_centre_mm)
    d = {"offset": _offset_dict(r.offset), "workpiece_xyz_mm": xyz, "workpiece_rpy_deg": rpy,
         "screen": {k: v for k, v in r.as_dict().items() if k != "offset"},
         "planned": _verified_dict(study.verified.get(r.offset))}
    return d if rank is None else {"rank": rank, **d}


@click.command("place")
@click.argument("job_file", metavar="JOB", type=click.Path(path_type=Path))
@click.option("--vary", "vary", multiple=True, metavar="NAME=LO:HI",
              help="A placement offset to search and its range: x, y, z in mm (world frame), yaw in deg about "
                   "world z, roll and pitch in deg about world x and y (the part tilted about its work's centre); "
                   "repeatable (default x=-300:300, y=-300:300, z=-300:300).")
@click.option("--tilt-max-deg", "tilt_max_deg", type=float, default=30.0, show_default=True,
              help="When no placement plans with the part as it stands, search its roll and pitch (a tilted "
                   "fixture) within +-this too; 0 = never tilt.")
@click.option("-j", "--jobs", type=int, default=1, show_default=True,
              help="Processes that screen and plan in parallel.")
@click.option("--seed", type=int, default=0, show_default=True,
              help="Random seed of the refinement: the same seed gives the same result.")
@click.option("--grid", "grid_max", type=int, default=1000, show_default=True,
              help="Placements of the raster screen at most (the grid is coarsened to fit).")
@click.option("--verify", type=int, default=3, show_default=True,
              help="Best placements planned in full (the real pipeline) per round.")
@click.option("--max-checks", type=int, default=9, show_default=True,
              help="Best placements tried in full before giving up.")
@click.option("--reach-margin", type=float, default=10.0, show_default=True,
              help="Goal of the reach margin (percent of the arm's reach); less is penalised.")
@click.option("--joint-margin", type=float, default=10.0, show_default=True,
              help="Goal of the joint-limit margin (percent of each joint's range); less is penalised.")
@click.option("--feed-weight", type=float, default=3.0, show_default=True,
              help="Weight of the work feed in the cost: a placement whose work is expected at a share f of "
                   "timing.tcp_speed_mm_s costs 1 + weight x (1 - f) times more (0: the feed is not weighed).")
@click.option("--top", type=int, default=10, show_default=True, help="Length of the ranked list.")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="Override a job-file key, e.g. --set raster.step_over_mm=20 (repeatable).")
@click.option("-o", "--outdir", type=click.Path(path_type=Path), default=None,
              help="Output folder (default: out/<job file name>_place).")
@click.option("--json", "as_json", is_flag=True, help="Print the summary (placement.json) as JSON.")
def command(job_file: Path, vary: tuple[str, ...], tilt_max_deg: float, jobs: int, seed: int, grid_max: int, verify: int,
            max_checks: int, reach_margin: float, joint_margin: float, feed_weight: float, top: int, overrides: tuple[str, ...], outdir: Path | None,
            as_json: bool) -> None:
    """Find where to put JOB's workpiece: offsets of cell.workpiece_xyz_mm and a yaw added to
    cell.workpiece_rpy_deg, within the --vary bounds; when none plans, the part tilted too (roll and pitch
    within --tilt-max-deg, about the centre of its work).

    Every pose of the raster must be reachable with margin. A fast screen
    (wrist-centre reach bound on every pose, closed-form IK on a subsample)
    scores a raster of placements and refines round the best; the best few
    are then planned and timed in full. Cost: estimated work time x (1 +
    penalty on joint-limit, reach and singularity margins below their goals)
    x (1 + 2 % per metre moved) x (1 + --feed-weight x the share of the
    feed the work is expected to lose); see docs/placement.md.

    Writes OUTDIR/placed_job.toml (`camtool run` accepts it),
    OUTDIR/feasible_region.png and OUTDIR/placement.json. Exit 3 when no
    placement within the bounds plans with every pose reachable.
    """
    from ..placement.plots import plot_feasible_region
    from ..placement.screen import ScreenSettings
    from ..placement.search import (DEFAULT_VARY, PlacementProblem, format_offset, parse_vary, placement_of,
                                    write_placed_job)
    from ..placement.tilt import TiltSettings
    from ..report.run_report import write_json_atomic
    from ..run.job_settings import JobSettings

    for name, value, least in (("--grid", grid_max, 8), ("--verify", verify, 1), ("--max-checks", max_checks, 1),
                               ("--top", top, 1), ("-j", jobs, 1)):
        if value < least:
            raise BadInput(f"{name}: expected at least {least}, found {value}")
    for name, value in (("--reach-margin", reach_margin), ("--joint-margin", joint_margin)):
        if not 0.0 < value < 50.0:
            raise BadInput(f"{name}: expected a percentage in (0, 50), found {value:g}")
    if not (math.isfinite(feed_weight) and 0.0 <= feed_weight <= 100.0):
        raise BadInput(f"--feed-weight: expected a weight in [0, 100], found {feed_weight:g}")
    tilt = TiltSettings(max_deg=tilt_max_deg)
    variables = [parse_vary(v) for v in (vary or DEFAULT_VARY)]
    job = load_job(job_file, list(overrides))
    outdir = outdir or Path("out") / f"{job_file.stem}_place"
    safe_io.check_outdir(outdir)  # not / or home, no links, no foreign files
    t0 = time.perf_counter()
    live = progress_enabled() and not as_json

    def on_progress(msg):
        if live:
            click.echo(f"  {msg}  {time.perf_counter() - t0:6.1f} s", err=True)

    from ..run.stages import robot_for_job

    robot = robot_for_job(job)
    st = JobSettings.from_job(job, robot)
    settings = ScreenSettings(joint_margin_goal=joint_margin / 100.0, reach_margin_goal=reach_margin / 100.0,
                              orientation_mm=st.planner.orientation_weight_mm, track_scale_mm=st.planner.track_scale_mm,
                              tcp_speed_mm_s=st.timing.tcp_speed_mm_s, feed_weight=feed_weight)
    with PlacementProblem(job, variables, jobs, settings, tilt) as problem:
        study = problem.run(seed, verify, max_checks, grid_max, on_progress)
    user = study.zero
    files = [plot_feasible_region(study, outdir / "feasible_region.png")]
    if study.chosen is not None:
        files.insert(0, write_placed_job(job, study.chosen, outdir / "placed_job.toml", list(overrides),
                                         tilt_centre_mm=study.tilt_centre_mm))
    grid = [len(g) for g in study.grid]
    summary = {
        "job": str(job_file), "robot": study.robot_name, "families": study.families, "seed": seed,
        "placement": {"workpiece_xyz_mm": list(job.cell.workpiece_xyz_mm),
                      "workpiece_rpy_deg": list(job.cell.workpiece_rpy_deg)},
        "variables": {v.name: [v.lower, v.upper] for v in study.variables},
        "units": {"x": "mm", "y": "mm", "z": "mm", "yaw": "deg", "roll": "deg", "pitch": "deg"},
        "tilt": _tilt_dict(study, tilt),
        "cost": {"formula": "est_work_s * (1 + penalty) * (1 + move_per_m * (|d| / 1 m + |yaw| / 90 deg)) * "
                            "(1 + feed_weight * (1 - feed_share)); planned: cycle_s in place of est_work_s, "
                            "feed_share of the planned run's median work feed",
                 "feed_weight": settings.feed_weight, "tcp_speed_mm_s": settings.tcp_speed_mm_s,
                 "joint_margin_goal": settings.joint_margin_goal, "reach_margin_goal": settings.reach_margin_goal,
                 "dexterity_goal": settings.dexterity_goal, "move_per_m": settings.move_per_m},
        "screen": {"poses": study.n_poses, "ik_poses": study.n_ik_poses, "grid": grid,
                   "grid_placements": len(study.grid_offsets), "placements": len(study.results),
                   "feasible": study.feasible_count, "seconds": round(study.screen_s, 3)},
        "user": _entry(study, job, study.user),
        "ranked": [_entry(study, job, r, k) for k, r in enumerate(study.ranked(top), 1)],
        "planned": [{**_offset_dict(o), **_verified_dict(v)} for o, v in study.verified.items()],
        "chosen": None if study.chosen is None else _entry(study, job, study.results[study.chosen]),
        "plan_seconds": round(study.verify_s, 3), "wall_s": round(time.perf_counter() - t0, 3), "processes": jobs,
    }
    summary["files"] = [str(f) for f in files] + [str(outdir / "placement.json")]
    write_json_atomic(summary, outdir / "placement.json")
    if as_json:
        echo_json(summary)
    else:
        _print_summary(summary, study, job, format_offset, placement_of, outdir)
    if study.chosen is None:
        v = study.verified.get(user)
        bound = f" and a tilt within +-{tilt.max_deg:g} deg" if study.upright is not None else ""
        raise PlanInfeasible(f"no placement within the --vary bounds{bound} plans with every pose reachable"
                             + ("" if study.feasible_count else " (none passes the reach screen)")
                             + _nearest_text(study) + _beyond_text(study)
                             + "; widen the bounds or add a variable (see placement.json and feasible_region.png)"
                             + ("" if v is None or v["ok"] else f"; your placement: {v.get('reason', '')}"))


def _tilt_dict(study, tilt) -> dict:
    """placement.json's ``tilt``: the bound, the pivot and, when the part was tilted, the upright search's figures."""
    c = study.tilt_centre_mm
    return {"max_deg": tilt.max_deg, "searched": study.upright is not None,
            "centre_mm": None if c is None else [round(float(v), 3) for v in c], "upright": study.upright,
            "beyond": study.beyond}


def _nearest_text(study) -> str:
    """The refusal's nearest miss: the best screened placement, where it fails."""
    from ..placement.search import format_offset, rank_key

    if not study.results:
        return ""
    r = sorted(study.results.values(), key=rank_key)[0]
    if r.feasible:
        return ""
    if r.stage == "part":
        return (f"; nearest: {format_offset(r.offset)}, where the part comes nearer than the cell's clearance to "
                f"{r.unreachable} world-fixed obstacle(s)")
    where = {"bound": "beyond the wrist-centre reach", "ik": "outside the joint limits or bent into the tool",
             "full": "outside the joint limits or bent into the tool"}[r.stage]
    return f"; nearest: {format_offset(r.offset)} with {r.unreachable} of {r.checked} screened poses {where}"


def _beyond_text(study) -> str:
    """The refusal's 'what would work' past the tilt's bound (``PlacementProblem._beyond``)."""
    from ..placement.search import format_offset

    b = study.beyond
    if b is None:
        return ""
    if b["offset"] is None:
        return f"; no tilt within +-{b['max_deg']:g} deg passes the screen either ({b['screened']} placements)"
    return (f"; a wider tilt passes the closed-form screen (not planned): {format_offset(b['offset'])} "
            f"(--tilt-max-deg {b['max_deg']:g})")


def _fmt_screen(s: dict) -> str:
    if not s["feasible"] and s["stage"] == "part":
        return (f"INFEASIBLE in the screen: the part comes nearer than the cell's clearance to {s['unreachable']} of "
                f"the {s['checked']} world-fixed obstacles and floor")
    if not s["feasible"]:
        where = {"bound": "beyond the wrist-centre reach", "ik": "outside the joint limits (IK subsample)",
                 "full": "outside the joint limits"}[s["stage"]]
        return f"INFEASIBLE in the screen: {s['unreachable']} of {s['checked']} poses {where}"
    feed = "" if s.get("feed_mm_s") is None else f", expected work feed {s['feed_mm_s']:.0f} mm/s"
    return (f"screen cost {s['cost']:.1f} s, joint margin {100 * s['joint_margin']:.1f} % ({s['joint_margin_joint']}), "
            f"reach used {100 * s['reach_used']:.1f} %, dexterity {s['dexterity']:.3f}{feed}")


def _fmt_planned(v: dict | None) -> str:
    if v is None:
        return "not planned"
    if not v["ok"]:
        return f"plan FAILS: {v.get('reason', '')}"
    m = v["margins"]
    reach = f", reach used {m['reach']['max_used_pct']:.1f} %" if m.get("reach") else ""
    jl = m["joint_limit"]
    return (f"plans: 0 unreachable, cycle {v['cycle_s']:.1f} s, {v['reverse_plans']} reverse plans, "
            f"{v['retracts']} retracts, joint margin {100 * jl['min_share']:.1f} % ({jl['joint']}){reach}, "
            f"{_fmt_feed(v)}cost {v['cost']:.1f}")


def _fmt_feed(v: dict) -> str:
    return "" if v.get("feed_mm_s") is None else f"median work feed {v['feed_mm_s']:.1f} mm/s, "


def _print_summary(s: dict, study, job, format_offset, placement_of, outdir) -> None:
    sc = s["screen"]
    click.echo(f"{s['robot']} ({s['families']}): {sc['poses']} poses; screen: wrist-centre bound on every pose, "
               f"closed-form IK on {sc['ik_poses']}")
    u = s["user"]
    click.echo(f"your placement   xyz {u['workpiece_xyz_mm']} mm, rpy {u['workpiece_rpy_deg']} deg: "
               f"{_fmt_screen(u['screen'])}")
    click.echo(f"                 {_fmt_planned(u['planned'])}")
    ranges = ", ".join(f"{n} {a:g}:{b:g} {s['units'][n]}" for n, (a, b) in s["variables"].items())
    click.echo(f"searched         {ranges}: {sc['grid_placements']} grid ({' x '.join(map(str, sc['grid']))}) + "
               f"{sc['placements'] - sc['grid_placements']} more placements, {sc['feasible']} feasible, "
               f"{sc['seconds']:.1f} s screen + {s['plan_seconds']:.1f} s planning, {s['processes']} process(es)")
    tilted = s["tilt"]["searched"]
    if tilted:
        up = s["tilt"]["upright"]
        click.echo(f"upright          none of {up['placements']} placements plans ({up['feasible']} pass the screen, "
                   f"{up['planned']} planned): the part tilted, roll and pitch within +-{s['tilt']['max_deg']:g} deg "
                   f"about its work's centre {s['tilt']['centre_mm']} mm")
    click.echo(" rank    dx mm    dy mm    dz mm  yaw deg" + (" roll deg pitch deg" if tilted else "")
               + "  cost s  joint %  reach %  dexter  feed mm/s  planned")
    for e in s["ranked"]:
        o, r, v = e["offset"], e["screen"], e["planned"]
        if r["feasible"]:
            feed = "-" if r.get("feed_mm_s") is None else f"{r['feed_mm_s']:.0f}"
            figs = (f"{r['cost']:7.1f}  {100 * r['joint_margin']:7.1f}  {100 * r['reach_used']:7.1f}  "
                    f"{r['dexterity']:6.3f}  {feed:>9}")
        else:
            figs = f"{'-':>7}  {'-':>7}  {100 * r['reach_used']:7.1f}  {'-':>6}  {'-':>9}"
        plan = "-" if v is None else (f"ok, cycle {v['cycle_s']:.1f} s, {_fmt_feed(v)}cost {v['cost']:.1f}" if v["ok"]
                                      else f"fails ({v.get('unreachable', 0)} unreachable)")
        tilt = f" {o['droll_deg']:8.1f} {o['dpitch_deg']:9.1f}" if tilted else ""
        click.echo(f" {e['rank']:4d} {o['dx_mm']:8.1f} {o['dy_mm']:8.1f} {o['dz_mm']:8.1f} {o['dyaw_deg']:8.1f}{tilt} "
                   f"{figs}  {plan}")
    c = s["chosen"]
    if c is None:
        click.echo("chosen           none: no placement within the bounds plans with every pose reachable")
    else:
        o = study.chosen
        click.echo(f"chosen           xyz {c['workpiece_xyz_mm']} mm, rpy {c['workpiece_rpy_deg']} deg "
                   f"({format_offset(o)})")
        click.echo(f"                 {_fmt_planned(c['planned'])}")
        click.echo(f"run it:          camtool run {outdir / 'placed_job.toml'}")
    for f in s["files"]:
        click.echo(f"wrote {f}")
