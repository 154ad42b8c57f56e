"""Output files: make the folder, and turn OS errors into one clear line."""
from __future__ import annotations

from pathlib import Path

from .errors import BadInput


def output_file(path: str | Path) -> Path:
    """``path`` with its folder created; BadInput when the folder cannot be made or written."""
    p = Path(path)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise BadInput(f"{p}: cannot create the folder {p.parent} ({exc.strerror or exc})") from None
    if p.is_dir():
        raise BadInput(f"{p}: is a folder, expected a file name")
    return p
