"""Robot library: DH descriptions built into Pinocchio models.

``get_robot(name_or_file, params)`` is the one entry point: a built-in name
(``seed8``, ``irb2400``, ``irb2400_paper``, ``sia20``), a TOML DH file, or a
URDF file.
"""
from .library import BUILTIN_ROBOTS, get_robot, robot_from_toml
from .model import Robot

__all__ = ["BUILTIN_ROBOTS", "Robot", "get_robot", "robot_from_toml"]
