"""``gridmap evaluate``: a map scored against the true world, or without it by what the log it
was built from tells (:mod:`gridmap_cli.evaluation.quality`)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import click
import numpy as np

from gridmap_cli.cli.common import (
    check_input,
    check_output_folder,
    force_option,
    format_option,
    handle_errors,
    json_option,
    json_text,
    quiet_option,
    selection_options,
    warn,
)
from gridmap_cli.errors import UsageError
from gridmap_cli.mapping.models.fading import ErrorAwareParams
from gridmap_cli.mapping.selection import Selection, apply_selection
from gridmap_cli.poses.odometry_error import OdometryError, load_odometry_error
from gridmap_cli.poses.sources import SOURCES, PoseSettings, pose_source
from gridmap_cli.readers import resolve_format
from gridmap_cli.robot import load_robot, robot_from_log
from gridmap_cli.writers import check_output

if TYPE_CHECKING:
    import numpy.typing as npt

    # scipy.ndimage (0.3 s) comes with it: imported when the command runs
    from gridmap_cli.evaluation.evaluate import Evaluation, ProbabilityMap, Truth
    from gridmap_cli.mapping.grid import GridSpec

    #: The pose spread of the readings on the world grid: position and heading.
    Spread = tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]
    from gridmap_cli.poses.uncertainty.pose_uncertainty import PoseUncertainty
    from gridmap_cli.records import RangeLog
    from gridmap_cli.robot import RobotDescription


@click.command()
@click.argument("map_yaml", metavar="MAP.yaml", type=click.Path(path_type=Path, readable=False))
@click.option(
    "--truth",
    "truth_yaml",
    type=click.Path(path_type=Path, readable=False),
    help="Ground-truth world map (map_server YAML, e.g. samples/worlds/*.yaml). Without it, "
    "--log is required and the map is judged by what the log itself tells: its pose spread, "
    "how many laser echoes it contradicts, how far apart it puts the places the scans saw "
    "twice (a laser log's pose graph is solved for them), and a pose graph's closures "
    "(docs/quality.md).",
)
@click.option(
    "--log",
    "log_path",
    type=click.Path(path_type=Path, readable=False),
    help="The log the map was built from (with ground truth): places the odometry frame in the "
    "world and limits the scores to the cells its sensors could have sensed.",
)
@format_option
@click.option(
    "--robot",
    help="Robot preset, YAML or ARIA .p file for the sensors of --log; default: its '# robot:'.",
)
@click.option(
    "--pose",
    type=click.Choice([s.name for s in SOURCES if not s.chooses]),
    help="The track the map was built with (build's --pose; default odometry): global puts the "
    "map in the world frame; odometry, scan-matched and slam in the odometry frame, placed by "
    "--log. --spread-plot draws that track's pose spread: the odometry error along the "
    "odometry or the scan-matched track, or the pose graph's own uncertainty (slam).",
)
@click.option(
    "--frame",
    type=click.Choice(["odometry", "world"]),
    help="Frame of the map: odometry (built from odometry, scan-matched or slam poses: the "
    "frame starts at the log's first true pose, needs --log) or world (built with --pose "
    "global)  [default: from --pose, else odometry]",
)
@selection_options()
@json_option("Print the scores as JSON on stdout.")
@quiet_option("No table on stdout (with --plot: just draw).")
@click.option(
    "--plot",
    type=click.Path(path_type=Path, readable=False),
    help="Write a PNG: the map with the true walls, and a reliability diagram (needs matplotlib).",
)
@click.option(
    "--spread-plot",
    type=click.Path(path_type=Path, readable=False),
    help="Write a PNG of where the map's uncertainty comes from: per cell, the smallest "
    "position spread (and its heading spread) of the pose at which a reading of --log crossed "
    "it, the pose covariance carried along the odometry from --odometry-error (needs --log and "
    "matplotlib).",
)
@click.option(
    "--odometry-error",
    "odometry_file",
    type=click.Path(path_type=Path, readable=False),
    help="--spread-plot, or without --truth: the odometry-error file the map was built with "
    "(gridmap calibrate), whose pose spread is drawn or reported.",
)
@force_option("Overwrite existing --plot / --spread-plot outputs.")
@handle_errors
def evaluate(
    map_yaml: Path,
    truth_yaml: Path | None,
    log_path: Path | None,
    log_format: str | None,
    robot: str | None,
    pose: str | None,
    frame: str | None,
    sensor_patterns: tuple[str, ...],
    start: str | None,
    end: str | None,
    as_json: bool,
    quiet: bool,
    plot: Path | None,
    spread_plot: Path | None,
    odometry_file: Path | None,
    force: bool,
) -> None:
    """Score the map MAP.yaml against the ground-truth world of --truth, or without it, by what
    the log it was built from tells (--log).

    Scores (docs/evaluation.md): NLL and Brier score of the true occupancy under the map's
    probabilities, reliability table and expected calibration error, occupied-cell precision,
    recall and F1 within one cell, coverage. Unknown cells count as p = 0.5. With --log the
    region scored is the world cells the log's sensors could have sensed from the true path;
    without it, the whole world map.

    A map built from odometry (or scan-matched or slam poses) is in the odometry frame, which
    starts at the log's first true pose: --log places it in the world. A map built with --pose
    global is in the world frame already: give --pose global (or --frame world).
    """
    from gridmap_cli.evaluation import evaluate as ev

    _check_names(map_yaml, truth_yaml, plot, spread_plot, frame, log_path)
    pose, frame = _pose_and_frame(pose, frame)
    selection = _check_options(pose, frame, log_path, (sensor_patterns, start, end), spread_plot,
                               odometry_file, truth_yaml is None)  # fmt: skip
    _check_files(map_yaml, truth_yaml, log_path, odometry_file, plot, spread_plot, force)
    odometry = load_odometry_error(odometry_file) if odometry_file is not None else None
    robot_desc = load_robot(robot) if robot else None
    if truth_yaml is None:
        _quality_only(map_yaml, log_path, log_format, robot_desc, pose, odometry, selection,
                      as_json, quiet)  # fmt: skip
        return
    truth = ev.load_truth(truth_yaml)
    pmap = ev.load_probability_map(map_yaml)
    map_to_world, region, log_world, spread = (0.0, 0.0, 0.0), None, None, None
    if log_path is not None:
        map_to_world, region, log_world, spread = _log_in_world(
            log_path, log_format, robot_desc, pose, frame, selection, odometry, truth,
            str(truth_yaml), pmap, spread_plot is not None,
        )  # fmt: skip
    warn(
        ev.check_comparable(
            pmap, truth.spec, map_to_world, str(map_yaml), str(truth_yaml), log_world
        )
    )
    result = ev.evaluate_map(pmap, truth.walls, truth.spec, region, map_to_world, truth.known)
    _draw(plot, spread_plot, result, truth, region, spread, f"{map_yaml.name}",
          f"{truth_yaml.name}")  # fmt: skip
    if as_json:
        doc = {
            "map": str(map_yaml),
            "truth": str(truth_yaml),
            "log": str(log_path) if log_path else None,
            "pose": pose,
            "frame": frame,
            "map_to_world": list(map_to_world),
            "region": "sensed from the true path" if log_path else "whole world",
            **result.as_dict(),
        }
        click.echo(json_text(doc))
    elif not quiet:
        click.echo(_evaluation_table(map_yaml, truth_yaml, log_path, map_to_world, result))
    if plot is not None and not quiet:
        click.echo(f"gridmap: plot written to {plot}", err=True)
    if spread_plot is not None and not quiet:
        click.echo(f"gridmap: pose-spread plot written to {spread_plot}", err=True)


def _check_names(
    map_yaml: Path,
    truth_yaml: Path | None,
    plot: Path | None,
    spread_plot: Path | None,
    frame: str | None,
    log_path: Path | None,
) -> None:
    """Without --truth, the log judges the map (--log, in the map's own frame, no plots); MAP
    and --truth name maps' YAML files."""
    if truth_yaml is None and log_path is None:
        raise UsageError(
            "give --truth WORLD.yaml to score the map against ground truth, or --log LOG (the "
            "log it was built from) to judge it by what the log tells"
        )
    if truth_yaml is None and (plot is not None or spread_plot is not None):
        raise UsageError("--plot and --spread-plot draw the map against --truth: give it")
    if truth_yaml is None and frame == "world":
        raise UsageError("without --truth the map is judged in its own frame: no --frame world")
    for given, what in ((map_yaml, "MAP"), (truth_yaml, "--truth")):
        if given is not None and given.suffix.lower() not in (".yaml", ".yml"):
            raise UsageError(
                f"{given}: {what} must be a map's YAML file (the image is named inside it)"
            )


def _check_options(
    pose: str,
    frame: str,
    log_path: Path | None,
    part: tuple[tuple[str, ...], str | None, str | None],
    spread_plot: Path | None,
    odometry_file: Path | None,
    judged: bool = False,
) -> Selection:
    """Usage checks of the options against each other, before any file is read; the part of
    --log to use (``part``: --sensors, --start, --end). ``judged``: no --truth, the log judges
    the map."""
    if frame == "odometry" and log_path is None:
        raise UsageError(
            "a map in the odometry frame needs --log (its first true pose places the frame in "
            "the world); give --log, or --frame world for a map built with --pose global"
        )
    selection = Selection.parse(*part)
    if selection and log_path is None:
        raise UsageError("--sensors, --start and --end choose part of --log; give --log")
    own_spread = pose_source(pose).belief  # the pose graph's, not the odometry error's
    if spread_plot is not None and own_spread and log_path is None:
        raise UsageError("--spread-plot draws the pose spread of the readings of --log: give it")
    if (spread_plot is not None or judged) and own_spread and odometry_file is not None:
        raise UsageError(
            f"--pose {pose}: the pose spread is the pose graph's own; --odometry-error is for "
            "odometry and scan-matched maps"
        )
    if spread_plot is not None and not own_spread and (log_path is None or odometry_file is None):
        raise UsageError(
            "--spread-plot draws the pose spread of the readings of --log under the odometry "
            "error of --odometry-error FILE: give both"
        )
    if spread_plot is not None and frame != "odometry":
        raise UsageError(
            "--spread-plot is for maps built from odometry (--frame odometry): a map built with "
            "--pose global has no odometry spread"
        )
    if odometry_file is not None and spread_plot is None and not judged:
        raise UsageError("--odometry-error is for --spread-plot, or for evaluate without --truth")
    return selection


def _check_files(
    map_yaml: Path,
    truth_yaml: Path | None,
    log_path: Path | None,
    odometry_file: Path | None,
    plot: Path | None,
    spread_plot: Path | None,
    force: bool,
) -> None:
    """The inputs readable, the plots' names and folders fit to write."""
    if log_path is not None:
        check_input(log_path)
    if odometry_file is not None:
        check_input(odometry_file, folder_ok=False)
    for given in (map_yaml, truth_yaml):
        if given is not None:
            check_input(given, folder_ok=False)
    for out, flag in ((plot, "--plot"), (spread_plot, "--spread-plot")):
        if out is None:
            continue
        from gridmap_cli.evaluation.plot import check_plotting

        check_plotting(flag)
        if out.suffix.lower() != ".png":
            raise UsageError(f"{out}: {flag} writes a PNG; name it .png")
        check_output(out, force)
        check_output_folder(out)


def _log_in_world(
    log_path: Path,
    log_format: str | None,
    robot_desc: RobotDescription | None,
    pose: str,
    frame: str,
    selection: Selection,
    odometry: OdometryError | None,
    truth: Truth,
    truth_name: str,
    pmap: ProbabilityMap,
    with_spread: bool,
) -> tuple[tuple[float, float, float], npt.NDArray[np.bool_], str | None, Spread | None]:
    """What --log says of the map: where its frame is in the world, the region its sensors
    could sense from the true path, the world it names, and the pose spread of its readings
    on the world grid (``with_spread``)."""
    from gridmap_cli.evaluation import evaluate as ev
    from gridmap_cli.poses.sync import sensors_for_log

    map_to_world = (0.0, 0.0, 0.0)
    spread: Spread | None = None
    data = resolve_format(log_path, log_format).read(log_path)
    data.require_truth("evaluate needs the true path")  # before the robot is looked up
    log_world = data.metadata.get("world")
    if robot_desc is None:
        robot_desc = robot_from_log(log_path, data.metadata)
    if with_spread:
        placed, uncertainty = _pose_spread(data, robot_desc, pose, odometry)
        readings_log = apply_selection(placed, selection, robot_desc).log
    selected = apply_selection(data, selection, robot_desc)
    warn(selected.notes)
    data = selected.log
    true_path = data.require_truth("evaluate needs the true path")
    ev.check_path_in_world(truth, true_path, str(log_path), truth_name)
    sensors = sensors_for_log(data, robot_desc)
    if frame == "odometry":
        map_to_world = ev.odometry_frame_in_world(data)
    region = ev.sensed_region(truth.world, true_path, sensors)
    if with_spread:
        # robot_desc is None for logs that describe their own sensors (CARMEN)
        spread = _spread_in_world(
            readings_log, robot_desc, uncertainty, pmap, truth.spec, map_to_world
        )
    return map_to_world, region, log_world, spread


def _draw(
    plot: Path | None,
    spread_plot: Path | None,
    result: Evaluation,
    truth: Truth,
    region: npt.NDArray[np.bool_] | None,
    spread: Spread | None,
    map_name: str,
    truth_name: str,
) -> None:
    """The plots asked for: the scores, and where the map's uncertainty comes from."""
    if plot is not None:
        from gridmap_cli.evaluation.plot import plot_evaluation

        plot_evaluation(
            plot,
            result,
            truth.walls,
            region if region is not None else np.ones(truth.spec.shape, dtype=bool),
            truth.spec,
            title=f"{map_name} vs {truth_name}",
        )
    if spread_plot is not None and spread is not None:
        from gridmap_cli.evaluation.plot import plot_pose_spread

        limit = math.degrees(ErrorAwareParams.max_heading_spread_rad)
        plot_pose_spread(
            spread_plot,
            result.p_world,
            spread[0],
            spread[1],
            truth.walls,
            truth.spec,
            title=f"{map_name}: where its uncertainty comes from",
            max_heading_deg=limit if math.isfinite(limit) else None,
        )


def _quality_only(
    map_yaml: Path,
    log_path: Path | None,
    log_format: str | None,
    robot: RobotDescription | None,
    pose: str,
    odometry: OdometryError | None,
    selection: Selection,
    as_json: bool,
    quiet: bool,
) -> None:
    """Evaluate without ground truth (docs/quality.md): the log, posed as the map was built,
    judges the map read back from its file."""
    assert log_path is not None  # the usage checks ask for it
    from gridmap_cli.evaluation.quality import log_quality, quality_table
    from gridmap_cli.mapping.grid import OccupancyMap
    from gridmap_cli.mapping.mapfile import load_map
    from gridmap_cli.mapping.options import BuildOptions

    loaded = load_map(map_yaml)
    omap = OccupancyMap(loaded.spec, loaded.stored_probability())
    data = resolve_format(log_path, log_format).read(log_path)
    if robot is None:
        robot = robot_from_log(log_path, data.metadata)
    selected = apply_selection(data, selection, robot)
    warn(selected.notes)
    options = BuildOptions(odometry_error=odometry)
    thresholds = (loaded.occupied_thresh, loaded.free_thresh)
    quality = log_quality(omap, selected.log, robot, pose, options, thresholds)
    if as_json:
        doc = {"map": str(map_yaml), "log": str(log_path), "pose": pose, **quality.as_dict()}
        click.echo(json_text(doc))
    elif not quiet:
        click.echo(quality_table(str(map_yaml), log_path.name, pose, quality))


def _pose_and_frame(pose: str | None, frame: str | None) -> tuple[str, str]:
    """--pose and --frame, each from the other when not given; a usage error when they
    disagree."""
    if pose is None:  # the first source in that frame: the odometry, or the reference
        pose = next(s.name for s in SOURCES if s.frame == (frame or "odometry"))
    wanted = pose_source(pose).frame
    if frame is not None and frame != wanted:
        raise UsageError(
            f"a map built with --pose {pose} is in the {wanted} frame, not --frame {frame}"
        )
    return pose, wanted


def _pose_spread(
    log: RangeLog, robot: RobotDescription | None, pose: str, odometry: OdometryError | None
) -> tuple[RangeLog, PoseUncertainty]:
    """``log`` with the poses the map was built with, and their covariance as build's
    error-aware mode takes it: the pose source's own (the pose graph's), or the odometry error
    carried along its track."""
    from gridmap_cli.poses.uncertainty.pose_uncertainty import StepNoise, propagate

    posed = pose_source(pose).run(log, robot, PoseSettings(belief_samples=0))
    if posed.belief is not None:
        return posed.log, posed.belief.uncertainty
    assert odometry is not None  # the usage checks ask for it
    return posed.log, propagate(posed.log.poses, StepNoise.of(odometry))


def _spread_in_world(
    log: RangeLog,
    robot: RobotDescription | None,
    uncertainty: PoseUncertainty,
    pmap: ProbabilityMap,
    world: GridSpec,
    map_to_world: tuple[float, float, float],
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """The pose spread of ``log``'s readings on the map's grid, placed on the world grid: the
    position spread (m) and the heading spread (deg), shape ``world.shape``."""
    from gridmap_cli.evaluation import evaluate as ev
    from gridmap_cli.evaluation.spread_map import pose_spread_map
    from gridmap_cli.poses.sync import synchronise

    readings, _ = synchronise(log, robot)
    spread = pose_spread_map(pmap.spec, readings, uncertainty)
    placed = [
        ev.map_in_world(ev.ProbabilityMap(pmap.spec, values, 0.5), world, map_to_world)
        for values in (spread.position_m, np.degrees(spread.heading_rad))
    ]
    return placed[0], placed[1]


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
