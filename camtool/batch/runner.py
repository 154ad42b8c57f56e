"""Find, check and run the jobs of a batch; one job = one ``camtool run`` process.

Every job runs as ``python -m camtool.cli --debug run JOB -o OUTDIR/<name> --json``
in its own process group: an error of any kind, even a crash, stays inside
that process; its exit code is the job's exit code (same mapping as
``camtool run``), its stderr (with the traceback, thanks to ``--debug``) is
OUTDIR/<name>/camtool.log, and a job past its ``timeout`` is killed with its
whole process group.
"""
from __future__ import annotations

import atexit
import hashlib
import os
import signal
import subprocess
import sys
import threading
import time
import traceback
from dataclasses import asdict, dataclass, field
from pathlib import Path

from .. import __version__
from .. import safe_io
from ..alongside import die_with_parent
from ..errors import BadInput
from . import cache

LOG_NAME = "camtool.log"
TIMEOUT_EXIT = 124  # the exit code `timeout(1)` uses; camtool run itself never returns it
STATUS_BY_EXIT = {0: "ok", 2: "bad_input", 3: "infeasible", 4: "unavailable"}
JOB_CWD = "/"  # a job runs from a folder only root can write to, never from the hot or batch folder
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")
RESULT_FD_ENV = "CAMTOOL_RESULT_FD"  # the job's JSON result goes to this pipe, never to its stdout
MAX_RESULT_BYTES = 64 << 20


_live: set[subprocess.Popen] = set()
_live_lock = threading.Lock()


@dataclass(frozen=True)
class JobSpec:
    """One job to run: absolute job path, folder name, absolute output folder,
    the ``--set`` overrides, timeout (s, or None) and the input fingerprint."""

    job: str
    name: str
    outdir: str
    overrides: tuple[str, ...] = ()
    timeout_s: float | None = None
    fingerprint: str = ""


@dataclass
class JobResult:
    """The outcome of one job. ``files`` are relative to the job's folder."""

    job: str
    name: str
    outdir: str
    status: str  # ok | failed | infeasible | bad_input | unavailable | timeout | cached
    exit_code: int
    reason: str = ""
    wall_time_s: float = 0.0
    points: int | None = None
    cycle_time_s: float | None = None
    files: list[str] = field(default_factory=list)

    @property
    def succeeded(self) -> bool:
        return self.status in ("ok", "cached")

    def as_dict(self) -> dict:
        return asdict(self)


# ---------------------------------------------------------------- finding jobs

def discover_jobs(paths) -> list[Path]:
    """Job files from files and folders (every ``*.toml`` directly inside a folder),
    resolved, de-duplicated and sorted; BadInput for a missing path or no job."""
    found: set[Path] = set()
    for p in map(Path, paths):
        if p.is_dir():
            found.update(f.resolve() for f in p.glob("*.toml") if f.is_file())
        elif p.is_file():
            found.add(p.resolve())
        else:
            raise BadInput(f"{p}: no such job file or folder")
    if not found:
        raise BadInput("no job files found in " + ", ".join(map(str, paths)) + " (expected *.toml)")
    return sorted(found)


def job_names(jobs: list[Path]) -> dict[Path, str]:
    """Output folder name per job: the file stem made a safe name (``safe_io.safe_name``: ``...toml``
    gives ``job``, never ``..``), or ``name-<8 hex of the path's SHA-1>`` when several jobs share a
    name (stable whatever else is in the batch)."""
    base = {j: safe_io.safe_name(j.stem) for j in jobs}
    stems: dict[str, int] = {}
    for n in base.values():
        stems[n] = stems.get(n, 0) + 1
    return {j: n if stems[n] == 1 else f"{n}-{hashlib.sha1(str(j).encode()).hexdigest()[:8]}"
            for j, n in base.items()}


def check_overrides(overrides) -> None:
    """BadInput (one line) for a ``--set`` with bad syntax, an unknown key or a wrong type."""
    from ..job import validate

    validate({}, "--set", list(overrides))


def prepare_batch(paths, outdir, overrides=(), timeout_s=None, force=False):
    """Check the batch and sort its jobs into those to run and those already decided.

    Returns ``(specs, decided)``: JobSpecs to run, and JobResults of jobs that
    failed to load (bad_input, with the reason) or are up to date (cached).
    Raises BadInput for bad input to the batch itself: a missing path, no
    job, or a bad override; nothing is run or written then.
    """
    overrides = tuple(overrides)
    check_overrides(overrides)
    jobs = discover_jobs(paths)
    names = job_names(jobs)
    outdir = Path(outdir).resolve()
    specs, decided = [], []
    for j in jobs:
        item = prepare_job(j, outdir / names[j], names[j], overrides, timeout_s, force)
        (specs if isinstance(item, JobSpec) else decided).append(item)
    return specs, decided


def prepare_job(job: Path, folder: Path, name: str, overrides: tuple = (), timeout_s=None, force: bool = False,
                before_load=None) -> "JobSpec | JobResult":
    """One job: its JobSpec to run, or its decided result (bad_input, failed, or cached).

    ``before_load`` (optional) runs first inside the same error handling, e.g. to
    write a derived job file.
    """
    from ..job import load_job

    t0 = time.perf_counter()
    base = dict(job=str(job), name=name, outdir=str(folder))
    try:
        if before_load is not None:
            before_load()
        loaded = load_job(job, list(overrides))
        fp = cache.fingerprint(loaded, overrides)  # every input read with safe_io: no FIFO or device blocks it
    except BadInput as exc:
        return _decided(base, "bad_input", 2, str(exc), t0, str(exc))
    except Exception as exc:  # an internal error loading one job never stops the others
        return _decided(base, "failed", 1, _one_line(exc), t0, traceback.format_exc())
    m = None if force else cache.up_to_date(folder, fp)
    if m is not None:
        return JobResult(**base, status="cached", exit_code=0,
                         reason="inputs unchanged since the last successful run",
                         wall_time_s=round(time.perf_counter() - t0, 4), points=m.get("points"),
                         cycle_time_s=m.get("cycle_time_s"), files=list(m["files"]))
    if timeout_s is not None:  # the timeout covers the whole job: loading and hashing included
        spent = time.perf_counter() - t0
        if spent >= timeout_s:
            return _decided(base, "timeout", TIMEOUT_EXIT, f"still preparing after the {timeout_s:g} s timeout "
                            "(loading and hashing the inputs)", t0, "timeout while hashing the inputs")
        timeout_s = timeout_s - spent
    return JobSpec(**base, overrides=overrides, timeout_s=timeout_s, fingerprint=fp)


def _one_line(exc: BaseException) -> str:
    text = str(exc).splitlines()[0] if str(exc) else ""
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _decided(base: dict, status: str, code: int, reason: str, t0: float, log: str) -> JobResult:
    folder = Path(base["outdir"])
    try:
        safe_io.make_folder(folder.parent, folder.name)
        cache.forget(folder)
        safe_io.write_file(folder, LOG_NAME, f"# camtool {__version__} batch: {base['job']}\n{log.rstrip()}\n")
    except (OSError, BadInput):
        pass
    return JobResult(**base, status=status, exit_code=code, reason=reason,
                     wall_time_s=round(time.perf_counter() - t0, 4))


# ---------------------------------------------------------------- running one job

def job_command(spec: JobSpec) -> list[str]:
    """The command line that runs one job."""
    # -P: no folder goes on the job's import path. Without it ``-m`` puts the working folder first, and a
    # ``numpy.py`` or ``click.py`` dropped there (a hot folder, a batch folder) would run as the job's user.
    cmd = [sys.executable, "-P", "-m", "camtool.cli", "--debug", "run", os.path.abspath(spec.job),
           "-o", os.path.abspath(spec.outdir), "--json", "--progress"]
    for o in spec.overrides:
        cmd += ["--set", o]
    return cmd


def job_env() -> dict[str, str]:
    """The job's environment: ours, with one BLAS/OpenMP/numba thread unless set,
    so N jobs use N cores and results do not depend on the worker count."""
    env = dict(os.environ)
    for var in THREAD_VARS:
        env.setdefault(var, "1")
    env["PYTHONUNBUFFERED"] = "1"
    return env


def kill_running() -> None:
    """Kill the process groups of every job still running (on interrupt, and at exit whatever the way)."""
    with _live_lock:
        procs = list(_live)
    for p in procs:
        _kill_group(p)


atexit.register(kill_running)


def _kill_group(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


def reason_from_log(text: str, returncode: int) -> str:
    """The one-line reason of a failed job: camtool's own error line, else the signal
    or exit code."""
    for line in reversed(text.splitlines()):
        for prefix in ("camtool: error: ", "camtool: internal error: "):
            if line.startswith(prefix):
                reason = line[len(prefix):].split(" (rerun with --debug", 1)[0]
                return ("internal error: " if "internal" in prefix else "") + reason
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.startswith("# ")]
    if returncode > 0 and lines:  # e.g. a Python traceback from outside camtool's error handling
        return lines[-1].strip()
    if returncode < 0:
        try:
            return f"killed by signal {signal.Signals(-returncode).name}"
        except ValueError:
            return f"killed by signal {-returncode}"
    return f"exited with code {returncode} without a message (see {LOG_NAME})"


def run_one(spec: JobSpec) -> JobResult:
    """Run one job in its own process; never raises. The log is OUTDIR/<name>/camtool.log."""
    t0 = time.perf_counter()
    folder = Path(spec.outdir)
    base = dict(job=spec.job, name=spec.name, outdir=spec.outdir)
    log_file = folder / LOG_NAME
    try:
        safe_io.make_folder(folder.parent, folder.name)  # a symlink there is refused, never followed
        cache.forget(folder)
        cmd = job_command(spec)
        with safe_io.new_file(folder, LOG_NAME) as log:
            log.write((f"# camtool {__version__} batch job {spec.name}: {spec.job}\n# command: "
                       + " ".join(cmd) + "\n").encode())
            log.flush()
            # the result comes back on a pipe of its own: whatever the job (or a plugin it imports) prints
            # on stdout goes to the log and never into the JSON
            read_fd, write_fd = os.pipe()
            try:
                proc = subprocess.Popen(cmd, stdout=log, stderr=log, stdin=subprocess.DEVNULL,
                                        env={**job_env(), RESULT_FD_ENV: str(write_fd)}, pass_fds=(write_fd,),
                                        start_new_session=True, cwd=JOB_CWD, preexec_fn=die_with_parent)
            except BaseException:
                os.close(read_fd)
                raise
            finally:
                os.close(write_fd)
            with _live_lock:
                _live.add(proc)
            reader = _ResultReader(read_fd)
            try:
                proc.wait(timeout=spec.timeout_s)
                timed_out = False
            except subprocess.TimeoutExpired:
                timed_out = True
            finally:
                _kill_group(proc)  # its helpers too, on every way out (a timeout, an interrupt, an error)
                proc.wait()
                with _live_lock:
                    _live.discard(proc)
            out = reader.result()
        wall = round(time.perf_counter() - t0, 3)
        rc = proc.returncode
        text = safe_io.read_input_bytes(log_file, "text", follow=False).decode(errors="replace")
        if timed_out:
            result = JobResult(**base, status="timeout", exit_code=TIMEOUT_EXIT, wall_time_s=wall,
                               reason=f"still running after the {spec.timeout_s:g} s timeout; killed")
        elif rc == 0:
            result = _ok_result(base, out, folder, wall)
        else:
            result = JobResult(**base, status=STATUS_BY_EXIT.get(rc, "failed"),
                               exit_code=rc if rc in STATUS_BY_EXIT else 1, wall_time_s=wall,
                               reason=reason_from_log(text, rc))
            if result.status == "infeasible":
                result.points = _report_points(folder)
        with safe_io.new_file(folder, LOG_NAME, append=True) as log:
            if rc != 0 and out and not timed_out:
                log.write(out)
            log.write(f"# {result.status}: exit code {result.exit_code} after {wall:.2f} s\n".encode())
        if result.status == "ok":
            cache.write_manifest(folder, {"fingerprint": spec.fingerprint, "status": "ok",
                                          "camtool": __version__, "job": spec.job,
                                          "overrides": list(spec.overrides), "files": result.files,
                                          "points": result.points, "cycle_time_s": result.cycle_time_s})
        return result
    except BadInput as exc:  # e.g. a symlink planted in the job's folder: refused, this job only
        return JobResult(**base, status="bad_input", exit_code=2, reason=str(exc),
                         wall_time_s=round(time.perf_counter() - t0, 3))
    except Exception as exc:  # the batch machinery itself failed for this job only
        tb = traceback.format_exc()
        try:
            with safe_io.new_file(folder, LOG_NAME, append=True) as log:
                log.write(tb.encode())
        except (OSError, BadInput):
            pass
        return JobResult(**base, status="failed", exit_code=1, reason=f"batch: {_one_line(exc)}",
                         wall_time_s=round(time.perf_counter() - t0, 3))


class _ResultReader:
    """Reads a job's result pipe to its end in a thread (a result larger than the pipe never blocks the job)."""

    def __init__(self, fd: int):
        self.fd, self.chunks, self.size = fd, [], 0
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        try:
            while chunk := os.read(self.fd, 1 << 16):
                self.size += len(chunk)
                if self.size <= MAX_RESULT_BYTES:
                    self.chunks.append(chunk)
        except OSError:
            pass
        finally:
            os.close(self.fd)

    def result(self) -> bytes:
        self.thread.join(timeout=10)  # the group is gone: every write end is closed
        return b"".join(self.chunks)


def _ok_result(base: dict, out: bytes, folder: Path, wall: float) -> JobResult:
    report = safe_io.load_json(out, f"{folder}: the job's result")
    if not isinstance(report, dict):
        raise BadInput(f"{folder}: the job's result is not a JSON object")
    files = [*report.get("programs", []), str(folder / "report.json"), str(folder / "points.csv"),
             *report.get("plots", [])]
    rel = sorted({str(Path(f).resolve().relative_to(folder.resolve())) for f in files})
    return JobResult(**base, status="ok", exit_code=0, wall_time_s=wall, points=report.get("points_total"),
                     cycle_time_s=report.get("cycle_time_s"), files=rel)


def _report_points(folder: Path) -> int | None:
    data = safe_io.read_own_json(folder / "report.json")
    return data.get("points_total") if isinstance(data, dict) else None
