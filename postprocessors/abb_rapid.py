"""Former module of the ABB RAPID post-processor, kept so existing imports (and entry points
naming ``postprocessors.abb_rapid:RapidPost``) keep working; see ``postprocessors.rapid``."""
from .rapid import RapidPost  # noqa: F401
from .rapid.dialect import (BLEND_ZONES, RESERVED, SPEEDS, ZONE_MM, fmt_column, fmt_num, fmt_t,  # noqa: F401
                            rapid_identifier)
from .rapid.parser import Move, ModuleText, parse_module, program_modules, read_pgf  # noqa: F401
