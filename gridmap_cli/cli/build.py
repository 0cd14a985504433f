"""``gridmap build``: logs in, a map_server map (or an MCAP OccupancyGrid) out.

The command, its output options (-o, -f, --fmt, --draw-path) and --fuse; what and how to map
is in :mod:`.map_options`, what it says of the map in :mod:`.build_report`.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import TYPE_CHECKING

import click

from gridmap_cli.cli.build_report import (
    build_summary,
    fused_line,
    fused_summary,
    report,
    summary_line,
    undecided_note,
)
from gridmap_cli.cli.common import (
    STDIO,
    check_input,
    check_map_folder,
    check_not_folder,
    handle_errors,
    progress_bar,
    read_input,
    stdout_file,
    warn,
)
from gridmap_cli.cli.map_options import (
    build_settings,
    error_samples_option,
    image_format_option,
    map_options,
)
from gridmap_cli.cli.progress import StageBars, reading
from gridmap_cli.errors import MixedLogsError, NotRecordingFolderError, UsageError
from gridmap_cli.heap import TRIM_EVERY_BATCHES, TrimEvery, keep_scratch_memory, release_free_memory
from gridmap_cli.mapping.pipeline import BuildOptions, build_map, reference_spread_note
from gridmap_cli.mapping.selection import Selection, apply_selection
from gridmap_cli.poses.sync import select_poses
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import load_robot, preset_names, robot_from_log
from gridmap_cli.runs.executors import EXECUTORS, check_dask, fuse_dask, fuse_local
from gridmap_cli.runs.fuse import FuseJob, Partial, fused_map, parse_initial_pose
from gridmap_cli.writers import check_output
from gridmap_cli.writers.map_image import IMAGE_FORMATS, check_map_outputs, write_map

if TYPE_CHECKING:
    from gridmap_cli.poses.correction.scan_match import ScanMatch
    from gridmap_cli.poses.uncertainty.pose_belief import PoseBelief
    from gridmap_cli.writers.preview import DrawnTrack

#: --pose values whose track the laser makes: the readings are held, and --fuse refuses them
LASER_POSES = ("scan-matched", "slam")


@click.command()
@click.argument(
    "logs",
    metavar="LOG...",
    nargs=-1,
    required=True,
    type=click.Path(path_type=Path, readable=False),
)
@click.option(
    "-o",
    "--output",
    type=click.Path(path_type=Path, readable=False),
    help="Map to write: an image (.png, .pgm or .bmp) with its YAML beside it, or an MCAP "
    "(.mcap) holding a nav_msgs/msg/OccupancyGrid on /map; - writes the image alone to standard "
    "output (with --fmt).",
)
@click.option(
    "-f",
    "basename",
    type=click.Path(path_type=Path, readable=False),
    help="As map_saver_cli: write BASENAME.pgm (or --fmt) and BASENAME.yaml; instead of -o.",
)
@image_format_option(
    "As map_saver_cli: the image format for -f [default: pgm]; with -o it must match."
)
@map_options
@click.option(
    "--draw-path",
    is_flag=True,
    help="Also write a preview PNG (MAP_path.png): the map with unknown in pale blue, the "
    "odometry in red, the reference track in green, a scan-matched track in purple; never the "
    "map_server image itself.",
)
@click.option(
    "--fuse",
    is_flag=True,
    help="Several logs of one place (separate runs, any format) into one map, their evidence "
    "added; they must share a frame: --pose global, or one --initial-pose per log.",
)
@click.option(
    "--initial-pose",
    "initial_poses",
    multiple=True,
    metavar="X,Y,YAW_DEG",
    help="--fuse: where each log's first pose is in the common frame (metres, degrees); one "
    "per log, in the order of the logs.",
)
@click.option(
    "--executor",
    type=click.Choice(EXECUTORS),
    default="local",
    show_default=True,
    help="--fuse: map the logs in local processes, or on a Dask cluster (--scheduler).",
)
@click.option("--scheduler", metavar="ADDRESS", help="Dask scheduler for --executor dask.")
@click.option("-j", "--jobs", type=click.IntRange(min=1), default=1, show_default=True,
              help="Processes mapping at once: the readings of one log in standard mode (the "
              "map is the same bytes for every N; error-aware mode maps in one process when "
              "the compiled kernels are built), or with --fuse and the local executor, the "
              "logs.")  # fmt: skip
@error_samples_option
@click.option("--force", is_flag=True, help="Overwrite existing outputs.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary on stderr.")
@click.option("--json", "as_json", is_flag=True, help="Print a JSON summary on stdout.")
@handle_errors
def build(
    logs: tuple[Path, ...],
    output: Path | None,
    basename: Path | None,
    image_format: str | None,
    robot: str | None,
    log_format: str | None,
    resolution: float,
    mode: str,
    map_mode: str,
    occupied: float,
    free: float,
    no_echo_free: float | None,
    pose: str,
    topics: ReadOptions,
    sensor_patterns: tuple[str, ...],
    start: str | None,
    end: str | None,
    odometry_file: Path | None,
    coefficients: tuple[str, ...],
    trust_length: float,
    max_spread_deg: float,
    draw_path: bool,
    fuse: bool,
    initial_poses: tuple[str, ...],
    executor: str,
    scheduler: str | None,
    jobs: int,
    error_samples: int | None,
    max_range: float | None,
    correct_odometry: bool | None,
    force: bool,
    quiet: bool,
    as_json: bool,
) -> None:
    """Build an occupancy-grid map from LOG and write it as a map_server image + YAML, or as an
    OccupancyGrid in an MCAP file.

    LOG is a CSV, ARIA .2d, CARMEN (.log, .clf, .gz), MCAP, ROS 1 .bag file or rosbag2 folder, or -
    (a text log on standard input). Several ROS recordings
    (say, odometry and scans recorded into separate bags) are merged by time into one; with
    --fuse, several logs (separate runs through one place) are each mapped and their evidence
    added (README: "Several runs of one place").
    """
    started = time.perf_counter()
    output = map_output(output, basename, image_format)
    settings = build_settings(resolution, mode, occupied, free, no_echo_free, max_range, pose,
                              odometry_file, coefficients, trust_length, max_spread_deg,
                              error_samples, correct_odometry, fuse)  # fmt: skip
    selection = Selection.parse(sensor_patterns, start, end)
    to_stdout = output == STDIO
    if to_stdout:
        _check_stdout(image_format, as_json, draw_path)
    placed = _fuse_options(fuse, logs, initial_poses, pose, mode, executor, scheduler, jobs)
    if fuse and (to_stdout or draw_path or pose in LASER_POSES):
        raise UsageError(
            "--fuse writes one map file from placed logs: give -o FILE, no --draw-path, and "
            "--pose global or odometry"
        )
    to_mcap = output.suffix.lower() == ".mcap"
    if to_mcap:
        source = click.get_current_context().get_parameter_source("map_mode")
        if source is not None and source != click.core.ParameterSource.DEFAULT:
            raise UsageError("--map-mode applies to map images; an MCAP map holds 0..100 and -1")
    else:  # the name and mode, before any input
        check_map_outputs(Path(f"map.{image_format}") if to_stdout else output, map_mode, True)
    robot_desc = load_robot(robot) if robot else None
    for log in logs:  # the command line first, then the inputs, then the outputs
        check_input(log)
    if to_mcap:
        check_output(output, force)
    elif not to_stdout:
        check_map_outputs(output, map_mode, force)
    check_map_folder(output)
    preview = output.with_name(f"{output.stem}_path.png") if draw_path else None
    if preview is not None:
        check_output(preview, force)
    read_options = dataclasses.replace(topics, robot=robot_desc)
    if fuse:
        fuse_jobs = [
            FuseJob(log=log.resolve(), log_format=log_format,
                    read_options=dataclasses.replace(read_options, robot=None), pose=pose,
                    initial_pose=first, selection=selection,
                    robot_spec=_robot_spec(robot), options=BuildOptions(resolution_m=resolution,
                                                                         sonar=settings.sonar,
                                                                         ray=settings.ray))
            for log, first in zip(logs, placed, strict=True)
        ]  # fmt: skip
        if scheduler is not None:
            total = fuse_dask(fuse_jobs, scheduler)
        else:
            total = fuse_local(fuse_jobs, jobs)
        warn(total.notes, quiet)
        _write_fused(total, output, to_mcap, map_mode, occupied, free, force, started, quiet,
                     as_json, len(logs))  # fmt: skip
        return
    keep_scratch_memory()  # every check passed: from here on, the build's own process
    # a long log's readings stay in its file, read again for each pass, unless scan matching
    # or a time window needs them held
    stream = pose not in LASER_POSES and selection.start is None and selection.end is None
    with reading(_names(logs), quiet):
        whole = _read_logs(logs, log_format, dataclasses.replace(read_options, stream=stream))
    data = whole
    if robot_desc is None:
        robot_desc = robot_from_log(logs[0], data.metadata)
    match: ScanMatch | None = None
    slam_summary: dict[str, object] | None = None
    belief: PoseBelief | None = None
    if pose == "scan-matched":
        from gridmap_cli.poses.correction.scan_match import (
            scan_matched_log,
        )  # scipy, small_gicp: only here

        with StageBars(quiet) as bars:
            data, match = scan_matched_log(data, robot_desc, progress=bars)
    elif pose == "slam":
        from gridmap_cli.poses.correction.slam import slam_corrected_log  # gtsam: only here

        with StageBars(quiet) as bars:
            data, slam = slam_corrected_log(data, robot_desc, progress=bars)
        slam_summary = slam.summary()
        if mode == "error-aware":  # the graph's marginals and draws, not the odometry's
            from gridmap_cli.poses.uncertainty.pose_belief import slam_belief

            belief = slam_belief(slam, settings.error_samples, settings.error_seed)
            slam_summary["belief_noise_scale"] = [round(f, 3) for f in belief.scale]
        if slam.warning:
            warn((f"--pose slam: {slam.warning}",), quiet)
    else:
        data = select_poses(data, pose)
    note = reference_spread_note(pose, settings)
    if note is not None:
        warn((note,), quiet)
    if preview is None:  # the other tracks are drawn only; let them go (56 bytes a row)
        whole = data = dataclasses.replace(data, truth=None)
    selected = apply_selection(data, selection, robot_desc)
    warn(selected.notes, quiet)
    data = selected.log
    options = dataclasses.replace(settings, jobs=jobs, pose_belief=belief)
    with progress_bar(data.reading_count, quiet, "mapping") as bar:
        trim = TrimEvery(TRIM_EVERY_BATCHES)

        def mapped(readings: int) -> None:
            bar.update(readings)
            trim()

        result = build_map(data, robot_desc, options, mapped, release_free_memory)
    weak = result.map.weak_evidence_note(occupied, free) if map_mode == "trinary" else None
    if weak is not None and not to_mcap:
        warn((weak,), quiet)
    elif mode == "error-aware" and map_mode == "trinary" and not to_mcap:
        warn(undecided_note(result.map.prob, occupied, free), quiet)
    yaml_path: Path | None
    if not to_stdout:
        output.parent.mkdir(parents=True, exist_ok=True)  # checked: a folder, or none yet
    if to_mcap:
        # stamped at the last reading: the map is what the robot knew then
        stamp = data.reading_span()[1] if data.reading_count else 0
        from gridmap_cli.writers.map_mcap import write_map_mcap  # the MCAP writer only when asked

        image_path = write_map_mcap(
            output, result.map, stamp_ns=stamp, force=force, thresholds=(occupied, free)
        )
        yaml_path = None
    elif to_stdout:
        with stdout_file(f"map.{image_format}") as image:
            write_map(image, result.map, mode=map_mode, occupied_thresh=occupied, free_thresh=free)
        image_path, yaml_path = STDIO, None
    else:
        image_path, yaml_path = write_map(
            output, result.map, mode=map_mode, occupied_thresh=occupied, free_thresh=free,
            force=force,
        )  # fmt: skip
    if preview is not None:
        from gridmap_cli.writers.preview import write_preview  # only --draw-path draws

        write_preview(preview, result.map, _tracks(whole, data, pose))
    elapsed = time.perf_counter() - started
    summary = build_summary(result, image_path, yaml_path, elapsed, occupied, free)
    if preview is not None:
        summary["preview"] = str(preview)
    if match is not None:
        summary["scan_match"] = match.summary()
    if slam_summary is not None:
        summary["slam"] = slam_summary
    if settings.correct_odometry:
        summary["odometry_corrected"] = True
    report(summary, summary_line(summary), as_json, quiet)


def _names(logs: tuple[Path, ...]) -> str:
    """The logs as the reading stage names them."""
    return logs[0].name if len(logs) == 1 else f"{len(logs)} logs"


def _read_logs(logs: tuple[Path, ...], log_format: str | None, options: ReadOptions) -> RangeLog:
    """The log(s) to map; a folder of logs or several text logs are pointed to batch (one map
    per log) and --fuse (one map of several runs)."""
    try:
        return read_input(logs, log_format, options)
    except NotRecordingFolderError as exc:
        hint = f"gridmap batch {exc.path} -o OUTDIR maps each log in a folder"
        raise NotRecordingFolderError(exc.path, f"{exc.detail}; {hint}") from exc
    except MixedLogsError as exc:
        raise MixedLogsError(
            f"{exc}; gridmap batch maps each log on its own, and build --fuse maps several "
            "runs through one place into one map"
        ) from exc


def _tracks(whole: RangeLog, mapped: RangeLog, pose: str) -> list[DrawnTrack]:
    """The track the map was built with, where it is, and the log's other tracks (odometry,
    reference) placed on it by their first common pose."""
    from gridmap_cli.writers.preview import (
        ODOMETRY_RGB,
        REFERENCE_RGB,
        SCAN_MATCHED_RGB,
        drawn,
        placed_at,
    )

    if pose == "odometry":
        others = [(whole.truth, REFERENCE_RGB)]
        colour = ODOMETRY_RGB
    elif pose == "global":
        others = [(whole.poses, ODOMETRY_RGB)]
        colour = REFERENCE_RGB
    else:
        others = [(whole.poses, ODOMETRY_RGB), (whole.truth, REFERENCE_RGB)]
        colour = SCAN_MATCHED_RGB
    placed = [placed_at(track, mapped.poses, rgb) for track, rgb in others if track is not None]
    return [t for t in placed if t is not None] + [drawn(mapped.poses, colour)]


def _check_stdout(image_format: str | None, as_json: bool, draw_path: bool) -> None:
    """``-o -``: the image alone goes to standard output (no YAML: give -o FILE for it)."""
    if image_format is None:
        raise UsageError("-o - writes the map image to standard output: give --fmt pgm|png|bmp")
    if as_json:
        raise UsageError("-o - writes the map image to standard output; --json would mix with it")
    if draw_path:
        raise UsageError("--draw-path writes a file beside the map: give -o FILE, not -o -")


def map_output(output: Path | None, basename: Path | None, image_format: str | None) -> Path:
    """The map to write: ``-o`` as given, or map_saver_cli's ``-f BASENAME`` + ``--fmt`` (a
    BASENAME ending in an image extension is the image itself)."""
    if (output is None) == (basename is None):
        raise UsageError("give the map to write: -o FILE or -f BASENAME (one of them)")
    if output == STDIO:
        return output
    check_not_folder(output if output is not None else basename)  # type: ignore[arg-type]
    if basename is not None:
        given = basename.suffix.lower().lstrip(".")
        if given not in IMAGE_FORMATS:
            return basename.with_name(f"{basename.name}.{image_format or 'pgm'}")
        # -f map.pgm: the extension picks the format, and is not doubled (map.pgm.pgm)
        if image_format is not None and image_format != given:
            raise UsageError(f"--fmt {image_format} does not match -f {basename}")
        return basename
    assert output is not None
    if image_format is not None and output.suffix.lower() != f".{image_format}":
        raise UsageError(f"--fmt {image_format} does not match -o {output}")
    return output


def _fuse_options(
    fuse: bool,
    logs: tuple[Path, ...],
    initial_poses: tuple[str, ...],
    pose: str,
    mode: str,
    executor: str,
    scheduler: str | None,
    jobs: int,
) -> list[tuple[float, float, float] | None]:
    """Usage checks of --fuse and its options; the initial pose of each log (or None)."""
    ctx = click.get_current_context()
    given = [
        name for name in ("initial_poses", "executor", "scheduler")
        if ctx.get_parameter_source(name) != click.core.ParameterSource.DEFAULT
    ]  # fmt: skip
    if not fuse:
        if given:
            flags = ", ".join("--" + n.replace("_poses", "-pose").replace("_", "-") for n in given)
            raise UsageError(f"{flags}: only with --fuse")
        return [None] * len(logs)
    if mode != "standard":
        raise UsageError("--fuse adds log-odds evidence: it takes --mode standard only")
    if initial_poses and pose == "global":
        raise UsageError("--initial-pose places odometry; with --pose global the logs are placed")
    if pose != "global" and len(initial_poses) != len(logs):
        raise UsageError(
            f"--fuse needs the logs in one frame: --pose global, or one --initial-pose per log "
            f"(got {len(initial_poses)} for {len(logs)} logs)"
        )
    if executor == "dask":
        if scheduler is None:
            raise UsageError("--executor dask needs --scheduler ADDRESS (tcp://host:8786)")
        check_dask()
    elif scheduler is not None:
        raise UsageError("--scheduler applies to --executor dask")
    if pose == "global":
        return [None] * len(logs)
    return [parse_initial_pose(text) for text in initial_poses]


def _robot_spec(robot: str | None) -> str | None:
    """--robot as the workers can load it: a preset name, or an absolute path."""
    if robot is None or robot in preset_names():
        return robot
    return str(Path(robot).resolve())


def _write_fused(
    total: Partial,
    output: Path,
    to_mcap: bool,
    map_mode: str,
    occupied: float,
    free: float,
    force: bool,
    started: float,
    quiet: bool,
    as_json: bool,
    n_logs: int,
) -> None:
    omap = fused_map(total)
    yaml_path: Path | None = None
    output.parent.mkdir(parents=True, exist_ok=True)  # checked: a folder, or none yet
    if to_mcap:
        from gridmap_cli.writers.map_mcap import write_map_mcap  # the MCAP writer only when asked

        image_path = write_map_mcap(
            output, omap, stamp_ns=0, force=force, thresholds=(occupied, free)
        )
    else:
        image_path, yaml_path = write_map(
            output, omap, mode=map_mode, occupied_thresh=occupied, free_thresh=free, force=force
        )
    seconds = time.perf_counter() - started
    summary = fused_summary(omap, total.readings, image_path, yaml_path, n_logs, seconds,
                            occupied, free)  # fmt: skip
    report(summary, fused_line(summary), as_json, quiet)
