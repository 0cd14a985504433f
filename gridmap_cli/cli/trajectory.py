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

from gridmap_cli.cli.common import (
    check_input,
    check_output_folder,
    handle_errors,
    topic_options,
)
from gridmap_cli.cli.progress import StageBars, reading
from gridmap_cli.errors import GridmapError
from gridmap_cli.evaluation.relations import read_relations, reordered_on_logged_clock, score_track
from gridmap_cli.poses.correction.scan_match import STATUS_NAMES, corrected_track, match_log
from gridmap_cli.poses.sync import POSE_SOURCES, select_poses
from gridmap_cli.readers import format_names, read_logs
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.robot import load_robot, robot_from_log
from gridmap_cli.writers import check_output
from gridmap_cli.writers.trajectory import covariance_path, trajectory_format, write_trajectory


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
    required=True,
    type=click.Path(path_type=Path, dir_okay=False, readable=False),
    help="Track to write: .tum (TUM: 'time x y z qx qy qz qw', what evo reads) or .csv "
    "(time,x,y,theta; scan-matched and slam add each scan's status). --pose slam also writes "
    "NAME.cov.csv beside it: each pose's covariance from the pose graph.",
)
@click.option(
    "--pose",
    type=click.Choice((*POSE_SOURCES, "slam")),
    default="odometry",
    show_default=True,
    help="Which track (build's default too): the odometry, the log's reference (global: ARIA "
    "robotGlobal, CSV true_*, a ROS recording's TF map -> base or --pose-topic, e.g. "
    "/amcl_pose), the odometry corrected by the laser (scan-matched, one pose per scan) or "
    "that with loop closures on a pose graph (slam, one pose per scan). odometry and global "
    "need no range readings.",
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
    default=0.0,
    show_default=True,
    help="Seconds to add to the track's stamps to reach the relations' clock (for a log "
    "republished with times from its start).",
)
@click.option("--format", "log_format", type=click.Choice(format_names()), help="Log format.")
@topic_options
@click.option("--force", is_flag=True, help="Overwrite an existing output.")
@click.option("-q", "--quiet", is_flag=True, help="No summary on stderr.")
@click.option("--json", "as_json", is_flag=True, help="Print a JSON summary on stdout.")
@handle_errors
def trajectory(
    logs: tuple[Path, ...],
    output: Path,
    pose: str,
    robot: str | None,
    relations: Path | None,
    relations_offset: float,
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
    cov_path = covariance_path(output) if pose == "slam" else None
    if cov_path is not None:
        check_output(cov_path, force)
    check_output_folder(output)
    robot_desc = load_robot(robot) if robot else None
    for log in logs:
        check_input(log)
    if relations is not None:
        check_input(relations, folder_ok=False)
        truth = read_relations(relations)
    # the odometry and the reference need no range readings (a ROS recording of /odom and TF)
    laser_only = pose in ("scan-matched", "slam")  # the scans can make the motion
    read_options = dataclasses.replace(
        topics,
        robot=robot_desc,
        poses_only=pose in ("odometry", "global"),
        odometry_optional=laser_only,
    )
    with reading(logs[0].name if len(logs) == 1 else f"{len(logs)} logs", quiet):
        data = read_logs(logs, log_format, read_options)
    summary: dict[str, object] = {"output": str(output), "pose": pose}
    motion_note: str | None = None
    if laser_only and data.odometry_missing is not None and not len(data.poses):
        from gridmap_cli.poses.correction.scan_odometry import MOTION_NOTE, with_scan_motion

        if robot_desc is None:
            robot_desc = robot_from_log(logs[0], data.metadata)
        with StageBars(quiet) as bars:
            data = with_scan_motion(data, robot_desc, progress=bars)
        summary["motion"] = motion_note = MOTION_NOTE
    status: list[str] | None = None
    covariance: tuple[npt.NDArray[np.float64], npt.NDArray[np.bool_]] | None = None
    if pose == "scan-matched":
        if robot_desc is None:
            robot_desc = robot_from_log(logs[0], data.metadata)
        with StageBars(quiet) as bars:
            match = match_log(data, robot_desc, progress=bars)
        track = match.track
        scored = corrected_track(data.poses, match)
        status = [STATUS_NAMES[int(s)] for s in match.status]
        summary["scan_match"] = match.summary()
    elif pose == "slam":
        from gridmap_cli.poses.correction.slam import slam_log  # gtsam: only here

        if robot_desc is None:
            robot_desc = robot_from_log(logs[0], data.metadata)
        from gridmap_cli.poses.uncertainty.pose_belief import slam_belief

        with StageBars(quiet) as bars:
            result = slam_log(data, robot_desc, progress=bars)
        track = result.track
        scored = corrected_track(data.poses, result.match)
        status = [STATUS_NAMES[int(s)] for s in result.scan_matched.status]
        summary["slam"] = result.summary()
        # the graph's own noise: the benchmark's relations check it (docs/scan-matching.md)
        belief = slam_belief(result, calibrate=False)
        keyframe = np.isin(track.stamp_ns, belief.stamp_ns)
        covariance = (belief.marginals_at(track.stamp_ns), keyframe)
        summary["covariance"] = str(cov_path)
    else:
        track = select_poses(data, pose).poses
        scored = track
    summary["poses"] = len(track)
    if relations is not None:
        # a corrected track is scored at every odometry stamp too (the track `build` maps
        # with), so a relation between two scans finds the pose the estimate gives at its time
        score = score_track(
            scored, truth, data.poses, offset_s=relations_offset, moved=data.moved_stamps
        )
        if score.count == 0:
            raise GridmapError(
                f"{relations}: no relation lies within the track's time span; is the clock "
                "offset right (--relations-offset)?"
            )
        summary["relations"] = score.summary()
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
        line = f"gridmap: {len(track):,} {pose} poses -> {output}"
        if "scan_match" in summary:
            sm = match.summary()
            line += (
                f" ({sm['fallbacks']:,} scans fell back to odometry, {sm['degenerate']:,} "
                "degenerate)"
            )
        if "slam" in summary:
            sl = result.summary()
            line += (
                f" ({sl['closures_accepted']:,} loop closures accepted, "
                f"{sl['closures_rejected']:,} rejected; {sl['fallbacks']:,} scans fell back "
                "to odometry)"
            )
        if motion_note is not None:
            line += f"; {motion_note}"
        click.echo(line + f" in {summary['seconds']:.1f} s", err=True)
        if cov_path is not None:
            click.echo(f"gridmap: each pose's covariance -> {cov_path}", err=True)
        if "slam" in summary and result.warning:
            click.echo(f"gridmap: warning: {result.warning}", err=True)
        if relations is not None:
            r = score.summary()
            click.echo(
                f"gridmap: relations {r['relations']:,} (skipped {r['skipped']:,}): "
                f"translation {r['trans_mean_m']:.3f} +/- {r['trans_std_m']:.3f} m, "
                f"rotation {r['rot_mean_deg']:.2f} +/- {r['rot_std_deg']:.2f} deg",
                err=True,
            )
