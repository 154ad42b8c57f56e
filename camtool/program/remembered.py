"""Results of pure computations by their inputs' exact values, kept from one writing of a program to the next.

The post stage writes a program again where its simulator finds it off the planned path (``post``' closer
rounds): the writer's arc fit tests the same circles and corners again everywhere but in the stretches written
closer (the hood's second writing: nine stretches of 64 rows). A test's result is looked up by its inputs' bytes
(arrays: dtype, shape and bytes; numbers as they are), so it is the one computed from them: the same numbers.
"""
from __future__ import annotations

from typing import Any, Callable

import numpy as np


def _part(x) -> Any:
    """A hashable, exact stand-in of one input."""
    if isinstance(x, np.ndarray):
        return x.dtype.str, x.shape, x.tobytes()
    if isinstance(x, (tuple, list)):
        return tuple(_part(v) for v in x)
    if isinstance(x, (np.floating, np.integer, np.bool_)):
        return x.item()
    return x


class Remembered:
    """``value(name, inputs, compute)``: ``compute()``'s result, kept under ``name`` and the exact ``inputs``; at
    most ``keep`` results (then it starts again); ``forget()`` drops them (the post stage, a format done)."""

    def __init__(self, keep: int):
        self.keep = keep
        self._values: dict = {}

    def value(self, name: str, inputs: tuple, compute: Callable[[], Any]) -> Any:
        key = (name, _part(inputs))
        if key in self._values:
            return self._values[key]
        if len(self._values) >= self.keep:
            self._values.clear()
        value = self._values[key] = compute()
        return value

    def forget(self) -> None:
        self._values.clear()

    def __len__(self) -> int:
        return len(self._values)
