"""Writer for ARIA-style ``.2d`` logs with gridmap's sonar extension (``schemas/aria-log.md``).

Poses are written as ARIA does (mm, mm, degrees with two decimals), ranges in whole mm, times as
exact decimal seconds; a log at that resolution (as ``gridmap simulate`` makes them) therefore
reads back bit-identical. Metadata goes into ``# key: value`` comment lines, which ARIA's own
readers skip and gridmap's reader keeps.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import TextIO

import numpy as np

from gridmap_cli.atomic import atomic_output
from gridmap_cli.errors import GridmapError
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import RangeSensor
from gridmap_cli.writers.csv_log import ns_to_seconds_text

_SONAR_NAME = re.compile(r"^sonar(\d+)$")


def _num(value: float) -> str:
    """A number of mm or degrees without float noise: 147.0 -> '147', 12.5 -> '12.5'."""
    text = f"{value:.6f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def _pose(x_m: float, y_m: float, theta_rad: float) -> str:
    return f"{round(x_m * 1000.0):d} {round(y_m * 1000.0):d} {math.degrees(theta_rad):.2f}"


def write_aria_log(log: RangeLog, sensors: tuple[RangeSensor, ...], handle: TextIO) -> None:
    """Write a sonar log; ``sensors`` gives the geometry of ``log.sensor_names`` in order.

    Sonar units must be named ``sonar0`` .. ``sonarN-1`` in that order, as ARIA numbers them.
    """
    names = list(log.sensor_names)
    for i, name in enumerate(names):
        match = _SONAR_NAME.match(name)
        if match is None or int(match.group(1)) != i:
            raise GridmapError(
                f"the ARIA sonar format numbers its units: sensor {i} must be 'sonar{i}', "
                f"not {name!r}"
            )
    max_ranges = {s.max_range_m for s in sensors}
    if len(max_ranges) > 1:
        raise GridmapError("the ARIA sonar format has one sonarMaxRange for all units")
    for key, value in log.metadata.items():
        if not key or ":" in key or any(c in key + value for c in "\r\n"):
            raise GridmapError(f"metadata {key!r}: {value!r} cannot be a '# key: value' line")

    poses, truth, readings = log.poses, log.truth, log.readings
    row_of = np.searchsorted(poses.stamp_ns, readings.stamp_ns)
    inside = row_of < len(poses)
    if not inside.all() or not np.array_equal(poses.stamp_ns[row_of], readings.stamp_ns):
        raise GridmapError("the ARIA format keeps readings in pose blocks: a reading has no pose")
    if truth is not None and not np.array_equal(truth.stamp_ns, poses.stamp_ns):
        raise GridmapError("the ARIA format needs robotGlobal poses at the odometry stamps")
    table = np.zeros((len(poses), len(names)), dtype=np.int64)  # 0 = no reading
    table[row_of, readings.sensor] = np.round(readings.range_m * 1000.0).astype(np.int64)

    handle.write("LaserOdometryLog\n#Created by gridmap\n")
    for key, value in log.metadata.items():
        handle.write(f"# {key}: {value}\n")
    handle.write("version: 4\n")
    handle.write("locationTypes: robot" + (" robotGlobal\n" if truth is not None else "\n"))
    for i, s in enumerate(sensors):
        handle.write(
            f"sonarUnit: {i} {_num(s.x_m * 1000.0)} {_num(s.y_m * 1000.0)} "
            f"{_num(math.degrees(s.yaw_rad))}\n"
        )
    if sensors:
        handle.write(f"sonarMaxRange: {_num(sensors[0].max_range_m * 1000.0)}\n")
    for i in range(len(poses)):
        handle.write(f"logTime: {ns_to_seconds_text(int(poses.stamp_ns[i]))}\n")
        handle.write(f"robot: {_pose(poses.x_m[i], poses.y_m[i], poses.theta_rad[i])}\n")
        if truth is not None:
            handle.write(f"robotGlobal: {_pose(truth.x_m[i], truth.y_m[i], truth.theta_rad[i])}\n")
        if names:
            handle.write("sonar: " + " ".join(str(v) for v in table[i]) + "\n")


def save_aria_log(log: RangeLog, sensors: tuple[RangeSensor, ...], path: Path) -> None:
    """Write ``log`` to ``path`` atomically (nothing is left behind on failure)."""
    try:
        with atomic_output(path) as tmp, open(tmp, "w", encoding="ascii", newline="\n") as handle:
            write_aria_log(log, sensors, handle)
    except OSError as exc:
        raise GridmapError(f"{path}: cannot write the log: {exc.strerror or exc}") from exc
