"""Build's verdict on a log: what it would use (odometry, ranges, frames, robot) and whether it
would run.

The verdict is build's own: :func:`build_problem` runs
:func:`~gridmap_cli.mapping.pipeline.plan_build` with build's default options and
:func:`robot_for` finds the robot as build does, so ``build.problem`` is the first error build
would stop at, word for word, not a parallel set of rules, and ``build.problems`` every one it
would meet once the one before is fixed, as far as the read can tell. :func:`build_part` is
the ``build`` part of the description, :func:`build_lines` its text.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from gridmap_cli.describe.sensors import laser_text, lasers_part
from gridmap_cli.describe.text import ends, some
from gridmap_cli.errors import GridmapError
from gridmap_cli.mapping.pipeline import BuildOptions, plan_build
from gridmap_cli.poses.sources import DEFAULT_SOURCE, check_needs, has_laser, pose_source
from gridmap_cli.poses.sync import sensors_for_log
from gridmap_cli.readers import LogFormat
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.readers.ros.recording import RecordingRead
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import RobotDescription, robot_from_log


def robot_for(
    path: Path, log: RangeLog, options: ReadOptions
) -> tuple[RobotDescription | None, str | None, str | None]:
    """The robot build would use, where it comes from, and the error build would stop at."""
    if options.robot is not None:
        return options.robot, "--robot", None
    try:
        robot = robot_from_log(path, log.metadata)
    except GridmapError as exc:
        return None, None, str(exc)
    return robot, "the log's robot line" if robot is not None else None, None


def build_problem(log: RangeLog, robot: RobotDescription | None) -> str | None:
    """The error build would stop at once it has read the log and found the robot, or None.

    Build's own checks with its default options (``--mode standard``, 0.05 m cells): the
    sensors' mounting, readings left after sync, the size of the map. A log without odometry
    that build would map (a laser alone) gets its track from the scans, too slow to make here:
    of it only the sensors' description is checked.
    """
    try:
        check_needs(pose_source(DEFAULT_SOURCE), log, robot)  # build's default --pose
        if len(log.poses) == 0:
            sensors_for_log(log, robot)
            return None
        plan_build(log, robot, BuildOptions())
    except GridmapError as exc:
        return str(exc)
    return None


def build_part(
    fmt: LogFormat,
    log: RangeLog,
    mcap: RecordingRead | None,
    robot: RobotDescription | None,
    robot_source: str | None,
    problems: list[str],
) -> dict[str, Any]:
    """What build would read each input from, its robot, and whether it would run."""
    if mcap is not None:
        plan = mcap.plan
        if log.odometry_missing is not None:
            odometry = _no_odometry(log, robot)
        elif plan.odom_topic is not None:
            channel = mcap.survey.topic(plan.odom_topic)
            odometry = f"{plan.odom_topic} ({channel.type_name if channel else '?'})"
        elif plan.tf_topics:
            odometry = f"TF {plan.odom_frame} -> {mcap.base_frame} on {', '.join(plan.tf_topics)}"
        else:
            odometry = None
        ranges = list(plan.range_topics)
        truth = mcap.truth_from
        frames: dict[str, Any] = {"odom": plan.odom_frame, "base": mcap.base_frame}
        odom_topic = plan.odom_topic
    elif fmt.name == "csv":
        odometry = "columns time, x, y, theta"
        ranges = [f"{len(log.sensor_names)} sensor columns: {' '.join(ends(log.sensor_names))}"]
        truth = "columns true_x, true_y, true_theta" if log.truth is not None else None
        frames = {}
        odom_topic = None
    elif fmt.name == "carmen":
        odometry = (
            "ODOM lines: the chain of their increments (the robot's own odometry)"
            if log.odometry_missing is None
            else _no_odometry(log, robot)
        )
        lasers = sorted({n.rpartition("_")[0] for n in log.sensor_names})
        ranges = [f"{laser} ({sum(n.startswith(laser + '_') for n in log.sensor_names)} beams)"
                  for laser in lasers]  # fmt: skip
        truth = None
        if log.truth is not None:
            truth = log.metadata.get("truth", "reference track").removesuffix(" (--pose global)")
            truth = "reference track: " + truth
        frames = {}
        odom_topic = None
    else:
        odometry = "robot: lines (encoder pose)"
        lasers = [n for n in log.sensor_names if n.startswith("laser")]
        sonars = [n for n in log.sensor_names if not n.startswith("laser")]
        ranges = []
        if sonars:
            ranges.append(f"sonar: lines ({len(sonars)} sonars)")
        if lasers:
            ranges.append(f"sick/scan lines ({len(lasers)} laser beams)")
        truth = "robotGlobal: lines" if log.truth is not None else None
        frames = {}
        odom_topic = None
    mounted = {s.name for s in log.sensors or () if not math.isnan(s.x_m)}
    described_by_log = bool(log.sensor_names) and mounted >= set(log.sensor_names)
    if mcap is not None and any(v.startswith("robot") for v in mcap.mount_from.values()):
        described_by_log = False  # the robot gave a mounting the recording lacks
    return {
        "odometry": odometry,
        "odometry_topic": odom_topic,
        "frames": frames,
        "ranges": ranges,
        "truth": truth,
        "sensors": len(log.sensor_names),
        "lasers": lasers_part(fmt, log, robot),
        "robot": None
        if robot is None
        else {"name": robot.name, "from": robot_source, "needed": not described_by_log},
        "ready": not problems,
        "problem": problems[0] if problems else None,  # the error build stops at
        "problems": problems,
    }


def _no_odometry(log: RangeLog, robot: RobotDescription | None) -> str:
    """Why the log has no odometry, and what build's default makes of a laser alone."""
    why = (log.odometry_missing or "").removeprefix("missing: ").removeprefix("no odometry: ")
    motion = "; build takes the motion from the laser's scans" if has_laser(log, robot) else ""
    return f"none: {why}{motion}"


def build_lines(d: dict[str, Any]) -> list[str]:
    """The "What build would use" section of the whole description ``d``, verdict last."""
    b = d["build"]
    mcap = d.get("mcap")
    lines = ["", "What build would use:"]
    lines.append(f"  odometry  {b['odometry'] or 'none'}")
    if b["frames"] and mcap is not None and (mcap["tf"] or mcap["static_frames"]):
        lines.append(f"  frames    odometry '{b['frames']['odom']}', base '{b['frames']['base']}'")
    lines.append(f"  ranges    {some(b['ranges'], 6) or 'none'}")
    for laser in b["lasers"]:
        lines.append(f"  laser     {laser_text(laser)}")
    if b["truth"]:
        lines.append(f"  truth     {b['truth']} (with --pose global)")
    lines.append(f"  sensors   {b['sensors']}")
    robot = b["robot"]
    if robot is None:
        lines.append("  robot     none")
    else:
        lines.append(f"  robot     {robot['name']} ({robot['from']})")
        if not robot["needed"]:
            lines[-1] += f"; not needed: the log describes all {b['sensors']} sensors"
    if b["ready"]:
        lines.append("  -> ready to build")
    else:
        # the file name and topic list are shown above already
        for i, problem in enumerate(b["problems"]):
            problem = problem.removeprefix(f"{d['file']}: ").split("; topics: ")[0]
            lines.append(f"  -> build would fail: {problem}" if i == 0 else f"     and: {problem}")
    return lines
