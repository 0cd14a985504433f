"""``gridmap convert``: a log from one format to another."""

from __future__ import annotations

from pathlib import Path

import click

from gridmap_cli.cli.common import (
    STDIO,
    check_input,
    check_not_folder,
    check_output_folder,
    force_option,
    handle_errors,
    json_option,
    json_text,
    quiet_option,
    read_input,
    stdout_file,
)
from gridmap_cli.errors import UsageError
from gridmap_cli.readers import format_names, resolve_format
from gridmap_cli.robot import load_robot, robot_from_log
from gridmap_cli.writers import check_output
from gridmap_cli.writers.convert import output_writer, write_log, writer_names
from gridmap_cli.writers.mcap_log import ENCODINGS


@click.command()
@click.argument("log", type=click.Path(path_type=Path, readable=False))
@click.argument("output", type=click.Path(path_type=Path, readable=False))
@click.option(
    "--to",
    "out_format",
    type=click.Choice(writer_names()),
    help="Format of OUTPUT; default: from its extension (.csv, .2d, .mcap).",
)
@click.option(
    "--format",
    "--input-format",
    "input_format",
    type=click.Choice(format_names()),
    help="Format of LOG (as for every command); default: from its extension, else its content.",
)
@click.option(
    "--encoding",
    type=click.Choice(ENCODINGS),
    help="MCAP output only: gridmap's JSON channels (default) or standard ROS 2 messages.",
)
@click.option(
    "--robot",
    help="Robot preset, robot YAML or ARIA .p file for sensor geometry the log lacks "
    "(.2d and MCAP outputs need it); default: the log's own robot.",
)
@force_option("Overwrite an existing output.")
@quiet_option("No summary on stderr.")
@json_option("Print the summary as JSON on stdout.")
@handle_errors
def convert(
    log: Path,
    output: Path,
    out_format: str | None,
    input_format: str | None,
    encoding: str | None,
    robot: str | None,
    force: bool,
    quiet: bool,
    as_json: bool,
) -> None:
    """Convert LOG to OUTPUT between gridmap CSV, ARIA .2d and MCAP.

    What the output format cannot hold is refused, never dropped (see schemas/*.md).
    """
    check_not_folder(output)
    writer = output_writer(output, out_format, encoding)
    if output == STDIO and as_json:
        raise UsageError("- writes the log to standard output; --json would mix with it")
    robot_desc = load_robot(robot) if robot else None
    check_input(log)
    if output != STDIO:
        check_output(output, force)
        check_output_folder(output)
    format_name = input_format or (resolve_format(log).name if log != STDIO else "sniffed")
    data = read_input([log], input_format)
    if robot_desc is None and writer.needs_sensors:
        known = {s.name for s in data.sensors or ()}
        if not set(data.sensor_names) <= known:
            robot_desc = robot_from_log(log, data.metadata)
    if output == STDIO:
        with stdout_file(f"log{writer.extension}") as target:
            write_log(data, target, writer, robot_desc, encoding)
    else:
        write_log(data, output, writer, robot_desc, encoding)
    if as_json:
        summary = {
            "input": str(log),
            "input_format": format_name,
            "output": str(output),
            "format": writer.name,
            "encoding": (encoding or "json") if writer.name == "mcap" else None,
            "poses": len(data.poses),
            "readings": len(data.readings),
            "ground_truth": data.truth is not None,
        }
        click.echo(json_text(summary))
    if not quiet:
        what = writer.name + (f" ({encoding or 'json'})" if writer.name == "mcap" else "")
        click.echo(
            f"gridmap: {format_name} -> {what}: {len(data.poses):,} poses, "
            f"{len(data.readings):,} readings"
            f"{', ground truth' if data.truth is not None else ''} -> {output}",
            err=True,
        )
