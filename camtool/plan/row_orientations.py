"""Tool orientations between a free-form face's poses: a C2 rotation spline along each run, not a slerp per step.

The sag, densify and the spline's bow put midposes between two poses of the Path. Slerped step by step, the tool
turns at a constant rate within each step and changes that rate at every pose: the orientations are only C0 in
their rate there. Near the wrist's singularity (|sin j5| small) j4 and j6 follow every such kink at 1/|sin j5|,
and the time law's cubic spline through the midposes, a fraction of a step apart, bends j4 within one short piece:
its jerk bound set the work feed of most rows (issue #46: the bezier ocean sheet's rows where j5 crosses 0, the
noether wavy sheet's). Here the midposes' orientations come from scipy's ``RotationSpline`` (C2, through every pose
of the run) at the midpose's share of the step's chord length, so a midpose lies on one smooth turn of the tool,
and the joint spline through it needs no bend of its own. Steps outside a free-form face's surface runs (an
analytic face's: its arc's slerp is exact there) keep the slerp.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation, RotationSpline

from ..path.toolpath import SURFACE_CODES, Path

MIN_STEP_MM = 1e-6   # a step without TCP motion counts this long (RotationSpline needs increasing times)


@dataclass(frozen=True)
class RowOrientations:
    """The tool orientation (base frame) anywhere along the steps of a Path's free-form surface runs.

    ``run`` (n,) the run of each pose (-1: none), ``s_mm`` (n,) its chord length along its run, ``splines`` one
    ``RotationSpline`` per run (its times in mm of chord)."""

    run: np.ndarray
    s_mm: np.ndarray
    splines: tuple

    @staticmethod
    def build(path: Path, only: np.ndarray, base_inv: np.ndarray) -> "RowOrientations":
        """The runs of consecutive poses of one segment in the surface zones and on a free-form face (``only``
        (n,) bool); ``base_inv`` (4, 4) the robot base from world."""
        n = len(path)
        on = np.isin(path.zone, SURFACE_CODES) & np.asarray(only, bool)
        same = np.r_[False, (np.diff(path.segment) == 0) & on[1:] & on[:-1]]
        R = base_inv[:3, :3] @ path.poses_mm[:, :3, :3]
        p = path.poses_mm[:, :3, 3]
        run, s = np.full(n, -1), np.zeros(n)
        splines = []
        starts = np.flatnonzero(on & ~same)
        breaks = np.r_[np.flatnonzero(~same), n]          # a run goes on up to the next pose not joined to it
        for a, b in zip(starts, breaks[np.searchsorted(breaks, starts, side="right")]):
            if b - a < 3:   # two poses: the spline is their slerp
                continue
            t = np.r_[0.0, np.cumsum(np.maximum(np.linalg.norm(np.diff(p[a:b], axis=0), axis=1), MIN_STEP_MM))]
            run[a:b], s[a:b] = len(splines), t
            splines.append(RotationSpline(t, Rotation.from_matrix(R[a:b])))
        return RowOrientations(run, s, tuple(splines))

    def at(self, first: np.ndarray, share: np.ndarray) -> np.ndarray:
        """(m,) whether each step (its first pose's Path index ``first`` (m,)) lies on a run, and (m, 3, 3) the
        orientation ``share`` (m,) of the way along it (by chord length; identity where it lies on none)."""
        first = np.asarray(first, int)
        ok = (self.run[first] >= 0) & (self.run[np.minimum(first + 1, len(self.run) - 1)] == self.run[first])
        out = np.broadcast_to(np.eye(3), (len(first), 3, 3)).copy()
        for r in np.unique(self.run[first[ok]]):
            k = np.flatnonzero(ok & (self.run[first] == r))
            s = self.s_mm[first[k]] + np.asarray(share, float)[k] * (self.s_mm[first[k] + 1] - self.s_mm[first[k]])
            out[k] = self.splines[r](s).as_matrix()
        return ok, out


def along_runs(orientations: RowOrientations | None, first: np.ndarray):
    """``densify.bisected``'s ``orient`` for steps whose first poses are the Path's ``first`` (m,), or None."""
    if orientations is None:
        return None
    first = np.asarray(first, int)
    return lambda step, share: orientations.at(first[step], share)
