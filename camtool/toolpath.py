"""The ``Path``: tool-centre-point poses in S order, with segments and zones.

Each pose k carries ``segment[k]`` (i, 0-based), ``point[k]`` (j, 1-based on
work points, 0 elsewhere) and ``zone[k]`` (a code from ``ZONES``). Poses are
4x4 TCP poses in the **world (cell) frame**, translations in mm; the tool z
axis points into the surface.
"""
from __future__ import annotations

from dataclasses import dataclass
import numpy as np

def freeze_arrays(box) -> None:
    """Make every numpy array field of a frozen dataclass read-only (a stage box never changes)."""
    for name, value in vars(box).items():
        if isinstance(value, np.ndarray) and value.flags.writeable:
            if value.base is not None:  # a view: freeze a copy, the owner's array stays the owner's
                value = value.copy()
                object.__setattr__(box, name, value)
            value.flags.writeable = False


ZONES = ("work", "self_motion", "lead_in", "lead_out", "approach", "depart", "retract")
ZONE_CODE = {name: code for code, name in enumerate(ZONES)}
WORK = ZONE_CODE["work"]


@dataclass(frozen=True)
class Path:
    """Tool poses (N x 4 x 4, mm) with segment, point and zone per pose."""

    poses_mm: np.ndarray
    segment: np.ndarray
    point: np.ndarray
    zone: np.ndarray
    free_spin: bool = False
    step_over_mm: float = 0.0
    pitch_mm: float = 0.0

    def __post_init__(self):
        freeze_arrays(self)

    def __len__(self) -> int:
        return len(self.poses_mm)

    @property
    def is_work(self) -> np.ndarray:
        return self.zone == WORK

    def zone_names(self) -> list[str]:
        return [ZONES[z] for z in self.zone]

    def length_mm(self) -> float:
        """Length of the TCP polyline through every pose, in mm."""
        p = self.poses_mm[:, :3, 3]
        return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())
