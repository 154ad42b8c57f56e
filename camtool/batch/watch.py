"""Hot folder: run every new job file or workpiece file that appears in a folder.

A ``*.toml`` file is a job and runs as it is (with the ``--set`` overrides,
like ``camtool batch``). A file whose extension the workpiece loader accepts
(``camtool.part.workpiece.LOADERS``) runs with the template job, its
``workpiece.file`` set to the file's absolute path; that derived job is
written to OUTDIR/<file name>/job.toml first. Both go through the batch
runner (``run_one``: one process per job, logs, statuses, caching), and
OUTDIR/summary.json is updated after every round.

A file is taken only once it is stable: its size and mtime did not change
between two polls one interval apart. Polling only, no inotify. See
docs/batch.md, "Hot folder".
"""
from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

from .. import __version__, safe_io
from ..errors import BadInput
from .executors import run_batch
from .runner import JobResult, JobSpec, prepare_job
from .summary import STATUSES, summary_dict, write_summary

Signature = tuple[int, int]  # (size in bytes, mtime in ns)
TEMPLATE_PLACEHOLDER = "(watched workpiece file)"
SUCCEEDED = ("ok", "cached")


# ---------------------------------------------------------------- the folder

def workpiece_extensions() -> frozenset[str]:
    """Lower-case extensions (with dot) the workpiece loader registry accepts."""
    from ..part.workpiece import supported_extensions

    return frozenset(supported_extensions())


def kind_of(path: Path) -> str | None:
    """``job`` for a .toml file, ``workpiece`` for a loadable extension, else None."""
    ext = path.suffix.lower()
    if ext == ".toml":
        return "job"
    return "workpiece" if ext in workpiece_extensions() else None


def scan(indir: Path, exclude=()) -> dict[Path, Signature]:
    """The candidate files directly inside ``indir`` (hidden files and ``exclude``
    left out), resolved, each with its (size, mtime_ns) signature."""
    skip = {Path(p).resolve() for p in exclude}
    found = {}
    for p in Path(indir).iterdir():
        if p.name.startswith(".") or kind_of(p) is None:
            continue
        try:
            st = p.stat()
        except OSError:  # deleted between listing and stat
            continue
        rp = p.resolve()
        if rp in skip or not p.is_file():
            continue
        found[rp] = (st.st_size, st.st_mtime_ns)
    return found


def stable(previous: dict[Path, Signature], current: dict[Path, Signature]) -> list[Path]:
    """Files of ``current`` whose size and mtime equal those of ``previous`` (sorted):
    present at both polls and unchanged over the interval between them."""
    return sorted(p for p, sig in current.items() if previous.get(p) == sig)


def output_names(files) -> dict[Path, str]:
    """Output folder per file: the stem of a job file (as ``camtool batch``), the full
    name of a workpiece file (part.stl and part.ply never share a folder); a name
    that still clashes gets ``-<8 hex of the path's SHA-1>``."""
    base = {f: safe_io.safe_name(f.stem if kind_of(f) == "job" else f.name) for f in files}
    count: dict[str, int] = {}
    for name in base.values():
        count[name] = count.get(name, 0) + 1
    return {f: n if count[n] == 1 else f"{n}-{hashlib.sha1(str(f).encode()).hexdigest()[:8]}"
            for f, n in base.items()}


# ---------------------------------------------------------------- the watcher

@dataclass
class Watcher:
    """Watches ``indir``; writes into ``outdir``. Construct with ``Watcher.create``,
    which checks the input (BadInput, nothing written) before anything runs."""

    indir: Path
    outdir: Path
    template: Path
    template_data: dict
    overrides: tuple[str, ...] = ()
    timeout_s: float | None = None
    workers: int = 1
    results: list[JobResult] = field(default_factory=list)  # of this session, in run order
    pending: list[Path] = field(default_factory=list)  # still changing at the last poll
    _seen: dict[Path, Signature] = field(default_factory=dict)
    _sources: dict[str, dict] = field(default_factory=dict)
    _t0: float = field(default_factory=time.perf_counter)

    @classmethod
    def create(cls, indir, outdir, template, overrides=(), timeout_s=None, workers=1) -> "Watcher":
        """A watcher after checking INDIR, the template and the overrides."""
        from ..job import load_job

        indir, outdir, template = Path(indir), Path(outdir), Path(template)
        if not indir.is_dir():
            raise BadInput(f"{indir}: no such folder to watch" if not indir.exists()
                           else f"{indir}: not a folder; give the folder to watch")
        if outdir.exists() and not outdir.is_dir():
            raise BadInput(f"{outdir}: exists and is not a folder; give an output folder")
        safe_io.check_outdir(outdir)
        overrides = tuple(overrides)
        # the template with the overrides, its workpiece stood in for by a placeholder
        tpl = load_job(template, [*overrides, f"workpiece.file={json.dumps(TEMPLATE_PLACEHOLDER)}"])
        return cls(indir.resolve(), outdir.resolve(), template.resolve(), _absolute_files(tpl),
                   overrides, timeout_s, max(1, int(workers)))

    # -------------------------------------------------------- polling

    def scan(self) -> dict[Path, Signature]:
        return scan(self.indir, exclude=[self.template])

    def ready(self, previous: dict[Path, Signature], current: dict[Path, Signature]) -> list[Path]:
        """Stable files not yet run in their current state (sorted); forgets deleted files."""
        for p in [p for p in self._seen if p not in current]:
            del self._seen[p]
        return [p for p in stable(previous, current) if self._seen.get(p) != current[p]]

    def watch(self, interval: float, once: bool = False, max_jobs: int | None = None, sleep=time.sleep,
              on_start=None, on_done=None) -> list[JobResult]:
        """Poll every ``interval`` s and run what is ready. Returns this session's results
        after one round (``once``) or once ``max_jobs`` files were handled; otherwise
        runs until interrupted (KeyboardInterrupt propagates; ``results`` and
        summary.json hold everything finished before it)."""
        previous = self.scan()
        while True:
            sleep(interval)
            current = self.scan()
            todo = self.ready(previous, current)
            if max_jobs is not None:
                todo = todo[:max(0, max_jobs - len(self.results))]
            self.pending = sorted(p for p in current if p not in todo and self._seen.get(p) != current[p])
            if todo:
                self.run(todo, current, on_start, on_done)
            previous = current
            if once or (max_jobs is not None and len(self.results) >= max_jobs):
                self.write_summary()
                return self.results

    # -------------------------------------------------------- running

    def run(self, files, signatures=None, on_start=None, on_done=None) -> list[JobResult]:
        """Run ``files`` (paths in INDIR) as one round on the local pool, merge them into
        summary.json, and return their results (sorted by output folder)."""
        files = sorted(Path(f).resolve() for f in files)
        names = self._unclaimed(output_names(files))
        specs, decided = [], []
        for f in files:
            item = self._prepare(f, names[f])
            (specs if isinstance(item, JobSpec) else decided).append(item)
        for r in decided:
            if on_done:
                on_done(r)
        results = sorted(decided + run_batch(specs, "local", self.workers, None, on_start, on_done),
                         key=lambda r: r.name)
        for f in files:
            if signatures is not None and f in signatures:
                self._seen[f] = signatures[f]
        self.results.extend(results)
        self.write_summary()
        return results

    def _unclaimed(self, names: dict[Path, str]) -> dict[Path, str]:
        """``names`` with a suffix on every folder name that another source already has (in this session or
        in summary.json from earlier ones): after ``a b.stl`` ran into ``OUT/a_b.stl``, a later ``a_b.stl``
        runs into ``OUT/a_b.stl-<8 hex>``, never over the first one's programs and summary entry."""
        claimed = {e["name"]: e.get("source") for e in _read_entries(self.outdir / "summary.json")
                   if isinstance(e.get("name"), str)}
        claimed.update({n: v.get("source") for n, v in self._sources.items()})
        out = {}
        for f, name in names.items():
            owner = claimed.get(name)
            if owner is not None and owner != str(f):
                name = f"{name}-{hashlib.sha1(str(f).encode()).hexdigest()[:8]}"
            out[f] = name
        return out

    def _prepare(self, src: Path, name: str) -> JobSpec | JobResult:
        """The JobSpec of one file, or its decided result (bad_input, failed or cached)."""
        kind = kind_of(src)
        folder = self.outdir / name
        job = src if kind == "job" else folder / "job.toml"
        overrides = self.overrides if kind == "job" else ()
        self._sources[name] = {"source": str(src), "kind": kind}
        derive = (lambda: write_derived_job(self.template_data, src, job, self.template)) if kind == "workpiece" else None
        return prepare_job(job, folder, name, overrides, self.timeout_s, before_load=derive)

    # -------------------------------------------------------- summary

    def summary(self) -> dict:
        """OUTDIR/summary.json as it stands: earlier entries merged with this session's
        (one entry per output folder, the latest wins), sorted by output folder."""
        entries = {e["outdir"]: e for e in _read_entries(self.outdir / "summary.json")}
        for e in summary_dict(self.results, self.outdir)["jobs"]:  # in run order: the latest wins
            entries[e["outdir"]] = {**e, **self._sources.get(e["name"], {})}
        jobs = [entries[k] for k in sorted(entries)]
        counts = {s: sum(j.get("status") == s for j in jobs) for s in STATUSES}
        return {"camtool": __version__, "mode": "watch", "indir": str(self.indir),
                "template": str(self.template), "workers": self.workers, "overrides": list(self.overrides),
                "timeout_s": self.timeout_s, "wall_time_s": round(time.perf_counter() - self._t0, 3),
                "pending": [p.name for p in self.pending],
                "exit_code": 0 if all(j.get("status") in SUCCEEDED for j in jobs) else 3,
                "jobs_total": len(jobs), "counts": counts, "jobs": jobs}

    def write_summary(self) -> Path:
        return write_summary(self.summary(), self.outdir)


def _read_entries(file: Path) -> list[dict]:
    """The job entries of an existing summary.json ([] when absent or unreadable)."""
    data = safe_io.read_own_json(file)
    jobs = data.get("jobs") if isinstance(data, dict) else None
    return [e for e in jobs if isinstance(e, dict) and isinstance(e.get("outdir"), str)] if isinstance(jobs, list) else []


def _absolute_files(job) -> dict:
    """A validated job as a dict, every file name it holds made absolute."""
    from ..robots import BUILTIN_ROBOTS

    data = job.as_dict()
    if data["robot"]["name"] not in BUILTIN_ROBOTS:
        data["robot"]["name"] = str(job.resolve(data["robot"]["name"]).resolve())
    data["post"]["profiles"] = {k: str(job.resolve(v).resolve()) if isinstance(v, str) else v
                                for k, v in data["post"]["profiles"].items()}
    return data


def write_derived_job(template_data: dict, workpiece: Path, file: Path, template: Path) -> Path:
    """Write the template job with ``workpiece.file`` = the workpiece's absolute path.
    The bytes depend only on the inputs, so an unchanged file stays cached."""
    import tomli_w

    data = {k: dict(v) for k, v in template_data.items()}
    data["workpiece"]["file"] = str(Path(workpiece).resolve())
    # file names quoted with repr: a newline (or any control character) in a name cannot end the comment
    text = (f"# Written by `camtool watch`: template {str(template)!r} (with its --set overrides)\n"
            f"# for the workpiece {Path(workpiece).name!r}.\n" + tomli_w.dumps(data))
    file = Path(file)
    safe_io.make_folder(file.parent.parent, file.parent.name)
    try:
        same = safe_io.read_input_text(file, "job") == text
    except BadInput:
        same = False
    if not same:
        safe_io.write_file(file.parent, file.name, text)
    return file
