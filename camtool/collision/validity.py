"""The planner's validity checks: ``valid(q) -> bool`` for one configuration, and
``valid_many(Q)`` for a batch (an edge's samples), which a check answers with one
distance query instead of one per configuration."""
from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np


class Validity(ABC):
    """A configuration check. ``valid_many`` must agree with ``__call__`` row by row."""

    @abstractmethod
    def __call__(self, q) -> bool:
        """Whether configuration q (rad / mm) is valid."""

    def valid_many(self, Q) -> np.ndarray:
        """(K,) bool: each row of Q checked; subclasses batch the work."""
        return np.array([self(q) for q in np.asarray(Q, float)], bool)

    def reason(self, q) -> str:
        """Why an invalid configuration q is invalid, for a refusal a user can act on."""
        return "a link or the tool comes too close to the part"


def reason_of(valid, q) -> str:
    """``valid.reason(q)`` for a ``Validity``; a plain callable cannot say."""
    return valid.reason(q) if isinstance(valid, Validity) else "the validity check refuses it"


def valid_rows(valid, Q) -> np.ndarray:
    """(K,) bool of each row of Q under ``valid``: a ``Validity`` in one batch, any other callable
    (a plain ``valid(q) -> bool``) row by row."""
    if isinstance(valid, Validity):
        return np.asarray(valid.valid_many(Q), bool)
    return np.array([bool(valid(q)) for q in np.asarray(Q, float)], bool)
