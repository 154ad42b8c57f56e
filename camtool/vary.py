"""``--vary NAME=LO:HI``: one search variable and its range, as `camtool design` and `camtool place` take them."""
from __future__ import annotations

import math
from typing import Callable

from .errors import BadInput


def parse_range(text: str, example: str, unit_of: Callable[[str], str] = lambda name: "mm") -> tuple[str, float, float]:
    """(name, lo, hi) of ``NAME=LO:HI`` with finite LO < HI; BadInput with one clear line otherwise.

    ``example`` ends the format message (e.g. " in mm, e.g. L1=300:600"); ``unit_of(name)`` names the
    unit in the number messages.
    """
    if "=" not in text or ":" not in text.split("=", 1)[1]:
        raise BadInput(f"--vary {text!r}: expected NAME=LO:HI{example}")
    name, rng = (t.strip() for t in text.split("=", 1))
    lo_txt, hi_txt = rng.split(":", 1)
    unit = unit_of(name)
    try:
        lo, hi = float(lo_txt), float(hi_txt)
    except ValueError:
        raise BadInput(f"--vary {text!r}: LO and HI must be numbers ({unit})") from None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise BadInput(f"--vary {text!r}: LO and HI must be finite numbers ({unit})")
    if not lo < hi:
        raise BadInput(f"--vary {text!r}: empty range, LO must be below HI")
    return name, lo, hi
