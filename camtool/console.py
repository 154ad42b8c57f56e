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


def echo_json(obj) -> None:
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
