"""The collision world of a job's stages (the small hooks ``camtool.run.stages`` calls)."""
from __future__ import annotations

from .world import CollisionWorld, WorldChecker


def collision_world(settings, robot) -> CollisionWorld:
    """The job's world (``JobSettings.cell``; an empty cell without it): robot, tool, obstacles, floor."""
    return CollisionWorld(robot, settings.cell, settings.check.tool_radius_mm)


def with_world(valid, world: CollisionWorld | None):
    """A planner validity check that also keeps the world's clearances (``valid`` alone without a world)."""
    if world is None or not world.pairs:
        return valid
    return WorldChecker(valid, world)
