"""One consistent run per output folder: stage everything, then place it in one short step.

A run writes every file (programs, report.json, report.html, points.csv,
plots) into a staging folder ``OUT/.camtool-run-<pid>-<random>``. Only when
the run has finished are the files placed into ``OUT``:

1. ``OUT/report.json`` is removed first, so while placing the folder never
   claims a finished run;
2. files the previous run placed (``OUT/.camtool-manifest.json``) and this run
   does not write are removed: no stale program survives a rerun;
3. the manifest is written, then every new file is moved in with ``os.replace`` (a rename on one file
   system: milliseconds, not the seconds writing takes), report.json last.

A run that fails after it wrote its failure report (infeasible, unsafe) is
placed the same way, so the folder then holds that report.json (status and
reason), report.html and plots, and no program. A run that fails where no
stage writes a report (bad input, a timing or post failure, an internal error)
is placed with a report.json of that failure (``pipeline.failure_report``):
never the previous run's report. Leftover staging folders
of killed runs (their process is gone) are removed by the next run into the
same folder. Only files camtool listed in its manifest are ever removed.

Hostile cells (docs/security.md): the folder is resolved once without following links and held by its
descriptor for the whole run (``safe_io.held_outdir``: the staging folder is named through it), checked
through it (``safe_io.check_outdir``: not ``/`` or the home folder, no symlink or special file anywhere
below it, no foreign files) and locked for the run (``safe_io.locked``); every file is placed, and every stale one removed, through
``safe_io`` (dir descriptors and O_NOFOLLOW): a manifest naming ``../x`` or ``/x`` removes nothing,
and a folder or link where a file goes is one clear line (exit 2) before anything changes.
"""
from __future__ import annotations

import json
import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

from .. import safe_io
from ..errors import BadInput

STAGING_PREFIX = ".camtool-run-"
LEFTOVER_PREFIXES = (STAGING_PREFIX, ".camtool-post-", ".camtool-write-")
MANIFEST = ".camtool-manifest.json"
REPORT = "report.json"
TEXT_WITH_PATHS = ("report.json", "report.html")  # files that name other files of the run


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_leftovers(outdir: Path) -> list[Path]:
    """Remove staging folders of killed camtool runs in ``outdir``; returns what was removed."""
    removed = []
    for d in Path(safe_io.at(outdir)).glob(".camtool-*"):
        if d.is_symlink() or not d.is_dir() or not d.name.startswith(LEFTOVER_PREFIXES):
            continue
        pid_text = d.name.split("-")[2] if d.name.startswith(STAGING_PREFIX) else ""
        if pid_text.isdigit() and _alive(int(pid_text)) and int(pid_text) != os.getpid():
            continue  # another run into the same folder is still writing
        shutil.rmtree(d, ignore_errors=True)
        removed.append(d)
    return removed


def _manifest(outdir: Path) -> list[str]:
    data = safe_io.read_own_json(outdir / MANIFEST)
    files = data.get("files", []) if isinstance(data, dict) else []
    return [x for x in files if isinstance(x, str)] if isinstance(files, list) else []


def forget_previous(outdir: Path) -> None:
    """Remove the files the previous run placed (its manifest's, report.json first) and the manifest:
    a rerun that is killed or fails then never leaves the old report or plots looking current."""
    outdir = Path(outdir)
    if not os.path.isdir(safe_io.at(outdir)):
        return
    safe_io.remove_file(outdir, REPORT)
    for old in _manifest(outdir):
        safe_io.remove_file(outdir, old)
    safe_io.remove_file(outdir, MANIFEST)


@contextmanager
def staged_output(outdir: Path):
    """A fresh staging folder inside ``outdir`` (created if needed); removed on exit whatever happens."""
    outdir = Path(outdir)
    # held by its descriptor from the first check to the last rename: the staging folder is named through it
    # (/proc/<pid>/fd/<fd>/.camtool-run-...), so a -o swapped for a link or renamed mid-run is never left
    with safe_io.held_outdir(outdir, check=True), safe_io.locked(outdir):
        try:
            remove_leftovers(outdir)
            stage = Path(tempfile.mkdtemp(prefix=f"{STAGING_PREFIX}{os.getpid()}-", dir=safe_io.at(outdir)))
        except OSError as exc:
            raise BadInput(f"{outdir}: cannot write into the output folder ({exc.strerror or exc})") from None
        try:
            yield stage
        except OSError as exc:  # e.g. a full disk while staging: one line, the placed outputs untouched
            err = safe_io.disk_error(exc)
            if err is None:
                raise
            raise err from None
        finally:
            shutil.rmtree(stage, ignore_errors=True)


def place(stage: Path, outdir: Path) -> list[Path]:
    """Move every file of ``stage`` into ``outdir`` (see the module doc); returns the placed files."""
    stage, outdir = Path(stage), Path(outdir)
    new = sorted(str(p.relative_to(stage)) for p in stage.rglob("*") if p.is_file() and not p.is_symlink())
    for name in new:  # before anything changes: a folder, link or special file where a file goes
        safe_io.check_target(outdir, name)
    for name in TEXT_WITH_PATHS:  # the run named its files by their staging path
        f = stage / name
        if f.is_file():
            f.write_text(f.read_text().replace(str(stage), str(outdir)))
    try:
        safe_io.remove_file(outdir, REPORT)
        for old in _manifest(outdir):
            if old not in new and old != MANIFEST:
                safe_io.remove_file(outdir, old)  # only regular files inside outdir: ../x and /x are left alone
        # written before the files: a killed placing is cleaned up by the next run
        safe_io.write_file(outdir, MANIFEST, json.dumps({"files": new}, indent=1) + "\n")
        placed = []
        for name in [n for n in new if n != REPORT] + ([REPORT] if REPORT in new else []):
            placed.append(safe_io.place_file(stage / name, outdir, name))
    except OSError as exc:
        err = safe_io.disk_error(exc)
        if err is None:
            raise
        raise err from None
    return placed


def final_path(path: Path, stage: Path, outdir: Path) -> Path:
    """Where a file written as ``path`` inside ``stage`` lies after ``place``."""
    try:
        return Path(outdir) / Path(path).relative_to(stage)
    except ValueError:
        return Path(path)
