"""The command line: the only package that imports click, prints, shows progress or exits.

One module per command (build, inspect, simulate, calibrate, convert, evaluate, trajectory) and
what they share (:mod:`gridmap_cli.cli.common`). Each command checks every precondition (inputs
exist, outputs absent unless --force, options consistent) before reading a byte, then calls a
plain library function and reports. Library errors become one ``Error: ...`` line: exit 1 for bad
data or runtime failures, 2 for usage.
"""

from __future__ import annotations

import click

from gridmap_cli import __version__
from gridmap_cli.cli.build import build
from gridmap_cli.cli.calibrate import calibrate
from gridmap_cli.cli.convert import convert
from gridmap_cli.cli.evaluate import evaluate
from gridmap_cli.cli.inspect_log import inspect
from gridmap_cli.cli.simulate import simulate
from gridmap_cli.cli.trajectory import trajectory


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="gridmap")
@click.option("--debug", is_flag=True, help="Show tracebacks instead of one-line errors.")
@click.pass_context
def cli(ctx: click.Context, debug: bool) -> None:
    """Occupancy-grid maps from robot logs of range readings and wheel odometry."""
    ctx.obj = {"debug": debug}


for _command in (build, inspect, simulate, calibrate, convert, evaluate, trajectory):
    cli.add_command(_command)


def main() -> None:
    """Console-script entry point."""
    cli(prog_name="gridmap")
