"""``gridmap simulate``: a log of a simulated robot in a world, with its ground truth."""

from __future__ import annotations

import math
from pathlib import Path

import click
import numpy as np

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
    stdout_file,
)
from gridmap_cli.errors import UsageError
from gridmap_cli.robot import load_robot
from gridmap_cli.writers import check_output
from gridmap_cli.writers.convert import output_writer, write_log, writer_names
from gridmap_cli.writers.mcap_log import ENCODINGS


def _check_numbers(rate: float, drift: float, duration: float | None) -> None:
    """--rate, --drift and --duration: finite, and positive where zero means nothing."""
    if not (rate > 0.0 and math.isfinite(rate)):
        raise UsageError(f"--rate must be a positive number of Hz, got {rate}")
    if not (drift >= 0.0 and math.isfinite(drift)):
        raise UsageError(f"--drift must be a finite number >= 0, got {drift}")
    if duration is not None and not (duration > 0.0 and math.isfinite(duration)):
        raise UsageError(f"--duration must be a positive number of seconds, got {duration}")


@click.command()
@click.argument("world", type=click.Path(path_type=Path, readable=False))
@click.argument("path_file", metavar="PATH", type=click.Path(path_type=Path, readable=False))
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(path_type=Path, readable=False),
    help="Log to write: .csv (gridmap CSV), .2d (ARIA with sonar lines) or .mcap.",
)
@click.option(
    "--to",
    "log_format",
    type=click.Choice(writer_names()),
    help="Format of the log to write; default: from the output's extension.",
)
@click.option(
    "--encoding",
    type=click.Choice(ENCODINGS),
    help="MCAP only: gridmap's JSON channels (default) or standard ROS 2 messages (cdr).",
)
@click.option("--robot", default="p3at", show_default=True, help="Robot preset or YAML file.")
@click.option("--rate", type=float, default=10.0, show_default=True, help="Sensor rate, Hz.")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@click.option(
    "--drift",
    type=float,
    default=1.0,
    show_default=True,
    help="Odometry error level: 0 perfect, 1 typical, 2 poor (scales every error term).",
)
@click.option("--duration", type=float, help="Repeat laps until this many seconds have passed.")
@force_option("Overwrite an existing output.")
@quiet_option("No summary on stderr.")
@json_option("Print the summary as JSON on stdout.")
@handle_errors
def simulate(
    world: Path,
    path_file: Path,
    output: Path,
    log_format: str | None,
    encoding: str | None,
    robot: str,
    rate: float,
    seed: int,
    drift: float,
    duration: float | None,
    force: bool,
    quiet: bool,
    as_json: bool,
) -> None:
    """Drive a simulated robot along PATH in WORLD and write a log with ground truth.

    WORLD is a map_server map (YAML + image); PATH a waypoint file (see docs/simulator.md).
    """
    from gridmap_cli.mapping.mapfile import load_map
    from gridmap_cli.sim.path import load_path
    from gridmap_cli.sim.simulate import simulate as run_simulation
    from gridmap_cli.sim.world import World

    _check_numbers(rate, drift, duration)
    check_not_folder(output)
    writer = output_writer(output, log_format, encoding)
    if output == STDIO and as_json:
        raise UsageError("-o - writes the log to standard output; --json would mix with it")
    robot_desc = load_robot(robot)
    for given in (world, path_file):
        check_input(given, folder_ok=False)
    if output != STDIO:
        check_output(output, force)
        check_output_folder(output)
    loaded = load_map(world)
    waypoints = load_path(path_file)
    log = run_simulation(
        World(loaded.occupied_mask(), loaded.spec),
        waypoints,
        robot_desc,
        rate_hz=rate,
        seed=seed,
        drift=drift,
        duration_s=duration,
    )
    # everything needed to make the same log again goes into its header
    log.metadata.update({"robot": robot, "world": str(world), "path": str(path_file)})
    log.metadata["rate"] = repr(rate)
    if duration is not None:
        log.metadata["duration"] = repr(duration)
    if output == STDIO:
        with stdout_file(f"log{writer.extension}") as target:
            write_log(log, target, writer, robot_desc, encoding)
    else:
        write_log(log, output, writer, robot_desc, encoding)
    zmax = np.asarray([s.max_range_m for s in robot_desc.sensors])
    no_echo = int(np.count_nonzero(log.readings.range_m >= zmax[log.readings.sensor]))
    span = (log.poses.stamp_ns[-1] - log.poses.stamp_ns[0]) / 1e9
    if as_json:
        summary = {
            "output": str(output),
            "format": writer.name,
            "encoding": encoding if writer.name == "mcap" else None,
            "duration_s": span,
            "poses": len(log.poses),
            "readings": len(log.readings),
            "no_echo": no_echo,
            "seed": seed,
        }
        click.echo(json_text(summary))
    if not quiet:
        click.echo(
            f"gridmap: simulated {span:.1f} s: {len(log.poses):,} poses, "
            f"{len(log.readings):,} readings ({no_echo:,} no echo) -> {output}",
            err=True,
        )
