"""``gridmap inspect``: what a log holds and what build would make of it."""

from __future__ import annotations

import dataclasses
import io
import sys
from pathlib import Path

import click

from gridmap_cli.cli.common import (
    STDIO,
    check_input,
    format_option,
    handle_errors,
    json_option,
    json_text,
    logs_argument,
    one_line,
    plain_numbers,
    selection_options,
    topic_options,
)
from gridmap_cli.cli.progress import reading
from gridmap_cli.errors import UsageError
from gridmap_cli.mapping.selection import Selection
from gridmap_cli.poses.sources import DEFAULT_SOURCE, pose_source
from gridmap_cli.readers import STDIN_NAME, held_text, resolve_format
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.robot import load_robot


@click.command()
@logs_argument
@click.option("--robot", help="Robot preset, robot YAML file or ARIA .p file.")
@format_option
@topic_options
@selection_options()
@json_option("Print the description as JSON.")
@handle_errors
def inspect(
    logs: tuple[Path, ...],
    robot: str | None,
    log_format: str | None,
    topics: ReadOptions,
    sensor_patterns: tuple[str, ...],
    start: str | None,
    end: str | None,
    as_json: bool,
) -> None:
    """Describe LOG (CSV, ARIA .2d, MCAP, ROS 1 bag, rosbag2 folder, CARMEN; - reads a text log
    from standard input) and what build would make of it; several ROS recordings are described
    as the one build would merge.

    Channels or columns, message counts, time span, rates, distance travelled, sensors and
    their mounting poses, and the topics, frames and robot build would use. Exits 1, after
    the description, when build would fail: the reason is build's own error.
    With --sensors, --start or --end: the part of LOG they select, as build would map it.
    """
    from gridmap_cli.describe import describe_log, render_text

    selection = Selection.parse(sensor_patterns, start, end)
    robot_desc = load_robot(robot) if robot else None
    for log in logs:
        check_input(log)
    # read as build reads it by default: its automatic choice takes the motion from a laser's
    # scans where a recording has no odometry
    read_options = dataclasses.replace(
        topics, robot=robot_desc, odometry_optional=pose_source(DEFAULT_SOURCE).uses_laser
    )
    held = None
    if STDIO in logs:  # as build reads it: a text log, its format from --format or its head
        if len(logs) > 1:
            raise UsageError("- (standard input) is one log; it cannot be read with others")
        data = sys.stdin.buffer.read()
        fmt, text = held_text(data, STDIN_NAME, log_format)
        read_options.refuse_topic_flags(fmt.name.upper())
        assert fmt.text_reader is not None  # held_text refuses the others
        held = (fmt.text_reader(io.StringIO(text), STDIN_NAME, read_options), len(data))
        logs = (Path(STDIN_NAME),)
    else:
        fmt = resolve_format(logs[0], log_format)
        if fmt.sources is None:
            read_options.refuse_topic_flags(fmt.name.upper())
    with reading(logs[0].name if len(logs) == 1 else f"{len(logs)} logs", quiet=False):
        description = describe_log(logs, fmt, read_options, selection, held)
    click.echo(json_text(description) if as_json else plain_numbers(render_text(description)))
    if not description["build"]["ready"]:
        # the description is printed; the verdict is the line build would print, and its exit
        click.echo(f"Error: {one_line(description['build']['problem'])}", err=True)
        sys.exit(1)
