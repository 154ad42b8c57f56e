"""The part against the cell at a placement: a moved (or tilted) part must not meet the table or the floor.

``camtool place`` moves the part with its fixture: obstacles in the workpiece frame (``frame = "workpiece"``)
move with it, those in the world frame (a table, a wall, a guard) and the floor stay. ``PartClearance`` measures,
per placement, the part's distance (coal: the part's own triangles as a BVH, a cloud's convex hull) to each
world-fixed obstacle and to the floor, and refuses the placements where the part comes nearer to one than the
cell's clearance, or than it already is at the job's own placement (a part resting on its table stays allowed
as near as it rests). The robot's bodies against the obstacles are the planner's and the motion check's
business (``verify_placement`` plans in the cell).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..collision.shapes import WORLD

TOL_MM = 1e-6


def _part_geometry(workpiece):
    """The coal geometry of the placed workpiece (world frame, mm): its mesh as a BVH, else its points' hull."""
    from ..collision.body import convex_hull
    from ..collision.mesh_query import mesh_bvh

    if workpiece.vertices_mm is not None and workpiece.faces is not None and len(workpiece.faces):
        return mesh_bvh(workpiece.vertices_mm, workpiece.faces), np.asarray(workpiece.vertices_mm, float)
    pts = np.asarray(workpiece.points_mm, float)
    return convex_hull(pts), pts


class PartClearance:
    """The part's clearance from the world-fixed obstacles and the floor, per placement (module doc)."""

    def __init__(self, workpiece, cell, specs, placement):
        """``workpiece`` placed (world frame), ``cell`` the job's ``CellSettings``, ``specs`` its
        ``ObstacleSpec``s (their order is the cell's obstacles'), ``placement`` offset -> 4x4 world transform."""
        self.placement = placement
        self.clearance_mm = float(cell.clearance_mm)
        bodies = list(cell.obstacles)
        world = [b for b, s in zip(bodies, specs) if s.frame == "world"]
        self.floor = [b for b in bodies[len(specs):] if b.shape == "halfspace"]
        self.bodies = [b for b in world if b.parent == WORLD]
        self.active = bool(self.bodies or self.floor)
        if not self.active:
            return
        self._part, pts = _part_geometry(workpiece)
        self._z_points = pts
        self._shapes = [b.coal_geometry() for b in self.bodies]
        d0 = self.distances(np.eye(4))
        self.allowed_mm = np.minimum(self.clearance_mm, d0) - TOL_MM   # per obstacle, then the floor

    def distances(self, D: np.ndarray) -> np.ndarray:
        """(obstacles + floor,) distances (mm, negative: overlap) of the part moved by the world transform D."""
        import coal

        out = []
        if self.bodies:
            tf = coal.Transform3s(D[:3, :3], D[:3, 3])
            req, res = coal.DistanceRequest(), coal.DistanceResult()
            for body, shape in zip(self.bodies, self._shapes):
                T = body.local_T_mm
                res.clear()
                out.append(coal.distance(self._part, tf, shape, coal.Transform3s(T[:3, :3], T[:3, 3]), req, res))
        for f in self.floor:   # the lowest point of the part above the floor's top
            z = self._z_points @ D[2, :3] + D[2, 3]
            out.append(float(z.min()) - float(f.size_mm[0]))
        return np.asarray(out, float)

    def names(self) -> list[str]:
        return [b.name for b in self.bodies] + [f.name for f in self.floor]

    def refuse(self, results: list) -> list:
        """``results`` (screen results) with every placement whose part comes too near the cell refused (stage
        ``part``, ``unreachable``: the obstacles it comes too near)."""
        if not self.active:
            return results
        out = []
        for r in results:
            d = self.distances(self.placement(r.offset))
            near = int(np.count_nonzero(d < self.allowed_mm))
            out.append(r if not near else replace(r, feasible=False, stage="part", unreachable=near,
                                                  checked=len(d), cost=float("inf")))
        return out
