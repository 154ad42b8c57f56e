"""camtool's command line: a click group; each command is thin and lives in
``camtool/commands/``. Errors become one line on stderr and an exit code:
0 ok, 2 bad input, 3 plan infeasible, 4 stage not available, 1 internal error.
"""
from __future__ import annotations

import os

# One BLAS thread a process, set before numpy loads OpenBLAS (a user's own setting stands): camtool works in
# parallel by processes (the helpers alongside a run, a batch's workers), where OpenBLAS's threads only spin on
# the cores those use. Measured on the sample: 0.8 s less CPU and 0.5 s less wall time, programs bit for bit.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import atexit  # noqa: E402
import logging  # noqa: E402
import sys  # noqa: E402
import threading  # noqa: E402
import traceback  # noqa: E402

import click  # noqa: E402

from .commands import batch, check, design, faces, fit, fk, place, plan, post, posts, raster, robots, run, timing, watch  # noqa: E402
from .errors import CamtoolError  # noqa: E402

DEBUG_KEY = "camtool.debug"  # ctx.meta key set by the group's --debug option


MAX_MESSAGE = 2000  # characters of an error line; a 5 MB name is not echoed whole


def _print_version(ctx: click.Context) -> None:
    """``--version``, as click's version_option prints it; the version is read only when asked for."""
    from . import __version__

    click.echo(f"camtool, version {__version__}")
    ctx.exit()


def one_line(text: str) -> str:
    """A message as one line: line breaks and other control characters (e.g. from a file name) escaped,
    at most MAX_MESSAGE characters."""
    text = "".join(c if c.isprintable() or c == " " else repr(c)[1:-1] for c in str(text)[:MAX_MESSAGE + 1])
    return text[:MAX_MESSAGE] + ("... (cut)" if len(text) > MAX_MESSAGE else "")


class CamtoolGroup(click.Group):
    """A click group that turns exceptions into one line and an exit code."""

    def main(self, args=None, prog_name=None, **kwargs):
        """Usage errors are one line too (click prints four); then the exit code."""
        kwargs["standalone_mode"] = False
        try:
            code = super().main(args=args, prog_name=prog_name, **kwargs)
        except click.UsageError as exc:
            cmd = exc.ctx.command_path if exc.ctx is not None else "camtool"
            click.echo(f"camtool: error: {one_line(exc.format_message())} (see `{cmd} --help`)", err=True)
            sys.exit(exc.exit_code)
        except click.ClickException as exc:
            click.echo(f"camtool: error: {one_line(exc.format_message())}", err=True)
            sys.exit(exc.exit_code)
        except click.Abort:
            click.echo("camtool: interrupted", err=True)
            sys.exit(130)
        sys.exit(code if isinstance(code, int) else 0)

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except CamtoolError as exc:
            if ctx.meta.get(DEBUG_KEY):
                traceback.print_exc()
            click.echo(f"camtool: error: {one_line(exc)}", err=True)
            ctx.exit(exc.exit_code)
        except (click.exceptions.Exit, click.exceptions.Abort, click.ClickException):
            raise
        except BrokenPipeError:  # e.g. `camtool robots | head`: the reader has gone, which is no error (click
            _quiet_stdout()      # would exit 1 on it)
            ctx.exit(0)
        except KeyboardInterrupt:
            click.echo("camtool: interrupted", err=True)
            ctx.exit(130)
        except Exception as exc:
            from .safe_io import disk_error

            err = disk_error(exc) if isinstance(exc, OSError) else None
            if err is not None:  # full disk, quota, permission, read-only: the user's to fix
                click.echo(f"camtool: error: {one_line(err)}", err=True)
                ctx.exit(2)
            # an internal error: one line, traceback with --debug
            if ctx.meta.get(DEBUG_KEY):
                traceback.print_exc()
            first = one_line(str(exc).splitlines()[0]) if str(exc) else ""
            click.echo(f"camtool: internal error: {type(exc).__name__}: {first} "
                       "(rerun with --debug for the traceback, and please report it)", err=True)
            ctx.exit(1)


@click.group(cls=CamtoolGroup, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.option("--version", is_flag=True, expose_value=False, is_eager=True, help="Show the version and exit.",
              callback=lambda ctx, _param, value: _print_version(ctx) if value else None)
@click.option("--debug", is_flag=True, help="Show the Python traceback of an error.")
@click.option("--no-plugins", is_flag=True,
              help="Load no third-party post-processor, only the built-ins (also for batch children; "
                   "CAMTOOL_PLUGINS=name,... allows only those named).")
@click.pass_context
def cli(ctx: click.Context, debug: bool, no_plugins: bool) -> None:
    """camtool: offline CAM for robot surface work.

    A workpiece (mesh or point cloud) goes in; a fitted surface, an S-shaped
    raster path, a planned and timed joint trajectory, and controller
    programs (ABB RAPID, Yaskawa INFORM, CSV) come out.

    Stages one at a time: fit, raster, plan, time and post each run one stage
    of a JOB and save its result; --from resumes from a saved one. `run` is
    their composition.

    Exit codes: 0 ok, 2 bad input, 3 plan cannot be done, 4 stage not
    available yet, 1 internal error.
    """
    ctx.meta[DEBUG_KEY] = debug
    if no_plugins:
        from .program.registry import disable_plugins

        disable_plugins()
    if debug:  # library messages (loaders, plugins) through camtool's logger, on stderr
        logging.basicConfig(stream=sys.stderr, format="camtool: debug: %(name)s: %(message)s")
        logging.getLogger("camtool").setLevel(logging.DEBUG)


def _register() -> None:
    for module in (robots, fk, fit, faces, raster, plan, timing, post, run, batch, watch, design, place, posts, check):
        cli.add_command(module.command)


_register()


def drop_working_folder_from_path() -> None:
    """Take the working folder off the import path (``python -m`` puts it first), so a ``numpy.py``
    dropped in a hot or batch folder is never imported by a later import of this process or of a
    helper it forks: camtool often runs as root there. Folders PYTHONPATH names stay (the caller's)."""
    try:
        here = os.getcwd()
    except OSError:
        return
    chosen = {os.path.abspath(p) for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p}
    if here not in chosen:
        sys.path[:] = [p for p in sys.path if p != "" and os.path.abspath(p) != here]


def main() -> None:
    """Console-script entry point: the command, then a quick exit (``leave``)."""
    drop_working_folder_from_path()
    from .console import take_result_channel

    take_result_channel()  # a batch job's JSON goes to its own pipe, never mixed with what plugins print
    try:
        cli(prog_name="camtool")
        code = 0
    except SystemExit as exc:
        code = exc.code
    except BrokenPipeError:  # e.g. `camtool robots | head`: not an error
        _quiet_stdout()
        code = 0
    leave(code)


def _quiet_stdout() -> None:
    """Standard output to /dev/null: its reader has gone, and what is still buffered goes nowhere."""
    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())


def leave(code) -> None:
    """End the process with ``code`` (``SystemExit``'s: None, a number or a message) once the command is done.

    Why not the interpreter's own exit: its finalisation tears down every imported module (numba's
    LLVM, scipy, trimesh), 0.1-0.2 s of every run, measured, with nothing left to do: camtool's files
    are closed when written (``safe_io``). So the exit handlers run, the logs and the standard
    streams are flushed, and the process ends with ``os._exit``. While another thread is still alive
    (it would be waited for), the interpreter exits as usual."""
    if code is None:
        code = 0
    elif not isinstance(code, int):
        print(code, file=sys.stderr)
        code = 1
    if threading.active_count() > 1:
        sys.exit(code)
    logging.shutdown()
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (BrokenPipeError, ValueError):  # a closed reader or stream: nothing more can be said there
            pass
    os._exit(code)


if __name__ == "__main__":
    main()
