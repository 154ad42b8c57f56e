"""Safe file access for a shared cell: inputs opened once and checked once; outputs that no planted
symlink, special file or manifest can turn against the machine. See docs/security.md.

Inputs (``read_input_bytes``, ``read_input_text``): opened with ``O_NONBLOCK`` (a FIFO never blocks the
open), checked with ``fstat`` on that same descriptor (regular files only: no FIFO, device or socket)
and read up to a size cap per kind (``INPUT_CAPS_MB``, overridable with ``CAMTOOL_MAX_<KIND>_MB``).

Outputs: every path camtool creates, replaces or removes is reached from the output folder's own
descriptor, one component at a time, with ``O_NOFOLLOW``: a symlink or special file anywhere under
``-o`` is refused with one line, never followed. New files are created with ``O_EXCL | O_NOFOLLOW``
inside a private ``mkdtemp`` folder and renamed into place (one file system, atomic). Names come
from camtool or from its own manifests and are checked to stay inside ``-o`` (no ``..``, no
absolute path). ``locked`` serialises camtool processes writing into one folder with ``fcntl.flock``.

The standard library and the OS give every primitive; this module only composes them (no library
does this composition for a whole output tree).
"""
from __future__ import annotations

import errno
import fcntl
import json
import os
import stat
import tempfile
import threading
from contextlib import contextmanager
from pathlib import Path

from .errors import BadInput

# size caps per input kind, in MB (CAMTOOL_MAX_<KIND>_MB overrides one)
INPUT_CAPS_MB = {"job": 4, "profile": 4, "robot": 64, "workpiece": 2048, "program": 256, "stage": 2048,
                 "manifest": 16, "text": 64}
LOCK_NAME = ".camtool-lock"
MANIFESTS = (".camtool-manifest.json", ".camtool-programs.json", ".camtool-cache.json")
# files camtool places at fixed names: an existing one in a folder camtool has never written into is foreign
OWN_NAMES = ("report.json", "report.html", "points.csv", "summary.json", "plots")
MAX_SCAN_ENTRIES = 200_000
DISK_ERRNOS = {errno.ENOSPC: "the disk is full", errno.EDQUOT: "the disk quota is exceeded",
               errno.EACCES: "permission denied", errno.EPERM: "permission denied",
               errno.EROFS: "the file system is read-only"}
_DIR_FLAGS = os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC
# resolving -o: O_PATH where there is one, so a folder one may pass through but not list (0711) is walked too
_WALK_FLAGS = getattr(os, "O_PATH", os.O_RDONLY) | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC


# ---------------------------------------------------------------- inputs

def size_cap_bytes(kind: str) -> int:
    """The size cap of an input kind in bytes (CAMTOOL_MAX_<KIND>_MB overrides the default)."""
    env = f"CAMTOOL_MAX_{kind.upper()}_MB"
    raw = os.environ.get(env)
    mb = INPUT_CAPS_MB.get(kind, INPUT_CAPS_MB["text"])
    if raw:
        try:
            mb = float(raw)
        except ValueError:
            raise BadInput(f"{env}={snippet(raw)}: expected a size in MB") from None
        if not (0 < mb < 1 << 30):
            raise BadInput(f"{env}={snippet(raw)}: expected a size in MB above 0")
    return int(mb * 1024 * 1024)


def _what(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISLNK(mode):
        return "a symlink"
    return "not a regular file"


_HELD = threading.local()  # abspath -> (fd, stat) of inputs held open by ``held_input`` in this thread


def _held() -> dict:
    return _HELD.__dict__.setdefault("fds", {})


@contextmanager
def held_input(path, kind: str):
    """Open and check ``path`` once and hold that descriptor for the block: every ``read_input_bytes``,
    ``check_input``, ``opened_input`` and ``private_copy`` of the same path inside the block uses it
    (a duplicate read with ``pread``), never the name again. A file swapped or renamed after the first
    check is never seen. Yields the stat of the checked file."""
    key = os.path.abspath(path)
    held = _held()
    if key in held:
        yield held[key][1]
        return
    fd, st = _open_input(Path(path), kind)
    held[key] = (fd, st)
    try:
        yield st
    finally:
        del held[key]
        os.close(fd)


def _open_input(path: Path, kind: str, follow: bool = True) -> tuple[int, os.stat_result]:
    held = _held().get(os.path.abspath(path))
    if held is not None:
        return os.dup(held[0]), held[1]
    flags = os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY | os.O_CLOEXEC | (0 if follow else os.O_NOFOLLOW)
    try:
        fd = os.open(at(path), flags)
    except FileNotFoundError:
        raise BadInput(f"{path}: {kind} file not found") from None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise BadInput(f"{path}: is a symlink; camtool does not follow links in its output folder") from None
        raise BadInput(f"{path}: cannot read the {kind} file ({exc.strerror or exc})") from None
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode):
        os.close(fd)
        raise BadInput(f"{path}: is {_what(st.st_mode)}, not a regular file; give the {kind} as a file")
    cap = size_cap_bytes(kind)
    if st.st_size > cap:
        os.close(fd)
        raise BadInput(f"{path}: {st.st_size / 2**20:.1f} MB is over the {cap / 2**20:g} MB cap for a {kind} file "
                       f"(CAMTOOL_MAX_{kind.upper()}_MB raises it)")
    return fd, st


def check_input(path, kind: str) -> os.stat_result:
    """The stat of ``path`` after the checks of ``read_input_bytes`` (regular file, size cap), without reading."""
    fd, st = _open_input(Path(path), kind)
    os.close(fd)
    return st


def read_input_bytes(path, kind: str, follow: bool = True) -> bytes:
    """The bytes of a regular input file of ``kind`` (job, profile, robot, workpiece, program, ...).

    BadInput (one line) for a missing file, a folder, a FIFO, a device or a socket, a file over the cap
    of its kind, or one that grows past it while read. Never blocks on a special file.
    """
    path = Path(path)
    fd, _st = _open_input(path, kind, follow)
    cap = size_cap_bytes(kind)
    try:
        chunks, total = [], 0
        while True:
            chunk = os.pread(fd, 1 << 20, total)  # by offset: a held descriptor is shared, its position is not used
            if not chunk:
                break
            total += len(chunk)
            if total > cap:
                raise BadInput(f"{path}: grew past the {cap / 2**20:g} MB cap for a {kind} file while read")
            chunks.append(chunk)
    except OSError as exc:
        raise BadInput(f"{path}: cannot read the {kind} file ({exc.strerror or exc})") from None
    finally:
        os.close(fd)
    return b"".join(chunks)


def read_input_text(path, kind: str, errors: str = "strict") -> str:
    """``read_input_bytes`` decoded as UTF-8; BadInput when it is not UTF-8 (with ``errors="strict"``)."""
    data = read_input_bytes(path, kind)
    try:
        return data.decode("utf-8", errors=errors)
    except UnicodeDecodeError as exc:
        raise BadInput(f"{path}: cannot read the {kind} file: not UTF-8 text (byte {exc.start})") from None


def snippet(text, limit: int = 60) -> str:
    """A bounded, escaped quote of user text for an error line: repr-escaped, at most ``limit`` characters."""
    text = str(text)
    short = text[:limit]
    more = f"... ({len(text) - limit} more characters)" if len(text) > limit else ""
    return repr(short) + more


# ---------------------------------------------------------------- the output folder

# output folders held by their descriptor for a run: display path (absolute, as given) -> fd
_OUTDIRS: dict[str, int] = {}
_OUTDIRS_LOCK = threading.Lock()
_PROC_FD = os.path.isdir(f"/proc/{os.getpid()}/fd")


def _fd_path(fd: int, rel: str = "") -> str:
    """A name that reaches ``rel`` under the folder open as ``fd`` (``/proc/<pid>/fd/<fd>``; a forked helper
    of this process reaches it too), whatever has been renamed, swapped or linked at its old path since."""
    base = f"/proc/{os.getpid()}/fd/{fd}"
    return f"{base}/{rel}" if rel else f"{base}/."


def at(path) -> str:
    """The name to hand the OS for ``path``: below an output folder this process holds (``held_outdir``),
    a name relative to that folder's descriptor; anything else unchanged. Every primitive of this module
    goes through it, so a held ``-o`` swapped for a symlink or renamed mid-run is never written elsewhere."""
    raw = os.fspath(path)
    if not _OUTDIRS or raw.startswith("/proc/"):
        return raw
    p = os.path.abspath(raw)
    for root, fd in _OUTDIRS.items():
        if p == root:
            return _fd_path(fd)
        if p.startswith(root + "/"):
            return _fd_path(fd, p[len(root) + 1:])
    return raw


def shown(path) -> str:
    """A path as the user knows it: a held folder's ``/proc/<pid>/fd/<fd>`` name turned back into ``-o``'s."""
    text = os.fspath(path)
    for root, fd in _OUTDIRS.items():
        base = f"/proc/{os.getpid()}/fd/{fd}"
        text = text.replace(base + "/.", root).replace(base, root)
    return text


def resolve_outdir(outdir, create: bool = True) -> int:
    """The output folder opened once, component by component from ``/`` with ``O_NOFOLLOW``: a symlink in
    any component (``link/../out``, ``A/x/../../home`` with ``A/x`` a link) is refused, never followed, so
    ``..`` only ever climbs the folder it names; missing folders are made (``mkdirat``) when ``create``.
    Returns a descriptor of the folder (the caller closes it)."""
    raw = os.fspath(outdir)
    if "\0" in raw:
        raise BadInput(f"{snippet(raw)}: a NUL byte in the output folder's name")
    full = raw if os.path.isabs(raw) else os.path.join(os.getcwd(), raw)
    names = [name for name in full.split("/") if name not in ("", ".")]

    def refuse(i: int, exc: OSError, fd: int) -> None:
        walked = "/" + "/".join(names[:i + 1])
        if isinstance(exc, FileNotFoundError):
            raise BadInput(f"{raw}: {walked} does not exist") from None
        if exc.errno not in (errno.ELOOP, errno.ENOTDIR):
            raise BadInput(f"{raw}: cannot open the output folder ({exc.strerror or exc})") from None
        if stat.S_ISLNK(os.lstat(names[i], dir_fd=fd).st_mode):
            raise BadInput(f"{raw}: {walked} is a symlink; camtool resolves -o without following links "
                           "(give the folder's real path)") from None
        raise BadInput(f"{raw}: {walked} exists and is not a folder; give an output folder") from None

    return _walk(os.open("/", _WALK_FLAGS), names, _WALK_FLAGS, create, refuse)


def _walk(fd: int, names: list[str], flags: int, create: bool, refuse) -> int:
    """The one folder walker (``-o`` and the folders below it): from the folder open as ``fd`` down ``names``,
    one component at a time opened with ``flags`` (``O_NOFOLLOW``: a link is never followed); a missing one
    is made first (``mkdirat``) when ``create`` (never ``..``). A component that cannot be opened (missing
    and not made, a link, a file, ...) goes to ``refuse(i, exc, fd)`` (``fd``: the folder holding it), which
    raises or returns to have the OSError raised as it is. Returns the last folder's descriptor; ``fd`` is
    closed (the caller closes the one returned)."""
    try:
        for i, name in enumerate(names):
            try:
                nfd = os.open(name, flags, dir_fd=fd)
            except FileNotFoundError as exc:
                if not create or name == "..":
                    refuse(i, exc, fd)
                    raise
                try:
                    os.mkdir(name, 0o755, dir_fd=fd)
                except FileExistsError:
                    pass
                nfd = os.open(name, flags, dir_fd=fd)
            except OSError as exc:
                refuse(i, exc, fd)
                raise
            os.close(fd)
            fd = nfd
    except BaseException:
        os.close(fd)
        raise
    return fd


@contextmanager
def held_outdir(outdir, create: bool = True, check: bool = False):
    """Hold ``outdir`` by its descriptor for the block (``resolve_outdir``): every path below it that this
    module (and whatever writes into a staging folder made here) opens goes through ``at``, relative to
    that descriptor, from the first check to the last rename. Nested holds of the same folder share it."""
    key = os.path.abspath(os.fspath(outdir))
    if key in _OUTDIRS:
        if check:
            check_outdir(outdir)
        yield Path(key)
        return
    try:
        fd = resolve_outdir(outdir, create)
    except OSError as exc:
        err = disk_error(exc)
        raise (err or BadInput(f"{outdir}: cannot open the output folder ({exc.strerror or exc})")) from None
    with _OUTDIRS_LOCK:
        if _PROC_FD:  # elsewhere (no /proc/<pid>/fd) the folder is checked by name: docs/security.md
            _OUTDIRS[key] = fd
    try:
        if check:  # the folder held is the folder checked (check_outdir, through the descriptor)
            check_outdir(outdir)
        yield Path(key)
    finally:
        with _OUTDIRS_LOCK:
            _OUTDIRS.pop(key, None)
        os.close(fd)


def _refuse_special(path: Path, mode: int) -> None:
    raise BadInput(f"{path}: is {_what(mode)} inside the output folder; camtool never follows links or writes "
                   "through special files it did not make: remove it or choose another -o")


def check_outdir(outdir) -> Path:
    """Refuse an output folder camtool must not write into; returns it (absolute, not resolved).

    Refused: ``/``, the home folder, a path that is a symlink or not a folder, a folder holding a symlink
    or a special file anywhere below it, and a folder holding foreign files: one of camtool's fixed
    output names (``OWN_NAMES``) that no camtool manifest or lock file vouches for.
    """
    out = Path(os.path.abspath(outdir))
    held = _OUTDIRS.get(str(out))
    real = Path(os.readlink(f"/proc/self/fd/{held}") if held is not None else os.path.realpath(out))
    homes = {Path(os.path.realpath(Path.home()))} if Path.home() != Path("/") else set()
    if real == Path("/") or real in homes:
        raise BadInput(f"{outdir}: refusing to write into {'the root folder' if real == Path('/') else 'the home folder'}; "
                       "give camtool an output folder of its own")
    try:
        st = os.lstat(at(out))
    except FileNotFoundError:
        return out
    if stat.S_ISLNK(st.st_mode):
        raise BadInput(f"{outdir}: is a symlink; give the output folder itself")
    if not stat.S_ISDIR(st.st_mode):
        raise BadInput(f"{outdir}: exists and is not a folder; give an output folder")
    seen = 0
    for root, dirs, files in os.walk(at(out), followlinks=False):
        for name in dirs + files:
            seen += 1
            p = Path(root) / name
            try:
                mode = os.lstat(p).st_mode
                p = Path(shown(p))
            except FileNotFoundError:
                continue
            if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
                _refuse_special(p, mode)
        if seen > MAX_SCAN_ENTRIES:
            raise BadInput(f"{outdir}: holds more than {MAX_SCAN_ENTRIES} entries; give camtool an output folder of its own")
    names = set(os.listdir(at(out)))
    if names & set(OWN_NAMES) and not names & {LOCK_NAME, *MANIFESTS} and not _camtool_summary(out / "summary.json"):
        foreign = sorted(names & set(OWN_NAMES))
        raise BadInput(f"{outdir}: holds {', '.join(foreign)} that camtool did not write (no camtool manifest "
                       "there); give camtool an output folder of its own")
    return out


def read_own_json(file) -> object | None:
    """One of camtool's own JSON files in an output folder (a manifest, summary.json, report.json): read once
    without following a link, through ``load_json`` (depth bounded); None when it is absent, refused, not
    JSON or nested too deep: a planted file is never trusted and never an internal error."""
    try:
        return load_json(read_input_bytes(file, "manifest", follow=False), file)
    except (BadInput, ValueError, RecursionError):
        return None


def _camtool_summary(file: Path) -> bool:
    data = read_own_json(file)
    return isinstance(data, dict) and "camtool" in data and "jobs" in data


@contextmanager
def locked(outdir):
    """Hold the output folder's lock (``OUTDIR/.camtool-lock``, fcntl) for the block.

    A second camtool process writing into the same folder is refused with one line (exit 2) instead
    of mixing its files with the first one's. The lock file stays (it marks the folder as camtool's).
    """
    out = Path(outdir)
    try:
        if os.path.abspath(out) not in _OUTDIRS:
            out.mkdir(parents=True, exist_ok=True)
        fd = os.open(at(out / LOCK_NAME), os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC, 0o644)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            _refuse_special(out / LOCK_NAME, stat.S_IFLNK)
        raise BadInput(f"{outdir}: cannot write into the output folder ({exc.strerror or exc})") from None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            _refuse_special(out / LOCK_NAME, os.fstat(fd).st_mode)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise BadInput(f"{outdir}: another camtool process is writing into this output folder; wait for it "
                           "to finish or choose another -o") from None
        yield out
    finally:
        os.close(fd)  # closing releases the lock


@contextmanager
def writing_into(outdir):
    """The rules of ``camtool run``'s output folder for any command that writes into ``-o`` (run, post, batch,
    watch, fit, raster, plan, time): held by its descriptor (``held_outdir``), checked through it
    (``check_outdir``) and locked (``locked``) for the block. ``None`` (no -o): nothing."""
    if outdir is None:
        yield None
        return
    with held_outdir(outdir, check=True), locked(outdir):
        yield Path(os.path.abspath(outdir))


def _parts(rel) -> list[str]:
    """The components of a path relative to the output folder; BadInput when it could leave it."""
    text = str(rel)
    parts = text.split("/")
    if not text or text.startswith("/") or "\0" in text or any(p in ("", ".", "..") for p in parts):
        raise BadInput(f"{snippet(text)}: not a file name inside the output folder")
    return parts


def _open_dir(outdir, parts: list[str], create: bool) -> int:
    """A descriptor of ``outdir/parts...``, walked with O_NOFOLLOW (created with ``create``)."""
    def refuse(i: int, exc: OSError, fd: int) -> None:
        if exc.errno in (errno.ELOOP, errno.ENOTDIR):
            mode = os.lstat(parts[i], dir_fd=fd).st_mode
            if stat.S_ISREG(mode):
                raise BadInput(f"{Path(outdir, *parts[:i + 1])}: is a file where camtool needs a folder; "
                               "remove or rename it") from None
            _refuse_special(Path(outdir, *parts[:i + 1]), mode)

    return _walk(os.open(at(outdir), _DIR_FLAGS), parts, _DIR_FLAGS, create, refuse)


def _target_mode(dfd: int, name: str) -> int | None:
    try:
        return os.lstat(name, dir_fd=dfd).st_mode
    except FileNotFoundError:
        return None


def check_target(outdir, rel) -> None:
    """BadInput when ``outdir/rel`` could not be replaced by a file: a folder, symlink or special file on the way."""
    parts = _parts(rel)
    try:
        dfd = _open_dir(outdir, parts[:-1], create=False)
    except FileNotFoundError:
        return
    try:
        mode = _target_mode(dfd, parts[-1])
    finally:
        os.close(dfd)
    if mode is not None and stat.S_ISDIR(mode):
        raise BadInput(f"{Path(outdir, rel)}: is a folder where camtool places a file; remove or rename it")
    if mode is not None and not stat.S_ISREG(mode):
        _refuse_special(Path(outdir, rel), mode)


def place_file(src, outdir, rel) -> Path:
    """Rename ``src`` (a file camtool wrote, on the same file system) to ``outdir/rel``; returns the target.

    Folders on the way are created; a symlink or special file on the way or at the target, or a folder
    at the target, is refused (BadInput), never followed or replaced.
    """
    parts = _parts(rel)
    check_target(outdir, rel)
    dfd = _open_dir(outdir, parts[:-1], create=True)
    try:
        os.rename(at(src), parts[-1], dst_dir_fd=dfd)
    finally:
        os.close(dfd)
    return Path(outdir, rel)


def remove_file(outdir, rel) -> bool:
    """Remove the regular file ``outdir/rel``; True when removed. A name that would leave the folder,
    or a symlink, folder or special file there, is left alone (False): only camtool's own files go."""
    try:
        parts = _parts(rel)
        dfd = _open_dir(outdir, parts[:-1], create=False)
    except (BadInput, OSError):
        return False
    try:
        mode = _target_mode(dfd, parts[-1])
        if mode is None or not stat.S_ISREG(mode):
            return False
        os.unlink(parts[-1], dir_fd=dfd)
        return True
    except OSError:
        return False
    finally:
        os.close(dfd)


def make_folder(outdir, rel) -> Path:
    """``outdir/rel`` created folder by folder with O_NOFOLLOW (a symlink on the way is refused);
    ``outdir`` itself (the user's -o) is created when missing."""
    if os.path.abspath(outdir) not in _OUTDIRS:
        Path(at(outdir)).mkdir(parents=True, exist_ok=True)
    os.close(_open_dir(outdir, _parts(rel), create=True))
    return Path(outdir, rel)


def write_file(folder, name: str, data: bytes | str, mode: int = 0o644) -> Path:
    """Write ``folder/name`` atomically: created with O_EXCL|O_NOFOLLOW in a private mkdtemp folder
    inside ``folder``, then renamed into place (``place_file``). Never half-written, never through a link."""
    folder = Path(folder)
    check_target(folder, name)
    tmpdir = tempfile.mkdtemp(prefix=".camtool-write-", dir=at(folder))
    try:
        tmp = os.path.join(tmpdir, "file")
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, mode)
        with os.fdopen(fd, "wb") as f:
            f.write(data.encode("utf-8") if isinstance(data, str) else data)
        os.chmod(tmp, mode)
        return place_file(tmp, folder, name)
    finally:
        try:
            os.unlink(os.path.join(tmpdir, "file"))
        except FileNotFoundError:
            pass
        os.rmdir(tmpdir)


def new_file(folder, name: str, append: bool = False):
    """A binary file object for ``folder/name`` (e.g. a log written while a job runs).

    The old file, if any, is removed (only a regular file; a symlink or special file there is refused)
    and a new one is created with O_EXCL|O_NOFOLLOW; with ``append`` an existing regular file is opened
    for appending (O_NOFOLLOW, and checked regular with fstat) instead.
    """
    folder = Path(folder)
    check_target(folder, name)
    dfd = os.open(at(folder), _DIR_FLAGS)
    try:
        if append:
            fd = os.open(name, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC,
                         0o644, dir_fd=dfd)
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                os.close(fd)
                _refuse_special(folder / name, os.fstat(fd).st_mode)
        else:
            try:
                os.unlink(name, dir_fd=dfd)
            except FileNotFoundError:
                pass
            fd = os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644,
                         dir_fd=dfd)
    finally:
        os.close(dfd)
    return os.fdopen(fd, "ab" if append else "wb")


PATH_ERRNOS = {errno.ENAMETOOLONG: "a name in the path is too long (at most 255 bytes a name, 4096 a path)",
               errno.ELOOP: "too many levels of symbolic links", errno.ENOTDIR: "a part of the path is not a folder"}


def disk_error(exc: OSError) -> BadInput | None:
    """The one-line BadInput for an OS error the user can fix (full disk, quota, permission, read-only, a
    name too long), else None."""
    if exc.errno in PATH_ERRNOS:
        where = snippet(exc.filename, 200) if exc.filename else "a path"
        return BadInput(f"{where}: {PATH_ERRNOS[exc.errno]}")
    why = DISK_ERRNOS.get(exc.errno)
    if why is None:
        return None
    where = exc.filename or "the output folder"
    return BadInput(f"{where}: cannot write: {why}; the previous outputs are left as they were")


def safe_name(text: str, fallback: str = "job", limit: int = 100) -> str:
    """A file or folder name made from user text (a job file's stem, a workpiece's name): letters, digits,
    ``_``, ``-`` and ``.`` kept, anything else ``_``; no leading dot (so never ``.`` or ``..``); at most
    ``limit`` characters; ``fallback`` when nothing is left."""
    import re

    name = re.sub(r"[^\w.-]", "_", str(text))[:limit].lstrip(".").rstrip(". ")
    return name or fallback


def load_toml(path, kind: str, text: str | None = None) -> dict:
    """A TOML file read with ``read_input_text`` (or ``text``) and parsed; BadInput (one line, with a
    bounded quote) for a syntax error and for nesting too deep for the parser (RecursionError)."""
    import tomllib

    text = read_input_text(path, kind) if text is None else text
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise BadInput(f"{path}: TOML syntax error: {str(exc)[:200]}") from None  # tomllib quotes no user text
    except RecursionError:
        raise BadInput(f"{path}: the TOML is nested too deeply to read; a {kind} file is a few flat tables") from None
    except ValueError:  # tomllib's int(): past Python's 4300-digit conversion limit
        raise BadInput(f"{path}: a number with too many digits (more than 4300); a {kind} file holds real values") from None


@contextmanager
def opened_input(path, kind: str):
    """A name for a library that can only open files by name (trimesh, open3d), bound to one descriptor
    opened and checked like ``read_input_bytes``: ``/proc/self/fd/N`` on Linux, so the library reads the
    very file that was checked (a FIFO swapped in afterwards is never opened); the path elsewhere."""
    fd, _st = _open_input(Path(path), kind)
    try:
        proc = f"/proc/self/fd/{fd}"
        yield proc if os.path.exists(proc) else str(path)
    finally:
        os.close(fd)


@contextmanager
def private_copy(path, kind: str, suffix: str = ""):
    """A name for a library that can only open files by name and must not be handed the checked
    descriptor's own ``/proc/self/fd`` (OpenCASCADE): a copy of that descriptor's bytes in an anonymous
    memory file (``memfd_create``), named by its ``/proc/self/fd`` path. No file is made on any file system
    and nobody else can reach it; the library reads the very bytes checked. Where there is no memfd, a
    private folder (``mkdtemp``, mode 0700, the copy created ``O_EXCL | O_NOFOLLOW``) removed after the block."""
    fd, _st = _open_input(Path(path), kind)
    try:
        memfd = _memfd(suffix)
        if memfd is not None:
            try:
                _copy_checked(fd, memfd, path, kind)
                os.lseek(memfd, 0, os.SEEK_SET)
                name = f"/proc/self/fd/{memfd}"
                if os.path.exists(name):
                    yield name
                    return
            finally:
                os.close(memfd)
        tmpdir = tempfile.mkdtemp(prefix="camtool-input-")
        copy = os.path.join(tmpdir, "input" + suffix)
        try:
            out = os.open(copy, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600)
            try:
                _copy_checked(fd, out, path, kind)
            finally:
                os.close(out)
            yield copy
        finally:
            try:
                os.unlink(copy)
            except FileNotFoundError:
                pass
            os.rmdir(tmpdir)
    finally:
        os.close(fd)


def anonymous_file():
    """A binary read-write file object that no file system holds: a memory file (``memfd_create``) on
    Linux, else ``tempfile.TemporaryFile`` (whose first use probes the temporary folder with a named file)."""
    memfd = _memfd("")
    if memfd is None:
        return tempfile.TemporaryFile(mode="w+b")
    return os.fdopen(memfd, "w+b")


def _memfd(suffix: str) -> int | None:
    """An anonymous memory file (Linux), or None."""
    try:
        return os.memfd_create("camtool-input" + suffix, os.MFD_CLOEXEC)
    except (AttributeError, OSError):
        return None


def _copy_checked(src: int, dst: int, path, kind: str) -> None:
    """Copy descriptor ``src`` to ``dst`` in 1 MB reads, refusing a file that grows past its cap."""
    offset, cap = 0, size_cap_bytes(kind)
    while chunk := os.pread(src, 1 << 20, offset):
        offset += len(chunk)
        if offset > cap:
            raise BadInput(f"{path}: grew past the {cap / 2**20:g} MB cap for a {kind} file while read")
        view = memoryview(chunk)
        while view:
            view = view[os.write(dst, view):]


def save_figure(fig, file, **savefig_kw) -> Path:
    """``fig.savefig`` through ``write_file``: rendered in memory, then created O_EXCL|O_NOFOLLOW and
    renamed into place (a planted link at the PNG's name is refused, never written through)."""
    import io

    file = Path(file)
    file.parent.mkdir(parents=True, exist_ok=True)
    buf = io.BytesIO()
    fig.savefig(buf, format=savefig_kw.pop("format", file.suffix.lstrip(".") or "png"), **savefig_kw)
    return write_file(file.parent, file.name, buf.getvalue())


def comment_text(text) -> str:
    """User text (a file name) for a one-line comment of a file camtool writes: every character that is
    not printable (newline, carriage return, escape, ...) escaped, so it cannot end the comment."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(text))


def read_program_bytes(path) -> bytes:
    """A program file for the controller readers and ``camtool check`` (and the files it follows: a .pgf's
    modules, ``Load \\Dynamic``, ``CALL JOB:``): ``read_input_bytes`` of kind program, its BadInput given as
    the OSError those readers report as a finding; a missing file raises the OS's own error, as before."""
    if not os.path.lexists(path):
        return Path(path).read_bytes()
    try:
        return read_input_bytes(path, "program")
    except BadInput as exc:
        raise OSError(str(exc)) from None


MAX_NPZ_MEMBERS = 64
MAX_JSON_DEPTH = 64


def load_json(data: bytes | str, where) -> object:
    """JSON from checked bytes; BadInput (one line, no quote of the text) when it is not JSON or nested
    deeper than ``MAX_JSON_DEPTH`` (camtool's own files are a few levels deep: no RecursionError)."""
    try:
        text = data.decode("utf-8") if isinstance(data, bytes) else data
    except UnicodeDecodeError as exc:
        raise BadInput(f"{where}: not UTF-8 text (byte {exc.start})") from None
    depth = _json_depth(text)
    if depth > MAX_JSON_DEPTH:
        raise BadInput(f"{where}: the JSON is nested {depth} levels deep, more than the {MAX_JSON_DEPTH} camtool reads")
    try:
        return json.loads(text)
    except RecursionError:
        raise BadInput(f"{where}: the JSON is nested too deeply to read") from None
    except ValueError as exc:
        raise BadInput(f"{where}: not valid JSON ({type(exc).__name__} at character "
                       f"{getattr(exc, 'pos', '?')})") from None


def _json_depth(text: str) -> int:
    """The deepest bracket nesting of a JSON text, strings skipped (a linear scan, no recursion)."""
    import re

    stripped = re.sub(r'"(?:[^"\\]|\\.)*"', '""', text)
    depth = best = 0
    for ch in stripped:
        if ch in "[{":
            depth += 1
            if depth > best:
                best = depth
                if best > MAX_JSON_DEPTH:
                    return best
        elif ch in "]}":
            depth -= 1
    return best


def load_npz(data: bytes, where, cap_bytes: int) -> dict:
    """The arrays of an ``.npz`` held in memory (checked bytes, never a path), each read without pickle.

    What the archive inflates to is bounded before anything is allocated: at most ``MAX_NPZ_MEMBERS``
    members, and the sum of every member's declared size and of every array's ``shape x itemsize`` (from
    its .npy header) at most ``cap_bytes``. A 35 MB file claiming 8 GB is one line, never a MemoryError.
    """
    import io
    import math
    import zipfile

    from numpy.lib import format as npformat

    def damaged(exc=None):
        why = f" ({type(exc).__name__})" if exc is not None else ""
        return BadInput(f"{where}: not an .npz archive, or a damaged one{why}")

    def too_big(n):
        return BadInput(f"{where}: the archive inflates to {n / 2**20:.1f} MB, over the {cap_bytes / 2**20:g} MB cap")

    try:
        zf = zipfile.ZipFile(io.BytesIO(data))
        infos = zf.infolist()
        if len(infos) > MAX_NPZ_MEMBERS:
            raise BadInput(f"{where}: holds {len(infos)} entries; an .npz camtool reads has at most {MAX_NPZ_MEMBERS}")
        declared = sum(i.file_size for i in infos)
        if declared > cap_bytes:
            raise too_big(declared)
        arrays, total = {}, 0
        for info in infos:
            name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
            with zf.open(info) as f:
                version = npformat.read_magic(f)
                if version == (1, 0):
                    shape, fortran, dtype = npformat.read_array_header_1_0(f)
                elif version in ((2, 0), (3, 0)):
                    shape, fortran, dtype = npformat.read_array_header_2_0(f)
                else:
                    raise damaged()
                if dtype.hasobject:
                    raise BadInput(f"{where}: entry {snippet(name, 40)} holds Python objects; camtool reads numbers and text only")
                total += math.prod(int(s) for s in shape) * max(dtype.itemsize, 1)
                if total > cap_bytes:
                    raise too_big(total)
            with zf.open(info) as f:
                arrays[name] = npformat.read_array(f, allow_pickle=False)
        return arrays
    except BadInput:
        raise
    except (ValueError, OSError, EOFError, KeyError, TypeError, OverflowError, zipfile.BadZipFile,
            NotImplementedError, RuntimeError, MemoryError) as exc:
        raise damaged(exc) from None
