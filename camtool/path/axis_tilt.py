"""The tool axis tilted off the normal where the wrist meets the part: a path modifier, run after the raster.

A raster holds the tool along the surface normal. Beside a wall that rises above the face (a pocket's side,
the bulge over a recess) the bodies behind the TCP, the tool and the robot's wrist (a capsule on the tool's
axis, 150..235 mm behind the TCP of a 150 mm polisher on the IRB2400), run into the wall: the vendored
noether panel's pocket put the wrist 54 mm into its bulge at 0.6 % of the work poses. The raster knows only
its face; the wall is the part's, so the tilt is sized here, against the part's own signed distance (as the
motion check measures it) and the bodies that are rigid with the TCP (``AxisBody``, from the motion check's own
capsules: ``camtool.motion.tool_bodies``).

Each pose whose bodies are deeper than ``inside_mm`` in the part is turned about its TCP (the TCP stays where
it is, on the surface) by the least angle, on a grid of ``step_rad`` in ``azimuths`` directions across the
axis, that puts every body ``clear_mm`` in front of the part, up to ``max_rad``. The tilts are then blended
over the neighbouring poses (in path order) as raised-cosine bumps whose slope is at most ``turn_rad`` a pose:
each pose takes the largest bump over it, in the bumps' weighted direction, so no turn between neighbours
grows by more than ``turn_rad``. The blended path is measured again, and poses still inside are tilted further
(``ROUNDS`` rounds). A pose that ``max_rad`` does not clear is refused (``TiltRefused``: where, which body, the
tilt it would need). Deterministic (a fixed grid, no time budget); a path already clear comes back as it was
(the same object).

Why by hand: no library tilts a tool path's axes against a part's geometry (noether's tool-path modifiers fix
orientations by rules, not by collisions); the measuring is the part's own (``signed_distance``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np
from scipy.spatial.transform import Rotation

from .toolpath import SURFACE_CODES, ZONE_CODE, Path

ROUNDS = 4            # rounds of blending, measuring again and tilting further
NEED_MAX_DEG = 89.0   # a refused pose's needed tilt is sought up to this angle
OFF_SURFACE_CODES = tuple(ZONE_CODE[z] for z in ("self_motion", "approach", "depart"))


@dataclass(frozen=True)
class AxisBody:
    """A capsule rigid with the TCP: its axis from ``a_mm`` to ``b_mm`` (TCP frame, mm), its radius (mm)."""

    name: str
    a_mm: tuple[float, float, float]
    b_mm: tuple[float, float, float]
    radius_mm: float


@dataclass(frozen=True)
class AxisTiltSettings:
    """How far and how smoothly the tool axis may turn off the raster's to clear the part (angles in rad)."""

    max_rad: float = math.radians(30.0)   # the largest tilt; 0 = no tilt (the motion check judges the raster)
    turn_rad: float = math.radians(4.0)   # the most the tilt changes between neighbouring poses
    clear_mm: float = 1.0                 # a tilted pose's bodies end at least this far in front of the part
    inside_mm: float = 0.1                # a body deeper than this in the part needs a tilt (the check's tolerance)
    off_surface_mm: float = 0.0           # off the surface (self-motion, approach, depart) bodies keep this clearance
    step_rad: float = math.radians(0.5)   # the grid of tilt angles tried
    azimuths: int = 16                    # directions across the axis tried

    def __post_init__(self):
        if not (0.0 <= self.max_rad < math.pi / 2 and self.turn_rad > 0 and self.step_rad > 0 and self.azimuths >= 1
                and self.clear_mm >= 0 and self.inside_mm >= 0 and self.off_surface_mm >= 0):
            raise ValueError(f"AxisTiltSettings out of range: {self}")


@dataclass(frozen=True)
class TiltFigures:
    """What the modifier did: poses tilted (all, work), the largest tilt (deg), the poses that needed one."""

    poses_tilted: int = 0
    work_poses_tilted: int = 0
    max_tilt_deg: float = 0.0
    poses_needing_tilt: int = 0
    rounds: int = 0

    def to_dict(self) -> dict:
        return {"poses_tilted": self.poses_tilted, "work_poses_tilted": self.work_poses_tilted,
                "max_tilt_deg": round(self.max_tilt_deg, 3), "poses_needing_tilt": self.poses_needing_tilt,
                "rounds": self.rounds}


class TiltRefused(ValueError):
    """No tilt up to the maximum clears a pose's bodies of the part (the message names where and how much)."""


def body_points(bodies: tuple[AxisBody, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points (P, 3) in the TCP frame, mm; their radius (P,); their body's index (P,)): each capsule axis sampled
    at most a quarter of its radius apart (the distance to the part then is exact to radius / 8 along it)."""
    pts, rad, idx = [], [], []
    for i, b in enumerate(bodies):
        a, e = np.asarray(b.a_mm, float), np.asarray(b.b_mm, float)
        n = max(2, int(math.ceil(np.linalg.norm(e - a) / max(b.radius_mm / 4.0, 1.0))) + 1)
        s = np.linspace(0.0, 1.0, n)[:, None]
        pts.append(a + s * (e - a))
        rad.append(np.full(n, float(b.radius_mm)))
        idx.append(np.full(n, i))
    return np.vstack(pts), np.concatenate(rad), np.concatenate(idx)


class _Bodies:
    """The bodies' sample points, measured against the part for batches of rotations (world frame)."""

    def __init__(self, bodies: tuple[AxisBody, ...], signed_distance: Callable):
        self.names = tuple(b.name for b in bodies)
        self.pts, self.rad, self.idx = body_points(bodies)
        self.sd = signed_distance

    def clearance(self, R: np.ndarray, t: np.ndarray) -> np.ndarray:
        """(..., bodies) the least clearance (mm: distance in front of the part less the radius) of each body of
        the frames R (..., 3, 3) at TCPs t (..., 3)."""
        world = np.einsum("...ij,pj->...pi", R, self.pts) + t[..., None, :]
        c = np.nan_to_num(self.sd(world.reshape(-1, 3)), nan=np.inf).reshape(world.shape[:-1]) - self.rad
        out = np.full(c.shape[:-1] + (len(self.names),), np.inf)
        for i in range(len(self.names)):
            out[..., i] = c[..., self.idx == i].min(axis=-1)
        return out


def _candidates(R: np.ndarray, angles_rad: np.ndarray, azimuths: int) -> np.ndarray:
    """(azimuths, angles, 3) rotation vectors (world) that tilt the frame R's z axis by each angle towards each
    direction across it (azimuth from its x axis)."""
    phi = 2.0 * np.pi * np.arange(azimuths) / azimuths
    d = np.cos(phi)[:, None] * R[:, 0] + np.sin(phi)[:, None] * R[:, 1]   # where the axis behind the TCP goes
    axis = np.cross(d, R[:, 2])   # z turns to z cos a - d sin a about d x z: the axis behind the TCP towards d
    return axis[:, None, :] * angles_rad[None, :, None]


def least_tilt(bodies: _Bodies, R: np.ndarray, t: np.ndarray, s: AxisTiltSettings, max_rad: float,
               target_mm: float | None = None) -> tuple[np.ndarray | None, float, int]:
    """(the rotation vector (3,) of the least tilt up to ``max_rad`` that puts every body ``target_mm`` (default
    ``clear_mm``) in front, or None; the best clearance reached (mm); the body deepest at no tilt) for one frame R
    at TCP t."""
    n = int(math.floor(max_rad / s.step_rad + 1e-9))
    angles = s.step_rad * np.arange(1, n + 1)
    W = _candidates(R, angles, s.azimuths)                         # (A, n, 3)
    Rs = Rotation.from_rotvec(W.reshape(-1, 3)).as_matrix() @ R    # (A * n, 3, 3)
    c = bodies.clearance(Rs, np.broadcast_to(t, (len(Rs), 3))).min(axis=-1).reshape(W.shape[:2])
    worst = int(np.argmin(bodies.clearance(R[None], t[None])[0]))
    ok = c >= (s.clear_mm if target_mm is None else target_mm)
    if not ok.any():
        return None, float(c.max()) if c.size else -np.inf, worst
    first = np.where(ok.any(axis=1), ok.argmax(axis=1), n)         # the least angle per azimuth
    m = int(first.min())
    tied = np.flatnonzero(first == m)
    a = int(tied[np.argmax(c[tied, m])])                            # among the least, the one clearing most
    return W[a, m], float(c[a, m]), worst


def blended(omega: np.ndarray, z: np.ndarray, turn_rad: float) -> np.ndarray:
    """Rotation vectors (N, 3) of the needed tilts ``omega`` (zero where none is needed) blended over the poses:
    raised-cosine bumps of slope <= ``turn_rad`` a pose, each pose the largest bump over it in the bumps'
    weighted direction, across its axis ``z`` (N, 3)."""
    N = len(omega)
    theta = np.linalg.norm(omega, axis=1)
    mag = np.zeros(N)
    vec = np.zeros((N, 3))
    for j in np.flatnonzero(theta > 0):
        n = int(math.ceil(theta[j] * math.pi / (2.0 * turn_rad)))    # bump half-width: slope <= turn_rad
        k = np.arange(max(0, j - n), min(N, j + n + 1))
        b = theta[j] * 0.5 * (1.0 + np.cos(np.pi * np.abs(k - j) / (n + 1)))
        mag[k] = np.maximum(mag[k], b)
        vec[k] += b[:, None] * omega[j] / theta[j]
    vec -= np.sum(vec * z, axis=1)[:, None] * z          # across the axis: no spin about it
    norm = np.linalg.norm(vec, axis=1)
    out = np.zeros((N, 3))
    on = norm > 1e-12
    out[on] = vec[on] / norm[on, None] * mag[on, None]
    return out


def tilted_axes(path: Path, signed_distance: Callable[[np.ndarray], np.ndarray], bodies: tuple[AxisBody, ...],
                settings: AxisTiltSettings = AxisTiltSettings(),
                only: np.ndarray | None = None) -> tuple[Path, TiltFigures]:
    """(``path`` with its tool axes tilted clear of the part where its bodies are in it, what was done) (module
    docstring). ``signed_distance(points_mm)``: mm in front of the part (+) or inside it (-); ``bodies``: the
    capsules rigid with the TCP; ``only``: the poses that may need a tilt (a free-form face's), None: all.
    Measured on the surface poses (work and leads: a body inside the part) and off it (self-motion, approach,
    depart: a body nearer than ``off_surface_mm``). TiltRefused where ``settings.max_rad`` does not clear a surface
    pose; a pose off the surface it does not clear is left as it is (the motion check judges it)."""
    s = settings
    if s.max_rad <= 0 or not bodies or len(path) == 0:
        return path, TiltFigures()
    B = _Bodies(tuple(bodies), signed_distance)
    R0 = np.asarray(path.poses_mm[:, :3, :3], float)
    t = np.asarray(path.poses_mm[:, :3, 3], float)
    k, floor = _watched(path, s, only)
    inside = k[B.clearance(R0[k], t[k]).min(axis=1) < floor]
    if not len(inside):
        return path, TiltFigures()
    need = np.zeros((len(path), 3))
    omega = np.zeros((len(path), 3))
    R = R0
    for round_ in range(1, ROUNDS + 1):
        for j in inside:
            on_surface = floor[k == j][0] < 0
            target = s.clear_mm if on_surface else s.off_surface_mm + s.clear_mm
            w, _, worst = least_tilt(B, R[j], t[j], s, s.max_rad, target)   # from where the blend left it
            if w is None and round_ == 1 and on_surface:
                raise TiltRefused(_refusal(path, j, B, R0[j], t[j], s, worst))
            if w is not None:
                need[j] = omega[j] + w
                theta = float(np.linalg.norm(need[j]))
                need[j] *= min(1.0, s.max_rad / theta)    # at most the maximum; the next round measures it
        omega = blended(need, R0[:, :, 2], s.turn_rad)
        R = Rotation.from_rotvec(omega).as_matrix() @ R0
        c = B.clearance(R[k], t[k]).min(axis=1)
        inside = k[(c < floor) & ((floor < 0) | ~(need[k] != 0).any(1))]   # off the surface: tried once
        if not len(inside):
            break
    if len(inside) and (floor[np.isin(k, inside)] < 0).any():
        j = int(inside[floor[np.isin(k, inside)] < 0][0])
        raise TiltRefused(_refusal(path, j, B, R0[j], t[j], s, int(np.argmin(B.clearance(R[j][None], t[j][None])[0])),
                                   blended_fails=True))
    if not (need != 0).any():
        return path, TiltFigures()
    poses = np.array(path.poses_mm, float)
    poses[:, :3, :3] = R
    theta = np.linalg.norm(omega, axis=1)
    tilted = theta > 1e-9
    figures = TiltFigures(poses_tilted=int(tilted.sum()), work_poses_tilted=int((tilted & path.is_work).sum()),
                          max_tilt_deg=float(np.degrees(theta.max())), poses_needing_tilt=int((need != 0).any(1).sum()),
                          rounds=round_)
    return replace(path, poses_mm=poses), figures


def _watched(path: Path, s: AxisTiltSettings, only: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """(the poses measured, the clearance (mm) below which each needs a tilt): on the surface ``-inside_mm``, off it
    (self-motion, approach, depart) ``off_surface_mm``."""
    zone = np.asarray(path.zone)
    surface = np.isin(zone, SURFACE_CODES)
    watch = surface | np.isin(zone, OFF_SURFACE_CODES)
    if only is not None:
        watch &= np.asarray(only, bool)
    k = np.flatnonzero(watch)
    return k, np.where(surface[k], -s.inside_mm, s.off_surface_mm)


def _refusal(path: Path, j: int, B: _Bodies, R: np.ndarray, t: np.ndarray, s: AxisTiltSettings, worst: int,
             blended_fails: bool = False) -> str:
    """The one line naming where a tilt up to the maximum does not clear, which body, and the tilt it would need."""
    depth = -float(B.clearance(R[None], t[None])[0, worst])
    w, _, _ = least_tilt(B, R, t, replace(s, step_rad=max(s.step_rad, math.radians(1.0))),
                         math.radians(NEED_MAX_DEG))
    would = (f"it would need {math.degrees(float(np.linalg.norm(w))):.0f} deg" if w is not None
             else f"no tilt up to {NEED_MAX_DEG:g} deg clears it")
    why = ("the tilt blended over its neighbours does not clear it" if blended_fails
           else f"a tilt of up to raster.axis_tilt_max_deg = {math.degrees(s.max_rad):g} deg does not clear it")
    p = ", ".join(f"{v:.1f}" for v in t)
    return (f"the {B.names[worst]} is {depth:.1f} mm inside the part at pose {j} ({path.segment_text(j)}, point "
            f"{int(path.point[j])}, TCP at [{p}] mm) and {why}; {would}")
