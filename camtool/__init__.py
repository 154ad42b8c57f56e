"""camtool: offline CAM pipeline for robot surface work.

Job (TOML) -> Workpiece -> Surface -> Path -> JointPath -> Trajectory -> programs.
Lengths are mm throughout; angles are radians inside the code and degrees at
the edges (job files, reports, controller programs).
"""
import os as _os
import sys as _sys


def _drop_working_folder_from_path() -> None:
    """Take the working folder off the import path (``python -m camtool.cli`` puts it first), so a
    ``numpy.py`` or ``click.py`` dropped in a hot folder or a batch folder is never imported: camtool
    often runs as root there. Folders named in PYTHONPATH are the caller's choice and stay."""
    try:
        here = _os.getcwd()
    except OSError:
        here = None
    chosen = {p for p in _os.environ.get("PYTHONPATH", "").split(_os.pathsep) if p}
    chosen = {_os.path.abspath(p) for p in chosen}
    _sys.path[:] = [p for p in _sys.path
                    if not ((p == "" or (here is not None and _os.path.abspath(p) == here))
                            and here not in chosen)]


_drop_working_folder_from_path()


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
