"""camtool's command line: a click group; each command is thin and lives in
``camtool/commands/``. Errors become one line on stderr and an exit code:
0 ok, 2 bad input, 3 plan infeasible, 4 stage not available, 1 internal error.
"""
from __future__ import annotations

import logging
import sys
import traceback

import click

from . import __version__
from .commands import batch, check, design, fit, fk, place, plan, post, posts, raster, robots, run, timing, watch
from .errors import CamtoolError

DEBUG_KEY = "camtool.debug"  # ctx.meta key set by the group's --debug option


def one_line(text: str) -> str:
    """A message as one line: line breaks (e.g. from a file name) are shown as \\n."""
    return str(text).replace("\r", "\\r").replace("\n", "\\n")


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
        except BrokenPipeError:
            raise
        except KeyboardInterrupt:
            click.echo("camtool: interrupted", err=True)
            ctx.exit(130)
        except Exception as exc:  # an internal error: one line, traceback with --debug
            if ctx.meta.get(DEBUG_KEY):
                traceback.print_exc()
            first = one_line(str(exc).splitlines()[0]) if str(exc) else ""
            click.echo(f"camtool: internal error: {type(exc).__name__}: {first} "
                       "(rerun with --debug for the traceback, and please report it)", err=True)
            ctx.exit(1)


@click.group(cls=CamtoolGroup, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, "--version", prog_name="camtool")
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
    for module in (robots, fk, fit, raster, plan, timing, post, run, batch, watch, design, place, posts, check):
        cli.add_command(module.command)


_register()


def main() -> None:
    """Console-script entry point."""
    try:
        cli(prog_name="camtool")
    except BrokenPipeError:  # e.g. `camtool robots | head`: not an error
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        sys.exit(0)


if __name__ == "__main__":
    main()
