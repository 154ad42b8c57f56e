"""Former module of the CSV post-processor, kept so existing imports (and entry points naming
``postprocessors.csv_joint:CsvPost``) keep working; see ``postprocessors.csv``."""
from .csv import CsvPost  # noqa: F401
from .csv.dialect import columns_for, trailer  # noqa: F401
from .csv.parser import read_table  # noqa: F401
