"""Output helpers for the CLI: JSON or human text, and a progress context."""
from __future__ import annotations

import json
import sys
from contextlib import contextmanager

import click
import numpy as np


def _plain(obj):
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def to_json(obj) -> str:
    """Deterministic, indented JSON of dicts / lists / numpy values."""
    return json.dumps(_plain(obj), indent=2, sort_keys=False)


_RESULT_FD: list[int] = []  # a batch job's result pipe (CAMTOOL_RESULT_FD), taken once at start


def take_result_channel() -> None:
    """In a batch or watch job: take the result pipe its parent passed (``CAMTOOL_RESULT_FD``) and keep it
    from every process this one starts; ``echo_json`` then writes there, and stdout is only a log."""
    import os

    raw = os.environ.pop("CAMTOOL_RESULT_FD", None)
    if raw is None or not raw.isdigit():
        return
    fd = int(raw)
    try:
        os.set_inheritable(fd, False)
    except OSError:
        return
    _RESULT_FD.append(fd)


def echo_json(obj) -> None:
    if _RESULT_FD:
        import os

        fd = _RESULT_FD.pop()
        data = (to_json(obj) + "\n").encode()
        try:
            while data:
                data = data[os.write(fd, data):]
        finally:
            os.close(fd)
        return
    click.echo(to_json(obj))


def progress_enabled() -> bool:
    """Progress bars only on an interactive terminal (never in pipes or CI)."""
    return sys.stderr.isatty()


@contextmanager
def progress(description: str, total: int | None = None):
    """A rich progress bar on stderr when interactive; yields ``advance(n)``."""
    if not progress_enabled():
        yield lambda n=1: None
        return
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
    from rich.console import Console

    with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                  TimeRemainingColumn(), console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task(description, total=total)
        yield lambda n=1: bar.advance(task, n)


class StageProgress:
    """Progress of a run's stages on stderr: a rich status line on a terminal, one log line per stage elsewhere.

    ``done(name)`` is called when a stage finishes; ``NEXT`` names what comes
    after it, so the terminal shows what is running now. Off a terminal (batch
    logs, CI) and with ``log``, each finished stage is one line
    ``camtool: <stage> (<t> s)``; without ``log`` nothing is printed there, so an
    error stays the one line on stderr. ``quiet`` silences both.
    """

    NEXT = {"workpiece": "fitting the surface", "fit": "rastering the path", "raster": "planning the joints",
            "plan": "timing the trajectory", "time": "checking the motion", "check": "writing the programs",
            "post": "writing the report"}
    DONE = {"workpiece": "loaded workpiece", "fit": "fitted surface", "raster": "rastered path",
            "plan": "planned joints", "time": "timed trajectory", "check": "motion check passed",
            "post": "wrote programs"}

    def __init__(self, quiet: bool = False, log: bool = False):
        import time

        self._clock = time.perf_counter
        self.t0 = self._clock()
        self.quiet = quiet or not (progress_enabled() or log)
        self.live = progress_enabled() and not quiet
        self._status = None
        if self.live:
            from rich.console import Console

            self._status = Console(stderr=True).status("loading the workpiece")
            self._status.start()

    def done(self, name: str) -> None:
        t = self._clock() - self.t0
        if self.quiet:
            return
        if self._status is not None:
            self._status.console.print(f"  {self.DONE.get(name, name):<20} {t:7.1f} s")
            self._status.update(self.NEXT.get(name, "finishing"))
        else:
            click.echo(f"camtool: {self.DONE.get(name, name)} ({t:.1f} s)", err=True)

    def close(self) -> None:
        if self._status is not None:
            self._status.stop()
            self._status = None
