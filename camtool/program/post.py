"""The post stage: a timed Trajectory -> checked controller programs on disk.

Two steps:

- ``PostInputs``: everything the post stage needs, resolved once from the job at the top of a run
  (``camtool.run.post_inputs``): the post settings (``PostSettings``: formats, tolerances, the
  shortest move), each format's plugin and profile (``ResolvedPost``) and the process facts
  (``ProcessInfo``: feed, job name and time). This module never reads the raw job.
- ``write_programs(trajectory, robot, post_settings, profiles, outdir)`` writes every format
  through its plugin (``camtool.program.plugin.PostProcessor``) into a temporary folder
  inside ``outdir``, checks every file (``plugin.check``: the plugin's own, or its file read
  back), re-executes every program its plugin reads back move by move (``read_program``) in
  the simulator (``camtool.simulate``) against the planned path, and only when all pass
  moves them into place with ``os.replace``. A failed check or simulation raises
  PlanInfeasible and leaves no program behind.
"""
from __future__ import annotations

import logging
import os
import shutil
import tempfile
import time
from contextlib import ExitStack
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

from ..alongside import Alongside
from ..errors import BadInput, PlanInfeasible
from .profiles import Profile
from .candidates import forget_merged
from .check import check_file
from .plugin import PostProcessor
from .process import ProcessInfo
from .targets import forget_solved
from ..settings import PostSettings

log = logging.getLogger("camtool.post")
MAX_LISTED = 10


@dataclass(frozen=True)
class ResolvedPost:
    """One format of a job: its plugin and its profile, resolved once (``camtool.run.post_inputs.preflight``)."""

    fmt: str
    plugin: PostProcessor
    profile: Profile


@dataclass(frozen=True)
class PostInputs:
    """What the post stage takes from a job: settings, the formats' plugins and profiles (in
    ``post.formats`` order), and the process facts (feed, job name and time, tolerances)."""

    settings: PostSettings
    profiles: dict
    process: ProcessInfo


def row_labels(trajectory, path) -> tuple:
    """A label per work row of ``trajectory`` naming its raster segment (``path.segment``), and on a path
    over several faces its face (``path.face``), e.g. "face 2, segment 26"."""
    from ..path.toolpath import WORK

    work = np.asarray(trajectory.zone) == WORK
    first = np.flatnonzero(work & ~np.r_[False, work[:-1]])
    pidx = np.asarray(trajectory.path_index)[first]
    return tuple(path.segment_text(int(i)) if 0 <= i < len(path) else "" for i in pidx)


def summary_lines(sim):
    from ..simulate import summary_lines as lines
    return lines(sim)


def simulate_program(plugin, entry, robot, profile, trajectory, process, reference=None, world=None):
    """The simulator's report of one written program (``camtool.simulate``), against the
    planned path of ``trajectory``; with ``world``, the cell's pairs on the simulated motion too."""
    from ..simulate import reference_from_trajectory, simulate

    prog = plugin.read_program(entry, robot, profile)
    if reference is None:
        reference = reference_from_trajectory(trajectory, robot, process.feed_mm_s)
    return simulate(prog, robot, reference, path_tol_mm=process.path_tol_mm, profile=profile, world=world)


def check_limits(trajectory, robot) -> None:
    """PlanInfeasible when any trajectory sample is outside the robot's joint limits."""
    q = np.asarray(trajectory.q, float)
    L = robot.limits
    bad = np.argwhere((q < L.lower - 1e-9) | (q > L.upper + 1e-9))
    if len(bad):
        lines = []
        for k, i in bad[:MAX_LISTED]:
            v = q[k, i] if robot.prismatic[i] else np.degrees(q[k, i])
            unit = "mm" if robot.prismatic[i] else "deg"
            lines.append(f"sample {k} (t = {trajectory.t_s[k]:.3f} s): {robot.joint_names[i]} = {v:.4f} {unit}")
        more = f"; and {len(bad) - MAX_LISTED} more" if len(bad) > MAX_LISTED else ""
        raise PlanInfeasible(f"the trajectory leaves the joint limits of {robot.name}, no program written: "
                             + "; ".join(lines) + more)
    # the axes the controller limits (the IRB2400's axis 3 is j2 + j3): a program must not need
    # a configuration the controller refuses
    conv = robot.conventions
    bad = np.argwhere(conv.controller_limit_violations(conv.controller_from_model(q)))
    if len(bad):
        lines = [f"sample {k} (t = {trajectory.t_s[k]:.3f} s): " + conv.check_controller_limits(
            conv.controller_from_model(q[k]))[0] for k in dict.fromkeys(int(k) for k, _ in bad[:MAX_LISTED])]
        more = f"; and {len(bad) - MAX_LISTED} more" if len(bad) > MAX_LISTED else ""
        raise PlanInfeasible(f"the trajectory leaves the controller's axis limits of {robot.name}, no program "
                             "written: " + "; ".join(lines) + more)


def prepare_outdir(outdir: Path) -> None:
    """Create the output folder; BadInput when it cannot be made or written."""
    try:
        outdir.mkdir(parents=True, exist_ok=True)
    except (OSError, FileExistsError) as exc:
        raise BadInput(f"{outdir}: cannot create the output folder ({exc.strerror or exc})") from None
    if not outdir.is_dir() or not os.access(outdir, os.W_OK | os.X_OK):
        raise BadInput(f"{outdir}: the output folder is not writable")


def thin_waypoints(trajectory, min_move_s: float):
    """Drop inserted samples (path_index -1) closer than ``min_move_s`` to the last kept waypoint.

    Controllers execute a program move by move; moves of a few ms (ruckig's
    switching points, in free zones and, with timing.method = "ruckig", on
    work zones) overload their interpolators. Every path pose is kept at its
    scheduled time, so the tool still meets every surface point; kept samples
    lie on the timed motion and, since an average never exceeds the peak, the
    joint speeds between kept points stay within the limits. The jerk-limited
    shape between kept points is the Trajectory's, not the program's.
    """
    import numpy as np
    from dataclasses import replace

    if min_move_s <= 0 or len(trajectory.t_s) < 3:
        return trajectory
    t, pidx = trajectory.t_s, trajectory.path_index
    keep = pidx >= 0
    keep[0] = keep[-1] = True
    anchors = np.flatnonzero(keep)
    for a, b in zip(anchors[:-1], anchors[1:]):  # samples between two kept path poses
        last = t[a]
        for k in range(a + 1, b):
            if t[k] - last >= min_move_s and t[b] - t[k] >= min_move_s:
                keep[k] = True
                last = t[k]
    fields = {name: getattr(trajectory, name)[keep] for name in ("t_s", "q", "qd", "qdd", "zone", "path_index")}
    return replace(trajectory, **fields)


PROGRAMS_MANIFEST = ".camtool-programs.json"


def _forget_stale_programs(outdir: Path, final: list[Path]) -> None:
    """Remove programs an earlier run into ``outdir`` wrote and this run did not (e.g. the
    extra parts of a program that is now split into fewer), then record this run's set.

    Only files listed in camtool's own manifest are ever removed.
    """
    import json

    manifest = outdir / PROGRAMS_MANIFEST
    names = sorted(f.name for f in final)
    from .. import safe_io

    data = safe_io.read_own_json(manifest)
    before = data.get("programs", []) if isinstance(data, dict) else []
    before = before if isinstance(before, list) else []
    for name in set(before) - set(names):
        if isinstance(name, str) and "/" not in name and name not in ("", ".", ".."):
            safe_io.remove_file(outdir, name)  # a regular file inside outdir only, never through a link
    safe_io.write_file(outdir, PROGRAMS_MANIFEST, json.dumps({"programs": names}, indent=1) + "\n")


def write_programs(trajectory, robot, post_settings: PostSettings, profiles: dict, outdir, *,
                   process: ProcessInfo | None = None, path=None, report: dict | None = None,
                   world=None, before_placing=None) -> list[Path]:
    """Write, check, simulate and place the programs of every format in ``profiles``.

    ``profiles`` maps each format to its ``ResolvedPost`` (``post_inputs`` / ``preflight``);
    ``post_settings`` gives the tolerances and the shortest move; ``process`` the feed and job
    name and time (default: none, the settings' tolerances). ``path`` (the raster Path,
    optional) names the work rows. ``report`` (optional dict) receives, per format, the
    simulator's figures. ``world`` (a ``camtool.collision.CollisionWorld``, optional): the
    simulated programs are measured against the cell too (no body pair may touch). ``before_placing``
    (optional): called once every program has passed, before any is placed; what it raises
    leaves nothing behind (the motion check run alongside). Returns the final paths. Raises BadInput for an output folder that
    cannot be written, and PlanInfeasible (listing the findings) when the trajectory leaves
    the joint limits, a written program fails its check or its simulation; then nothing is
    left behind.
    """
    from dataclasses import replace

    outdir = Path(outdir)
    process = process if process is not None else ProcessInfo(path_tol_mm=post_settings.path_tol_mm,
                                                              ori_tol_deg=post_settings.ori_tol_deg)
    if path is not None:
        process = replace(process, row_labels=row_labels(trajectory, path))
    trajectory = thin_waypoints(trajectory, post_settings.min_move_s)
    check_limits(trajectory, robot)
    prepare_outdir(outdir)
    try:
        tmp = Path(tempfile.mkdtemp(prefix=".camtool-post-", dir=outdir))
    except OSError as exc:
        raise BadInput(f"{outdir}: cannot write into the output folder ({exc.strerror or exc})") from None
    try:
        written: list[Path] = []
        findings: list[str] = []
        reference = _reference(profiles, trajectory, robot, process)
        with ExitStack() as alongside:
            # each format's programs are written, checked and simulated on their own; every format but the
            # last in a forked process (``alongside.Alongside``), as the cores allow
            chains = [partial(_format_programs, fmt, post, trajectory, robot, (tmp, outdir), process, reference,
                              world) for fmt, post in profiles.items()]
            ahead = [alongside.enter_context(Alongside(chain)) for chain in chains[:-1]]
            here = [Alongside(chain, forked=False) for chain in chains[-1:]]
            for last in here:
                last.failure()   # run here, now; what it raised comes after the formats before it
            outcomes = [c.result() for c in ahead + here]
            for post in profiles.values():   # whichever process read them back, none is kept here
                post.plugin.forget()
            for fmt, (files, found, figures) in zip(profiles, outcomes):
                for f in files:
                    if f in written:
                        raise BadInput(f"post-processor {fmt!r} wrote {f.name}, which another format also wrote")
                written += files
                findings += found
                if figures is not None and report is not None:
                    report[fmt] = figures
        findings = list(dict.fromkeys(findings))  # each once, in order
        if findings:
            more = f" (and {len(findings) - MAX_LISTED} more)" if len(findings) > MAX_LISTED else ""
            raise PlanInfeasible(f"{len(findings)} program check finding(s), no program written: "
                                 + " | ".join(findings[:MAX_LISTED]) + more, {"findings": findings})
        from .. import safe_io

        if before_placing is not None:
            before_placing()
        for f in written:  # a folder, link or special file where a program goes: one line, before any change
            safe_io.check_target(outdir, f.name)
        final = [safe_io.place_file(f, outdir, f.name) for f in written]
        _forget_stale_programs(outdir, final)
        return final
    finally:
        forget_merged()
        shutil.rmtree(tmp, ignore_errors=True)


DEVIATION_FINDING = "from the planned path"
CLOSER_ROUNDS = 6     # rounds of writing again, closer to the plan, the stretches its simulator finds off the path
CLOSER_SHARE = 0.5    # ... each round within at most this share of the tolerance they had (less where they are
                      # farther off: the aim over their deviation)
CLOSER_PATIENCE = 2   # ... ending once this many rounds in a row have not lowered the largest deviation
AIM_SHARE = 0.8       # the writer aims the simulated deviation at this share of post.path_tol_mm: a margin for a real
                      # controller's rounding and zone handling (the simulator's finding stays at the tolerance)


def _tcp_robot(robot, post):
    """``robot`` with the format's profile tool: the simulator measures the job's TCP (the robot given may
    come without the job's tool)."""
    from .plan import profile_tool

    return robot.with_placement(tool_T_mm=profile_tool(post.profile))


def _reference(profiles: dict, trajectory, robot, process):
    """The planned motion the simulated programs are measured against (``simulate.reference_from_trajectory``),
    with the first simulated format's TCP; None when no format is simulated."""
    first = next((post for post in profiles.values() if post.plugin.simulated), None)
    if first is None:
        return None
    from ..simulate import reference_from_trajectory

    return reference_from_trajectory(trajectory, _tcp_robot(robot, first), process.feed_mm_s)


def _format_programs(fmt, post, trajectory, robot, folders: tuple[Path, Path], process, reference, world=None):
    """One format's programs, written into the private folder, checked and simulated (``_write_checked``);
    written again with joint moves where the simulator finds straight moves the controller cannot follow
    (``_joint_move_rounds``), then with the stretches it finds off the planned path written closer to it
    (``_closer_rounds``). Returns (files, findings, figures or None)."""
    once = _Once()   # a format written again says its warnings (a job name cut short) once
    log.addFilter(once)
    try:
        return _rewritten_programs(fmt, post, trajectory, robot, folders, process, reference, world)
    finally:
        log.removeFilter(once)


class _Once(logging.Filter):
    """Passes each message once (level and text)."""

    def __init__(self):
        super().__init__()
        self.seen: set = set()

    def filter(self, record) -> bool:
        key = (record.levelno, record.getMessage())
        if key in self.seen:
            return False
        self.seen.add(key)
        return True


def _rewritten_programs(fmt, post, trajectory, robot, folders: tuple[Path, Path], process, reference, world=None):
    """``_format_programs``' rounds: the first writing, the joint-move rounds, then the closer rounds."""
    from ..motion.cell_check import forget_measured
    from .steps import forget_fitted

    args = (fmt, post, trajectory, robot, folders, process, reference, world)
    last = (process,) + _write_checked(fmt, post, trajectory, robot, folders, process, process, reference, world)
    last = _joint_move_rounds(*args, last)
    files, found, figures = _closer_rounds(*args, last)
    post.plugin.forget()   # what a format kept of its own files (a dense job's: hundreds of MB)
    forget_solved()
    forget_measured()   # the cell pass's distances, kept from round to round
    forget_fitted()     # the arc fit's tests, too
    return files, found, figures


JOINT_MOVE_ROUNDS = 4  # rounds of writing straight moves the controller cannot follow as joint moves


def joint_spans(spans: tuple, new: tuple) -> tuple:
    """``spans`` with the (start, end) spans ``new`` added: a new span that meets one already there (the
    joint moves did not suffice) takes their union widened by its length on either side; in time order."""
    out = [tuple(x) for x in spans]
    for a, b in new:
        meets = [i for i, (c, d) in enumerate(out) if a <= d + 1e-9 and c <= b + 1e-9]
        if meets:
            lo = min([a] + [out[i][0] for i in meets])
            hi = max([b] + [out[i][1] for i in meets])
            out = [x for i, x in enumerate(out) if i not in meets]
            a, b = max(lo - (hi - lo), 0.0), hi + (hi - lo)
        out.append((a, b))
    return tuple(sorted(out))


def _joint_move_rounds(fmt, post, trajectory, robot, folders, process, reference, world, last):
    """Written again, up to ``JOINT_MOVE_ROUNDS`` times, with joint moves over the straight moves the
    simulator found the controller cannot follow (near a wrist singularity a straight line needs joint
    speeds without bound, or has no solution; a joint move through there has neither, and it is merged
    within the path tolerance like any other). ``last`` and the result: (writing, files, findings, figures,
    unfollowed, deviations) of the last round (``_write_checked``)."""
    from dataclasses import replace

    writing, files, found, figures, unfollowed, deviations = last
    for _ in range(JOINT_MOVE_ROUNDS):
        if not (found and unfollowed):
            break
        spans = joint_spans(writing.joint_moves_s, unfollowed)
        for f in files:
            f.unlink(missing_ok=True)
        log.info("%s: the controller cannot follow %d straight move(s) as written (first at t = %.3f s); "
                 "written again with joint moves there", fmt, len(unfollowed), unfollowed[0][0])
        writing = replace(writing, joint_moves_s=spans)
        files, found, figures, unfollowed, deviations = _write_checked(fmt, post, trajectory, robot, folders, process,
                                                                       writing, reference, world)
    return writing, files, found, figures, unfollowed, deviations


def closer_spans(spans: tuple, deviations: tuple, above_mm: float) -> tuple:
    """``spans`` (start, end, share) with the moves of ``deviations`` (start, end, deviation mm, in time
    order) farther than ``above_mm`` from the planned path added, each with the moves just before and after
    it (a corner is cut by the moves on both sides of its target): a stretch that meets spans already there
    takes their union, within the smallest share they had times ``above_mm`` over the stretch's deviation
    (at most ``CLOSER_SHARE``); a new one within that of the whole tolerance. In time order."""
    new: list = []
    for i, (a, b, dev) in enumerate(deviations):
        if dev <= above_mm:
            continue
        if i > 0 and abs(deviations[i - 1][1] - a) < 1e-9:
            a = deviations[i - 1][0]
        if i + 1 < len(deviations) and abs(deviations[i + 1][0] - b) < 1e-9:
            b = deviations[i + 1][1]
        if new and a <= new[-1][1] + 1e-9:
            a, b, dev = new[-1][0], max(b, new[-1][1]), max(dev, new[-1][2])
            new.pop()
        new.append((a, b, dev))
    out = [tuple(x) for x in spans]
    for a, b, dev in new:
        meets = [x for x in out if a <= x[1] + 1e-9 and x[0] <= b + 1e-9]
        share = min(CLOSER_SHARE, above_mm / dev) * min([1.0] + [x[2] for x in meets])
        a, b = min([a] + [x[0] for x in meets]), max([b] + [x[1] for x in meets])
        out = [x for x in out if x not in meets] + [(a, b, share)]
    return tuple(sorted(out))


def _off_path(found: list, figures, aim_mm: float) -> bool:
    """True when what a program's check and simulation found is its distance from the planned path alone,
    or, with nothing found, that distance is above ``aim_mm``."""
    if found:
        return all(DEVIATION_FINDING in x for x in found)
    dev = (figures or {}).get("max_deviation_mm")
    return dev is not None and dev > aim_mm


def _closer_rounds(fmt, post, trajectory, robot, folders, process, reference, world, last):
    """Written again, up to ``CLOSER_ROUNDS`` times, with the stretches the simulator finds farther than
    ``AIM_SHARE`` of the tolerance from the planned path merged and blended closer to it (``closer_spans``:
    shorter moves there, targets on the plan's own motion, smaller corners); the rounds stop early once
    ``CLOSER_PATIENCE`` of them in a row have not lowered the largest deviation (where the plan's own motion
    is that far from its poses' path, no target mends it). The writing that passed with the smallest deviation
    is the one placed (written again if a later round came out worse). Returns (files, findings, figures)."""
    from dataclasses import replace

    writing, files, found, figures, _unfollowed, deviations = last
    aim = AIM_SHARE * process.path_tol_mm
    lowest = _max_deviation(figures)
    best = None if found else (lowest, writing)   # the passing writing with the smallest deviation
    rounds = stale = 0
    while rounds < CLOSER_ROUNDS and stale < CLOSER_PATIENCE and _off_path(found, figures, aim):
        spans = closer_spans(writing.closer_s, deviations, aim)
        if spans == tuple(writing.closer_s):
            break
        rounds += 1
        for f in files:
            f.unlink(missing_ok=True)
        log.info("%s: the simulated program is %.4g mm from the planned path; written again closer to it in %d "
                 "stretch(es)", fmt, _max_deviation(figures), len(spans))
        writing = replace(writing, closer_s=spans)
        files, found, figures, _unfollowed, deviations = _write_checked(fmt, post, trajectory, robot, folders,
                                                                        process, writing, reference, world)
        dev = _max_deviation(figures)
        stale = 0 if dev < lowest else stale + 1
        lowest = min(lowest, dev)
        if not found and (best is None or dev < best[0]):
            best = (dev, writing)
    if best is not None and best[1] is not writing:   # a later round came out worse: the best one, again
        for f in files:
            f.unlink(missing_ok=True)
        files, found, figures, _unfollowed, _dev = _write_checked(fmt, post, trajectory, robot, folders, process,
                                                                  best[1], reference, world)
    elif found and rounds:
        found = [x + (f" (written {rounds} time(s) closer to the plan there; loosen post.path_tol_mm or place the "
                      "part elsewhere: camtool place)" if DEVIATION_FINDING in x else "") for x in found]
    return files, found, figures


def _max_deviation(figures) -> float:
    """The simulated program's largest distance from the planned path on work (mm; inf when not measured)."""
    dev = (figures or {}).get("max_deviation_mm")
    return float("inf") if dev is None else float(dev)


def _write_checked(fmt, post, trajectory, robot, folders: tuple[Path, Path], process, writing, reference,
                   world=None):
    """Write one format into the private folder with ``writing`` (the process, its tolerance perhaps
    tightened), check its files and simulate them against ``process``' tolerance and ``reference``;
    findings name the output folder. Returns (files, findings, figures or None, the moves the controller
    cannot follow (``SimReport.unfollowed_s``), each move's deviation on work (``SimReport.deviation_s``))."""
    tmp, outdir = folders
    plugin, profile = post.plugin, post.profile
    tcp_robot = _tcp_robot(robot, post)
    t0 = time.perf_counter()
    files = [Path(f) for f in plugin.write(trajectory, robot, profile, tmp, writing)]
    t_write = time.perf_counter() - t0
    for f in files:
        if f.parent != tmp:
            raise BadInput(f"post-processor {fmt!r} wrote {f} outside its output folder")
    findings: list[str] = []
    t0 = time.perf_counter()
    # a plugin whose check of the entry file follows every file it loads or calls says so
    # (``check_covers_calls``): its entry file alone is checked; a file read back (no own
    # check) is the entry file alone
    for f in (files[:1] if plugin.check_covers_calls or not plugin.own_check else files):
        findings += [s.replace(str(tmp), str(outdir)) for s in check_file(plugin, f, tcp_robot, profile)]
    t_check = time.perf_counter() - t0
    figures, unfollowed, deviations = None, (), ()
    if plugin.simulated and files and not findings:
        t0 = time.perf_counter()
        sim = simulate_program(plugin, files[0], tcp_robot, profile, trajectory, process, reference, world)
        findings += [s.replace(str(tmp), str(outdir)) for s in sim.findings]
        figures = sim.as_dict()
        figures.pop("findings")
        figures.update(write_s=round(t_write, 4), check_s=round(t_check, 4),
                       simulate_s=round(time.perf_counter() - t0, 4),
                       bytes=sum(f.stat().st_size for f in files), path_tol_mm=process.path_tol_mm)
        log.info("%s: %s", fmt, "; ".join(summary_lines(sim)))
        unfollowed, deviations = sim.unfollowed_s, sim.deviation_s
    elif plugin.simulated and files and _motion_findings(findings):
        # the check found joints too fast between targets: where the controller runs them so is named by
        # its simulation (a target solved on the other wrist branch), for the joint-move rounds only
        unfollowed = simulate_program(plugin, files[0], tcp_robot, profile, trajectory, process, reference).unfollowed_s
    return files, findings, figures, unfollowed, deviations


def _motion_findings(findings: list[str]) -> bool:
    """True when every finding of a program's check is a joint too fast between targets or outside its
    limits (``camtool.program.check``): findings joint moves there may mend."""
    return bool(findings) and all(("above the limit" in f) or ("outside the limits" in f) or ("more steps above" in f)
                                  or ("more values outside" in f) for f in findings)
