"""The command line: the only package that imports click, prints, shows progress or exits.

One module per command (build, batch, inspect, simulate, calibrate, convert, evaluate,
trajectory) and what they share (:mod:`gridmap_cli.cli.common`); build's map options
(:mod:`gridmap_cli.cli.map_options`, for batch to share too) and its report
(:mod:`gridmap_cli.cli.build_report`) have their own modules. Each command checks every
precondition (inputs exist, outputs absent unless --force, options consistent) before reading a
byte, then calls a plain library function and reports. Library errors become one ``Error: ...``
line: exit 1 for bad data or runtime failures, 2 for usage, 130 for Ctrl-C.

A command's module is imported when that command runs (or help lists it): ``gridmap build`` on a
CSV log does not load the simulator, the evaluation's scipy or the MCAP writers.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Sequence
from typing import Any

import click

from gridmap_cli import __version__

#: command name -> module under gridmap_cli.cli and the click command's name in it
COMMANDS = {
    "build": ("build", "build"),
    "batch": ("batch", "batch"),
    "inspect": ("inspect_log", "inspect"),
    "simulate": ("simulate", "simulate"),
    "calibrate": ("calibrate", "calibrate"),
    "convert": ("convert", "convert"),
    "evaluate": ("evaluate", "evaluate"),
    "trajectory": ("trajectory", "trajectory"),
}

#: click >= 8.2 raises this for a command given no arguments that it answers with its help
_NO_ARGS_IS_HELP: tuple[type[BaseException], ...] = tuple(
    c for c in [getattr(click.exceptions, "NoArgsIsHelpError", None)] if c is not None
)


#: Command names people try from other tools, and the command that does what they meant.
_COMMAND_HINTS = {
    name: ("inspect LOG", "to see what a log holds and what build would use, run")
    for name in ("info", "show", "describe", "stat", "stats")
}


class GridmapGroup(click.Group):
    """click's group, with commands imported on first use and click's own usage errors on one
    line too.

    Standalone click prints a usage error as three lines (``Usage: ...``, ``Try ...``,
    ``Error: ...``); cron mails and log scrapers want one ``Error:`` line, as for every other
    error. Exit codes are click's (2 for usage); Ctrl-C outside a command exits 130 as inside.
    """

    def list_commands(self, ctx: click.Context) -> list[str]:
        return list(COMMANDS)

    def resolve_command(
        self, ctx: click.Context, args: list[str]
    ) -> tuple[str | None, click.Command | None, list[str]]:
        name = args[0] if args else ""
        if name in _COMMAND_HINTS and name not in COMMANDS:
            command, what = _COMMAND_HINTS[name]
            ctx.fail(f"No such command '{name}'; {what}: gridmap {command}")
        return super().resolve_command(ctx, args)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in COMMANDS:
            return None
        module, attr = COMMANDS[cmd_name]
        command = getattr(importlib.import_module(f"gridmap_cli.cli.{module}"), attr)
        assert isinstance(command, click.Command)
        return command

    def main(
        self,
        args: Sequence[str] | None = None,
        prog_name: str | None = None,
        complete_var: str | None = None,
        standalone_mode: bool = True,
        **extra: Any,
    ) -> Any:
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, False, **extra)
        try:
            code = super().main(args, prog_name, complete_var, False, **extra)
        except click.ClickException as exc:
            if isinstance(exc, _NO_ARGS_IS_HELP):
                exc.show()  # ``gridmap`` alone: the help, as click prints it
                sys.exit(exc.exit_code)
            from gridmap_cli.cli.common import one_line  # only now: --version loads no command

            if isinstance(exc, click.NoSuchOption):
                exc = _suggest_longer(exc)
            click.echo(f"Error: {one_line(exc.format_message())}", err=True)
            sys.exit(exc.exit_code)
        except (click.exceptions.Abort, EOFError, KeyboardInterrupt):
            from gridmap_cli.cli.common import Interrupted

            stop = Interrupted()
            click.echo(f"Error: {stop.format_message()}", err=True)
            sys.exit(stop.exit_code)
        sys.exit(code if isinstance(code, int) else 0)


def _suggest_longer(exc: click.NoSuchOption) -> click.NoSuchOption:
    """The error suggesting the options an unknown one begins (``--res``: ``--resolution``),
    which click's close-spelling suggestions leave out; ``exc`` when it begins none."""
    if exc.ctx is None or not exc.option_name.startswith("--"):
        return exc
    longer = sorted(
        o for p in exc.ctx.command.params for o in p.opts if o.startswith(exc.option_name)
    )
    if not longer:
        return exc
    named = ", ".join(repr(o) for o in longer)
    message = f"No such option {exc.option_name!r}. Did you mean {named}?"
    return click.NoSuchOption(exc.option_name, message=message, ctx=exc.ctx)


@click.group(cls=GridmapGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="gridmap")
@click.option("--debug", is_flag=True, help="Show tracebacks instead of one-line errors.")
@click.pass_context
def cli(ctx: click.Context, debug: bool) -> None:
    """Occupancy-grid maps from robot logs of range readings and wheel odometry."""
    ctx.obj = {"debug": debug}


def main() -> None:
    """Console-script entry point."""
    cli(prog_name="gridmap")
