"""The cell's collision world in coal: robot link bodies, the tool, obstacles, the allowed-collision matrix."""
from .acm import AllowedCollisions, compute_acm, robot_acm
from .shapes import Body, link_radius_mm, obstacle_bodies, robot_bodies
from .world import CellSettings, CollisionWorld, Pair, WorldChecker

__all__ = ["AllowedCollisions", "Body", "CellSettings", "CollisionWorld", "Pair", "WorldChecker", "compute_acm",
           "link_radius_mm", "obstacle_bodies", "robot_acm", "robot_bodies"]
