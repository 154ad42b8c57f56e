"""The independent motion check (docs/motion-check.md).

It shares no code with the planner or the timing stage: joint-linear
interpolation of the program's waypoints at <= 4 ms, a batch DH forward
kinematics, and the part as a signed distance to an open surface.
"""
from .check import MotionCheckSettings, MotionReport, Place, WaypointIndex, check_motion
from .fk_batch import BatchFK, FKBatch
from .geometry import PartGeometry, PartQuery, part_from_path

__all__ = ["BatchFK", "FKBatch", "MotionCheckSettings", "MotionReport", "PartGeometry", "PartQuery",
           "Place", "WaypointIndex", "check_motion", "part_from_path"]
