"""Work done alongside: a function run in a forked child process while this process goes on.

The last stages of a run are independent of one another: the independent motion check
and the figures (PNG plots, the redundancy map) need only the timed trajectory, while
the programs are written, read back and simulated. ``Alongside(fn)`` forks, runs ``fn()`` in the child and hands its
result back by pickle through a pipe; ``result()`` waits for it, re-raising what the
child raised (``failure()`` returns it), and gives the same when asked again. Where the machine gives this process one CPU, or has no ``fork``,
``fn`` runs in this process when its result is asked for: the same files, the same
result, only later.

The child starts with the objects it inherits frozen (``gc.freeze`` before the fork, as CPython's
documentation advises for a process that forks): its cyclic collector then never writes to the pages
it shares, which would copy them (a tenth fewer page faults and about 0.3 s less CPU on the sample
run, measured). The parent unfreezes its own at once: a long-lived one (a hot folder) collects them.

Why by hand: threads would hold the GIL (matplotlib draws in Python), and the standard
pools pickle their inputs (a dense job's trajectory is hundreds of MB) where a fork
shares them copy-on-write; ``os.fork`` and ``pickle`` are all it takes. A child never
outlives the run: ``cancel()`` (and leaving a ``with`` block by an exception) kills it
and reaps it, and it is in the run's process group, which a batch kills on timeout.

``Standby(prepare)`` forks early, while this process still works on one CPU (planning):
the child runs ``prepare()`` (heavy imports: open3d, matplotlib) at once, then waits.
``start(fn)`` hands it ``fn`` by pickle (a module-level function, or a ``functools.partial``
of one, and its inputs), ``then(fn)`` a further task, and ``result()`` is the last task's
value, as with ``Alongside``. What a
child imports ahead this way is off the busy end of the run, and the imports never enter
this process (a dense job's peak memory).
"""
from __future__ import annotations

import gc
import os
import pickle
import signal
import struct
import sys
import time
from abc import ABC, abstractmethod
from functools import partial
from typing import Any, Callable


PR_SET_PDEATHSIG = 1   # linux/prctl.h


def _load_prctl():
    """libc's prctl, looked up once in the parent (a child between fork and exec only calls it)."""
    try:
        import ctypes

        return ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None


_PRCTL = _load_prctl() if sys.platform.startswith("linux") else None


def die_with_parent() -> None:
    """In a child process: SIGKILL when the thread that forked it dies, even by SIGKILL (``PR_SET_PDEATHSIG``),
    so no child camtool started outlives it (a batch's job, a helper computing alongside a run)."""
    if _PRCTL is not None:
        _PRCTL(PR_SET_PDEATHSIG, signal.SIGKILL)

_OK, _RAISED = "ok", "raised"


def cpus_available() -> int:
    """CPUs this process may run on (its affinity), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def timed(fn: Callable[[], Any]) -> tuple[Any, tuple[float, float]]:
    """(``fn()``, (wall s, CPU s of this process)): what work done alongside took where it ran."""
    wall, cpu = time.perf_counter(), time.process_time()
    value = fn()
    return value, (round(time.perf_counter() - wall, 3), round(time.process_time() - cpu, 3))


def _outcome(fn: Callable[[], Any]) -> tuple:
    """(``_OK``, ``fn()``) or (``_RAISED``, what it raised)."""
    try:
        return _OK, fn()
    except Exception as exc:   # handed on: raised where the result is asked for
        return _RAISED, exc


def _reraise(exc: BaseException):
    """Raise ``exc`` (what ``prepare`` raised, handed on as ``fn``'s outcome)."""
    raise exc


def _payload(fn: Callable[[], Any]) -> bytes:
    """``fn()``'s result, or what it raised, pickled (an exception that does not pickle as its message)."""
    try:
        return pickle.dumps((_OK, fn()), protocol=pickle.HIGHEST_PROTOCOL)
    except BaseException as exc:  # handed to the parent, which re-raises it where it asks for the result
        try:
            return pickle.dumps((_RAISED, exc), protocol=pickle.HIGHEST_PROTOCOL)
        except Exception:
            return pickle.dumps((_RAISED, RuntimeError(f"{type(exc).__name__}: {exc}")))


class _Child(ABC):
    """What ``Alongside`` and ``Standby`` share: the result taken from the child, its failure, cancelling it."""

    forked: bool

    def __init__(self, forked: bool | None):
        self._pid, self._fd, self._done = None, None, False
        self._outcome = None   # (kind, value) once taken
        self.forked = (hasattr(os, "fork") and cpus_available() > 1) if forked is None else forked

    def _fork(self, child: Callable[[int], None]) -> None:
        """Fork; the child runs ``child(fd to write the result to)`` and leaves without the parent's exit handlers."""
        read_fd, write_fd = os.pipe()
        sys.stdout.flush()
        sys.stderr.flush()  # nothing buffered is written twice
        gc.freeze()   # what exists now is shared with the child: its collector leaves it alone
        parent = os.getpid()
        pid = os.fork()
        if pid == 0:
            os.close(read_fd)
            code = 0
            try:
                die_with_parent()             # a parent that ends early (an error, a signal) takes the child along
                if os.getppid() != parent:    # ... also one that ended before the line above
                    os._exit(1)
                signal.signal(signal.SIGINT, signal.SIG_DFL)   # Ctrl-C stops the child at once
                child(write_fd)
            except BaseException:
                code = 1
            finally:
                os._exit(code)
        gc.unfreeze()   # here the collector goes on as before: a long-lived process (a hot folder) collects it
        os.close(write_fd)
        self._pid, self._fd = pid, read_fd

    @abstractmethod
    def _inline(self) -> tuple:
        """The outcome, (kind, value), computed in this process (unforked)."""

    def result(self) -> Any:
        """The child's result (it is waited for), or what it raised, raised here; asked again, the same."""
        if self._outcome is None:
            self._outcome = self._take()
        kind, value = self._outcome
        if kind == _RAISED:
            raise value
        return value

    def failure(self) -> BaseException | None:
        """What ``fn`` raised (the child waited for), or None when it returned."""
        try:
            self.result()
        except Exception as exc:  # handed to the caller, who decides which error is the run's (Ctrl-C is not)
            return exc
        return None

    def _take(self) -> tuple:
        if self._done:
            raise RuntimeError(f"{type(self).__name__} was cancelled: it has no result")
        self._done = True
        if not self.forked:
            return self._inline()
        fd, self._fd = self._fd, None
        with os.fdopen(fd, "rb") as pipe:
            data = pipe.read()
        _, status = os.waitpid(self._pid, 0)
        self._pid = None
        if not data:
            code = os.waitstatus_to_exitcode(status)
            how = f"signal {-code}" if code < 0 else f"exit code {code}"
            raise RuntimeError(f"the process working alongside the run ended without a result ({how})")
        return pickle.loads(data)

    def cancel(self) -> None:
        """Kill and reap the child if it still runs; its result is then never taken."""
        self._done = True
        if self._pid is not None:
            try:
                os.kill(self._pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            os.waitpid(self._pid, 0)
            self._pid = None
        if self._fd is not None:
            try:
                os.close(self._fd)
            except OSError:
                pass
            self._fd = None

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is not None or not self._done:
            self.cancel()


class Alongside(_Child):
    """``fn()`` in a forked child while the caller goes on; ``result()`` is its return value.

    ``forked`` says whether a child runs it (False: it runs in this process, at
    ``result()``). Use as a context manager so that an error in the caller's own
    work cancels the child.
    """

    def __init__(self, fn: Callable[[], Any], forked: bool | None = None):
        super().__init__(forked)
        self._fn = fn
        if self.forked:
            self._fork(self._run)

    def _run(self, write_fd: int) -> None:
        data = _payload(self._fn)
        with os.fdopen(write_fd, "wb") as pipe:
            pipe.write(data)

    def _inline(self) -> tuple:
        return _outcome(self._fn)


class Standby(_Child):
    """A child forked now that runs ``prepare()`` at once, then the tasks handed to it, in order.

    ``start(fn)`` hands the first task, ``then(fn)`` each further one (by pickle, so a
    module-level function or a ``functools.partial`` of one); ``result()`` is the last
    task's value. With ``hand_on``, each task is given the value before it: ``prepare()``'s
    for the first (work done ahead on data the run already has: the motion check's part),
    the previous task's after that (the redundancy map's sweep of the raster, drawn once
    the plan is known). A task handed over while the child still works on one is read by
    a thread of the child as it comes, so this process never waits on a full pipe.
    Unforked (one CPU), ``prepare()`` and the tasks run in this process at ``result()``.
    A context manager as ``Alongside``: leaving the block by an error, or without starting
    it, kills the waiting child.
    """

    def __init__(self, prepare: Callable[[], Any], forked: bool | None = None, hand_on: bool = False,
                 nice: int = 0):
        super().__init__(forked)
        self._prepare, self._tasks, self._hand_on, self._nice = prepare, [], hand_on, nice
        self._task_pipe = None   # this process's end of the pipe that hands the tasks over
        if self.forked:
            task_read, task_write = os.pipe()
            _widen(task_write)
            self._fork(lambda write_fd: self._wait_and_run(task_read, task_write, write_fd))
            os.close(task_read)
            self._task_pipe = os.fdopen(task_write, "wb")

    def _wait_and_run(self, task_read: int, task_write: int, write_fd: int) -> None:
        os.close(task_write)
        if self._nice:
            os.nice(self._nice)
        handed = _HandedTasks(task_read)   # read from now on: a task handed while this prepares waits here
        value = _outcome(self._prepare)
        ran = False
        for task in handed:
            ran = True
            if value[0] != _OK:   # after a failure the tasks are read and not run: the failure is the result
                continue
            fn = _outcome(partial(pickle.loads, task))
            value = fn if fn[0] != _OK else _outcome(self._task(fn[1], value))
        if not ran:  # never started: the run went another way
            return
        data = _payload(lambda: _reraise(value[1]) if value[0] == _RAISED else value[1])
        with os.fdopen(write_fd, "wb") as out:
            out.write(data)

    def start(self, fn: Callable[[], Any]) -> "Standby":
        """Hand the first task to the child (pickled through a pipe)."""
        if self._tasks:
            raise RuntimeError("Standby was started already: hand further tasks with then()")
        return self._hand(fn)

    def then(self, fn: Callable[..., Any]) -> "Standby":
        """Hand a further task, run once the ones before it are done; ``result()`` is then its value."""
        if not self._tasks:
            raise RuntimeError("Standby was not started: hand the first task with start()")
        return self._hand(fn)

    def _hand(self, fn: Callable) -> "Standby":
        if self._done:
            raise RuntimeError("Standby was cancelled: it takes no work")
        self._tasks.append(fn)
        if self.forked and self._task_pipe is not None:
            try:
                _write_frame(self._task_pipe, pickle.dumps(fn, protocol=pickle.HIGHEST_PROTOCOL))
            except BrokenPipeError:
                self._close_tasks(tell=False)   # the child is gone: result() says how
        return self

    def _close_tasks(self, tell: bool = True) -> None:
        """No more tasks: the child hands its result back once the last is done. It is told so in so
        many words (an empty frame): the end of the pipe alone would not do, as a child forked later
        holds a copy of this end."""
        if self._task_pipe is not None:
            pipe, self._task_pipe = self._task_pipe, None
            try:
                if tell:
                    _write_frame(pipe, b"")
                pipe.close()
            except BrokenPipeError:
                pass

    def _take(self) -> tuple:
        if not self._tasks and not self._done:
            raise RuntimeError("Standby was not started: it has no result")
        self._close_tasks()
        return super()._take()

    def _task(self, fn: Callable, before: tuple) -> Callable[[], Any]:
        """What runs once ``fn`` is handed over: ``fn()``, or ``fn(the value before it)`` with ``hand_on``."""
        return partial(fn, before[1]) if self._hand_on else fn

    def _inline(self) -> tuple:
        value = _outcome(self._prepare)
        for fn in self._tasks:
            if value[0] != _OK:
                break
            value = _outcome(self._task(fn, value))
        return value

    def cancel(self) -> None:
        self._close_tasks(tell=False)
        super().cancel()


_FRAME = struct.Struct("<Q")   # a task's length in bytes, before its pickle; 0: no more tasks
PIPE_BYTES = 1 << 20           # a task pipe's capacity where the system allows it (Linux: F_SETPIPE_SZ)


def _widen(fd: int) -> None:
    """Give the task pipe ``PIPE_BYTES`` of room where the system allows: the child's reader thread then
    takes a large task (a plan, a trajectory: megabytes) in a few reads instead of 64 kB ones, and each
    read waits for the interpreter lock that the child's busy main thread holds."""
    import fcntl

    try:
        fcntl.fcntl(fd, getattr(fcntl, "F_SETPIPE_SZ", 1031), PIPE_BYTES)
    except OSError:   # more than this system gives a pipe: its default stands
        pass


def _write_frame(pipe, data: bytes) -> None:
    pipe.write(_FRAME.pack(len(data)))
    pipe.write(data)
    pipe.flush()


def _read_exactly(pipe, size: int) -> bytes:
    """``size`` bytes of ``pipe`` (a buffered reader), taken in as few reads as the pipe allows."""
    chunks, left = [], size
    while left:
        chunk = pipe.read1(min(left, PIPE_BYTES))
        if not chunk:
            break
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


class _HandedTasks:
    """The tasks handed to a ``Standby`` child, in order, as pickled bytes: a thread reads each frame from the
    pipe as it comes, from the child's start (the parent's write never waits on the child's work, its
    ``prepare`` included), until an empty frame (or the pipe's end). The child unpickles them itself, one
    by one: a thread reading bytes imports nothing while ``prepare`` imports."""

    _END = object()

    def __init__(self, fd: int):
        import queue
        import threading

        self._queue = queue.SimpleQueue()
        threading.Thread(target=self._read, args=(fd,), daemon=True).start()

    def _read(self, fd: int) -> None:
        try:
            with os.fdopen(fd, "rb") as pipe:
                while True:
                    head = pipe.read(_FRAME.size)
                    if len(head) < _FRAME.size:
                        break    # the parent's end closed
                    (size,) = _FRAME.unpack(head)
                    if not size:
                        break    # no more tasks
                    self._queue.put(_read_exactly(pipe, size))
        finally:
            self._queue.put(self._END)

    def __iter__(self):
        """Each task's pickle as it comes, until there are no more (an incomplete one: the pipe closed)."""
        while (task := self._queue.get()) is not self._END:
            yield task
