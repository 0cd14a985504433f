"""The command line: the only module that imports click, prints, shows progress or exits.

Each command checks every precondition (inputs exist, outputs absent unless --force, options
consistent) before reading a byte, then calls a plain library function and reports. Library
errors become one ``Error: ...`` line: exit 1 for bad data or runtime failures, 2 for usage.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, ParamSpec, TypeVar

import click
import numpy as np
from tqdm import tqdm

from gridmap_cli import __version__
from gridmap_cli.convert import output_writer, write_log, writer_names
from gridmap_cli.errors import GridmapError, InputFileError, UsageError
from gridmap_cli.models.error_aware import ErrorAwareParams
from gridmap_cli.models.standard import StandardSonarParams
from gridmap_cli.odometry_error import OdometryError, load_odometry_error
from gridmap_cli.pipeline import MAPPING_MODES, BuildOptions, BuildResult, build_map
from gridmap_cli.readers import format_names, recording_sources, resolve_format
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.readers.ros_recording import read_recording
from gridmap_cli.robot import RobotDescription, load_robot, robot_from_log
from gridmap_cli.selection import EXCLUDE, Selection, apply_selection
from gridmap_cli.sync import POSE_SOURCES, select_poses
from gridmap_cli.writers import check_output
from gridmap_cli.writers.map_image import MAP_MODES, check_map_outputs, write_map
from gridmap_cli.writers.map_mcap import write_map_mcap
from gridmap_cli.writers.mcap_log import ENCODINGS

if TYPE_CHECKING:
    # calibrate and evaluate pull in scipy.ndimage (0.3 s): imported by their commands only,
    # so that `gridmap build` in a loop over many logs does not pay for them
    from gridmap_cli.calibrate import Calibration
    from gridmap_cli.evaluate import Evaluation

P = ParamSpec("P")
R = TypeVar("R")


class _UsageFailure(click.ClickException):
    """A usage error reported on one line (click's UsageError would print the usage block)."""

    exit_code = 2


def _handle_errors(func: Callable[P, R]) -> Callable[P, R]:
    """Turn library errors into one-line ``Error:`` messages; tracebacks only with --debug."""

    @functools.wraps(func)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            return func(*args, **kwargs)
        except GridmapError as exc:
            if _debug_enabled():
                raise
            if isinstance(exc, UsageError):
                raise _UsageFailure(str(exc)) from exc
            raise click.ClickException(str(exc)) from exc

    return wrapper


def _debug_enabled() -> bool:
    ctx = click.get_current_context(silent=True)
    root = ctx.find_root() if ctx is not None else None
    return bool(root is not None and root.obj and root.obj.get("debug"))


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="gridmap")
@click.option("--debug", is_flag=True, help="Show tracebacks instead of one-line errors.")
@click.pass_context
def cli(ctx: click.Context, debug: bool) -> None:
    """Occupancy-grid maps from robot logs of range readings and wheel odometry."""
    ctx.obj = {"debug": debug}


def _progress_bar(total: int, quiet: bool, desc: str) -> tqdm[Any]:
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


def _check_input(log: Path) -> None:
    """A log must exist: a file, or a folder (rosbag2)."""
    if not log.exists():
        raise InputFileError(log, "no such file")
    if not (log.is_file() or log.is_dir()):
        raise InputFileError(log, "not a regular file or folder")


def _check_output_folder(output: Path) -> None:
    folder = output.parent
    if not folder.is_dir():
        raise GridmapError(f"{output}: directory {folder} does not exist")


def _topic_options(func: Callable[P, R]) -> Callable[P, R]:
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


def _selection_options(sensors: bool = True) -> Callable[[Callable[P, R]], Callable[P, R]]:
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


def _warn(notes: tuple[str, ...], quiet: bool = False) -> None:
    if not quiet:
        for note in notes:
            click.echo(f"Warning: {note}", err=True)


def _read_options(
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


@cli.command()
@click.argument("logs", metavar="LOG...", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(path_type=Path, dir_okay=False),
    help="Map to write: an image (.png or .pgm) with its YAML beside it, or an MCAP (.mcap) "
    "holding a nav_msgs/msg/OccupancyGrid on /map.",
)
@click.option(
    "--robot",
    help="Robot preset (p3at, p3dx), robot YAML file or ARIA .p file; default: the log's own "
    "'# robot:' line.",
)
@click.option("--format", "log_format", type=click.Choice(format_names()), help="Log format.")
@click.option(
    "--resolution", type=float, default=0.05, show_default=True, help="Cell size in metres."
)
@click.option(
    "--mode",
    type=click.Choice(MAPPING_MODES),
    default="standard",
    show_default=True,
    help="Mapping algorithm.",
)
@click.option(
    "--map-mode",
    type=click.Choice(MAP_MODES),
    default="trinary",
    show_default=True,
    help="How occupancy is stored in the image (map_server modes).",
)
@click.option(
    "--occupied",
    type=float,
    default=0.65,
    show_default=True,
    help="Probability at or above which a cell is occupied.",
)
@click.option(
    "--free",
    type=float,
    default=0.25,
    show_default=True,
    help="Probability at or below which a cell is free.",
)
@click.option(
    "--no-echo-free",
    type=float,
    default=StandardSonarParams.no_echo_free_m,
    show_default=True,
    help="Metres of free space a max-range (no echo) reading clears; 0 ignores them.",
)
@click.option(
    "--pose",
    type=click.Choice(POSE_SOURCES),
    default="odometry",
    show_default=True,
    help="Map with the odometry, or with the log's global pose (ARIA robotGlobal, CSV true_*, "
    "CARMEN's corrected poses or TRUEPOS).",
)
@_topic_options
@_selection_options()
@click.option(
    "--odometry-error",
    "odometry_file",
    type=click.Path(path_type=Path, dir_okay=False),
    help="Error-aware mode: odometry-error YAML (what gridmap calibrate writes).",
)
@click.option(
    "--odometry-coefficient",
    "coefficients",
    multiple=True,
    metavar="NAME=VALUE",
    help="Error-aware mode: set one f/g coefficient (docs/odometry-error.md names them), e.g. "
    "range_m_per_m=0.01; overrides the file; repeatable.",
)
@click.option(
    "--trust-length",
    type=float,
    default=ErrorAwareParams.trust_length_m,
    show_default=True,
    help="Error-aware mode: pose error (m) at which a reading counts half.",
)
@click.option("--force", is_flag=True, help="Overwrite existing outputs.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary on stderr.")
@click.option("--json", "as_json", is_flag=True, help="Print a JSON summary on stdout.")
@_handle_errors
def build(
    logs: tuple[Path, ...],
    output: Path,
    robot: str | None,
    log_format: str | None,
    resolution: float,
    mode: str,
    map_mode: str,
    occupied: float,
    free: float,
    no_echo_free: float,
    pose: str,
    odom_topic: str | None,
    range_topics: tuple[str, ...],
    odom_frame: str | None,
    base_frame: str | None,
    pose_topic: str | None,
    map_frame: str | None,
    sensor_patterns: tuple[str, ...],
    start: str | None,
    end: str | None,
    odometry_file: Path | None,
    coefficients: tuple[str, ...],
    trust_length: float,
    force: bool,
    quiet: bool,
    as_json: bool,
) -> None:
    """Build an occupancy-grid map from LOG and write it as a map_server image + YAML, or as an
    OccupancyGrid in an MCAP file.

    LOG is a CSV, ARIA .2d, MCAP, ROS 1 .bag file or a rosbag2 folder. Several ROS recordings
    (say, odometry and scans recorded into separate bags) are merged by time into one.
    """
    started = time.perf_counter()
    if not (0.0 <= free < occupied <= 1.0):
        raise UsageError(f"need 0 <= --free < --occupied <= 1, got {free} and {occupied}")
    if not (resolution > 0.0 and math.isfinite(resolution)):
        raise UsageError(f"--resolution must be a positive number of metres, got {resolution}")
    try:
        sonar = StandardSonarParams(no_echo_free_m=no_echo_free)
    except ValueError as exc:
        raise UsageError(str(exc)) from exc
    error_aware, odometry_error = _error_aware_options(
        mode, odometry_file, coefficients, trust_length
    )
    selection = Selection.parse(sensor_patterns, start, end)
    to_mcap = output.suffix.lower() == ".mcap"
    if to_mcap:
        source = click.get_current_context().get_parameter_source("map_mode")
        if source is not None and source != click.core.ParameterSource.DEFAULT:
            raise UsageError("--map-mode applies to map images; an MCAP map holds 0..100 and -1")
        check_output(output, force)
    else:
        check_map_outputs(output, map_mode, force)
    _check_output_folder(output)
    robot_desc = load_robot(robot) if robot else None
    for log in logs:
        _check_input(log)
    read_options = _read_options(
        odom_topic, range_topics, odom_frame, base_frame, pose_topic, map_frame, robot_desc
    )
    sources = recording_sources(logs, log_format)
    if sources is None:
        fmt = resolve_format(logs[0], log_format)
        read_options.refuse_topic_flags(fmt.name.upper())
        data = fmt.read(logs[0], read_options)
    else:
        data = read_recording(sources, read_options).log
    data = select_poses(data, pose)
    if robot_desc is None:
        robot_desc = robot_from_log(logs[0], data.metadata)
    selected = apply_selection(data, selection, robot_desc)
    _warn(selected.notes, quiet)
    data = selected.log
    options = BuildOptions(
        resolution_m=resolution,
        mode=mode,
        sonar=sonar,
        error_aware=error_aware,
        odometry_error=odometry_error,
    )
    with _progress_bar(len(data.readings), quiet, "mapping") as bar:
        result = build_map(data, robot_desc, options, progress=bar.update)
    yaml_path: Path | None
    if to_mcap:
        # stamped at the last reading: the map is what the robot knew then
        stamp = int(data.readings.stamp_ns[-1]) if len(data.readings) else 0
        image_path = write_map_mcap(output, result.map, stamp_ns=stamp, force=force)
        yaml_path = None
    else:
        image_path, yaml_path = write_map(
            output, result.map, mode=map_mode, occupied_thresh=occupied, free_thresh=free,
            force=force,
        )  # fmt: skip
    elapsed = time.perf_counter() - started
    summary = _summary(result, image_path, yaml_path, elapsed, occupied, free)
    if as_json:
        click.echo(json.dumps(summary, indent=2))
    if not quiet:
        click.echo(_summary_line(summary), err=True)


def _error_aware_options(
    mode: str, odometry_file: Path | None, coefficients: tuple[str, ...], trust_length: float
) -> tuple[ErrorAwareParams, OdometryError | None]:
    """The error-aware model's settings from build's flags (usage errors before any reading)."""
    ctx = click.get_current_context()
    trust_given = ctx.get_parameter_source("trust_length") != click.core.ParameterSource.DEFAULT
    given = odometry_file is not None or bool(coefficients)
    if mode != "error-aware":
        if given or trust_given:
            raise UsageError(
                "--odometry-error, --odometry-coefficient and --trust-length apply to "
                "--mode error-aware"
            )
        return ErrorAwareParams(), None
    if not given:
        raise UsageError(
            "--mode error-aware needs the odometry error: --odometry-error FILE (gridmap "
            "calibrate writes one) or --odometry-coefficient NAME=VALUE"
        )
    try:
        params = ErrorAwareParams(trust_length_m=trust_length)
    except ValueError as exc:
        raise UsageError(f"--trust-length: {exc}") from exc
    names = [f.name for f in dataclasses.fields(OdometryError)]
    overrides: dict[str, float] = {}
    for item in coefficients:
        name, sep, text = item.partition("=")
        name = name.strip()
        if not sep or name not in names:
            raise UsageError(
                f"--odometry-coefficient {item!r}: expected NAME=VALUE, NAME one of "
                f"{', '.join(names)}"
            )
        try:
            overrides[name] = float(text)
        except ValueError:
            raise UsageError(f"--odometry-coefficient {item!r}: {text!r} is not a number") from None
    model = load_odometry_error(odometry_file) if odometry_file is not None else OdometryError()
    try:
        return params, dataclasses.replace(model, **overrides)
    except ValueError as exc:
        raise UsageError(f"--odometry-coefficient: {exc}") from exc


def _summary(
    result: BuildResult,
    image: Path,
    yaml_path: Path | None,
    seconds: float,
    occupied: float,
    free: float,
) -> dict[str, Any]:
    spec = result.map.spec
    prob = result.map.prob
    known = ~np.isnan(prob)
    return {
        "image": str(image),
        "yaml": str(yaml_path) if yaml_path is not None else None,
        "readings": {
            "total": result.sync.total,
            "used": result.sync.used,
            "skipped": result.sync.total - result.sync.used,
            "outside_odometry": result.sync.outside_odometry,
            "below_min_range": result.sync.below_min_range,
        },
        "map": {
            "width": spec.width,
            "height": spec.height,
            "resolution": spec.resolution_m,
            "origin": [spec.origin_x_m, spec.origin_y_m, 0.0],
        },
        "cells": {
            "observed": int(known.sum()),
            "occupied": int((prob[known] >= occupied).sum()),
            "free": int((prob[known] <= free).sum()),
        },
        "cell_updates": result.cell_updates,
        "seconds": round(seconds, 3),
    }


def _summary_line(s: dict[str, Any]) -> str:
    r, m = s["readings"], s["map"]
    skipped = ""
    if r["skipped"]:
        skipped = (
            f" ({r['skipped']:,} skipped: {r['outside_odometry']:,} outside the odometry's time "
            f"span, {r['below_min_range']:,} below minimum range)"
        )
    return (
        f"gridmap: {r['used']:,} of {r['total']:,} readings mapped{skipped}; "
        f"{m['width']} x {m['height']} cells at {m['resolution']} m "
        f"({m['width'] * m['resolution']:.1f} x {m['height'] * m['resolution']:.1f} m) "
        f"in {s['seconds']:.1f} s -> {s['image']}" + (f", {s['yaml']}" if s["yaml"] else "")
    )


@cli.command()
@click.argument("log", type=click.Path(path_type=Path))
@click.option("--robot", help="Robot preset, robot YAML file or ARIA .p file.")
@click.option("--format", "log_format", type=click.Choice(format_names()), help="Log format.")
@_topic_options
@_selection_options()
@click.option("--json", "as_json", is_flag=True, help="Print the description as JSON.")
@_handle_errors
def inspect(
    log: Path,
    robot: str | None,
    log_format: str | None,
    odom_topic: str | None,
    range_topics: tuple[str, ...],
    odom_frame: str | None,
    base_frame: str | None,
    pose_topic: str | None,
    map_frame: str | None,
    sensor_patterns: tuple[str, ...],
    start: str | None,
    end: str | None,
    as_json: bool,
) -> None:
    """Describe LOG (CSV, ARIA .2d, MCAP, ROS 1 bag or rosbag2 folder) and what build would
    make of it.

    Channels or columns, message counts, time span, rates, distance travelled, sensors and
    their mounting poses, and the topics, frames and robot build would use. Exits 1, after
    the description, when build would fail: the reason is build's own error.
    With --sensors, --start or --end: the part of LOG they select, as build would map it.
    """
    from gridmap_cli.describe import describe_log, render_text

    selection = Selection.parse(sensor_patterns, start, end)
    robot_desc = load_robot(robot) if robot else None
    _check_input(log)
    fmt = resolve_format(log, log_format)
    read_options = _read_options(
        odom_topic, range_topics, odom_frame, base_frame, pose_topic, map_frame, robot_desc
    )
    if fmt.sources is None:
        read_options.refuse_topic_flags(fmt.name.upper())
    description = describe_log(log, fmt, read_options, selection)
    click.echo(json.dumps(description, indent=2) if as_json else render_text(description))
    if not description["build"]["ready"]:
        # the description is printed; the verdict is the line build would print, and its exit
        click.echo(f"Error: {description['build']['problem']}", err=True)
        sys.exit(1)


@cli.command()
@click.argument("world", type=click.Path(path_type=Path, dir_okay=False))
@click.argument("path_file", metavar="PATH", type=click.Path(path_type=Path, dir_okay=False))
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(path_type=Path, dir_okay=False),
    help="Log to write: .csv (gridmap CSV), .2d (ARIA with sonar lines) or .mcap.",
)
@click.option(
    "--format",
    "log_format",
    type=click.Choice(writer_names()),
    help="Log format; default: from the output's extension.",
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
@click.option("--force", is_flag=True, help="Overwrite an existing output.")
@click.option("-q", "--quiet", is_flag=True, help="No summary on stderr.")
@_handle_errors
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
) -> None:
    """Drive a simulated robot along PATH in WORLD and write a log with ground truth.

    WORLD is a map_server map (YAML + image); PATH a waypoint file (see docs/simulator.md).
    """
    from gridmap_cli.mapfile import load_map
    from gridmap_cli.sim.path import load_path
    from gridmap_cli.sim.simulate import simulate as run_simulation
    from gridmap_cli.sim.world import World

    if not (rate > 0.0 and math.isfinite(rate)):
        raise UsageError(f"--rate must be a positive number of Hz, got {rate}")
    if not (drift >= 0.0 and math.isfinite(drift)):
        raise UsageError(f"--drift must be a finite number >= 0, got {drift}")
    if duration is not None and not (duration > 0.0 and math.isfinite(duration)):
        raise UsageError(f"--duration must be a positive number of seconds, got {duration}")
    writer = output_writer(output, log_format, encoding)
    check_output(output, force)
    _check_output_folder(output)
    robot_desc = load_robot(robot)
    for given in (world, path_file):
        if not given.is_file():
            raise InputFileError(given, "no such file")
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
    write_log(log, output, writer, robot_desc, encoding)
    if not quiet:
        zmax = np.asarray([s.max_range_m for s in robot_desc.sensors])
        no_echo = int(np.count_nonzero(log.readings.range_m >= zmax[log.readings.sensor]))
        span = (log.poses.stamp_ns[-1] - log.poses.stamp_ns[0]) / 1e9
        click.echo(
            f"gridmap: simulated {span:.1f} s: {len(log.poses):,} poses, "
            f"{len(log.readings):,} readings ({no_echo:,} no echo) -> {output}",
            err=True,
        )


@cli.command()
@click.argument("log", type=click.Path(path_type=Path, dir_okay=False))
@click.option(
    "-o",
    "--output",
    type=click.Path(path_type=Path, dir_okay=False),
    help="Odometry-error YAML to write (what build takes); default: print only.",
)
@click.option("--format", "log_format", type=click.Choice(format_names()), help="Log format.")
@click.option(
    "--window",
    "window_m",
    type=float,
    default=1.0,
    show_default=True,
    help="Metres of travel per comparison window.",
)
@click.option(
    "--window-turn",
    "window_deg",
    type=float,
    default=90.0,
    show_default=True,
    help="Degrees of turning that also close a window (for turns on the spot).",
)
@click.option(
    "--sonar-error",
    type=float,
    default=0.01,
    show_default=True,
    help="The sonar's relative range error k to write into the file (0.01 = 1 %).",
)
@_selection_options(sensors=False)
@click.option("--force", is_flag=True, help="Overwrite an existing output.")
@click.option("--json", "as_json", is_flag=True, help="Print the figures as JSON on stdout.")
@_handle_errors
def calibrate(
    log: Path,
    output: Path | None,
    log_format: str | None,
    window_m: float,
    window_deg: float,
    sonar_error: float,
    start: str | None,
    end: str | None,
    force: bool,
    as_json: bool,
) -> None:
    """Estimate the odometry-error coefficients of LOG against its ground truth.

    LOG must carry ground truth (CSV true_x/true_y/true_theta, ARIA robotGlobal). Odometry and
    truth are compared over consecutive windows of travel; see docs/odometry-error.md.
    """
    from gridmap_cli.calibrate import calibrate as calibrate_log
    from gridmap_cli.odometry_error import save_odometry_error

    if not (window_m > 0.0 and math.isfinite(window_m)):
        raise UsageError(f"--window must be a positive number of metres, got {window_m}")
    if not (window_deg > 0.0 and math.isfinite(window_deg)):
        raise UsageError(f"--window-turn must be a positive number of degrees, got {window_deg}")
    if not (sonar_error >= 0.0 and math.isfinite(sonar_error)):
        raise UsageError(f"--sonar-error must be a finite number >= 0, got {sonar_error}")
    selection = Selection.parse((), start, end)
    if output is not None:
        check_output(output, force)
        _check_output_folder(output)
    if not log.is_file():
        raise InputFileError(log, "no such file" if not log.exists() else "not a regular file")
    data = resolve_format(log, log_format).read(log)
    data = apply_selection(data, selection, None, need_readings=False).log
    result = calibrate_log(data, window_m, math.radians(window_deg), sonar_error)
    if output is not None:
        save_odometry_error(
            result.model,
            output,
            comments=[
                f"gridmap {__version__} calibrate {log.name}: {result.windows} windows of "
                f"{window_m:g} m or {window_deg:g} deg, {result.driven_m:.1f} m driven, "
                f"{math.degrees(result.turned_rad):.0f} deg turned",
            ],
        )
    if as_json:
        doc = {"log": str(log), "output": str(output) if output else None, **result.as_dict()}
        click.echo(json.dumps(doc, indent=2))
    else:
        click.echo(_calibration_table(str(log), result, output))


def _calibration_table(log: str, c: Calibration, output: Path | None) -> str:
    m = c.model

    def maybe(ok: bool, text: str) -> str:
        return text if ok else "not estimated"

    rows = [
        (
            "distance scale error",
            maybe(c.distance_estimated, f"{100 * c.scale_error:+.2f} % of distance"),
            f"range_m_per_m: {m.range_m_per_m:.4g}",
        ),
        (
            "distance random walk",
            maybe(c.distance_estimated, f"{100 * m.range_m_per_sqrt_m:.2f} cm after 1 m"),
            f"range_m_per_sqrt_m: {m.range_m_per_sqrt_m:.4g}",
        ),
        (
            "turn scale error",
            maybe(c.turn_estimated, f"{100 * c.turn_scale_error:+.2f} % of rotation"),
            f"bearing_rad_per_rad: {m.bearing_rad_per_rad:.4g}",
        ),
        (
            "turn random walk",
            maybe(
                c.turn_estimated,
                f"{math.degrees(m.bearing_rad_per_sqrt_rad):.2f} deg after 1 rad",
            ),
            f"bearing_rad_per_sqrt_rad: {m.bearing_rad_per_sqrt_rad:.4g}",
        ),
        (
            "heading drift",
            maybe(c.drift_estimated, f"{math.degrees(c.heading_drift_rad_per_m):+.3f} deg/m"),
            f"heading_drift_rad_per_m: {m.heading_drift_rad_per_m:.4g}",
        ),
    ]
    lines = [
        f"{log}: {c.windows} windows ({c.driving_windows} of {c.window_m:g} m, "
        f"{c.turning_windows} of {math.degrees(c.window_rad):g} deg turning), "
        f"{c.driven_m:.1f} m driven, {math.degrees(c.turned_rad):.0f} deg turned",
        "",
        f"{'':22s} {'odometry vs truth':24s} file",
    ]
    lines += [f"{a:22s} {b:24s} {f}" for a, b, f in rows]
    lines += [
        "",
        f"residual per window (rms, systematic terms removed): distance "
        f"{100 * c.distance_residual_m:.2f} cm, heading "
        f"{math.degrees(c.heading_residual_rad):.3f} deg",
        f"wrote {output}" if output is not None else "(give -o FILE to write these)",
    ]
    return "\n".join(lines)


@cli.command()
@click.argument("log", type=click.Path(path_type=Path, dir_okay=False))
@click.argument("output", type=click.Path(path_type=Path, dir_okay=False))
@click.option(
    "--format",
    "out_format",
    type=click.Choice(writer_names()),
    help="Output format; default: from OUTPUT's extension (.csv, .2d, .mcap).",
)
@click.option("--input-format", type=click.Choice(format_names()), help="Format of LOG.")
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
@click.option("--force", is_flag=True, help="Overwrite an existing output.")
@click.option("-q", "--quiet", is_flag=True, help="No summary on stderr.")
@_handle_errors
def convert(
    log: Path,
    output: Path,
    out_format: str | None,
    input_format: str | None,
    encoding: str | None,
    robot: str | None,
    force: bool,
    quiet: bool,
) -> None:
    """Convert LOG to OUTPUT between gridmap CSV, ARIA .2d and MCAP.

    What the output format cannot hold is refused, never dropped (see schemas/*.md).
    """
    writer = output_writer(output, out_format, encoding)
    check_output(output, force)
    _check_output_folder(output)
    robot_desc = load_robot(robot) if robot else None
    if not log.is_file():
        raise InputFileError(log, "no such file" if not log.exists() else "not a regular file")
    fmt = resolve_format(log, input_format)
    data = fmt.read(log)
    if robot_desc is None and writer.needs_sensors:
        known = {s.name for s in data.sensors or ()}
        if not set(data.sensor_names) <= known:
            robot_desc = robot_from_log(log, data.metadata)
    write_log(data, output, writer, robot_desc, encoding)
    if not quiet:
        what = writer.name + (f" ({encoding or 'json'})" if writer.name == "mcap" else "")
        click.echo(
            f"gridmap: {fmt.name} -> {what}: {len(data.poses):,} poses, "
            f"{len(data.readings):,} readings"
            f"{', ground truth' if data.truth is not None else ''} -> {output}",
            err=True,
        )


@cli.command()
@click.argument("map_yaml", metavar="MAP.yaml", type=click.Path(path_type=Path, dir_okay=False))
@click.option(
    "--truth",
    "truth_yaml",
    required=True,
    type=click.Path(path_type=Path, dir_okay=False),
    help="Ground-truth world map (map_server YAML, e.g. samples/worlds/*.yaml).",
)
@click.option(
    "--log",
    "log_path",
    type=click.Path(path_type=Path, dir_okay=False),
    help="The log the map was built from (with ground truth): places the odometry frame in the "
    "world and limits the scores to the cells its sensors could have sensed.",
)
@click.option("--format", "log_format", type=click.Choice(format_names()), help="Log format.")
@click.option(
    "--robot",
    help="Robot preset, YAML or ARIA .p file for the sensors of --log; default: its '# robot:'.",
)
@click.option(
    "--frame",
    type=click.Choice(["odometry", "world"]),
    default="odometry",
    show_default=True,
    help="Frame of the map: odometry (built from odometry: the frame starts at the log's first "
    "true pose, needs --log) or world (built with --pose global).",
)
@_selection_options()
@click.option("--json", "as_json", is_flag=True, help="Print the scores as JSON on stdout.")
@click.option(
    "--plot",
    type=click.Path(path_type=Path, dir_okay=False),
    help="Write a PNG: the map with the true walls, and a reliability diagram (needs matplotlib).",
)
@click.option("--force", is_flag=True, help="Overwrite an existing --plot output.")
@_handle_errors
def evaluate(
    map_yaml: Path,
    truth_yaml: Path,
    log_path: Path | None,
    log_format: str | None,
    robot: str | None,
    frame: str,
    sensor_patterns: tuple[str, ...],
    start: str | None,
    end: str | None,
    as_json: bool,
    plot: Path | None,
    force: bool,
) -> None:
    """Score the map MAP.yaml against the ground-truth world of --truth.

    Scores (docs/evaluation.md): NLL and Brier score of the true occupancy under the map's
    probabilities, reliability table and expected calibration error, occupied-cell precision,
    recall and F1 within one cell, coverage. Unknown cells count as p = 0.5. With --log the
    region scored is the world cells the log's sensors could have sensed from the true path;
    without it, the whole world map.

    A map built from odometry is in the odometry frame, which starts at the log's first true
    pose: --log places it in the world. A map built with --pose global is in the world frame
    already: give --frame world.
    """
    from gridmap_cli import evaluate as ev
    from gridmap_cli.sync import sensors_for_log

    for given, what in ((map_yaml, "MAP"), (truth_yaml, "--truth")):
        if given.suffix.lower() not in (".yaml", ".yml"):
            raise UsageError(
                f"{given}: {what} must be a map's YAML file (the image is named inside it)"
            )
    if frame == "odometry" and log_path is None:
        raise UsageError(
            "a map in the odometry frame needs --log (its first true pose places the frame in "
            "the world); give --log, or --frame world for a map built with --pose global"
        )
    selection = Selection.parse(sensor_patterns, start, end)
    if selection and log_path is None:
        raise UsageError("--sensors, --start and --end choose part of --log; give --log")
    if plot is not None:
        from gridmap_cli.evaluate_plot import check_plotting

        check_plotting()
        if plot.suffix.lower() != ".png":
            raise UsageError(f"{plot}: --plot writes a PNG; name it .png")
        check_output(plot, force)
        _check_output_folder(plot)
    robot_desc = load_robot(robot) if robot else None
    for given in (map_yaml, truth_yaml, *([log_path] if log_path else [])):
        if not given.is_file():
            raise InputFileError(given, "no such file" if not given.exists() else "not a file")
    truth = ev.load_truth(truth_yaml)
    pmap = ev.load_probability_map(map_yaml)
    map_to_world = (0.0, 0.0, 0.0)
    region = None
    if log_path is not None:
        data = resolve_format(log_path, log_format).read(log_path)
        data.require_truth("evaluate needs the true path")  # before the robot is looked up
        if robot_desc is None:
            robot_desc = robot_from_log(log_path, data.metadata)
        selected = apply_selection(data, selection, robot_desc)
        _warn(selected.notes)
        data = selected.log
        true_path = data.require_truth("evaluate needs the true path")
        sensors = sensors_for_log(data, robot_desc)
        if frame == "odometry":
            map_to_world = ev.odometry_frame_in_world(data)
        region = ev.sensed_region(truth.world, true_path, sensors)
    result = ev.evaluate_map(pmap, truth.walls, truth.spec, region, map_to_world)
    if plot is not None:
        from gridmap_cli.evaluate_plot import plot_evaluation

        plot_evaluation(
            plot,
            result,
            truth.walls,
            region if region is not None else np.ones(truth.spec.shape, dtype=bool),
            truth.spec,
            title=f"{map_yaml.name} vs {truth_yaml.name}",
        )
    if as_json:
        doc = {
            "map": str(map_yaml),
            "truth": str(truth_yaml),
            "log": str(log_path) if log_path else None,
            "frame": frame,
            "map_to_world": list(map_to_world),
            "region": "sensed from the true path" if log_path else "whole world",
            **result.as_dict(),
        }
        click.echo(json.dumps(_nan_to_none(doc), indent=2, allow_nan=False))
    else:
        click.echo(_evaluation_table(map_yaml, truth_yaml, log_path, map_to_world, result))
    if plot is not None:
        click.echo(f"gridmap: plot written to {plot}", err=True)


def _nan_to_none(value: Any) -> Any:
    """JSON has no NaN: undefined scores (an empty bin, no occupied cell) become null."""
    if isinstance(value, float) and math.isnan(value):
        return None
    if isinstance(value, dict):
        return {k: _nan_to_none(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_nan_to_none(v) for v in value]
    return value


def _evaluation_table(
    map_yaml: Path,
    truth_yaml: Path,
    log_path: Path | None,
    map_to_world: tuple[float, float, float],
    e: Evaluation,
) -> str:
    x, y, th = map_to_world
    where = (
        f"{e.cells:,} cells the sensors of {log_path.name} could have sensed"
        if log_path
        else f"all {e.cells:,} cells of the world"
    )

    def num(v: float, fmt: str) -> str:
        return "n/a" if math.isnan(v) else format(v, fmt)

    lines = [
        f"{map_yaml} against {truth_yaml}",
        f"map frame in the world: x {x:.3f} m, y {y:.3f} m, theta {math.degrees(th):.2f} deg",
        f"scored over {where} ({e.occupied_cells:,} truly occupied)",
        "",
        f"NLL (nats per cell)   {e.nll:.4f}",
        f"Brier score           {e.brier:.4f}",
        f"ECE (10 bins)         {e.ece:.4f}",
        f"occupied (p >= {e.occupied_thresh:g}), one cell of tolerance: precision "
        f"{num(e.precision, '.3f')}, recall {num(e.recall, '.3f')}, F1 {num(e.f1, '.3f')} "
        f"({e.predicted_occupied:,} cells called occupied)",
        f"coverage              {e.coverage:.3f} of the region known",
        "",
        "reliability   cells   mean p   occupied",
    ]
    for b in e.reliability:
        lines.append(
            f"{b.lower:.1f}-{b.upper:.1f}  {b.count:8,d}   {num(b.mean_predicted, '6.3f'):>6s}"
            f"   {num(b.observed_frequency, '6.3f'):>8s}"
        )
    return "\n".join(lines)


def main() -> None:
    """Console-script entry point."""
    cli(prog_name="gridmap")
