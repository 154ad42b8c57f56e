"""Former home of the plugin protocol and registry, kept so existing imports keep working.

The plugin base is ``camtool.program.plugin.PostProcessor``, the registry
``camtool.program.registry``, the process facts ``camtool.program.process``
(docs/plugins.md).
"""
from camtool.program.plugin import PostProcessor  # noqa: F401
from camtool.program.process import DATE_FORMAT, ProcessInfo, program_date  # noqa: F401
from camtool.program.registry import (GROUP, PluginInfo, clear_cache, describe_plugins, discover,  # noqa: F401
                                      get_plugin)
from camtool.program.text import chunks, joint_values_edge, sanitise_name  # noqa: F401
