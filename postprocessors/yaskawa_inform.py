"""Former module of the Yaskawa INFORM post-processor, kept so existing imports (and entry
points naming ``postprocessors.yaskawa_inform:InformPost``) keep working; see
``postprocessors.inform``."""
from .inform import InformPost  # noqa: F401
from .inform.dialect import PL_MM, group_axes, job_name, vj_percent  # noqa: F401
from .inform.parser import JbiMove, JbiText, job_files, parse_jbi  # noqa: F401
