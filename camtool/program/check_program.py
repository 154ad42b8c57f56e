"""A program file by path (``camtool check``): its format from the extensions the registered
plugins declare, the profile to check it with, and its findings and summary."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from camtool.errors import BadInput

from .check import check_file

def format_of(path: Path) -> str:
    """The format of a program file from its extension, as the installed plugins declare it
    (``extensions``, else ``extension``); BadInput when none or several claim it."""
    from .registry import discover

    ext = Path(path).suffix.lower()
    # the built-ins first: a third-party plugin is imported only when no built-in reads this extension
    known = {name: info.plugin.file_types() for name, info in discover(load=False).items() if info.plugin is not None}
    if not any(ext in exts for exts in known.values()):
        known = {name: info.plugin.file_types() for name, info in discover().items() if info.plugin is not None}
    fmts = [name for name, exts in known.items() if ext in exts]
    if not fmts:
        every = sorted({e for exts in known.values() for e in exts})
        raise BadInput(f"{path}: unknown program type {ext!r} (expected {', '.join(every)}; "
                       "or name the format with --format)")
    if len(fmts) > 1:
        raise BadInput(f"{path}: {ext!r} files are written by several post-processors ({', '.join(fmts)}); "
                       "name the format with --format")
    return fmts[0]


def profile_for_check(fmt: str, plugin, robot, profile_file=None):
    """The profile to check a file with: the given file, else the shipped default for the
    robot, else (for a plugin with ``requires_profile = False``) its option defaults."""
    from .profiles import default_profile_path

    from .profiles import defaults_profile, load_profile

    if profile_file is None and default_profile_path(robot.name, fmt) is None and not plugin.requires_profile:
        return defaults_profile(fmt, robot.name, plugin)
    return load_profile(profile_file, robot.name, fmt, robot, plugin)


def _program(path, robot, profile, fmt):
    from .registry import get_plugin

    path = Path(path)
    if not path.is_file():
        raise BadInput(f"{path}: program file not found")
    fmt = fmt or format_of(path)
    plugin = get_plugin(fmt)
    if profile is None:
        profile = profile_for_check(fmt, plugin, robot)
    return path, fmt, plugin, profile


def check_program(path, robot, profile=None, fmt: str | None = None) -> list[str]:
    """Findings for one program file (empty when clean). ``fmt`` None takes the format from
    the file's extension; ``profile`` None the shipped default (``profile_for_check``)."""
    path, fmt, plugin, profile = _program(path, robot, profile, fmt)
    return check_file(plugin, path, robot, profile)


def check_summary(path, robot, profile=None, fmt: str | None = None) -> dict:
    """``check_program`` with a summary for scripts (``camtool check --json``): file, format,
    robot, profile, ok, findings, moves and duration_s (from the plugin's ``read``; None
    when the program cannot be read back)."""
    path, fmt, plugin, profile = _program(path, robot, profile, fmt)
    findings = check_file(plugin, path, robot, profile)
    moves = duration = None
    try:
        dur, q = plugin.read(path, robot, profile)
        dur = np.asarray(dur, float).reshape(-1)
        moves = int(len(np.asarray(q).reshape(-1, robot.dof)))
        total = float(np.nansum(dur)) if len(dur) else 0.0
        duration = round(total, 6) if np.isfinite(total) else None
    except Exception:  # noqa: BLE001 - the findings already say why it cannot be read
        moves = duration = None
    return {"file": str(path), "format": fmt, "robot": robot.name, "profile": profile.source,
            "ok": not findings, "findings": findings, "moves": moves, "duration_s": duration}
