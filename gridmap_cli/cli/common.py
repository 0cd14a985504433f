"""What the commands share: one-line errors, progress bars, input and output checks, and the
options several commands take (topics and frames, sensor and time selection)."""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, ParamSpec, TypeVar

import click
from tqdm import tqdm

from gridmap_cli.errors import GridmapError, InputFileError, UsageError
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.robot import RobotDescription
from gridmap_cli.selection import EXCLUDE

P = ParamSpec("P")
R = TypeVar("R")


class UsageFailure(click.ClickException):
    """A usage error reported on one line (click's UsageError would print the usage block)."""

    exit_code = 2


def handle_errors(func: Callable[P, R]) -> Callable[P, R]:
    """Turn library errors into one-line ``Error:`` messages; tracebacks only with --debug."""

    @functools.wraps(func)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            return func(*args, **kwargs)
        except GridmapError as exc:
            if debug_enabled():
                raise
            if isinstance(exc, UsageError):
                raise UsageFailure(one_line(str(exc))) from exc
            raise click.ClickException(one_line(str(exc))) from exc
        except (click.exceptions.ClickException, click.exceptions.Exit, click.exceptions.Abort):
            raise
        except MemoryError as exc:
            if debug_enabled():
                raise
            raise click.ClickException(
                "out of memory: the input is larger than this machine can map (--debug shows where)"
            ) from exc
        except Exception as exc:
            # unattended runs (cron) get one line and exit 1 even for what gridmap did not
            # foresee; the text says it is gridmap's fault, not the data's
            if debug_enabled():
                raise
            raise click.ClickException(
                f"internal error ({type(exc).__name__}: {one_line(str(exc))[:300]}); please "
                "report it with the output of --debug"
            ) from exc

    return wrapper


def one_line(text: str) -> str:
    """``text`` with its line breaks (and runs of spaces around them) folded into one space:
    every error is one line, whatever a library put in its message."""
    return " ".join(part.strip() for part in text.splitlines() if part.strip())


def debug_enabled() -> bool:
    """True when the command line asked for tracebacks (``gridmap --debug ...``)."""
    ctx = click.get_current_context(silent=True)
    root = ctx.find_root() if ctx is not None else None
    return bool(root is not None and root.obj and root.obj.get("debug"))


def progress_bar(total: int, quiet: bool, desc: str) -> tqdm[Any]:
    # hidden when stderr is not a terminal (pipelines, cron) or with --quiet
    return tqdm(
        total=total,
        desc=desc,
        unit=" readings",
        unit_scale=True,
        file=sys.stderr,
        disable=quiet or not sys.stderr.isatty(),
        leave=False,
    )


def check_input(log: Path) -> None:
    """A log must exist: a file, or a folder (rosbag2)."""
    if not log.exists():
        raise InputFileError(log, "no such file")
    if not (log.is_file() or log.is_dir()):
        raise InputFileError(log, "not a regular file or folder")


def check_output_folder(output: Path) -> None:
    folder = output.parent
    if not folder.is_dir():
        raise GridmapError(f"{output}: directory {folder} does not exist")


def topic_options(func: Callable[P, R]) -> Callable[P, R]:
    """The topic and frame choices of ROS recordings (MCAP, bag, rosbag2), for build and
    inspect."""
    options = [
        click.option(
            "--odom-topic",
            help="ROS: pose topic to use as odometry, or /tf for its odom -> base transforms; "
            "default: the only Odometry/PoseStamped topic, else TF.",
        ),
        click.option(
            "--range-topic",
            "range_topics",
            multiple=True,
            help="ROS: range topic to map (repeatable); default: every Range, LaserScan, "
            "RosAria sonar and gridmap range topic.",
        ),
        click.option("--odom-frame", help="ROS: odometry frame in TF [default: odom]."),
        click.option(
            "--base-frame",
            help="ROS: the robot's base frame; default: the odometry's child frame, else the "
            "lowest frame TF moves below the odometry frame, else base_link.",
        ),
        click.option(
            "--pose-topic",
            help="ROS: the reference (corrected) pose topic for --pose global: PoseStamped, "
            "PoseWithCovarianceStamped (/amcl_pose) or Odometry; default: a ground_truth topic, "
            "else TF map -> base, else the one PoseWithCovarianceStamped topic.",
        ),
        click.option("--map-frame", help="ROS: the reference track's frame in TF [default: map]."),
    ]
    for option in reversed(options):
        func = option(func)
    return func


def selection_options(sensors: bool = True) -> Callable[[Callable[P, R]], Callable[P, R]]:
    """The choice of part of a log (``--sensors``, ``--start``, ``--end``), shared by the
    commands that read one; calibrate, comparing poses only, takes the window alone."""
    options = [
        click.option(
            "--start",
            metavar="TIME",
            help="Use the log from TIME on: seconds from the log's start (its first pose or "
            "reading), or an ISO 8601 time (2025-04-08T14:34:30Z; no offset means UTC).",
        ),
        click.option(
            "--end",
            metavar="TIME",
            help="Use the log up to TIME, not including it (as --start).",
        ),
    ]
    if sensors:
        options.insert(
            0,
            click.option(
                "--sensors",
                "sensor_patterns",
                multiple=True,
                metavar="PATTERN",
                help="Use the sensors whose names match this shell-style pattern ('sonar*', "
                f"'base_laser_link_*'); repeatable; '{EXCLUDE}PATTERN' leaves them out "
                "(quote it); default: all.",
            ),
        )

    def decorate(func: Callable[P, R]) -> Callable[P, R]:
        for option in reversed(options):
            func = option(func)
        return func

    return decorate


def warn(notes: tuple[str, ...], quiet: bool = False) -> None:
    if not quiet:
        for note in notes:
            click.echo(f"Warning: {note}", err=True)


def make_read_options(
    odom_topic: str | None,
    range_topics: tuple[str, ...],
    odom_frame: str | None,
    base_frame: str | None,
    pose_topic: str | None,
    map_frame: str | None,
    robot: RobotDescription | None,
) -> ReadOptions:
    return ReadOptions(
        odom_topic=odom_topic,
        range_topics=tuple(range_topics),
        odom_frame=odom_frame,
        base_frame=base_frame,
        pose_topic=pose_topic,
        map_frame=map_frame,
        robot=robot,
    )
