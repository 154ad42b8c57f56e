"""Up-to-date checks: a hash manifest per job in OUTDIR/<job>/.camtool-cache.json.

A job is up to date when the fingerprint of its inputs (job file bytes,
workpiece file bytes, robot and controller-profile files it names, the
``--set`` overrides, the camtool version and a digest of its code) equals the one stored after its
last successful run, and every output file listed there still exists.
"""
from __future__ import annotations

import functools
import hashlib
import json
from pathlib import Path

from .. import __version__, safe_io
from ..errors import BadInput

MANIFEST = ".camtool-cache.json"


def _file_digest(path: Path, kind: str = "text") -> str:
    """SHA-256 of a file read with ``safe_io`` (regular files only, size-capped; a FIFO or device is
    BadInput, never a hang); "missing" when it does not exist (the job's own checks name it)."""
    if not Path(path).exists():
        return "missing"
    return hashlib.sha256(safe_io.read_input_bytes(path, kind)).hexdigest()


def input_files(job) -> dict[str, Path]:
    """The files a loaded job reads, by role: job, workpiece, robot, profile.<fmt>."""
    from ..robots import BUILTIN_ROBOTS

    files = {"job": Path(job.path), "workpiece": job.resolve(job.workpiece.file)}
    if job.robot.name not in BUILTIN_ROBOTS:
        files["robot"] = job.resolve(job.robot.name)
    for fmt, name in sorted(job.post.profiles.items()):
        if isinstance(name, str):
            files[f"profile.{fmt}"] = job.resolve(name)
    return files


@functools.lru_cache(maxsize=1)
def code_digest() -> str:
    """Digest of camtool's own code and data (the package, its robots and profiles, and
    the built-in post-processors): a changed source tree invalidates the cache even
    when the version number stays the same."""
    import importlib.util

    # the built-in plugins' folder, found without importing it (core code never imports the plugins)
    spec = importlib.util.find_spec("postprocessors")
    roots = [Path(__file__).resolve().parents[1]]
    if spec is not None and spec.submodule_search_locations:
        roots += [Path(p).resolve() for p in spec.submodule_search_locations]
    h = hashlib.sha256()
    for root in roots:
        for f in sorted(root.rglob("*")):
            if f.suffix in (".py", ".toml") and "__pycache__" not in f.parts:
                h.update(str(f.relative_to(root)).encode())
                h.update(_file_digest(f).encode())
    return h.hexdigest()


def fingerprint(job, overrides: tuple[str, ...] | list[str]) -> str:
    """SHA-256 hex digest of everything that decides a job's outputs."""
    parts = {"camtool": __version__, "code": code_digest(), "overrides": list(overrides),
             "files": {role: _file_digest(p, role.split(".")[0]) for role, p in input_files(job).items()}}
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()


def manifest_path(outdir: Path) -> Path:
    return Path(outdir) / MANIFEST


def read_manifest(outdir: Path) -> dict | None:
    """The stored manifest of a job folder, or None when absent or unreadable."""
    data = safe_io.read_own_json(manifest_path(outdir))
    return data if isinstance(data, dict) else None


def up_to_date(outdir: Path, fp: str) -> dict | None:
    """The manifest when the job folder holds a successful run with fingerprint ``fp``
    whose outputs all still exist; else None."""
    m = read_manifest(outdir)
    if not m or m.get("fingerprint") != fp or m.get("status") != "ok":
        return None
    files = m.get("files")
    if not isinstance(files, list) or not files:
        return None
    try:
        if not all(isinstance(f, str) and safe_io.check_target(outdir, f) is None and (Path(outdir) / f).is_file()
                   for f in files):
            return None
    except BadInput:  # a name leaving the folder, or a link or folder where a listed file was
        return None
    return m


def write_manifest(outdir: Path, data: dict) -> None:
    """Write the manifest atomically (temporary file + rename)."""
    safe_io.write_file(outdir, MANIFEST, json.dumps(data, indent=2, sort_keys=True) + "\n")


def forget(outdir: Path) -> None:
    """Before a rerun: drop the manifest, the outputs it lists and everything the last run placed
    (report.html and plots too, ``output.forget_previous``), so a failed or killed rerun never leaves
    an old program, report or plot looking current. Only regular files inside ``outdir`` go."""
    from ..run.output import forget_previous

    outdir = Path(outdir)
    m = read_manifest(outdir)
    safe_io.remove_file(outdir, MANIFEST)
    for f in (m or {}).get("files", []) if isinstance((m or {}).get("files"), list) else []:
        if isinstance(f, str):
            safe_io.remove_file(outdir, f)
    forget_previous(outdir)
