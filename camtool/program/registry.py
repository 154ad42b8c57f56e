"""The post-processor registry: the built-ins, registered here in code, and the plugins of
the entry-point group ``camtool.postprocessors``.

- **Built-ins always win.** ``rapid``, ``inform``, ``csv``, ``krl`` and ``fanuc`` are named below, not through
  installed metadata, so no installed package (nor a stale install of camtool itself) can
  replace them. An entry point of another package that claims a built-in's name (or a name
  another plugin already has) is a clash: it is not loaded, and ``camtool posts`` lists it
  as an error.
- **A broken plugin breaks only itself.** Whatever its import raises (``SystemExit`` and
  ``KeyboardInterrupt`` included) is caught per plugin and listed by ``camtool posts``;
  every other command runs on without it.
- **Locked-down cells**: ``camtool --no-plugins`` (``disable_plugins()``, which sets
  ``CAMTOOL_NO_PLUGINS=1`` for child processes too) loads no third-party plugin; the
  environment variable ``CAMTOOL_PLUGINS`` (a comma-separated allow-list, empty: none) loads only
  the plugins it names by distribution: ``DIST`` (every entry point of that installed package) or
  ``DIST:NAME`` (one entry point of it). A plugin name alone allows nothing: a package that sorts
  first cannot take a name from the real one.
- **A name two packages claim** is refused for both (``camtool posts`` lists them): camtool never
  picks one of two by sort order.
- **Imported only when asked for**: a plugin is imported when its format is used (``get_plugin``) or
  listed (``camtool posts``), never by a run or a check of another format, and under a time limit
  (``CAMTOOL_PLUGIN_TIMEOUT_S``, default 10 s): a plugin whose import hangs is an error of its own.

The registry is built once per process and cached; ``clear_cache()`` forgets it.
"""
from __future__ import annotations

import functools
import importlib
import os
import re
import threading
from dataclasses import dataclass, field
from importlib.metadata import entry_points

from camtool.errors import BadInput

from .plugin import PostProcessor

GROUP = "camtool.postprocessors"
ALLOW_ENV = "CAMTOOL_PLUGINS"
TIMEOUT_ENV = "CAMTOOL_PLUGIN_TIMEOUT_S"
IMPORT_TIMEOUT_S = 10.0
OFF_ENV = "CAMTOOL_NO_PLUGINS"
SELF_DIST = "camtool"  # camtool's own (possibly stale) entry points: the built-ins below replace them
BUILTINS = {  # name -> module:class, imported on first use
    "rapid": "postprocessors.rapid:RapidPost",
    "inform": "postprocessors.inform:InformPost",
    "csv": "postprocessors.csv:CsvPost",
    "krl": "postprocessors.krl:KrlPost",
    "fanuc": "postprocessors.fanuc:FanucPost",
}


@dataclass(frozen=True)
class PluginInfo:
    """A registered (or refused) post-processor: its object, the package providing it, any error."""

    name: str
    plugin: PostProcessor | None
    source: str
    entry_point: str
    error: str = ""
    builtin: bool = False
    load: object = field(default=None, repr=False, compare=False)  # a third-party plugin not imported yet


def disable_plugins() -> None:
    """Load only the built-ins from now on, in this process and its children (``--no-plugins``)."""
    os.environ[OFF_ENV] = "1"
    clear_cache()


def _enabled() -> bool:
    return os.environ.get(OFF_ENV, "") in ("", "0")


def _dist_key(name: str) -> str:
    """A distribution name compared as packaging does (PEP 503: case, ``-``, ``_`` and ``.`` alike)."""
    return re.sub(r"[-_.]+", "-", name).lower()


def _allowed() -> set[tuple[str, str | None]] | None:
    """The (distribution, entry point or None: all of it) pairs ``CAMTOOL_PLUGINS`` allows, or None
    when it is not set (all allowed)."""
    raw = os.environ.get(ALLOW_ENV)
    if raw is None:
        return None
    out = set()
    for item in (n.strip() for n in raw.split(",")):
        if item:
            dist, _, name = item.partition(":")
            out.add((_dist_key(dist.strip()), name.strip() or None))
    return out


def _is_allowed(allowed, source: str, name: str) -> bool:
    return allowed is None or (_dist_key(source), None) in allowed or (_dist_key(source), name) in allowed


def _timeout_s() -> float:
    try:
        t = float(os.environ.get(TIMEOUT_ENV, IMPORT_TIMEOUT_S))
    except ValueError:
        return IMPORT_TIMEOUT_S
    return t if 0 < t <= 3600 else IMPORT_TIMEOUT_S


def _load_in_time(info: PluginInfo) -> PluginInfo:
    """Import a third-party plugin now, in a thread given ``CAMTOOL_PLUGIN_TIMEOUT_S``: an import that
    hangs leaves that thread behind and makes this plugin an error, never the command a hang."""
    box: list[PluginInfo] = []
    worker = threading.Thread(target=lambda: box.append(_load(info.name, info.entry_point, info.source, info.load)),
                              daemon=True, name=f"camtool-plugin-{info.name}")
    worker.start()
    worker.join(_timeout_s())
    if not box:
        return PluginInfo(info.name, None, info.source, info.entry_point,
                          f"its import did not finish within {_timeout_s():g} s ({TIMEOUT_ENV})")
    return box[0]


_LOADED: dict[tuple[str, str], PluginInfo] = {}
_LOADED_LOCK = threading.Lock()


def _loaded(info: PluginInfo) -> PluginInfo:
    if info.load is None:
        return info
    key = (info.source, info.name)
    with _LOADED_LOCK:
        if key not in _LOADED:
            _LOADED[key] = _load_in_time(info)
        return _LOADED[key]


def _load(name: str, value: str, source: str, load, builtin: bool = False) -> PluginInfo:
    try:
        obj = load()
        plugin = obj() if isinstance(obj, type) else obj
        if not isinstance(plugin, PostProcessor):
            raise TypeError("it does not derive from camtool.program.plugin.PostProcessor (docs/plugins.md)")
        if plugin.name != name:
            raise TypeError(f"entry point name {name!r} differs from plugin.name {plugin.name!r}")
        if not plugin.extension:
            raise TypeError("it declares no file extension")
        return PluginInfo(name, plugin, source, value, builtin=builtin)
    except BaseException as exc:  # noqa: BLE001 - a plugin's import must never stop camtool (SystemExit too)
        if builtin:
            raise
        return PluginInfo(name, None, source, value, f"{type(exc).__name__}: {exc}")


def _builtin_loader(value: str):
    module, attr = value.split(":")
    return lambda: getattr(importlib.import_module(module), attr)


@functools.cache
def _registry() -> tuple[tuple[tuple[str, PluginInfo], ...], tuple[PluginInfo, ...]]:
    """((name, info) of every plugin, sorted), (refused entry points: clashes))."""
    found = {name: _load(name, value, "camtool", _builtin_loader(value), builtin=True)
             for name, value in BUILTINS.items()}
    refused: list[PluginInfo] = []
    allowed = _allowed()
    if _enabled():
        try:
            eps = sorted(entry_points(group=GROUP), key=lambda e: (e.name, e.value))
        except Exception as exc:  # noqa: BLE001 - broken installed metadata: no third-party plugins
            eps = []
            refused.append(PluginInfo("?", None, "?", GROUP, f"cannot read the installed entry points ({exc})"))
        claims: dict[str, list[str]] = {}
        for ep in eps:
            dist = getattr(ep, "dist", None)
            source = dist.name if dist is not None else "?"
            if source != SELF_DIST and _is_allowed(allowed, source, ep.name) and ep.name not in found:
                claims.setdefault(ep.name, []).append(source)
        for ep in eps:
            dist = getattr(ep, "dist", None)
            source = dist.name if dist is not None else "?"
            if source == SELF_DIST:
                continue
            if not _is_allowed(allowed, source, ep.name):
                continue
            if len(set(claims.get(ep.name, ()))) > 1:  # two packages claim one name: neither is trusted
                refused.append(PluginInfo(ep.name, None, source, ep.value,
                                          f"name clash: {ep.name!r} is claimed by {', '.join(sorted(set(claims[ep.name])))}; "
                                          f"neither is loaded (allow one with {ALLOW_ENV}=DIST:{ep.name})"))
                continue
            if ep.name in found:
                winner = found[ep.name]
                refused.append(PluginInfo(ep.name, None, source, ep.value,
                                          f"name clash: {ep.name!r} is already provided by {winner.source}"
                                          + (" (a built-in, which always wins)" if winner.builtin else "")
                                          + "; this entry point is ignored"))
                continue
            found[ep.name] = PluginInfo(ep.name, None, source, ep.value, load=ep.load)  # imported when asked for
    return tuple(sorted(found.items())), tuple(refused)


def discover(load: bool = True) -> dict[str, PluginInfo]:
    """Every post-processor by name (a plugin that failed to load is listed with its error); each call
    returns a new dict. ``load=False``: third-party plugins are not imported (their ``plugin`` is None)."""
    return {name: (_loaded(info) if load else info) for name, info in _registry()[0]}


def clashes() -> list[PluginInfo]:
    """Entry points refused because their name was taken (built-ins always win)."""
    return list(_registry()[1])


def clear_cache() -> None:
    """Forget the registry: the next call scans the entry points again."""
    _registry.cache_clear()
    with _LOADED_LOCK:
        _LOADED.clear()


def get_plugin(name: str) -> PostProcessor:
    """The plugin object for a format name; BadInput naming the installed ones."""
    plugins = discover(load=False)
    info = plugins.get(name)
    if info is not None:
        info = _loaded(info)  # only the format asked for is imported
    if info is None:
        raise BadInput(f"post.formats: no post-processor {name!r} is installed "
                       f"(installed: {', '.join(plugins) or 'none'}; see `camtool posts`)")
    if info.plugin is None:
        raise BadInput(f"post.formats: post-processor {name!r} from {info.source} failed to load: {info.error}")
    return info.plugin


def describe_plugins() -> list[dict]:
    """Name, extension, source package, entry point, options, check (for ``camtool posts``);
    refused entry points (clashes) follow as rows named ``name@package`` with their error."""
    out = []
    for info in discover().values():
        p = info.plugin
        row = {"name": info.name, "extension": p.extension if p is not None else "", "source": info.source,
               "entry_point": info.entry_point, "builtin": info.builtin, "options": {}}
        if p is not None:
            for k, (typ, default, doc) in p.options_schema.items():
                row["options"][k] = {"type": typ.__name__ if isinstance(typ, type) else str(typ),
                                     "default": default, "doc": doc}
            row["check"] = "own" if p.own_check else "read-back"
            row["simulated"] = p.simulated
        if info.error:
            row["error"] = info.error
        out.append(row)
    for info in clashes():
        out.append({"name": f"{info.name}@{info.source}", "extension": "", "source": info.source,
                    "entry_point": info.entry_point, "builtin": False, "options": {}, "error": info.error,
                    "clash": True})
    return out
