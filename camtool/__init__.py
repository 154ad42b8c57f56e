"""camtool: offline CAM pipeline for robot surface work.

Job (TOML) -> Workpiece -> Surface -> Path -> JointPath -> Trajectory -> programs.
Lengths are mm throughout; angles are radians inside the code and degrees at
the edges (job files, reports, controller programs).
"""


def __getattr__(name: str):
    """``camtool.__version__``, read from the installed metadata when first asked for (importlib.metadata
    costs ~0.1 s of every start-up otherwise)."""
    if name != "__version__":
        raise AttributeError(f"module 'camtool' has no attribute {name!r}")
    from importlib.metadata import PackageNotFoundError, version

    try:
        value = version("camtool")
    except PackageNotFoundError:  # running from a source tree without install
        value = "0.0.0+src"
    globals()["__version__"] = value
    return value
