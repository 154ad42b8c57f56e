"""The redundancy map: where along the path the redundant parameter may go.

For a subsample of the path's work poses (x, at most ``max_poses``) and a sweep
of the robot's redundant parameter (y), every cell is solved in closed form and
classified:

- SRS 7R arms (``sia20``): y is the arm angle (deg) of ``robots.ik_srs.SrsIK``;
  every cell takes the best of the 8 solution families.
- ``seed8`` (a track before an SRS 7R arm): y is the track position (mm); every
  cell takes the best of the 8 families over ``track_arm_angles`` arm angles.
- 6R arms with a spherical wrist (``irb2400``): y is a spin of the tool about
  its z axis (deg), solved by a batched form of ``robots.ik_spherical_wrist``.
  With a fixed-spin path only y = 0 is what the program asks; the map shows
  how much room a free spin would give.

Other robots (numerical IK only) are not mapped: ``redundancy_kind`` gives
None and ``redundancy_map`` raises BadInput.

"Best" is the solution (and 2*pi-equivalent of each revolute joint) with the
largest joint-limit margin: the smallest distance of any joint to its nearer
limit as a share of that joint's range (0 at a limit, 0.5 at mid-range). Cell
codes: ``NO_IK`` (the pose is out of reach or the arm angle is undefined),
``OUTSIDE_LIMITS`` (solutions exist, none inside the joint limits),
``REACHABLE``, and, given the job's collision world (``camtool.collision``),
``IN_COLLISION``: the best solution is inside the limits but a robot or tool
body comes closer than ``cell.clearance_mm`` to an obstacle, the floor or
another link (self-collision). Only the best solution is checked: another
family may be clear there. Reachable cells also carry the manipulability
sqrt(det(J J^T)) of the TCP Jacobian (mm / rad rows, whole robot) at the
best solution, normalised by the largest over the map.

Given the planned ``JointPath``, ``planned`` holds the y value of the planned
solution at every x (NaN where the pose was not planned or not reached).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path as FsPath

import numpy as np

from ..errors import BadInput, PlanInfeasible
from ..robots.ik_common import rz_batch, wrap_pi
from ..robots.ik_srs import track_shift
from ..path.toolpath import WORK, Path
from .. import safe_io

NO_IK, OUTSIDE_LIMITS, REACHABLE, IN_COLLISION = 0, 1, 2, 3
CODE_NAMES = {NO_IK: "no IK solution", OUTSIDE_LIMITS: "outside joint limits", REACHABLE: "reachable",
              IN_COLLISION: "in collision (cell or self)"}
KIND_LABELS = {"arm_angle": "arm angle [deg]", "track": "track position [mm]", "tool_spin": "tool spin about z [deg]"}
TWO_PI = 2.0 * np.pi
BAD_COLORS = ["#555555", "#f4b6b6", "#f0a030"]   # no IK, outside the limits, in collision


@dataclass(frozen=True)
class RedundancySettings:
    """How finely the map is sampled (bounded work: at most max_poses x sweep cells)."""

    max_poses: int = 200           # x: work poses, evenly subsampled
    arm_angle_step_deg: float = 5.0
    spin_step_deg: float = 5.0
    track_values: int = 41         # seed8: track positions over the track's range
    track_arm_angles: int = 8      # seed8: arm angles tried per cell (the best is kept)


@dataclass(frozen=True, eq=False)
class RedundancyMap:
    """Cells (y, x) of a redundancy sweep; see the module doc.

    ``x``: path indices (nx,); ``y``: sweep values (ny,) in deg or mm;
    ``code``, ``margin``, ``manipulability``: (ny, nx); ``planned``: (nx,).
    """

    robot: str
    kind: str                      # "arm_angle" | "track" | "tool_spin"
    x: np.ndarray
    y: np.ndarray
    code: np.ndarray
    margin: np.ndarray             # share of the joint range, NaN unless reachable
    manipulability: np.ndarray     # normalised to the map's largest, NaN unless reachable
    planned: np.ndarray            # planned y per x, NaN where unknown
    manipulability_max: float = 0.0
    notes: tuple[str, ...] = field(default=())

    @property
    def y_label(self) -> str:
        return KIND_LABELS[self.kind]

    @property
    def reachable(self) -> np.ndarray:
        return self.code == REACHABLE

    def planned_rows(self) -> np.ndarray:
        """(nx,) index of the y cell nearest to the planned value (-1 where none)."""
        out = np.full(len(self.x), -1)
        ok = np.isfinite(self.planned)
        if ok.any():
            d = np.abs(self.y[:, None] - self.planned[None, ok])
            if self.kind != "track":  # angles: distance round the circle
                d = np.minimum(d, 360.0 - d)
            out[ok] = np.argmin(d, axis=0)
        return out


def redundancy_kind(robot) -> str | None:
    """"arm_angle", "track" or "tool_spin" when ``robot`` has closed-form families, else None."""
    from ..robots.ik_spherical_wrist import SphericalWristIK
    from ..robots.ik_srs import SrsIK

    try:
        if robot.dof == 7:
            SrsIK(robot)
            return "arm_angle"
        if robot.dof == 8 and robot.prismatic[0] and not robot.prismatic[1:].any():
            SrsIK(robot, [0.5 * (robot.limits.lower[0] + robot.limits.upper[0])])
            return "track"
        if robot.dof == 6:
            SphericalWristIK(robot)
            return "tool_spin"
    except BadInput:
        return None
    return None


def map_poses(path: Path, max_poses: int, include=()) -> np.ndarray:
    """The x of a map (at most ``max_poses``): ``include`` (path indices, e.g. failing poses; at most half
    of the columns, evenly subsampled) and the work poses evenly subsampled."""
    extra = np.unique(np.asarray([int(i) for i in include if 0 <= int(i) < len(path)], dtype=int))
    max_poses = max(2, int(max_poses))
    extra = extra[_spread(len(extra), max_poses // 2)]
    cand = np.flatnonzero(path.zone == WORK)
    if not len(cand):
        cand = np.arange(len(path))
    pick = cand[_spread(len(cand), max_poses - len(extra))]
    return np.unique(np.concatenate([pick, extra])).astype(int)


def _spread(n: int, m: int) -> np.ndarray:
    """At most m evenly spread indices of n items (first and last kept)."""
    if n <= m:
        return np.arange(n)
    return np.unique(np.round(np.linspace(0, n - 1, max(m, 1))).astype(int))


SWEEP_MATCH_MM = 1e-6   # a sweep serves a path whose mapped poses are this close (mm, any matrix entry)


@dataclass(frozen=True, eq=False)
class RedundancySweep:
    """The cells of a redundancy map, before the plan is known: its poses swept (``sweep_map``).

    ``poses_mm`` (nx, 4, 4): the path's poses at ``x``, which the cells were solved for; the
    rest as ``RedundancyMap`` (``manipulability`` not yet normalised)."""

    robot: str
    kind: str
    settings: RedundancySettings
    free_spin: bool
    x: np.ndarray
    poses_mm: np.ndarray
    y: np.ndarray
    code: np.ndarray
    margin: np.ndarray
    manipulability: np.ndarray
    notes: tuple[str, ...] = ()

    @property
    def reachable_any(self) -> bool:
        return bool((self.code == REACHABLE).any())

    def serves(self, path: Path, x: np.ndarray, robot, settings: RedundancySettings) -> bool:
        """Whether these cells are the map of ``path``'s poses ``x``: the same robot, settings and tool-spin
        freedom, and the same poses (within ``SWEEP_MATCH_MM``; a raster whose leads were lengthened
        keeps its work poses, not their path indices)."""
        return (self.robot == robot.name and self.settings == settings and self.free_spin == path.free_spin
                and len(x) == len(self.x)
                and bool(np.allclose(path.poses_mm[x], self.poses_mm, rtol=0.0, atol=SWEEP_MATCH_MM)))


def sweep_map(path: Path, robot, settings: RedundancySettings | None = None, *, include=(),
              world=None) -> RedundancySweep:
    """The cells of ``path``'s redundancy map (``redundancy_map`` without the plan): most of its work,
    which the raster task does while the path is planned. Raises BadInput for a robot without
    closed-form families."""
    st = settings or RedundancySettings()
    kind = redundancy_kind(robot)
    if kind is None:
        raise BadInput(f"robot {robot.name}: no closed-form IK families (SRS 7R arm, track + SRS arm, or 6R "
                       "spherical wrist); the redundancy map needs one (numerical IK is not mapped)")
    x = map_poses(path, st.max_poses, include)
    tool_inv = np.linalg.inv(robot.tool_T_mm)
    targets = _targets(path, robot, x)
    if kind == "arm_angle":
        y = np.arange(-180.0, 180.0, st.arm_angle_step_deg)
        best_q, best_m, has_ik = _sweep_arm_angle(robot, targets @ tool_inv, np.radians(y))
    elif kind == "track":
        y = np.linspace(robot.limits.lower[0], robot.limits.upper[0], st.track_values)
        best_q, best_m, has_ik = _sweep_track(robot, targets @ tool_inv, y, st.track_arm_angles)
    else:
        y = np.arange(-180.0, 180.0, st.spin_step_deg)
        best_q, best_m, has_ik = _sweep_tool_spin(robot, targets, tool_inv, np.radians(y))
    code = np.where(~has_ik, NO_IK, np.where(best_m >= -1e-9, REACHABLE, OUTSIDE_LIMITS)).astype(np.int8)
    notes = ()
    if world is not None and world.pairs:
        cells = np.argwhere(code == REACHABLE)
        free = world.valid_many(best_q[cells[:, 0], cells[:, 1]])
        code[cells[~free, 0], cells[~free, 1]] = IN_COLLISION
        notes += (f"collision layer: {int(np.count_nonzero(~free))} of {len(cells)} reachable cells collide "
                  f"with the cell or the robot itself (best solution only)",)
    reach = code == REACHABLE
    margin = np.where(reach, np.clip(best_m, 0.0, None), np.nan)
    manip = np.full(code.shape, np.nan)
    manip[reach] = _manipulability(robot, best_q[reach])
    if kind == "tool_spin" and not path.free_spin:
        notes = ("the path fixes the tool spin: only y = 0 is what the program asks",) + notes
    if kind == "track":
        notes = (f"best of {st.track_arm_angles} arm angles per cell",) + notes
    return RedundancySweep(robot.name, kind, st, bool(path.free_spin), x, path.poses_mm[x].copy(), y, code, margin,
                           manip, notes)


def _targets(path: Path, robot, x: np.ndarray) -> np.ndarray:
    """(nx, 4, 4) the TCP poses of ``path`` at ``x`` in the robot's base frame."""
    return np.einsum("ij,njk->nik", np.linalg.inv(robot.base_T_mm), path.poses_mm[x])


def redundancy_map(path: Path, robot, joint_path=None, settings: RedundancySettings | None = None, *,
                   include=(), world=None, sweep: RedundancySweep | None = None) -> RedundancyMap:
    """The redundancy map of ``path`` for ``robot`` (see the module doc).

    ``include``: path indices that must be columns (e.g. failing poses).
    ``world``: the job's ``CollisionWorld``; with it, reachable cells whose best solution collides
    become ``IN_COLLISION``.
    ``sweep``: ``sweep_map``'s cells made ahead (of the raster before its leads were sized); taken
    where it ``serves`` this path, else the poses are swept here.
    Raises BadInput for a robot without closed-form families.
    """
    st = settings or RedundancySettings()
    x = map_poses(path, st.max_poses, include)
    if sweep is None or not sweep.serves(path, x, robot, st):
        sweep = sweep_map(path, robot, st, include=include, world=world)
    manip = sweep.manipulability
    mmax = float(np.nanmax(manip)) if sweep.reachable_any else 0.0
    if mmax > 0:
        manip = manip / mmax
    planned = np.full(len(x), np.nan)
    if joint_path is not None:
        planned = _planned_values(sweep.kind, robot, joint_path, x, _targets(path, robot, x))
    return RedundancyMap(robot.name, sweep.kind, x, sweep.y, sweep.code, sweep.margin, manip, planned, mmax,
                         sweep.notes)


def _manipulability(robot, qs: np.ndarray) -> np.ndarray:
    """sqrt(det(J J^T)) of the TCP Jacobian at each row of ``qs``: compiled and batched for DH robots
    (``DhKernel.jacobians``, checked against Pinocchio when built), else one ``robot.jacobian`` per row."""
    if not len(qs):
        return np.zeros(0)
    from ..plan.cwln import IkSettings
    from ..plan.kernel import DhKernel

    kernel = DhKernel.build(robot, IkSettings(), False, np.full(robot.dof, np.inf))
    if kernel is not None:
        J = kernel.jacobians(qs)
    else:
        J = np.array([robot.jacobian(q, tcp=True) for q in qs])
    return np.sqrt(np.maximum(np.linalg.det(J @ np.swapaxes(J, 1, 2)), 0.0))


# ----------------------------------------------------------------------------- sweeps

def _best(cands: np.ndarray, lower: np.ndarray, upper: np.ndarray, revolute: np.ndarray):
    """Best of candidate solutions (C, K, n) by joint-limit margin: (K, n) q, (K,) margin, (K,) any-solution.

    Each revolute joint takes its 2*pi-equivalent farthest from its limits.
    Rows with NaN (no root) are no candidate.
    """
    span = upper - lower
    best_x = cands.copy()
    best_mj = np.minimum(cands - lower, upper - cands) / span
    for k in (-2, -1, 1, 2):
        xk = cands + k * TWO_PI
        mk = np.minimum(xk - lower, upper - xk) / span
        better = revolute & (mk > best_mj)
        best_x = np.where(better, xk, best_x)
        best_mj = np.where(better, mk, best_mj)
    valid = ~np.isnan(cands).any(axis=-1)
    m = np.where(valid, best_mj.min(axis=-1), -np.inf)                  # (C, K)
    c = np.argmax(m, axis=0)
    K = cands.shape[1]
    return best_x[c, np.arange(K)], m[c, np.arange(K)], valid.any(axis=0)


def _srs_candidates(ik, st: dict, angles: np.ndarray) -> np.ndarray:
    """(8 * len(angles), n, 7): every family at every arm angle for n stacked poses (``prepare_batch``)."""
    from ..robots.ik_srs import FAMILIES

    n, A = len(st["u"]), len(angles)
    tiled = {"u": np.tile(st["u"], (A, 1)), "R7": np.tile(st["R7"], (A, 1, 1)),
             "q4": {g: np.tile(v, A) for g, v in st["q4"].items()},
             "R3ref": {g: np.tile(v, (A, 1, 1)) for g, v in st["R3ref"].items()}}
    psi = np.repeat(angles, n)
    with np.errstate(invalid="ignore"):
        out = np.stack([ik.family_q_batch(tiled, psi, fam) for fam in FAMILIES])   # (8, A*n, 7)
    return out.reshape(len(FAMILIES), A, n, 7).reshape(len(FAMILIES) * A, n, 7)


def _sweep_arm_angle(robot, flanges: np.ndarray, psi: np.ndarray):
    from ..robots.ik_srs import FAMILIES, SrsIK

    ik = SrsIK(robot)
    L = robot.limits
    ny, nx = len(psi), len(flanges)
    best_q = np.zeros((ny, nx, 7))
    best_m = np.full((ny, nx), -np.inf)
    has = np.zeros((ny, nx), bool)
    st, prepared = ik.prepare_batch(flanges)
    ok = np.flatnonzero(prepared)
    if len(ok):
        tiled = {"u": np.tile(st["u"], (ny, 1)), "R7": np.tile(st["R7"], (ny, 1, 1)),
                 "q4": {g: np.tile(v, ny) for g, v in st["q4"].items()},
                 "R3ref": {g: np.tile(v, (ny, 1, 1)) for g, v in st["R3ref"].items()}}
        with np.errstate(invalid="ignore"):
            cands = np.stack([ik.family_q_batch(tiled, np.repeat(psi, len(ok)), f) for f in FAMILIES])
        q, m, h = _best(cands, L.lower, L.upper, ~robot.prismatic)
        best_q[:, ok] = q.reshape(ny, len(ok), 7)
        best_m[:, ok] = m.reshape(ny, len(ok))
        has[:, ok] = h.reshape(ny, len(ok))
    return best_q, best_m, has


def _sweep_track(robot, flanges: np.ndarray, tracks: np.ndarray, n_angles: int):
    from ..robots.ik_srs import SrsIK

    L = robot.limits
    t_mid = 0.5 * (L.lower[0] + L.upper[0])
    ik0 = SrsIK(robot, [t_mid])
    shift = track_shift(robot, ik0)
    ny, nx = len(tracks), len(flanges)
    angles = np.linspace(-np.pi, np.pi, max(1, int(n_angles)), endpoint=False)
    best_q = np.zeros((ny, nx, robot.dof))
    best_m = np.full((ny, nx), -np.inf)
    has = np.zeros((ny, nx), bool)
    if shift is not None:   # the track moves the arm: move the targets instead, all cells in one batch
        T = np.repeat(np.asarray(flanges, float)[None], ny, axis=0)
        T[:, :, :3, 3] -= (tracks - t_mid)[:, None, None] * shift
        st, prepared = ik0.prepare_batch(T.reshape(-1, 4, 4))
        cells = np.argwhere(prepared.reshape(ny, nx))
    else:                   # one solver per track value
        parts, cell_parts = [], []
        for iy, t in enumerate(tracks):
            st_t, prepared = SrsIK(robot, [t]).prepare_batch(flanges)
            parts.append(st_t)
            cell_parts.append(np.column_stack([np.full(int(prepared.sum()), iy), np.flatnonzero(prepared)]))
        st = {"u": np.concatenate([p["u"] for p in parts]), "R7": np.concatenate([p["R7"] for p in parts]),
              "q4": {g: np.concatenate([p["q4"][g] for p in parts]) for g in (1, -1)},
              "R3ref": {g: np.concatenate([p["R3ref"][g] for p in parts]) for g in (1, -1)}}
        cells = np.vstack(cell_parts).astype(int)
    if not len(cells):
        return best_q, best_m, has
    cands = _srs_candidates(ik0, st, angles)                           # (8A, n, 7), ik0's P: same arm
    iy, ix = cells.T
    t = tracks[iy]
    arm_q, m, h = _best(cands, L.lower[1:], L.upper[1:], np.ones(7, bool))
    m_track = np.minimum(t - L.lower[0], L.upper[0] - t) / (L.upper[0] - L.lower[0])
    best_q[iy, ix] = np.column_stack([t, arm_q])
    best_m[iy, ix] = np.minimum(m, m_track)
    has[iy, ix] = h
    return best_q, best_m, has


def _roots(kc, ks, k0, value, tol=1e-9):
    """Vectorised ``ik_common.sinusoid_roots``: (x_plus, x_minus), NaN where there is no real root."""
    r = np.hypot(kc, ks)
    with np.errstate(invalid="ignore", divide="ignore"):
        c = (value - k0) / r
    bad = (r < 1e-12) | (1.0 - np.abs(c) < -tol) | np.isnan(c)
    a = np.arccos(np.clip(np.where(bad, 0.0, c), -1.0, 1.0))
    phi = np.arctan2(ks, kc)
    plus, minus = phi + a, phi - a
    return np.where(bad, np.nan, plus), np.where(bad, np.nan, minus)


def spherical_wrist_batch(ik, T_flange: np.ndarray) -> np.ndarray:
    """Every closed-form solution of K flange poses: (8, K, 6), NaN rows where a branch has no root.

    The batched form of ``SphericalWristIK.solve`` (same steps, same geometry);
    branch order (shoulder, elbow, wrist) = product((1, -1), repeat=3).
    """
    from ..robots.ik_common import spherical_group_batch

    ch = ik.ch
    P = ch.P
    T = np.asarray(T_flange, float)
    R, p = T[:, :3, :3], T[:, :3, 3]
    W = np.einsum("kij,j->ki", R, ik.w_flange) + p
    Wp = W @ ik.P1i[:3, :3].T + ik.P1i[:3, 3]
    n2, s3, w3 = ik.n2, ik.s3, ik.w3
    r1 = _roots(n2[0] * Wp[:, 0] + n2[1] * Wp[:, 1], n2[0] * Wp[:, 1] - n2[1] * Wp[:, 0], n2[2] * Wp[:, 2],
                ik.c_plane)
    R6 = R @ ch.flange[:3, :3].T
    out = []
    for q1 in r1:
        W1 = np.einsum("kji,kj->ki", rz_batch(np.nan_to_num(q1)), Wp)
        d2 = np.sum((W1 - ik.o2) ** 2, axis=1)
        r3 = _roots(s3[0] * w3[0] + s3[1] * w3[1], s3[1] * w3[0] - s3[0] * w3[1], s3[2] * w3[2],
                    0.5 * (s3 @ s3 + w3 @ w3 - d2))
        for q3 in r3:
            q3n = np.nan_to_num(q3)
            w2 = (rz_batch(q3n) @ w3) @ P[2][:3, :3].T + P[2][:3, 3]
            w2p = (W1 - P[1][:3, 3]) @ P[1][:3, :3]
            q2 = np.arctan2(w2p[:, 1], w2p[:, 0]) - np.arctan2(w2[:, 1], w2[:, 0])
            R3 = (P[0][:3, :3] @ rz_batch(np.nan_to_num(q1)) @ P[1][:3, :3] @ rz_batch(q2) @ P[2][:3, :3]
                  @ rz_batch(q3n))
            M = np.transpose(R3 @ P[3][:3, :3], (0, 2, 1)) @ R6
            for g3 in (1, -1):
                wr = spherical_group_batch(M, P[4][:3, :3], P[5][:3, :3], g3)
                q = wrap_pi(np.column_stack([q1, q2, q3, wr]))
                q[np.isnan(q).any(axis=1)] = np.nan
                out.append(q)
    return np.stack(out)


def _spin(a: np.ndarray) -> np.ndarray:
    """(K, 4, 4) rotations about z by angles a."""
    S = np.zeros((len(a), 4, 4))
    S[:, :3, :3] = rz_batch(a)
    S[:, 3, 3] = 1.0
    return S


def _sweep_tool_spin(robot, targets: np.ndarray, tool_inv: np.ndarray, spins: np.ndarray):
    from ..robots.ik_spherical_wrist import SphericalWristIK

    ik = SphericalWristIK(robot)
    L = robot.limits
    ny, nx = len(spins), len(targets)
    T = np.tile(targets, (ny, 1, 1)) @ _spin(np.repeat(spins, nx)) @ tool_inv   # row-major (y, x)
    with np.errstate(invalid="ignore"):
        cands = spherical_wrist_batch(ik, T)
    q, m, h = _best(cands, L.lower, L.upper, ~robot.prismatic)
    return q.reshape(ny, nx, robot.dof), m.reshape(ny, nx), h.reshape(ny, nx)


def _planned_values(kind: str, robot, joint_path, x: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """The y of the planned solution at every x (NaN where not planned or not reached)."""
    rows = {}
    for k, i in enumerate(joint_path.path_index):
        if i >= 0 and int(i) not in rows:
            rows[int(i)] = k
    out = np.full(len(x), np.nan)
    ik = None
    if kind == "arm_angle":
        from ..robots.ik_srs import SrsIK
        ik = SrsIK(robot)
    for j, i in enumerate(x):
        k = rows.get(int(i))
        if k is None or not joint_path.reached[k]:
            continue
        q = joint_path.q[k]
        if kind == "track":
            out[j] = q[0]
        elif kind == "arm_angle":
            try:
                out[j] = np.degrees(wrap_pi(ik.arm_angle(q)))
            except (PlanInfeasible, TypeError, ValueError):
                continue
        else:
            Rrel = targets[j][:3, :3].T @ robot.fk_tcp(q)[:3, :3]
            out[j] = np.degrees(np.arctan2(Rrel[1, 0], Rrel[0, 0]))
    if kind != "track":  # into the sweep's [-180, 180)
        out = (out + 180.0) % 360.0 - 180.0
    return out


# ----------------------------------------------------------------------------- PNG

def plot_redundancy_map_png(rmap: RedundancyMap, file) -> FsPath:
    """The map as a PNG (matplotlib, Agg): joint-limit margin and manipulability side by side.

    Unreachable cells are dark grey (no IK) or light red (outside the joint
    limits), colliding ones orange; the planned curve is drawn in black.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    file = FsPath(file)
    file.parent.mkdir(parents=True, exist_ok=True)
    xe = _edges(rmap.x.astype(float))
    ye = _edges(rmap.y.astype(float))
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.8), sharey=True)
    bad = np.select([rmap.code == NO_IK, rmap.code == OUTSIDE_LIMITS, rmap.code == IN_COLLISION],
                    [0.0, 1.0, 2.0], np.nan)
    for ax, z, title, vmax in ((axes[0], rmap.margin, "joint-limit margin [share of range]", 0.5),
                               (axes[1], rmap.manipulability, "manipulability [normalised]", 1.0)):
        ax.pcolormesh(xe, ye, bad, cmap=ListedColormap(BAD_COLORS), vmin=0, vmax=2, shading="flat")
        im = ax.pcolormesh(xe, ye, z, cmap="viridis", vmin=0, vmax=vmax, shading="flat")
        fig.colorbar(im, ax=ax, fraction=0.05)
        if np.isfinite(rmap.planned).any():
            ax.plot(rmap.x, rmap.planned, "k.-", lw=0.8, ms=2, label="planned")
            ax.legend(loc="upper right", fontsize=8)
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("path index (work poses)")
    axes[0].set_ylabel(rmap.y_label)
    fig.suptitle(f"{rmap.robot}: redundancy map (grey: no IK, red: outside joint limits, orange: in collision)",
                 fontsize=11)
    fig.tight_layout()
    safe_io.save_figure(fig, file, dpi=90)
    plt.close(fig)
    return file


def _edges(c: np.ndarray) -> np.ndarray:
    """Cell edges round centres c (midpoints, ends mirrored)."""
    if len(c) == 1:
        return np.array([c[0] - 0.5, c[0] + 0.5])
    mid = 0.5 * (c[1:] + c[:-1])
    return np.concatenate([[c[0] - (mid[0] - c[0])], mid, [c[-1] + (c[-1] - mid[-1])]])
