"""The ``Path``: tool-centre-point poses in S order, with segments and zones.

Each pose k carries ``segment[k]`` (i, 0-based), ``point[k]`` (j, 1-based on
work points, 0 elsewhere) and ``zone[k]`` (a code from ``ZONES``); a path over
several faces of a part also ``face[k]``, the face's number (``camtool.path.face_set``). Poses are
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
SURFACE_ZONES = ("work", "lead_in", "lead_out")  # the tool is on the part
SURFACE_CODES = tuple(ZONE_CODE[z] for z in SURFACE_ZONES)


def row_segments(path_index: np.ndarray, zone: np.ndarray, path_segment: np.ndarray) -> np.ndarray:
    """The Path segment of every JointPath row; an inserted surface row (path_index -1, e.g. a densified
    work pose) belongs to the segment of the row before it, other inserted rows to none (-1)."""
    pidx = np.asarray(path_index)
    seg = np.where(pidx >= 0, np.asarray(path_segment)[np.maximum(pidx, 0)], -1)
    fill = (pidx < 0) & np.isin(zone, SURFACE_CODES)
    if fill.any():
        known = np.where(fill, -1, np.arange(len(seg)))
        last = np.maximum.accumulate(known)
        seg = np.where(fill & (last >= 0), seg[np.maximum(last, 0)], seg)
    return seg


def run_bounds(zone: np.ndarray, segment: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The one definition of a *run*: consecutive surface poses (work, lead-in, lead-out) of one segment.

    ``zone`` and ``segment`` per row (a Path's poses or a JointPath's rows;
    inserted rows may carry segment -1). Returns boolean arrays (surface,
    start, end): which rows are on the surface, which start a run, which end one.
    """
    zone, segment = np.asarray(zone), np.asarray(segment)
    surface = np.isin(zone, SURFACE_CODES)
    n = len(zone)
    same_prev = np.zeros(n, bool)
    same_prev[1:] = surface[:-1] & surface[1:] & (segment[1:] == segment[:-1])
    start = surface & ~same_prev
    end = np.zeros(n, bool)
    if n:
        end[:-1] = surface[:-1] & ~same_prev[1:]
        end[-1] = surface[-1]
    return surface, start, end


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
    face: np.ndarray | None = None  # the part's face of each pose (a job of several faces), else None
    contour: np.ndarray | None = None  # True on the poses of a contour run (``raster.contour``), else None

    def __post_init__(self):
        for name in ("face", "contour"):
            a = getattr(self, name)
            if a is not None and len(a) != len(self.poses_mm):
                raise ValueError(f"Path.{name} has {len(a)} entries for {len(self.poses_mm)} poses")
        freeze_arrays(self)

    def __len__(self) -> int:
        return len(self.poses_mm)

    @property
    def is_work(self) -> np.ndarray:
        return self.zone == WORK

    def zone_names(self) -> list[str]:
        return [ZONES[z] for z in self.zone]

    def segment_text(self, k: int) -> str:
        """Where pose k is, for messages: "segment S", or on a path over several faces "face F, segment S"."""
        seg = f"segment {int(self.segment[k])}" + (" (contour)" if self.on_contour(k) else "")
        return seg if self.face is None else f"face {int(self.face[k])}, {seg}"

    def on_contour(self, k: int) -> bool:
        """Whether pose k belongs to a contour run."""
        return self.contour is not None and bool(self.contour[k])

    def length_mm(self) -> float:
        """Length of the TCP polyline through every pose, in mm."""
        p = self.poses_mm[:, :3, 3]
        return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())
