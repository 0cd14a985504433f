"""The command line: the only package that imports click, prints, shows progress or exits.

One module per command (build, inspect, simulate, calibrate, convert, evaluate) and what they
share (:mod:`gridmap_cli.cli.common`). Each command checks every precondition (inputs exist,
outputs absent unless --force, options consistent) before reading a byte, then calls a plain
library function and reports. Library errors become one ``Error: ...`` line: exit 1 for bad
data or runtime failures, 2 for usage.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

import click

from gridmap_cli import __version__
from gridmap_cli.cli.batch import batch
from gridmap_cli.cli.build import build
from gridmap_cli.cli.calibrate import calibrate
from gridmap_cli.cli.common import one_line
from gridmap_cli.cli.convert import convert
from gridmap_cli.cli.evaluate import evaluate
from gridmap_cli.cli.inspect_log import inspect
from gridmap_cli.cli.simulate import simulate

#: click >= 8.2 raises this for a command given no arguments that it answers with its help
_NO_ARGS_IS_HELP: tuple[type[BaseException], ...] = tuple(
    c for c in [getattr(click.exceptions, "NoArgsIsHelpError", None)] if c is not None
)


class OneLineErrors(click.Group):
    """click's group, reporting click's own usage errors on one line too.

    Standalone click prints a usage error as three lines (``Usage: ...``, ``Try ...``,
    ``Error: ...``); cron mails and log scrapers want one ``Error:`` line, as for every other
    error. Exit codes are click's (2 for usage).
    """

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
            click.echo(f"Error: {one_line(exc.format_message())}", err=True)
            sys.exit(exc.exit_code)
        except (click.exceptions.Abort, EOFError, KeyboardInterrupt):
            click.echo("Aborted!", err=True)
            sys.exit(1)
        sys.exit(code if isinstance(code, int) else 0)


@click.group(cls=OneLineErrors, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="gridmap")
@click.option("--debug", is_flag=True, help="Show tracebacks instead of one-line errors.")
@click.pass_context
def cli(ctx: click.Context, debug: bool) -> None:
    """Occupancy-grid maps from robot logs of range readings and wheel odometry."""
    ctx.obj = {"debug": debug}


for _command in (build, batch, inspect, simulate, calibrate, convert, evaluate):
    cli.add_command(_command)


def main() -> None:
    """Console-script entry point."""
    cli(prog_name="gridmap")
