"""The wrist bend a tool leaves free: where the tool keeps the clearance from the link before the wrist.

A tool wider than the flange meets the forearm when the wrist bends far: a 50 mm polisher on the
IRB2400 comes within 5 mm of link_4 at |j5| = 104.7 deg, though j5's limit is 120 deg. The planner
measures it (``CollisionWorld``), but the placement screen solves the closed-form IK against the
joint limits only, so it proposed placements the planner then refused at every configuration.

The pairs that decide it are the measured ones between bodies on the last three joint frames (on a
6R arm link_4, link_5, link_6 and the tool): their relative pose depends only on the last two
joints. ``WristBend`` measures those pairs once on a grid of the last two joints (coal, the
planner's own bodies and distances) and answers for batches of configurations: a configuration
is kept where the clearance holds at the grid cell's corners around it. The grid is fine in the
bend joint (``bend_step_deg``) and coarse in the last (``roll_samples``); a cell is kept only when
every roll sample at both bend edges keeps the clearance (conservative in the roll: the screen
may refuse a bend a tool mesh clears at one roll only; the planner stays the judge either way).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class WristBendSettings:
    """The grid of the last two joints: the bend joint's step (deg) and the roll joint's samples."""

    bend_step_deg: float = 0.5
    roll_samples: int = 8


class WristBend:
    """Which values of the bend joint (the last but one) keep the wrist pairs' clearance (module doc)."""

    def __init__(self, world, settings: WristBendSettings = WristBendSettings()):
        robot = world.robot
        self.dof = robot.dof
        self.bend_joint = self.dof - 2
        first = self.dof - 2            # bodies on joint frames first .. dof (1-based) move only with the last two
        self.pairs = tuple(p for p in world.pairs if p.kind == "self"
                           and min(world.bodies[p.a].parent, world.bodies[p.b].parent) >= first)
        self.names = tuple(world.pair_name(p) for p in self.pairs)
        lo, hi = float(robot.limits.lower[self.bend_joint]), float(robot.limits.upper[self.bend_joint])
        n = max(2, int(math.ceil((hi - lo) / math.radians(settings.bend_step_deg))) + 1)
        self.grid_rad = np.linspace(lo, hi, n)
        self.clearance_mm = float(world.clearance_mm)
        self.distance_mm = np.full(n, np.inf)   # the smallest over the roll samples and the pairs
        if not self.pairs:
            return
        q = 0.5 * (np.asarray(robot.limits.lower, float) + np.asarray(robot.limits.upper, float))
        q = np.where(robot.prismatic, q, 0.0)
        rolls = np.linspace(-math.pi, math.pi, settings.roll_samples, endpoint=False)
        for i, b in enumerate(self.grid_rad):
            for r in rolls:
                q[self.bend_joint], q[self.dof - 1] = b, r
                self.distance_mm[i] = min(self.distance_mm[i], float(world.pair_distances_mm(q, self.pairs).min()))
        self.kept = self.distance_mm >= self.clearance_mm

    @property
    def matters(self) -> bool:
        """Whether any bend inside the limits breaks the clearance."""
        return bool(self.pairs) and not bool(self.kept.all())

    def ok(self, Q) -> np.ndarray:
        """(...,) whether each configuration's bend (rows of Q, (..., dof), rad) keeps the clearance."""
        Q = np.asarray(Q, float)
        b = Q[..., self.bend_joint]
        if not self.pairs:
            return np.ones(b.shape, bool)
        g = self.grid_rad
        with np.errstate(invalid="ignore"):
            i = np.clip(np.searchsorted(g, b, side="right") - 1, 0, len(g) - 2)
            inside = (b >= g[0]) & (b <= g[-1])
        return inside & self.kept[i] & self.kept[i + 1]

    def free_range_deg(self) -> tuple[float, float] | None:
        """The kept interval of the bend joint round 0 deg (deg), or None if 0 is not kept."""
        k = int(np.argmin(np.abs(self.grid_rad)))
        if not self.pairs or not self.kept[k]:
            return None
        a = k
        while a > 0 and self.kept[a - 1]:
            a -= 1
        b = k
        while b < len(self.kept) - 1 and self.kept[b + 1]:
            b += 1
        return math.degrees(self.grid_rad[a]), math.degrees(self.grid_rad[b])

    def why(self, q, joint_names) -> str:
        """'<joint> = v deg there; with this tool it keeps cell.clearance_mm from <link> within [a, b] deg (its
        limits: [lo, hi])' when configuration q's bend is one the wrist pairs refuse, else ''."""
        q = np.asarray(q, float)
        if not self.matters or bool(self.ok(q[None])[0]):
            return ""
        j = self.bend_joint
        free = self.free_range_deg()
        lo, hi = math.degrees(self.grid_rad[0]), math.degrees(self.grid_rad[-1])
        links = sorted({n for pair in self.names for n in pair if n != "tool"})
        where = (f"within [{free[0]:.1f}, {free[1]:.1f}] deg" if free is not None else "at no bend")
        return (f"{joint_names[j]} = {math.degrees(q[j]):.1f} deg there; with this tool and cell.clearance_mm "
                f"{self.clearance_mm:g} mm it clears {', '.join(links) or 'the wrist'} only {where} "
                f"(its limits: [{lo:g}, {hi:g}] deg)")
