"""Issue 49's acceptance, as the kernel sees it: a run creates, changes or removes no file outside its
real ``-o`` (``strace -f -y -e trace=%file,%desc``, every thread and child process included).

What a run may touch outside ``-o``, and why: ``/dev/null`` (a child's standard input), and camtool's own
``__pycache__`` folders, where Python keeps its bytecode and numba its compiled kernels (written once per
install, like any ``.pyc``; numba probes the folder with an unnamed ``O_TMPFILE``, which creates no file).
The output folder is held by its descriptor, so most writes name it as ``/proc/PID/fd/N/...``; those are
checked through the descriptor's own path (``-y`` prints it where the folder is opened)."""
from __future__ import annotations

import functools
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
STRACE = shutil.which("strace")

pytestmark = pytest.mark.skipif(STRACE is None, reason="strace is not installed")

WRITE_FLAGS = re.compile(r"O_WRONLY|O_RDWR|O_CREAT|O_TRUNC|O_APPEND")
MUTATING = ("mkdir", "mkdirat", "unlink", "unlinkat", "rename", "renameat", "renameat2", "rmdir", "symlink",
            "symlinkat", "link", "linkat", "chmod", "fchmodat", "chown", "fchownat", "lchown", "truncate",
            "utimensat", "utime", "utimes", "mknod", "mknodat")
CALL = re.compile(r"^(\d+)\s+(\w+)\((.*)$")
# an argument: a descriptor with its path (5</tmp/out>) or a quoted string
ARG = re.compile(r'(?:AT_FDCWD|-?\d+)<([^>]*)>|"((?:[^"\\]|\\.)*)"')


def _paths(call: str, rest: str) -> list[str]:
    """The paths a call names, each joined to the descriptor it is relative to (``*at`` calls)."""
    args = [(m.group(1), m.group(2)) for m in ARG.finditer(rest)]
    out, base = [], None
    for fd_path, text in args:
        if fd_path is not None:
            base = fd_path
        elif text is not None:
            out.append(text if text.startswith("/") or base is None else f"{base}/{text}")
            base = None
    if not out and base is not None:  # e.g. fchmodat(fd, "") / futimens: the descriptor itself
        out.append(base)
    return out


def _writes(trace: str) -> list[tuple[str, str]]:
    """(call, path) of every successful call that creates, changes or removes a file."""
    found = []
    for line in trace.splitlines():
        m = CALL.match(line)
        if m is None or re.search(r"= -1 E", line) or "<unfinished" in line:
            continue
        call, rest = m.group(2), m.group(3)
        if call in ("open", "openat", "openat2", "creat"):
            if call != "creat" and not WRITE_FLAGS.search(rest):
                continue
        elif call not in MUTATING:
            continue
        found += [(call, p) for p in _paths(call, rest)]
    return found


def _allowed(path: str, outdir: Path, out_fds: set[str]) -> bool:
    real_out = str(outdir.resolve())
    if path == "/dev/null" or path == real_out or path.startswith(real_out + "/"):
        return True
    m = re.match(r"/proc/(?:\d+|self)/fd/(\d+)(?:/|$)", path)
    if m:  # through a held descriptor: only the output folder's
        return m.group(1) in out_fds
    return "/__pycache__" in path and any(path.startswith(str(p) + "/") for p in _packages())


@functools.cache
def _packages() -> tuple[Path, ...]:
    """This checkout's camtool and the one a subprocess imports (an editable install may point elsewhere)."""
    out = subprocess.run([sys.executable, "-c", "import camtool; print(camtool.__file__)"], cwd="/",
                         capture_output=True, text=True, timeout=120).stdout.strip()
    return (ROOT / "camtool", *([Path(out).resolve().parent] if out else []))


def _output_fds(trace: str, outdir: Path) -> set[str]:
    """The descriptor numbers that -y printed as the output folder itself."""
    return set(re.findall(rf"\b(\d+)<{re.escape(str(outdir.resolve()))}>", trace))


def _traced_run(args: list[str], tmp_path: Path) -> tuple[str, Path]:
    """The strace of ``camtool ARGS`` run from ``tmp_path``, which must exit 0."""
    trace = tmp_path / "trace.txt"
    proc = subprocess.run([STRACE, "-f", "-y", "-qq", "-e", "trace=%file,%desc", "-o", str(trace),
                           sys.executable, "-m", "camtool.cli", *args],
                          cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    return trace.read_text(errors="replace"), tmp_path


def test_a_run_touches_no_file_outside_its_output_folder(tmp_path):
    outdir = tmp_path / "out"
    trace, _ = _traced_run(["run", str(ROOT / "samples" / "plate_hole.toml"), "-o", str(outdir)], tmp_path)
    writes = _writes(trace)
    assert any("PLATE" in p for _, p in writes), "the trace saw no program written"
    out_fds = _output_fds(trace, outdir)
    outside = [(c, p) for c, p in writes if not _allowed(p, outdir, out_fds)]
    assert not outside, outside[:10]


def test_a_step_part_is_read_without_a_file_made_anywhere(tmp_path):
    """OpenCASCADE reads a memory copy of the checked STEP and no temporary file is made (``camtool faces`` has no output folder: nothing may be written at all)."""
    trace, _ = _traced_run(["faces", str(ROOT / "samples" / "pipe_half_step.toml")], tmp_path)
    assert re.search(r"memfd:camtool-input", trace), "the STEP was not read from a memory copy"
    assert not [(c, p) for c, p in _writes(trace) if not _allowed(p, tmp_path / "none", set())]


def test_the_checker_sees_a_write_outside(tmp_path):
    """The parser is no test that cannot fail: a write beside -o is found."""
    trace = (f'1 openat(AT_FDCWD</x>, "{tmp_path}/elsewhere.txt", O_WRONLY|O_CREAT|O_TRUNC, 0644) = 3</y>\n'
             f'1 renameat(3</a>, "b", 4<{tmp_path}/out>, "c") = 0\n'
             f'1 unlinkat(5<{tmp_path}>, "victim", 0) = 0\n'
             f'1 openat(AT_FDCWD</x>, "/proc/1/fd/7/planted", O_WRONLY|O_CREAT, 0644) = 3</y>\n'
             f'1 openat(AT_FDCWD</x>, "/proc/1/fd/4/fine", O_WRONLY|O_CREAT, 0644) = 3</y>\n'
             f'1 openat(AT_FDCWD</x>, "{tmp_path}/read.txt", O_RDONLY) = 3</y>\n')
    writes = _writes(trace)
    outside = [p for _, p in writes if not _allowed(p, tmp_path / "out", {"4"})]
    assert outside == [f"{tmp_path}/elsewhere.txt", "/a/b", f"{tmp_path}/victim", "/proc/1/fd/7/planted"]
