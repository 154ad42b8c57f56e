"""The post stage's inputs, read from the job once at the top of a run: every format's plugin and
profile (the job's ``post.profiles`` file or the shipped default, with the job's program name, tool,
work object and the options the plugin takes from the settings), the post settings and the process
facts. ``preflight`` builds them before any planning, and checks that the output folder can be
written, so bad input surfaces in seconds; below ``run/`` nothing reads the raw job.
"""
from __future__ import annotations

from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from ..errors import BadInput
from ..program.plugin import PostProcessor
from ..program.post import PostInputs, ResolvedPost, prepare_outdir, write_programs
from ..program.process import DATE_FORMAT, ProcessInfo
from ..program.profiles import Profile, default_profile_path, defaults_profile, load_profile
from ..program.registry import get_plugin
from ..settings import PostSettings, TimingSettings


def profile_for_job(fmt: str, plugin: PostProcessor, robot, job, post: PostSettings | None = None) -> Profile:
    """The profile of one format: the job's post.profiles entry (relative to the job
    file), else the shipped default; then the job's program name and tool, the workpiece
    as work object and the options the plugin takes from the post settings."""
    post = post if post is not None else PostSettings.from_section(job.post)
    given = post.profiles.get(fmt)
    if given is not None:
        if not isinstance(given, str):
            raise BadInput(f"{job.path}: post.profiles.{fmt}: expected a profile file name, found {given!r}")
        profile = load_profile(job.resolve(given), robot.name, fmt, robot, plugin)
    elif default_profile_path(robot.name, fmt) is not None:
        profile = load_profile(None, robot.name, fmt, robot, plugin)
    elif not plugin.requires_profile:
        profile = defaults_profile(fmt, robot.name, plugin)
    else:
        raise BadInput(f"post.formats: no {fmt} profile for robot {robot.name!r}: camtool ships none, so write "
                       f"one (docs/controllers.md) and name it in the job's post.profiles.{fmt}")
    tool = {}
    if job.tool.name != "tool0":  # the job's default; the profile names camtool's own tool data
        tool["name"] = job.tool.name
    tool.update(tcp_xyz_mm=list(job.tool.tcp_xyz_mm), tcp_rpy_deg=list(job.tool.tcp_rpy_deg),
                mass_kg=job.tool.mass_kg)
    changes = {"program_name": post.program_name, "tool": tool, "wobj": workpiece_wobj(job, robot)}
    options = plugin.post_options(post)
    if options:
        changes["options"] = dict(options)
    return profile.with_changes(**changes)


def workpiece_wobj(job, robot) -> dict:
    """The job's workpiece frame in the robot base frame as profile ``wobj`` keys (xyz_mm,
    rpy_deg): Cartesian targets are written in it, so the work object is the workpiece."""
    from scipy.spatial.transform import Rotation

    from ..transforms import invert, matrix_from_xyz_rpy

    wp = matrix_from_xyz_rpy(job.cell.workpiece_xyz_mm, job.cell.workpiece_rpy_deg)
    T = invert(np.asarray(robot.base_T_mm, float)) @ wp
    import warnings

    with warnings.catch_warnings():  # a gimbal lock (pitch +-90 deg) still gives the same matrix
        warnings.simplefilter("ignore")
        rpy = Rotation.from_matrix(T[:3, :3]).as_euler("xyz", degrees=True)
    return {"xyz_mm": [float(round(v, 6)) + 0.0 for v in T[:3, 3]],
            "rpy_deg": [float(round(v, 9)) + 0.0 for v in rpy]}


def process_for_job(job, post: PostSettings) -> ProcessInfo:
    """The ``ProcessInfo`` of a job: the post tolerances, the feed ``timing.tcp_speed_mm_s``
    and the job file's name and modification time (UTC)."""
    try:
        when = datetime.fromtimestamp(Path(job.path).stat().st_mtime, timezone.utc).strftime(DATE_FORMAT)
    except (OSError, TypeError, ValueError):
        when = None
    feed = TimingSettings.from_section(job.timing).tcp_speed_mm_s
    return ProcessInfo(path_tol_mm=post.path_tol_mm, ori_tol_deg=post.ori_tol_deg, feed_mm_s=float(feed) or None,
                       job_name=Path(str(job.path)).name, job_time=when)


_RESOLVED: dict = {}  # the last job's PostInputs, by the job object (kept alive here): resolved once


def post_inputs(job, robot) -> PostInputs:
    """Settings, resolved profiles and process facts of ``job`` for ``robot``: built once per
    job object (``preflight`` builds them; later calls get the same object)."""
    key = (id(job), robot.name, np.asarray(robot.base_T_mm, float).tobytes())
    hit = _RESOLVED.get("value")
    if hit is not None and _RESOLVED.get("key") == key and _RESOLVED.get("job") is job:
        return hit
    post = PostSettings.from_section(job.post)
    profiles = {}
    for fmt in post.formats:
        plugin = get_plugin(fmt)
        profiles[fmt] = ResolvedPost(fmt, plugin, profile_for_job(fmt, plugin, robot, job, post))
    value = PostInputs(post, profiles, process_for_job(job, post))
    _RESOLVED.clear()
    _RESOLVED.update(key=key, job=job, value=value)
    return value


def preflight(robot, job, outdir) -> PostInputs:
    """Before any work: every format's plugin and profile load and the output folder can be
    written (bad input surfaces in seconds, not after planning). Returns the post inputs."""
    inputs = post_inputs(job, robot)
    prepare_outdir(Path(outdir))
    return inputs


def write_job_programs(trajectory, robot, job, outdir, path=None, report: dict | None = None,
                       world=None, before_placing=None) -> list[Path]:
    """``write_programs`` with the job's post inputs (``post_inputs``): for callers that hold a job."""
    inputs = post_inputs(job, robot)
    return write_programs(trajectory, robot, inputs.settings, inputs.profiles, outdir, process=inputs.process,
                          path=path, report=report, world=world, before_placing=before_placing)
