"""One collision world in coal: the robot's bodies, the tool, the obstacles and the floor.

``CollisionWorld`` holds the bodies (``shapes``), the allowed-collision matrix
(``acm``) and the pairs to measure: every robot or tool body against every
obstacle (bodies fixed to the robot base are not measured against the floor
they stand on), and every pair of robot bodies the matrix does not allow.
The planner asks one configuration at a time (``clearance_mm``, ``valid``);
the independent motion check (``camtool.motion.cell_check``) takes the same
bodies and pairs and does its own sampling and bounding.

Distances are coal's (GJK / EPA on the primitives and convex hulls), in mm,
negative when two bodies overlap (the penetration depth).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .acm import AllowedCollisions, robot_acm
from ..robots.joint_frames import JointFrames, joint_frames_mm
from .shapes import BASE, WORLD, Body, robot_bodies
from .validity import Validity, reason_of, valid_rows

MM_PER_M = 1000.0


@dataclass(frozen=True)
class Pair:
    """Two bodies measured against each other (indices into ``CollisionWorld.bodies``)."""

    a: int
    b: int
    kind: str   # "environment" (robot / tool x obstacle) or "self" (robot x robot)


@dataclass(frozen=True)
class CellSettings:
    """The cell beyond the part: obstacles (bodies), clearance (mm), the matrix overrides."""

    obstacles: tuple[Body, ...] = ()
    clearance_mm: float = 5.0
    allow: tuple[tuple[str, str], ...] = ()
    check: tuple[tuple[str, str], ...] = ()
    tool_points_mm: np.ndarray | None = field(default=None, repr=False)


class CollisionWorld:
    """The robot (placed), its tool, the obstacles; the pairs to measure and their coal shapes."""

    def __init__(self, robot, cell: CellSettings | None = None, tool_radius_mm: float = 25.0,
                 acm: AllowedCollisions | None = None):
        cell = cell or CellSettings()
        self._made_from = (robot, cell, tool_radius_mm, acm)   # what a pickle rebuilds it from (__reduce__)
        self.robot = robot
        self.cell = cell
        self.clearance_mm = float(cell.clearance_mm)
        self.robot_bodies = robot_bodies(robot, tool_radius_mm, cell.tool_points_mm)
        self.bodies: tuple[Body, ...] = self.robot_bodies + tuple(cell.obstacles)
        self.acm = (acm or robot_acm(robot, self.robot_bodies)).overridden(cell.allow, cell.check,
                                                                           [b.name for b in self.robot_bodies])
        self.acm = _with_tool_neighbour(self.acm, self.robot_bodies, cell.check)
        self.geometry = [b.coal_geometry() for b in self.bodies]
        n_robot = len(self.robot_bodies)
        pairs = []
        for i, b in enumerate(self.robot_bodies):
            for j in range(n_robot, len(self.bodies)):
                if b.parent == BASE and self.bodies[j].shape == "halfspace":
                    continue   # the base stands on the floor
                pairs.append(Pair(i, j, "environment"))
        for i in range(n_robot):
            for j in range(i + 1, n_robot):
                bi, bj = self.bodies[i], self.bodies[j]
                if bi.parent == bj.parent or (bi.parent <= BASE and bj.parent <= BASE):
                    continue   # rigidly joined: their distance never changes
                if not self.acm.allowed(bi.name, bj.name):
                    pairs.append(Pair(i, j, "self"))
        self.pairs = tuple(pairs)
        base = np.asarray(robot.base_T_mm, float)
        self._base = base
        self._data = robot.model.createData()
        self._frames = JointFrames(robot)   # many configurations' frames at once (valid_many)
        self.calls = 0
        self._fixed_poses = np.array([b.local_T_mm if b.parent == WORLD else base @ b.local_T_mm
                                      for b in self.bodies])   # moving bodies' rows are overwritten
        self._moving = np.array([b.parent > BASE for b in self.bodies], bool)
        self._moving_frame = np.array([b.parent - 1 for b in self.bodies if b.parent > BASE], int)
        self._moving_local = np.array([b.local_T_mm for b in self.bodies if b.parent > BASE]).reshape(-1, 4, 4)
        balls = [b.ball_mm for b in self.bodies]
        self._ball_centre = np.array([c for c, _ in balls])
        self._ball_radius = np.array([r for _, r in balls])
        self._pair_a = np.array([p.a for p in self.pairs], int)
        self._pair_b = np.array([p.b for p in self.pairs], int)
        self.skipped = 0   # pair queries the broad phase left out

    def __reduce__(self):
        """Pickled as what it is made from (coal's shapes do not pickle): a process on standby
        (``camtool.alongside.Standby``) rebuilds the same world."""
        return CollisionWorld, self._made_from

    @property
    def has_obstacles(self) -> bool:
        return len(self.bodies) > len(self.robot_bodies)

    def pair_name(self, p: Pair) -> tuple[str, str]:
        return self.bodies[p.a].name, self.bodies[p.b].name

    def joint_frames_mm(self, q) -> np.ndarray:
        """(dof, 4, 4) world poses (mm) of the joint frames after their motion (Pinocchio's oMi)."""
        return self._base @ joint_frames_mm(self.robot, q, self._data)

    def body_poses_mm(self, frames: np.ndarray) -> list[np.ndarray]:
        """World pose (mm) of every body for these joint frames (``joint_frames_mm``)."""
        return list(self._poses(frames))

    def _poses(self, frames: np.ndarray) -> np.ndarray:
        poses = self._fixed_poses.copy()
        poses[self._moving] = frames[self._moving_frame] @ self._moving_local
        return poses

    def pair_distances_mm(self, q, pairs=None) -> np.ndarray:
        """coal distance (mm, negative = overlap) of each pair at configuration q."""
        import coal

        self.calls += 1
        poses = self.body_poses_mm(self.joint_frames_mm(q))
        tf = [coal.Transform3s(T[:3, :3].copy(), T[:3, 3].copy()) for T in poses]
        req, res = coal.DistanceRequest(), coal.DistanceResult()
        pairs = self.pairs if pairs is None else pairs
        d = np.empty(len(pairs))
        for k, p in enumerate(pairs):
            res.clear()
            d[k] = coal.distance(self.geometry[p.a], tf[p.a], self.geometry[p.b], tf[p.b], req, res)
        return d

    def clearance_mm_at(self, q) -> tuple[float, Pair | None]:
        """The smallest pair distance at q and its pair (inf, None without pairs)."""
        if not self.pairs:
            return np.inf, None
        d = self.pair_distances_mm(q)
        k = int(np.argmin(d))
        return float(d[k]), self.pairs[k]

    def valid(self, q) -> bool:
        """Every pair keeps ``clearance_mm`` (``valid_many`` of one row)."""
        return bool(self.valid_many(np.asarray(q, float)[None])[0])

    def valid_many(self, Q) -> np.ndarray:
        """(K,) whether every pair keeps ``clearance_mm`` at each row of Q. A broad phase first, over
        all rows at once: pairs whose bounding balls are at least the clearance apart cannot fail and
        are not queried (the answer is the same); a row stops at its first failing pair."""
        import coal

        Q = np.asarray(Q, float).reshape(-1, self.robot.dof)
        ok = np.ones(len(Q), bool)
        if not self.pairs or not len(Q):
            return ok
        self.calls += len(Q)
        frames = self._base @ self._frames(Q)                                         # (K, dof, 4, 4)
        poses = np.repeat(self._fixed_poses[None], len(Q), axis=0)
        poses[:, self._moving] = frames[:, self._moving_frame] @ self._moving_local
        centres = np.einsum("kbij,bj->kbi", poses[..., :3, :3], self._ball_centre) + poses[..., :3, 3]
        apart = np.linalg.norm(centres[:, self._pair_a] - centres[:, self._pair_b], axis=2)
        with np.errstate(invalid="ignore"):
            gap = apart - self._ball_radius[self._pair_a] - self._ball_radius[self._pair_b]
        near = ~(gap >= self.clearance_mm)                                            # NaN (a floor): query
        self.skipped += int(near.size - np.count_nonzero(near))
        req, res = coal.DistanceRequest(), coal.DistanceResult()
        for k, n in zip(*np.nonzero(near)):
            if not ok[k]:
                continue
            p = self.pairs[n]
            Ta, Tb = poses[k, p.a], poses[k, p.b]
            res.clear()
            d = coal.distance(self.geometry[p.a], coal.Transform3s(Ta[:3, :3].copy(), Ta[:3, 3].copy()),
                              self.geometry[p.b], coal.Transform3s(Tb[:3, :3].copy(), Tb[:3, 3].copy()), req, res)
            ok[k] = d >= self.clearance_mm
        return ok

    def closest_pair_text(self, q) -> str:
        """'<a> and <b> are d mm apart (< cell.clearance_mm c mm)' for the closest pair at q ('' if clear)."""
        d, pair = self.clearance_mm_at(q)
        if pair is None or d >= self.clearance_mm:
            return ""
        a, b = self.pair_name(pair)
        what = f"overlap by {-d:.1f} mm" if d < 0 else f"are {d:.1f} mm apart"
        return f"{a} and {b} {what} (< cell.clearance_mm {self.clearance_mm:g} mm)"

    def describe(self) -> dict:
        return {"bodies": [b.describe() for b in self.bodies], "clearance_mm": self.clearance_mm,
                "pairs": {"environment": sum(p.kind == "environment" for p in self.pairs),
                          "self": sum(p.kind == "self" for p in self.pairs)},
                "allowed_collisions": self.acm.describe()}


class WorldChecker(Validity):
    """A planner validity check ``valid(q) -> bool``: another check (the part) and the collision world."""

    def __init__(self, inner, world: CollisionWorld):
        self.inner, self.world = inner, world

    def __call__(self, q) -> bool:
        if self.inner is not None and not self.inner(q):
            return False
        return self.world.valid(q)

    def valid_many(self, Q) -> np.ndarray:
        """The inner check on all rows at once, then the world on the rows it passes."""
        Q = np.asarray(Q, float)
        ok = valid_rows(self.inner, Q) if self.inner is not None else np.ones(len(Q), bool)
        rows = np.flatnonzero(ok)
        ok[rows] = self.world.valid_many(Q[rows])
        return ok

    def reason(self, q) -> str:
        """The closest pair of the world when it is what fails, else the inner check's reason."""
        if self.inner is not None and not valid_rows(self.inner, np.asarray(q, float)[None])[0]:
            return reason_of(self.inner, q)
        d, pair = self.world.clearance_mm_at(q)
        a, b = self.world.pair_name(pair)
        gap = f"overlap by {-d:.3f} mm" if d < 0 else f"are {d:.3f} mm apart"
        return f"{a} and {b} {gap} (< cell.clearance_mm {self.world.clearance_mm:g} mm)"

    def __getattr__(self, name):   # the inner checker's figures (calls, mesh, ...)
        return getattr(self.inner, name)


def _with_tool_neighbour(acm: AllowedCollisions, bodies, check=()) -> AllowedCollisions:
    """The tool is adjacent to the link body before the one it is mounted on (the wrist's other side).

    The link capsules end in half-spheres round the joint origins; round a
    spherical wrist the forearm's end sphere is the wrist housing the tool is
    bolted next to, and a wrist bend of 60-90 deg brings a tool cylinder into
    it though no real wrist collides there. ``cell.check_collision`` measures
    the pair anyway.
    """
    tools = [b for b in bodies if b.kind == "tool"]
    links = [b for b in bodies if b.kind == "link"]
    if not tools or not links:
        return acm
    tool = tools[0]
    before = [b for b in links if b.parent < tool.parent]
    if not before:
        return acm
    neighbour = max(before, key=lambda b: b.parent)
    pair = frozenset((tool.name, neighbour.name))
    if any(frozenset(c) == pair for c in check):
        return acm
    return AllowedCollisions({**acm.reasons, pair: "adjacent (wrist)"}, acm.samples, acm.geometry_hash)
