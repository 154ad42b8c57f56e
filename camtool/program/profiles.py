"""Controller profiles for a plugin: a profile file (or the shipped default) validated against
the plugin's options schema and ``validate_profile``; and a format's option defaults.

The plugin is passed in by the caller (the post stage resolves it once); given only a format
name, it is looked up in the registry.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from camtool.errors import BadInput
from camtool.profiles import Profile, default_profile_path, parse_profile, read_profile_file

from .plugin import PostProcessor


def _plugin(fmt: str, plugin: PostProcessor | None) -> PostProcessor:
    if plugin is not None:
        return plugin
    from .registry import get_plugin

    return get_plugin(fmt)


def load_profile(path: str | Path | None, robot_name: str, fmt: str, robot=None,
                 plugin: PostProcessor | None = None) -> Profile:
    """Load and validate a controller profile.

    ``path`` None takes the shipped default ``<robot_name>_<fmt>.toml`` (BadInput when there
    is none). Options are checked against the plugin's schema (``plugin``, else the
    registered plugin of ``fmt``); with ``robot`` given, the axis map is checked against
    its joints and by the plugin's ``validate_profile``.
    """
    if path is None:
        path = default_profile_path(robot_name, fmt)
        if path is None:
            raise BadInput(f"no default {fmt} profile for robot {robot_name!r}: write one (docs/controllers.md) "
                           f"and name it in the job's post.profiles.{fmt}")
    path = Path(path)
    data = read_profile_file(path)
    plugin = _plugin(fmt, plugin)
    profile = parse_profile(data, str(path), fmt, robot, plugin.options_schema)
    if robot is not None:
        plugin.validate_profile(profile, robot)
    return profile


def default_options(fmt_or_plugin: str | PostProcessor) -> dict[str, Any]:
    """The options of a format's plugin at their defaults."""
    plugin = fmt_or_plugin if isinstance(fmt_or_plugin, PostProcessor) else _plugin(fmt_or_plugin, None)
    return {k: d for k, (_t, d, _doc) in plugin.options_schema.items()}


def defaults_profile(fmt: str, robot_name: str, plugin: PostProcessor) -> Profile:
    """A profile of option defaults only, for a plugin that needs no axis map."""
    return Profile("<defaults>", fmt, robot_name, options=default_options(plugin))
