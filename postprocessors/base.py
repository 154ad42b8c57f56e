"""The post-processor plugin protocol and the entry-point registry.

A post-processor turns a timed ``camtool.trajectory.Trajectory`` into
controller program files. Plugins are found through the entry-point group
``camtool.postprocessors`` (``importlib.metadata.entry_points``); the
built-ins (rapid, inform, csv) register the same way in camtool's
pyproject.toml. An entry point names a class (instantiated without arguments)
or an instance. See docs/plugins.md.

The built-ins are ordinary plugins: each owns its writer, reader and check.
The registry is discovered once per process and cached (``discover``);
``clear_cache()`` forgets it, for tests that install or fake plugins.
"""
from __future__ import annotations

import functools
import logging
import re
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from camtool.errors import BadInput

GROUP = "camtool.postprocessors"
log = logging.getLogger("camtool.post")

# Built-in plugins, used only when camtool runs from a source tree that was
# never pip-installed (then no entry points exist).
_BUILTIN_FALLBACK = {
    "rapid": "postprocessors.abb_rapid:RapidPost",
    "inform": "postprocessors.yaskawa_inform:InformPost",
    "csv": "postprocessors.csv_joint:CsvPost",
}


@runtime_checkable
class PostProcessor(Protocol):
    """What a post-processor plugin provides.

    - ``name``: the format name used in ``post.formats`` (e.g. ``"rapid"``).
    - ``extension``: main file extension with the dot (e.g. ``".mod"``).
    - ``options_schema``: option -> (type, default, doc); the options live in
      the ``[options]`` table of the controller profile.
    - ``write(trajectory, robot, profile, outdir)`` writes the program files
      into ``outdir`` and returns their paths, the entry file first.
    - ``read(path, robot, profile)`` returns ``(durations_s, q)``: the duration
      of each move (s, NaN where the program gives none) and the joint values
      (M x dof, rad / mm) of each move's target.

    Optional attributes: ``requires_profile`` (bool, default True: a profile
    with an axis map is needed), ``extensions`` (every file type it writes,
    default ``(extension,)``; ``camtool check`` finds a file's format by
    them), ``validate_profile(profile, robot)``, ``job_options(job) -> dict``
    (options the plugin takes from job keys, such as the CSV angle unit) and
    ``check(path, robot, profile) -> list[str]`` (findings for one written
    file, empty when clean).
    A plugin without ``check`` is checked by reading its entry file back
    (``postprocessors.check.read_back_check``).
    """

    name: str
    extension: str
    options_schema: dict[str, tuple[type, Any, str]]

    def write(self, trajectory, robot, profile, outdir: Path) -> list[Path]: ...

    def read(self, path: Path, robot, profile) -> tuple[np.ndarray, np.ndarray]: ...


@dataclass(frozen=True)
class ProcessInfo:
    """What camtool knows about the process beyond the joint trajectory, for plugins that
    take it: ``write(trajectory, robot, profile, outdir, process=ProcessInfo(...))``.

    A plugin opts in by accepting the keyword ``process`` in ``write`` (camtool inspects the
    signature; a plugin without it is called as before). Every field has a default, so a
    plugin must work with ``ProcessInfo()`` too.

    - ``path_tol_mm``: largest distance of the program's interpolated TCP from the planned
      path (job key ``post.path_tol_mm``); moves are merged and corners blended within it.
    - ``ori_tol_deg``: largest tool-orientation deviation of merged Cartesian moves.
    - ``feed_mm_s``: the commanded TCP speed on work (``timing.tcp_speed_mm_s``), or None.
    - ``job_name``: the job file's name (for program comments), ``""`` when unknown.
    - ``job_time``: ``"yyyy/mm/dd hh:mm"`` (UTC) of the job file's modification, or None.
    - ``row_labels``: a label per work row, in order (e.g. the raster segment), or ().
    """

    path_tol_mm: float = 0.1
    ori_tol_deg: float = 0.5
    feed_mm_s: float | None = None
    job_name: str = ""
    job_time: str | None = None
    row_labels: tuple = field(default_factory=tuple)


DATE_FORMAT = "%Y/%m/%d %H:%M"


def program_date(option: str, process: "ProcessInfo | None" = None) -> str:
    """The date a program shows, ``yyyy/mm/dd hh:mm`` (UTC):

    - ``"job"`` (the default of the built-ins): the job file's modification time
      (``process.job_time``), so rerunning the same job gives byte-identical programs;
      without a job, as ``"now"``;
    - ``"now"``: the clock, or ``SOURCE_DATE_EPOCH`` when set (reproducible builds);
    - anything else is taken as the date itself (already checked by the plugin).
    """
    import os
    from datetime import datetime, timezone

    if option == "job" and process is not None and process.job_time:
        return process.job_time
    if option in ("job", "now"):
        epoch = os.environ.get("SOURCE_DATE_EPOCH")
        when = datetime.fromtimestamp(int(epoch), timezone.utc) if epoch and epoch.isdigit() \
            else datetime.now(timezone.utc)
        return when.strftime(DATE_FORMAT)
    return option


def accepts_process(plugin) -> bool:
    """True when ``plugin.write`` takes the keyword ``process`` (a ``ProcessInfo``)."""
    import inspect

    try:
        params = inspect.signature(plugin.write).parameters
    except (TypeError, ValueError):
        return False
    return "process" in params or any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())


@dataclass(frozen=True)
class PluginInfo:
    """A discovered plugin: its object, the package that provides it, any load error."""

    name: str
    plugin: Any
    source: str
    entry_point: str
    error: str = ""


def _load_entry(name: str, value: str, source: str, load) -> PluginInfo:
    try:
        obj = load()
        plugin = obj() if isinstance(obj, type) else obj
        missing = [a for a in ("name", "extension", "options_schema", "write") if not hasattr(plugin, a)]
        if missing:
            raise TypeError(f"missing {', '.join(missing)}")
        if plugin.name != name:
            raise TypeError(f"entry point name {name!r} differs from plugin.name {plugin.name!r}")
        return PluginInfo(name, plugin, source, value)
    except Exception as exc:  # a broken third-party plugin must not break camtool
        return PluginInfo(name, None, source, value, f"{type(exc).__name__}: {exc}")


def discover() -> dict[str, PluginInfo]:
    """All post-processors, by name: entry points of group ``camtool.postprocessors``.

    A plugin that fails to load is listed with its error. When two packages
    register the same name, the first one found wins and the other is ignored
    with a log warning. The entry points are scanned once per process (the
    result is cached; ``clear_cache()`` forgets it); each call returns a new dict.
    """
    return dict(_registry())


def clear_cache() -> None:
    """Forget the discovered plugins: the next ``discover`` scans the entry points again."""
    _registry.cache_clear()


@functools.cache
def _registry() -> tuple[tuple[str, PluginInfo], ...]:
    found: dict[str, PluginInfo] = {}
    for ep in sorted(entry_points(group=GROUP), key=lambda e: (e.name, e.value)):
        source = ep.dist.name if getattr(ep, "dist", None) is not None else "?"
        if ep.name in found:
            log.warning("post-processor %r from %s ignored: already provided by %s",
                        ep.name, source, found[ep.name].source)
            continue
        found[ep.name] = _load_entry(ep.name, ep.value, source, ep.load)
    for name, value in _BUILTIN_FALLBACK.items():
        if name not in found:
            module, attr = value.split(":")

            def load(module=module, attr=attr):
                import importlib
                return getattr(importlib.import_module(module), attr)
            found[name] = _load_entry(name, value, "camtool (source tree)", load)
    return tuple(sorted(found.items()))


def get_plugin(name: str):
    """The plugin object for a format name; BadInput naming the installed ones."""
    plugins = discover()
    info = plugins.get(name)
    if info is None:
        raise BadInput(f"post.formats: no post-processor {name!r} is installed "
                       f"(installed: {', '.join(plugins) or 'none'}; see `camtool posts`)")
    if info.plugin is None:
        raise BadInput(f"post.formats: post-processor {name!r} from {info.source} failed to load: {info.error}")
    return info.plugin


def describe_plugins() -> list[dict]:
    """Name, extension, source package, entry point, options (for ``camtool posts``)."""
    out = []
    for info in discover().values():
        p = info.plugin
        options = {}
        if p is not None:
            for k, (typ, default, doc) in p.options_schema.items():
                options[k] = {"type": getattr(typ, "__name__", str(typ)), "default": default, "doc": doc}
        out.append({"name": info.name, "extension": getattr(p, "extension", ""), "source": info.source,
                    "entry_point": info.entry_point, "options": options,
                    **({"check": "own" if hasattr(p, "check") else "read-back"} if p is not None else {}),
                    **({"error": info.error} if info.error else {})})
    return out


# --- helpers shared by the built-in writers -------------------------------------------------

def sanitise_name(raw: str, *, max_len: int, reserved: frozenset[str] = frozenset(),
                  upper: bool = False, what: str = "name") -> tuple[str, str]:
    """A controller-safe identifier: letters, digits and ``_``, leading letter, at most
    ``max_len`` characters, not in ``reserved`` (compared case-insensitively).

    Returns ``(name, note)``; ``note`` is empty when ``raw`` was already valid.
    """
    s = raw.upper() if upper else raw
    s = re.sub(r"[^A-Za-z0-9_]", "_", s.encode("ascii", "replace").decode("ascii"))
    if not s or not s[0].isalpha():
        s = ("P" if upper else "p") + s
    s = s[:max_len]
    if s.upper() in {r.upper() for r in reserved}:
        s = (s[:max_len - 2] + "_1")
    note = "" if s == raw else f"{what} {raw!r} is not valid for the controller; written as {s!r}"
    if note:
        log.warning(note)
    return s, note


def joint_values_edge(trajectory_q: np.ndarray, prismatic: np.ndarray) -> np.ndarray:
    """Joint values in edge units: degrees for revolute joints, mm for prismatic."""
    return np.where(prismatic[None, :], trajectory_q, np.degrees(trajectory_q))


def chunks(n: int, size: int) -> list[range]:
    """Split range(n) into consecutive ranges of at most ``size``."""
    return [range(i, min(i + size, n)) for i in range(0, n, size)] or [range(0)]
