"""camtool: offline CAM pipeline for robot surface work.

Job (TOML) -> Workpiece -> Surface -> Path -> JointPath -> Trajectory -> programs.
Lengths are mm throughout; angles are radians inside the code and degrees at
the edges (job files, reports, controller programs).
"""
from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("camtool")
except PackageNotFoundError:  # running from a source tree without install
    __version__ = "0.0.0+src"
