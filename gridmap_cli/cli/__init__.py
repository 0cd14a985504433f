"""The command line: the only package that imports click, prints, shows progress or exits.

One module per command (build, inspect, simulate, calibrate, convert, evaluate, trajectory) and
what they share (:mod:`gridmap_cli.cli.common`). Each command checks every precondition (inputs
exist, outputs absent unless --force, options consistent) before reading a byte, then calls a
plain library function and reports. Library errors become one ``Error: ...`` line: exit 1 for bad
data or runtime failures, 2 for usage.

A command's module is imported when that command runs (or help lists it): ``gridmap build`` on a
CSV log does not load the simulator, the evaluation's scipy or the MCAP writers.
"""

from __future__ import annotations

import importlib

import click

from gridmap_cli import __version__

#: command name -> module under gridmap_cli.cli and the click command's name in it
COMMANDS = {
    "build": ("build", "build"),
    "inspect": ("inspect_log", "inspect"),
    "simulate": ("simulate", "simulate"),
    "calibrate": ("calibrate", "calibrate"),
    "convert": ("convert", "convert"),
    "evaluate": ("evaluate", "evaluate"),
    "trajectory": ("trajectory", "trajectory"),
}


class LazyGroup(click.Group):
    """A group whose commands are imported on first use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return list(COMMANDS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in COMMANDS:
            return None
        module, attr = COMMANDS[cmd_name]
        command = getattr(importlib.import_module(f"gridmap_cli.cli.{module}"), attr)
        assert isinstance(command, click.Command)
        return command


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="gridmap")
@click.option("--debug", is_flag=True, help="Show tracebacks instead of one-line errors.")
@click.pass_context
def cli(ctx: click.Context, debug: bool) -> None:
    """Occupancy-grid maps from robot logs of range readings and wheel odometry."""
    ctx.obj = {"debug": debug}


def main() -> None:
    """Console-script entry point."""
    cli(prog_name="gridmap")
