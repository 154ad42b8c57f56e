"""The ``Path``: tool-centre-point poses in S order, with segments and zones.

Each pose k carries ``segment[k]`` (i, 0-based), ``point[k]`` (j, 1-based on
work points, 0 elsewhere) and ``zone[k]`` (a code from ``ZONES``). Poses are
4x4 TCP poses in the **world (cell) frame**, translations in mm; the tool z
axis points into the surface.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path as FsPath

import numpy as np

from .errors import BadInput

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


def save_path(path: Path, file: str | FsPath) -> None:
    """Save a Path to ``.npz``."""
    from .files import output_file

    np.savez_compressed(
        output_file(file), poses_mm=path.poses_mm, segment=path.segment, point=path.point, zone=path.zone,
        free_spin=np.array(path.free_spin), step_over_mm=np.array(path.step_over_mm),
        pitch_mm=np.array(path.pitch_mm), zones=np.array(ZONES),
    )


def load_path(file: str | FsPath) -> Path:
    """Load a Path saved by ``save_path``."""
    try:
        with np.load(file) as d:
            if tuple(d["zones"]) != ZONES:
                raise BadInput(f"{file}: path file uses zone labels {tuple(d['zones'])}, expected {ZONES}")
            return Path(
                d["poses_mm"], d["segment"], d["point"], d["zone"], bool(d["free_spin"]),
                float(d["step_over_mm"]), float(d["pitch_mm"]),
            )
    except FileNotFoundError:
        raise BadInput(f"{file}: path file not found") from None
    except (KeyError, ValueError, OSError) as exc:
        raise BadInput(f"{file}: not a camtool path file ({exc})") from None
