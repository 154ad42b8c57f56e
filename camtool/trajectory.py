"""``JointPath`` (planned joint values per pose), ``Trajectory`` (timed) and its resampling.

Joint vectors ``q`` are in native units: **rad for revolute joints, mm for
prismatic joints** (the track). Speeds are rad/s or mm/s, and so on.

``sample_trajectory(trajectory, dt_s)`` resamples a Trajectory at a fixed step
into ``TrajectorySamples``; the independent checker and the timing report both
use it (it lives here, with the data, so the checker needs no timing code).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .path.toolpath import freeze_arrays


@dataclass(frozen=True)
class JointPath:
    """Joint values per path pose, with per-pose diagnostics.

    Arrays have one row per pose of the Path (plus any inserted retract poses,
    which have ``path_index == -1``).
    """

    q: np.ndarray                 # (N, dof) rad / mm
    path_index: np.ndarray        # (N,) index into Path poses, -1 if inserted
    zone: np.ndarray              # (N,) zone codes (camtool.path.toolpath.ZONES)
    position_error_mm: np.ndarray # (N,)
    orientation_error_rad: np.ndarray  # (N,)
    jump: np.ndarray              # (N,) bool: step into this pose exceeded the jump threshold
    reverse_planned: np.ndarray   # (N,) bool
    retract: np.ndarray           # (N,) bool: pose belongs to a retract-reorient-return move
    singular: np.ndarray          # (N,) bool: fallback singular point
    reached: np.ndarray           # (N,) bool: IK converged within tolerance
    events: dict = field(default_factory=dict)  # planner events: reverse plans, retracts, ...

    def __post_init__(self):
        freeze_arrays(self)

    def with_rows_inserted(self, inserts: dict, step_zone: dict, events: dict) -> "JointPath":
        """A new joint path with rows inserted: ``inserts[r]`` (k, dof) after row r, in the zone
        ``step_zone[r]``; inserted rows have path_index -1, zero errors and are reached."""
        count = np.zeros(len(self.q), int)
        count[list(inserts)] = [len(v) for v in inserts.values()]
        src = np.repeat(np.arange(len(self.q)), 1 + count)  # each row, then its step's inserted rows
        new = np.ones(len(src), bool)
        new[np.cumsum(1 + count) - 1 - count] = False
        order = sorted(inserts)
        q = self.q[src].copy()
        q[new] = np.concatenate([inserts[r] for r in order])
        zone = np.asarray(self.zone)[src].copy()
        zone[new] = np.concatenate([np.full(len(inserts[r]), step_zone[r]) for r in order])

        def spread(a, fill):
            out = np.asarray(a)[src].copy()
            out[new] = fill
            return out
        return JointPath(q=q, path_index=spread(self.path_index, -1), zone=zone,
                         position_error_mm=spread(self.position_error_mm, 0.0),
                         orientation_error_rad=spread(self.orientation_error_rad, 0.0), jump=spread(self.jump, False),
                         reverse_planned=spread(self.reverse_planned, False), retract=spread(self.retract, False),
                         singular=spread(self.singular, False), reached=spread(self.reached, True), events=events)


@dataclass(frozen=True)
class Trajectory:
    """Timed joint trajectory: waypoints with time, q, q', q''.

    Between waypoints the motion is the quintic Hermite polynomial fixed by the
    positions, speeds and accelerations at both ends (``sample`` evaluates it).
    Its arrays (and those in ``limits``) are read-only after construction.
    """

    robot_name: str
    joint_names: tuple[str, ...]
    prismatic: np.ndarray   # (dof,) bool
    t_s: np.ndarray         # (M,)
    q: np.ndarray           # (M, dof) rad / mm
    qd: np.ndarray          # (M, dof) rad/s / mm/s
    qdd: np.ndarray         # (M, dof) rad/s^2 / mm/s^2
    zone: np.ndarray        # (M,) zone codes
    path_index: np.ndarray  # (M,) index into the Path, -1 for inserted samples
    limits: dict = field(default_factory=dict)  # name -> (dof,) arrays used for timing

    def __post_init__(self):
        freeze_arrays(self)
        if any(isinstance(v, np.ndarray) and v.flags.writeable for v in self.limits.values()):
            object.__setattr__(self, "limits", {k: _frozen(v) for k, v in self.limits.items()})

    @property
    def dof(self) -> int:
        return self.q.shape[1]

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0])

    def sample(self, dt_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Resample at a fixed step: (t, q, qd, qdd, qddd) from the quintic Hermite pieces.

        One grid over the whole trajectory; ``sample_trajectory`` is the chunked
        resampling the checker and the timing report use.
        """
        t = _grid(self.t_s, dt_s)
        return (t, *_hermite(self.t_s, self.q, self.qd, self.qdd, t))


def _frozen(value):
    """A read-only array with ``value``'s data: the array itself if it owns its data, else a copy."""
    if not isinstance(value, np.ndarray) or not value.flags.writeable:
        return value
    if value.base is not None:
        value = value.copy()
    value.flags.writeable = False
    return value


def _grid(t_s: np.ndarray, dt_s: float) -> np.ndarray:
    """Sample times from t_s[0] every ``dt_s``, plus t_s[-1]."""
    t = np.arange(t_s[0], t_s[-1], dt_s)
    return np.append(t, t_s[-1])


def _hermite(t_s, q, qd, qdd, t):
    """(q, qd, qdd, qddd) at times ``t`` of the quintic Hermite pieces through the waypoints."""
    k = np.clip(np.searchsorted(t_s, t, side="right") - 1, 0, len(t_s) - 2)
    return quintic_at(t_s, q, qd, qdd, k, t, derivatives=3)


def quintic_at(t_s, q, qd, qdd, k, tt, derivatives: int = 0):
    """The timed motion at times ``tt`` inside steps ``k`` (waypoint k to k+1): its quintic Hermite
    piece's joint values, or with ``derivatives`` = 1..3 the tuple (q, qd[, qdd[, qddd]]). The one
    evaluation of the planned motion: sampling, the writers' merging and the simulator's reference
    all read the motion through it. A step of zero duration has zero derivatives."""
    # each step's duration and coefficients once, then taken for its samples: the same values as per sample
    step, at = np.unique(np.asarray(k), return_inverse=True)
    at = at.reshape(-1)
    hk = (t_s[step + 1] - t_s[step])[:, None]
    h = hk[at]
    s = ((tt - t_s[k])[:, None]) / np.where(h > 0, h, 1.0)
    c = quintic_coefficients(q[step], qd[step] * hk, qdd[step] * hk**2, q[step + 1], qd[step + 1] * hk,
                             qdd[step + 1] * hk**2)
    p = np.zeros((len(k), np.shape(q)[1]))
    for n in range(5, -1, -1):
        p *= s
        p += c[n][at]
    if not derivatives:
        return p
    hs = np.where(h > 0, h, np.inf)
    out = [p]
    for order in range(1, derivatives + 1):
        d = np.zeros_like(p)
        for n in range(5, order - 1, -1):
            f = 1
            for m in range(order):
                f *= n - m
            d *= s
            d += (f * c[n])[at]
        out.append(d / hs ** order)
    return tuple(out)


SAMPLE_CHUNK_WAYPOINTS = 20000  # sample_trajectory resamples this many waypoints at a time (bounded memory)


@dataclass(frozen=True)
class TrajectorySamples:
    """A Trajectory resampled at ``dt_s`` by ``sample_trajectory`` (native units, per s^k); read-only.

    ``t_s`` (K,), ``q``, ``qd``, ``qdd``, ``qddd`` (K, dof). The waypoints are
    taken in chunks of ``SAMPLE_CHUNK_WAYPOINTS``; each chunk is sampled from its
    first time stamp every ``dt_s`` plus its last one, so a chunk boundary
    appears twice (t_s is non-decreasing). ``waypoints``, ``t_first_s`` and
    ``t_last_s`` identify the trajectory sampled (``matches``).
    """

    dt_s: float
    waypoints: int
    t_first_s: float
    t_last_s: float
    t_s: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    qddd: np.ndarray

    def __post_init__(self):
        freeze_arrays(self)

    def matches(self, trajectory: "Trajectory", dt_s: float | None = None) -> bool:
        """True if these are samples of ``trajectory`` (same waypoint count and end times) at ``dt_s``."""
        t = trajectory.t_s
        return (self.waypoints == len(t) and len(t) > 0 and self.t_first_s == float(t[0])
                and self.t_last_s == float(t[-1]) and self.q.shape[1:] == np.shape(trajectory.q)[1:]
                and (dt_s is None or self.dt_s == dt_s))


def _chunks(m: int) -> list[tuple[int, int]]:
    """(first, last) waypoint of each chunk of ``SAMPLE_CHUNK_WAYPOINTS`` steps."""
    return [(a, min(a + SAMPLE_CHUNK_WAYPOINTS, m - 1)) for a in range(0, max(m - 1, 1), SAMPLE_CHUNK_WAYPOINTS)]


def sample_blocks(trajectory: Trajectory, dt_s: float):
    """``sample_trajectory``'s samples a chunk of waypoints at a time: one ``TrajectorySamples`` per
    chunk (``waypoints`` and the end times are the whole trajectory's), for passes that need not hold
    every sample at once; together, in order, they are ``sample_trajectory(trajectory, dt_s)``."""
    tr = trajectory
    t_s, q, qd, qdd = tr.t_s, tr.q, tr.qd, tr.qdd
    m = len(t_s)
    for a, b in _chunks(m):
        t = _grid(t_s[a:b + 1], dt_s)
        values = _hermite(t_s[a:b + 1], q[a:b + 1], qd[a:b + 1], qdd[a:b + 1], t)
        yield TrajectorySamples(float(dt_s), int(m), float(t_s[0]), float(t_s[-1]), t, *values)


def sample_trajectory(trajectory: Trajectory, dt_s: float) -> TrajectorySamples:
    """Resample ``trajectory`` every ``dt_s`` (s) in chunks of ``SAMPLE_CHUNK_WAYPOINTS`` waypoints.

    Chunk [a, b] (waypoint indices, b = a + chunk or the last one) is sampled
    like ``Trajectory.sample`` on that chunk alone (``sample_blocks``); the
    chunks' samples are written one after another into arrays allocated once.
    """
    tr = trajectory
    m = len(tr.t_s)
    total = sum(len(_grid(tr.t_s[a:b + 1], dt_s)) for a, b in _chunks(m))
    out = [np.empty(total)] + [np.empty((total, np.shape(tr.q)[1])) for _ in range(4)]
    i = 0
    for block in sample_blocks(tr, dt_s):
        n = len(block.t_s)
        for dst, src in zip(out, (block.t_s, block.q, block.qd, block.qdd, block.qddd)):
            dst[i:i + n] = src
        i += n
    return TrajectorySamples(float(dt_s), int(m), float(tr.t_s[0]), float(tr.t_s[-1]), *out)


def quintic_coefficients(p0, v0, a0, p1, v1, a1) -> list[np.ndarray]:
    """Coefficients c0..c5 of the quintic on s in [0, 1] matching p, p', p'' at both ends.

    Speeds and accelerations are per unit s (already scaled by the segment
    duration h and h^2).
    """
    c0, c1, c2 = p0, v0, a0 / 2.0
    c3 = 10 * (p1 - p0) - 6 * v0 - 4 * v1 - 1.5 * a0 + 0.5 * a1
    c4 = -15 * (p1 - p0) + 8 * v0 + 7 * v1 + 1.5 * a0 - a1
    c5 = 6 * (p1 - p0) - 3 * v0 - 3 * v1 - 0.5 * a0 + 0.5 * a1
    return [c0, c1, c2, c3, c4, c5]
