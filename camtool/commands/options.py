"""Bounded command-line values shared by batch and watch: one clear line (exit 2) for nan, inf or a
value past its bound, and SIGTERM handled like Ctrl-C so no job outlives its batch."""
from __future__ import annotations

import math
import signal
from contextlib import contextmanager

import click

MAX_WORKERS = 256
MAX_TIMEOUT_S = 7 * 24 * 3600.0  # a week
MAX_INTERVAL_S = 24 * 3600.0  # a day


class BoundedFloat(click.ParamType):
    """A finite float in (0, ``maximum``]: nan and inf are refused (click's FloatRange lets nan through)."""

    name = "float"

    def __init__(self, maximum: float, unit: str = "s"):
        self.maximum, self.unit = maximum, unit

    def convert(self, value, param, ctx):
        try:
            x = float(value)
        except (TypeError, ValueError):
            self.fail(f"{str(value)[:40]!r} is not a number", param, ctx)
        if not math.isfinite(x) or not 0 < x <= self.maximum:
            self.fail(f"{str(value)[:40]!r} is not a finite number above 0 and at most {self.maximum:g} {self.unit}",
                      param, ctx)
        return x


WORKERS = click.IntRange(min=1, max=MAX_WORKERS)
TIMEOUT = BoundedFloat(MAX_TIMEOUT_S)
INTERVAL = BoundedFloat(MAX_INTERVAL_S)


@contextmanager
def sigterm_as_interrupt():
    """Inside the block SIGTERM raises KeyboardInterrupt in the main thread, as Ctrl-C does: the batch
    machinery then kills every running job's process group before camtool exits (exit 130)."""
    def handler(signum, frame):
        raise KeyboardInterrupt

    try:  # SIGHUP (the terminal or the session went away) too: never leave the jobs running
        previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGTERM, signal.SIGHUP)}
    except ValueError:  # not the main thread (e.g. embedded): nothing to install
        yield
        return
    try:
        yield
    finally:
        for sig, prev in previous.items():
            signal.signal(sig, prev)
