"""The post stage: a timed Trajectory -> checked controller programs on disk.

``write_programs(trajectory, robot, job, outdir)`` runs every format of
``job.post.formats`` through its plugin (``postprocessors.base``), with the
controller profile named in ``job.post.profiles`` or the shipped default.
Programs are written into a temporary folder inside ``outdir``, every file is
checked by its plugin (``plugin.check``; a plugin without one has its entry
file read back and checked, ``postprocessors.check.read_back_check``), and
only when all pass are they moved into place with ``os.replace``. Every plugin,
built-in or not, goes through the same protocol. A failed check raises
PlanInfeasible and leaves no program behind.
"""
from __future__ import annotations

import logging
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from .errors import BadInput, PlanInfeasible
from .profiles import Profile, default_options, default_profile_path, load_profile

log = logging.getLogger("camtool.post")
MAX_LISTED = 10


def profile_for_job(fmt: str, plugin, robot, job) -> Profile:
    """The profile of one format: the job's post.profiles entry (relative to the job
    file), else the shipped default; then the job's program name and tool, and the
    options the plugin takes from the job (``plugin.job_options(job)``, e.g. the CSV
    angle unit)."""
    given = job.post.profiles.get(fmt)
    if given is not None:
        if not isinstance(given, str):
            raise BadInput(f"{job.path}: post.profiles.{fmt}: expected a profile file name, found {given!r}")
        profile = load_profile(job.resolve(given), robot.name, fmt, robot)
    elif default_profile_path(robot.name, fmt) is not None:
        profile = load_profile(None, robot.name, fmt, robot)
    elif not getattr(plugin, "requires_profile", True):
        profile = Profile("<defaults>", fmt, robot.name, options=default_options(fmt))
    else:
        raise BadInput(f"post.formats: no {fmt} profile for robot {robot.name!r}: camtool ships none, so write "
                       f"one (docs/controllers.md) and name it in the job's post.profiles.{fmt}")
    tool = {}
    if job.tool.name != "tool0":  # the job's default; the profile names camtool's own tool data
        tool["name"] = job.tool.name
    tool.update(tcp_xyz_mm=list(job.tool.tcp_xyz_mm), tcp_rpy_deg=list(job.tool.tcp_rpy_deg),
                mass_kg=job.tool.mass_kg)
    changes = {"program_name": job.post.program_name, "tool": tool}
    job_options = getattr(plugin, "job_options", None)  # options a plugin takes from job keys
    if job_options is not None:
        changes["options"] = dict(job_options(job))
    return profile.with_changes(**changes)


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


def _prepare_outdir(outdir: Path) -> None:
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


def preflight(robot, job, outdir) -> None:
    """Check, before any work, that every format's plugin and profile load and the
    output folder can be written: bad input surfaces in seconds, not after planning."""
    from postprocessors.base import get_plugin

    for fmt in job.post.formats:
        profile_for_job(fmt, get_plugin(fmt), robot, job)
    _prepare_outdir(Path(outdir))


PROGRAMS_MANIFEST = ".camtool-programs.json"


def _forget_stale_programs(outdir: Path, final: list[Path]) -> None:
    """Remove programs an earlier run into ``outdir`` wrote and this run did not (e.g. the
    extra parts of a program that is now split into fewer), then record this run's set.

    Only files listed in camtool's own manifest are ever removed.
    """
    import json

    manifest = outdir / PROGRAMS_MANIFEST
    names = sorted(f.name for f in final)
    try:
        before = json.loads(manifest.read_text()).get("programs", [])
    except (OSError, ValueError, AttributeError):
        before = []
    for name in set(before) - set(names):
        if "/" not in name and name not in ("", ".", ".."):
            (outdir / name).unlink(missing_ok=True)
    tmp = outdir / (PROGRAMS_MANIFEST + ".tmp")
    tmp.write_text(json.dumps({"programs": names}, indent=1) + "\n")
    os.replace(tmp, manifest)


def write_programs(trajectory, robot, job, outdir) -> list[Path]:
    """Write, check and place the programs of every ``job.post.formats`` entry.

    Returns the final paths. Raises BadInput for an unknown format, a bad or
    missing profile or an output folder that cannot be written, and
    PlanInfeasible (listing the findings) when the trajectory leaves the joint
    limits or a written program fails the checker; then nothing is left behind.
    """
    from postprocessors.base import get_plugin
    from postprocessors.check import check_file

    outdir = Path(outdir)
    trajectory = thin_waypoints(trajectory, job.post.min_move_ms / 1000.0)
    plugins = {fmt: get_plugin(fmt) for fmt in job.post.formats}
    profiles = {fmt: profile_for_job(fmt, p, robot, job) for fmt, p in plugins.items()}
    check_limits(trajectory, robot)
    _prepare_outdir(outdir)
    try:
        tmp = Path(tempfile.mkdtemp(prefix=".camtool-post-", dir=outdir))
    except OSError as exc:
        raise BadInput(f"{outdir}: cannot write into the output folder ({exc.strerror or exc})") from None
    try:
        written: list[Path] = []
        findings: list[str] = []
        for fmt, plugin in plugins.items():
            files = [Path(f) for f in plugin.write(trajectory, robot, profiles[fmt], tmp)]
            for f in files:
                if f.parent != tmp:
                    raise BadInput(f"post-processor {fmt!r} wrote {f} outside its output folder")
                if f in written:
                    raise BadInput(f"post-processor {fmt!r} wrote {f.name}, which another format also wrote")
            written += files
            # the plugin's own check for every file; without one, the entry file read back
            for f in (files if hasattr(plugin, "check") else files[:1]):
                findings += [s.replace(str(tmp), str(outdir)) for s in check_file(plugin, f, robot, profiles[fmt])]
        if findings:
            more = f" (and {len(findings) - MAX_LISTED} more)" if len(findings) > MAX_LISTED else ""
            raise PlanInfeasible(f"{len(findings)} program check finding(s), no program written: "
                                 + " | ".join(findings[:MAX_LISTED]) + more, {"findings": findings})
        final = []
        for f in written:
            target = outdir / f.name
            os.replace(f, target)
            final.append(target)
        _forget_stale_programs(outdir, final)
        return final
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
