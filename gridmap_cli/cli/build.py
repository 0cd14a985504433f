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
    force_option,
    handle_errors,
    json_option,
    logs_argument,
    progress_bar,
    quiet_option,
    read_input,
    stdout_file,
    warn,
)
from gridmap_cli.cli.map_options import (
    error_samples_option,
    image_format_option,
    map_options,
)
from gridmap_cli.cli.progress import StageBars, reading
from gridmap_cli.errors import MixedLogsError, NotRecordingFolderError, UsageError
from gridmap_cli.evaluation.quality import quality_notes
from gridmap_cli.heap import TRIM_EVERY_BATCHES, TrimEvery, keep_scratch_memory, release_free_memory
from gridmap_cli.mapping.options import BuildOptions
from gridmap_cli.mapping.selection import Selection
from gridmap_cli.poses.sources import ODOMETRY_SOURCE, pose_source, source_names
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.records import PoseTrack, RangeLog
from gridmap_cli.robot import load_robot, preset_names
from gridmap_cli.runs.build import (
    BuildHooks,
    BuildRequest,
    MapBuild,
    has_spread_layer,
    map_stage,
    pose_stage,
)
from gridmap_cli.runs.executors import EXECUTORS, check_dask, fuse_dask, fuse_local
from gridmap_cli.runs.fuse import FuseJob, Partial, fused_map, parse_initial_pose
from gridmap_cli.runs.settings import MapOptions, map_settings
from gridmap_cli.writers import check_output
from gridmap_cli.writers.map_image import IMAGE_FORMATS, check_map_outputs, write_map
from gridmap_cli.writers.spread_layer import (
    SPREAD_TOPIC,
    spread_levels,
    spread_output,
    spread_paths,
)

if TYPE_CHECKING:
    from collections.abc import Sequence

    from gridmap_cli.writers.preview import DrawnTrack


@click.command()
@logs_argument
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
@force_option("Overwrite existing outputs.")
@quiet_option("No progress bar and no summary on stderr.")
@json_option("Print a JSON summary on stdout.")
@handle_errors
def build(
    logs: tuple[Path, ...],
    output: Path | None,
    basename: Path | None,
    image_format: str | None,
    map_options: MapOptions,
    draw_path: bool,
    fuse: bool,
    initial_poses: tuple[str, ...],
    executor: str,
    scheduler: str | None,
    jobs: int,
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
    opts = map_options
    if fuse and pose_source(opts.pose).chooses:  # placed logs: their odometry, not a choice
        opts = dataclasses.replace(opts, pose=ODOMETRY_SOURCE)
    output = map_output(output, basename, image_format)
    settings = map_settings(opts, fuse)
    selection = opts.selection()
    to_stdout = output == STDIO
    if to_stdout:
        _check_stdout(image_format, as_json, draw_path)
    placed = _fuse_options(fuse, logs, initial_poses, opts.pose, opts.mode, executor, scheduler,
                           jobs)  # fmt: skip
    if fuse and (to_stdout or draw_path or pose_source(opts.pose).uses_laser):
        placing = " or ".join(sorted(source_names(needs_not="laser")))
        raise UsageError(
            "--fuse writes one map file from placed logs: give -o FILE, no --draw-path, and "
            f"--pose {placing}"
        )
    to_mcap = _check_map_name(output, image_format, opts.map_mode)
    robot = load_robot(opts.robot) if opts.robot else None
    for log in logs:  # the command line first, then the inputs, then the outputs
        check_input(log)
    if to_mcap:
        check_output(output, force)
    elif not to_stdout:
        check_map_outputs(output, opts.map_mode, force)
    check_map_folder(output)
    preview = output.with_name(f"{output.stem}_path.png") if draw_path else None
    if preview is not None:
        check_output(preview, force)
    # the pose-spread layer beside a map that knows its poses' uncertainty
    layered = not fuse and not to_stdout and has_spread_layer(settings, opts.pose)
    if layered and not to_mcap:
        for path in spread_paths(output):
            check_output(path, force)
    if fuse:
        total = _fused(logs, placed, opts, selection, settings, scheduler, jobs)
        warn(total.notes, quiet)
        _write_fused(total, output, to_mcap, opts, force, started, quiet, as_json, len(logs))
        return
    request = BuildRequest(
        inputs=logs, robot=robot, options=dataclasses.replace(settings, jobs=jobs),
        pose=opts.pose, selection=selection, log_format=opts.log_format,
        read_options=opts.topics, keep_tracks=preview is not None,
    )  # fmt: skip
    built = _build_one(request, quiet)
    _write_one(built, output, image_format, to_mcap, opts, preview, force, started, quiet,
               as_json)  # fmt: skip


def _check_map_name(output: Path, image_format: str | None, map_mode: str) -> bool:
    """The map's name and mode, before any input; True for an MCAP map."""
    if output.suffix.lower() == ".mcap":
        source = click.get_current_context().get_parameter_source("map_mode")
        if source is not None and source != click.core.ParameterSource.DEFAULT:
            raise UsageError("--map-mode applies to map images; an MCAP map holds 0..100 and -1")
        return True
    check_map_outputs(Path(f"map.{image_format}") if output == STDIO else output, map_mode, True)
    return False


def _fused(
    logs: tuple[Path, ...],
    placed: list[tuple[float, float, float] | None],
    opts: MapOptions,
    selection: Selection,
    settings: BuildOptions,
    scheduler: str | None,
    jobs: int,
) -> Partial:
    """Each log mapped on its own, placed, and the partial grids added (locally or on Dask)."""
    fuse_jobs = [
        FuseJob(log=log.resolve(), log_format=opts.log_format, read_options=opts.topics,
                pose=opts.pose, initial_pose=first, selection=selection,
                robot_spec=_robot_spec(opts.robot), options=_fused_settings(settings))
        for log, first in zip(logs, placed, strict=True)
    ]  # fmt: skip
    if scheduler is not None:
        return fuse_dask(fuse_jobs, scheduler)
    return fuse_local(fuse_jobs, jobs)


def _fused_settings(settings: BuildOptions) -> BuildOptions:
    """What a fused log is mapped with: the cell size and the standard models' settings."""
    return BuildOptions(resolution_m=settings.resolution_m, sonar=settings.sonar, ray=settings.ray)


def _build_one(request: BuildRequest, quiet: bool) -> MapBuild:
    """The map of ``request``, with progress on a terminal and warnings as they arise."""
    keep_scratch_memory()  # every check passed: from here on, the build's own process
    hooks = BuildHooks(
        read=_read_logs, reading=lambda: reading(_names(request.inputs), quiet),
        warn=lambda note: warn((note,), quiet), between_passes=release_free_memory,
    )  # fmt: skip
    with StageBars(quiet) as bars:
        placed = pose_stage(request, dataclasses.replace(hooks, stages=bars))
    with progress_bar(placed.log.reading_count, quiet, "mapping") as bar:
        trim = TrimEvery(TRIM_EVERY_BATCHES)

        def mapped(readings: int) -> None:
            bar.update(readings)
            trim()

        return map_stage(request, placed, dataclasses.replace(hooks, mapped=mapped))


def _write_one(
    built: MapBuild,
    output: Path,
    image_format: str | None,
    to_mcap: bool,
    opts: MapOptions,
    preview: Path | None,
    force: bool,
    started: float,
    quiet: bool,
    as_json: bool,
) -> None:
    """Write the map (and its preview) where the command line says, and report it."""
    occupied, free, map_mode = opts.occupied, opts.free, opts.map_mode
    weak = built.map.weak_evidence_note(occupied, free) if map_mode == "trinary" else None
    if weak is not None and not to_mcap:
        warn((weak,), quiet)
    elif opts.mode == "error-aware" and map_mode == "trinary" and not to_mcap:
        warn(undecided_note(built.map.prob, occupied, free), quiet)
    spread = built.spread() if output != STDIO else None
    yaml_path: Path | None = None
    if output != STDIO:
        output.parent.mkdir(parents=True, exist_ok=True)  # checked: a folder, or none yet
    if to_mcap:
        # stamped at the last reading: the map is what the robot knew then
        stamp = built.log.reading_span()[1] if built.log.reading_count else 0
        from gridmap_cli.writers.map_mcap import write_map_mcap  # the MCAP writer only when asked

        layers = [] if spread is None else [(SPREAD_TOPIC, spread_levels(spread[0]))]
        image_path = write_map_mcap(
            output, built.map, stamp_ns=stamp, force=force, layers=layers,
            thresholds=(occupied, free),
        )  # fmt: skip
    elif output == STDIO:
        with stdout_file(f"map.{image_format}") as image:
            write_map(image, built.map, mode=map_mode, occupied_thresh=occupied, free_thresh=free)
        image_path = STDIO
    else:
        also = [] if spread is None else [spread_output(output, spread[0], built.map.spec)]
        image_path, yaml_path = write_map(
            output, built.map, mode=map_mode, occupied_thresh=occupied, free_thresh=free,
            force=force, also=also,
        )  # fmt: skip
    if preview is not None and built.placed.read is not None:
        from gridmap_cli.writers.preview import write_preview  # only --draw-path draws

        tracks = _tracks(built.placed.read, built.log, built.placed.posed.source)
        write_preview(preview, built.map, tracks, None if spread is None else spread[0])
    elapsed = time.perf_counter() - started
    summary = build_summary(built.stats, image_path, yaml_path, elapsed, occupied, free)
    if preview is not None:
        summary["preview"] = str(preview)
    summary.update(built.summary)
    if spread is not None:
        summary["spread"] = str(output if to_mcap else spread_paths(output)[1])
    line = summary_line(summary)
    if as_json or spread is not None:
        quality = built.quality((occupied, free), spread, echoes=as_json, revisits=as_json)
        summary["quality"] = quality.as_dict()
        notes = quality_notes(quality, built.placed.posed.source, built.log, built.placed.robot)
        line += "".join(f"; {part}" for part in notes)
    report(summary, line, as_json, quiet)


def _names(logs: Sequence[Path]) -> str:
    """The logs as the reading stage names them."""
    return logs[0].name if len(logs) == 1 else f"{len(logs)} logs"


def _read_logs(logs: Sequence[Path], log_format: str | None, options: ReadOptions) -> RangeLog:
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

    source = pose_source(pose)
    others: list[tuple[PoseTrack | None, tuple[int, int, int]]]
    if "reference" in source.needs:  # the reference itself
        others = [(whole.poses, ODOMETRY_RGB)]
        colour = REFERENCE_RGB
    elif "odometry" in source.needs:  # the robot's own odometry
        others = [(whole.truth, REFERENCE_RGB)]
        colour = ODOMETRY_RGB
    else:  # a correction of the odometry
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
    in_world = pose_source(pose).frame == "world"  # the reference's frame: placed already
    if initial_poses and in_world:
        raise UsageError(f"--initial-pose places odometry; with --pose {pose} the logs are placed")
    if not in_world and len(initial_poses) != len(logs):
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
    if in_world:
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
    opts: MapOptions,
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
            output, omap, stamp_ns=0, force=force, thresholds=(opts.occupied, opts.free)
        )
    else:
        image_path, yaml_path = write_map(output, omap, mode=opts.map_mode,
                                          occupied_thresh=opts.occupied, free_thresh=opts.free,
                                          force=force)  # fmt: skip
    seconds = time.perf_counter() - started
    summary = fused_summary(omap, total.readings, image_path, yaml_path, n_logs, seconds,
                            opts.occupied, opts.free)  # fmt: skip
    report(summary, fused_line(summary), as_json, quiet)
