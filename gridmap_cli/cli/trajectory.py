"""``gridmap trajectory``: a log's pose track (odometry, reference, scan-matched or slam) as a
file that trajectory tools read (TUM for evo, or CSV); with ``--pose slam`` also each pose's
covariance from the pose graph (a CSV beside the track)."""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

import click
import numpy as np
import numpy.typing as npt

from gridmap_cli.cli.build_report import widened_clause
from gridmap_cli.cli.common import (
    check_input,
    check_output_folder,
    force_option,
    format_option,
    handle_errors,
    json_option,
    logs_argument,
    quiet_option,
    topic_options,
    warn,
)
from gridmap_cli.cli.progress import StageBars, reading
from gridmap_cli.errors import GridmapError
from gridmap_cli.evaluation.relations import (
    ClockOffset,
    Relations,
    find_clock_offset,
    logged_stamps,
    moved_to,
    read_relations,
    reordered_on_logged_clock,
    score_track,
)
from gridmap_cli.poses.correction.scan_match import STATUS_NAMES
from gridmap_cli.poses.sources import (
    DEFAULT_SOURCE,
    PosedLog,
    PoseSettings,
    pose_help,
    pose_source,
    source_names,
)
from gridmap_cli.poses.sync import laser_point
from gridmap_cli.readers import read_logs
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.records import PoseTrack, RangeLog
from gridmap_cli.robot import load_robot, robot_from_log
from gridmap_cli.writers import check_output
from gridmap_cli.writers.trajectory import covariance_path, trajectory_format, write_trajectory


@click.command()
@logs_argument
@click.option(
    "-o",
    "--output",
    required=True,
    type=click.Path(path_type=Path, dir_okay=False, readable=False),
    help="Track to write: .tum (TUM: 'time x y z qx qy qz qw', what evo reads) or .csv "
    "(time,x,y,theta; scan-matched and slam add each scan's status). --pose slam also writes "
    "NAME.cov.csv beside it: each pose's covariance from the pose graph.",
)
@click.option(
    "--pose",
    type=click.Choice(source_names()),
    default=DEFAULT_SOURCE,
    show_default=True,
    help=pose_help("Which track (build's default too):")
    + " A track the laser makes has one pose per scan; the others need no range readings.",
)
@click.option(
    "--robot",
    help="Robot preset, robot YAML or ARIA .p file (the laser's mounting); default: the log's "
    "own '# robot:' line.",
)
@click.option(
    "--relations",
    type=click.Path(path_type=Path, readable=False),
    help="Score the track against a SLAM-benchmark relations file ('t1 t2 x y z roll pitch "
    "yaw' per line): mean and std of the translational (m) and rotational (deg) error.",
)
@click.option(
    "--relations-offset",
    type=float,
    help="Seconds to add to the track's stamps to reach the relations' clock (for a log "
    "republished with times from its start); default: found from the stamps, where the "
    "relation stamps land on the log's.",
)
@format_option
@topic_options
@force_option("Overwrite an existing output.")
@quiet_option("No summary on stderr.")
@json_option("Print a JSON summary on stdout.")
@handle_errors
def trajectory(
    logs: tuple[Path, ...],
    output: Path,
    pose: str,
    robot: str | None,
    relations: Path | None,
    relations_offset: float | None,
    log_format: str | None,
    topics: ReadOptions,
    force: bool,
    quiet: bool,
    as_json: bool,
) -> None:
    """Write LOG's pose track (odometry, reference, scan-matched or slam) as TUM or CSV.

    Compare tracks with evo: gridmap trajectory run.log --pose global -o ref.tum; gridmap
    trajectory run.log --pose scan-matched -o sm.tum; evo_ape tum ref.tum sm.tum -a.
    """
    started = time.perf_counter()
    trajectory_format(output)
    check_output(output, force)
    cov_path = covariance_path(output) if pose_source(pose).belief else None
    if cov_path is not None:
        check_output(cov_path, force)
    check_output_folder(output)
    robot_desc = load_robot(robot) if robot else None
    for log in logs:
        check_input(log)
    if relations is not None:
        check_input(relations, folder_ok=False)
        truth = read_relations(relations)
    source = pose_source(pose)
    # the odometry and the reference need no range readings (a ROS recording of /odom and TF)
    # and a source that reads the scans can take the motion from them where there is no odometry
    read_options = dataclasses.replace(
        topics,
        robot=robot_desc,
        poses_only="laser" not in source.needs,
        odometry_optional=source.uses_laser,
    )
    with reading(logs[0].name if len(logs) == 1 else f"{len(logs)} logs", quiet):
        data = read_logs(logs, log_format, read_options)
    if source.uses_laser and robot_desc is None:
        robot_desc = robot_from_log(logs[0], data.metadata)
    with StageBars(quiet) as bars:
        posed = source.run(data, robot_desc, PoseSettings(progress=bars))
    summary: dict[str, object] = {"output": str(output), "pose": posed.source, **posed.summary}
    if posed.motion is not None:
        summary["motion"] = posed.motion
    track, status, covariance = _written_track(posed)
    scored = posed.log.poses
    if covariance is not None:
        summary["covariance"] = str(cov_path)
    summary["poses"] = len(track)
    clock: ClockOffset | None = None  # found from the stamps when no offset is given
    if relations is not None:
        laser = laser_point(data, robot_desc)
        summary["relations"], clock = _scored(
            scored, truth, data, relations, relations_offset, laser
        )
    if data.moved_stamps is not None:
        # the log's own clock: a stamp the reader moved forward is written as the log gave it,
        # so the benchmark's relations (and evo) find this pose under the log's stamp
        track, order = reordered_on_logged_clock(track, data.moved_stamps)
        status = None if status is None else [status[int(k)] for k in order]
        covariance = None if covariance is None else (covariance[0][order], covariance[1][order])
    write_trajectory(output, track, status, covariance)
    summary["seconds"] = round(time.perf_counter() - started, 3)
    if as_json:
        click.echo(json.dumps(summary, indent=2))
    if not quiet:
        _report(summary, posed, len(track), cov_path, clock)


def _scored(
    scored: PoseTrack,
    truth: Relations,
    data: RangeLog,
    relations: Path,
    relations_offset: float | None,
    laser: tuple[float, float] | None = None,
) -> tuple[dict[str, object], ClockOffset | None]:
    """The track scored on the relations, on the clock offset given or found from the stamps.
    A corrected track is scored at every odometry stamp too (the track ``build`` maps with),
    so a relation between two scans finds the pose the estimate gives at its time. Where the
    laser sits off base_link (``laser``, its point), the track of the laser's point is scored
    too (``at_laser``): relations say the robot's relative pose, and which point of the robot
    they are of decides a figure that turns (a lever arm d moves a relation that turns by a by
    2 d sin(a/2))."""
    clock: ClockOffset | None = None
    offset = relations_offset
    if offset is None:
        clock = find_clock_offset(logged_stamps(data), truth)
        offset = clock.offset_s or 0.0
    score = score_track(scored, truth, data.poses, offset_s=offset, moved=data.moved_stamps)
    if score.count == 0:
        why = "is the clock offset right (--relations-offset)?"
        raise GridmapError(
            f"{relations}: no relation lies within the track's time span; "
            + (why if clock is None else clock.message())
        )
    scored_summary: dict[str, object] = {**score.summary(), "offset_s": offset}
    if laser is not None and laser != (0.0, 0.0):
        at = score_track(
            moved_to(scored, *laser), truth, moved_to(data.poses, *laser), offset_s=offset,
            moved=data.moved_stamps,
        )  # fmt: skip
        scored_summary["at_laser"] = {"laser_m": list(laser), **at.summary()}
    if clock is not None:
        scored_summary["clock"] = clock.message()
    return scored_summary, clock


Covariance = tuple[npt.NDArray[np.float64], npt.NDArray[np.bool_]]


def _written_track(posed: PosedLog) -> tuple[PoseTrack, list[str] | None, Covariance | None]:
    """The track to write: the source's at the odometry's stamps, or one pose per scan with
    how each scan was placed; with the pose graph's covariance of each pose where it has one."""
    if posed.match is None:
        return posed.log.poses, None, None
    track = posed.match.track
    matched = posed.slam.scan_matched if posed.slam is not None else posed.match
    status = [STATUS_NAMES[int(s)] for s in matched.status]
    if posed.slam is None:
        return track, status, None
    from gridmap_cli.poses.uncertainty.pose_belief import slam_belief

    # the graph's own noise: the benchmark's relations check it (docs/scan-matching.md)
    belief = slam_belief(posed.slam, calibrate=False)
    keyframe = np.isin(track.stamp_ns, belief.stamp_ns)
    return track, status, (belief.marginals_at(track.stamp_ns), keyframe)


def _report(
    summary: dict[str, object],
    posed: PosedLog,
    poses: int,
    cov_path: Path | None,
    clock: ClockOffset | None,
) -> None:
    """The lines on stderr: what was written, how the scans were placed, the score."""
    line = f"gridmap: {poses:,} {summary['pose']} poses -> {summary['output']}"
    if "scan_match" in summary:
        sm = posed.summary["scan_match"]
        line += (
            f" ({sm['fallbacks']:,} scans fell back to odometry, {sm['degenerate']:,} degenerate, "
            f"{sm['partial']:,} matched in part)"
        )
    if "slam" in summary:
        sl = posed.summary["slam"]
        line += (
            f" ({sl['closures_accepted']:,} loop closures accepted, "
            f"{sl['closures_rejected']:,} rejected; {sl['fallbacks']:,} scans fell back "
            f"to odometry{widened_clause(sl)})"
        )
    if posed.motion is not None:
        line += f"; {posed.motion}"
    click.echo(line + f" in {summary['seconds']:.1f} s", err=True)
    if cov_path is not None:
        click.echo(f"gridmap: each pose's covariance -> {cov_path}", err=True)
    # every warning the pose source gave, as build prints them: the graph's own, a failing
    # free-space check, the automatic choice's fallback, scans too far apart to chain
    warn(posed.warnings)
    if clock is not None and (clock.searched or clock.offset_s is None):
        caveat = "" if clock.offset_s is not None else "warning: scored on the log's clock: "
        click.echo(f"gridmap: relations: {caveat}{clock.message()}", err=True)
    relations = summary.get("relations")
    if isinstance(relations, dict):
        r = relations
        click.echo(
            f"gridmap: relations {r['relations']:,} (skipped {r['skipped']:,}): "
            f"translation {r['trans_mean_m']:.3f} +/- {r['trans_std_m']:.3f} m, "
            f"rotation {r['rot_mean_deg']:.2f} +/- {r['rot_std_deg']:.2f} deg",
            err=True,
        )
        at = r.get("at_laser")
        if isinstance(at, dict):
            lx, ly = at["laser_m"]
            click.echo(
                f"gridmap: relations of the laser's point ({lx:g}, {ly:g}) m from base_link "
                f"instead: translation {at['trans_mean_m']:.3f} +/- {at['trans_std_m']:.3f} m "
                "(a relations file does not say which point it is of; the SLAM benchmark's "
                "are of the laser's)",
                err=True,
            )
