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
  environment variable ``CAMTOOL_PLUGINS`` (a comma-separated allow-list of plugin names,
  empty: none) loads only those named.

The registry is built once per process and cached; ``clear_cache()`` forgets it.
"""
from __future__ import annotations

import functools
import importlib
import os
from dataclasses import dataclass
from importlib.metadata import entry_points

from camtool.errors import BadInput

from .plugin import PostProcessor

GROUP = "camtool.postprocessors"
ALLOW_ENV = "CAMTOOL_PLUGINS"
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


def disable_plugins() -> None:
    """Load only the built-ins from now on, in this process and its children (``--no-plugins``)."""
    os.environ[OFF_ENV] = "1"
    clear_cache()


def _enabled() -> bool:
    return os.environ.get(OFF_ENV, "") in ("", "0")


def _allowed() -> set[str] | None:
    """The names ``CAMTOOL_PLUGINS`` allows, or None when it is not set (all allowed)."""
    raw = os.environ.get(ALLOW_ENV)
    if raw is None:
        return None
    return {n.strip() for n in raw.split(",") if n.strip()}


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
        for ep in eps:
            dist = getattr(ep, "dist", None)
            source = dist.name if dist is not None else "?"
            if source == SELF_DIST:
                continue
            if allowed is not None and ep.name not in allowed:
                continue
            if ep.name in found:
                winner = found[ep.name]
                refused.append(PluginInfo(ep.name, None, source, ep.value,
                                          f"name clash: {ep.name!r} is already provided by {winner.source}"
                                          + (" (a built-in, which always wins)" if winner.builtin else "")
                                          + "; this entry point is ignored"))
                continue
            found[ep.name] = _load(ep.name, ep.value, source, ep.load)
    return tuple(sorted(found.items())), tuple(refused)


def discover() -> dict[str, PluginInfo]:
    """Every post-processor by name (a plugin that failed to load is listed with its error);
    each call returns a new dict."""
    return dict(_registry()[0])


def clashes() -> list[PluginInfo]:
    """Entry points refused because their name was taken (built-ins always win)."""
    return list(_registry()[1])


def clear_cache() -> None:
    """Forget the registry: the next call scans the entry points again."""
    _registry.cache_clear()


def get_plugin(name: str) -> PostProcessor:
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
