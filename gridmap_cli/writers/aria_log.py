"""Writer for ARIA-style ``.2d`` logs, lasers and gridmap's sonar extension (schemas/aria-log.md).

Poses are written as ARIA does (mm, mm, degrees with two decimals), ranges in whole mm, times as
exact decimal seconds; a log at that resolution (as ``gridmap simulate`` makes them) therefore
reads back bit-identical. Metadata goes into ``# key: value`` comment lines, which ARIA's own
readers skip and gridmap's reader keeps.

ARIA's loggers write no laser range, so each laser's range goes into gridmap's
``sick<N>minRange:`` / ``sick<N>maxRange:`` header lines (tags ARIA's readers skip, as they skip
every tag they do not know), and a beam with no echo is written as that maximum, rounded up to
whole mm: what ArSickLogger's ``sick1:`` lines hold for a beam that saw nothing (the laser's
out-of-range value), and what gridmap's reader turns back into no echo.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import TextIO

import numpy as np

from gridmap_cli.atomic import atomic_write
from gridmap_cli.errors import GridmapError
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import RangeSensor
from gridmap_cli.writers import Laser, check_metadata_lines, laser_groups
from gridmap_cli.writers.csv_log import ns_to_seconds_text

_SONAR_NAME = re.compile(r"^sonar(\d+)$")
_LASER_FRAME = re.compile(r"^laser(\d+)$")


def _num(value: float) -> str:
    """A number of mm or degrees without float noise: 147.0 -> '147', 12.5 -> '12.5'."""
    text = f"{value:.6f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def _pose(x_m: float, y_m: float, theta_rad: float) -> str:
    return f"{round(x_m * 1000.0):d} {round(y_m * 1000.0):d} {math.degrees(theta_rad):.2f}"


def _layout(sensors: tuple[RangeSensor, ...]) -> tuple[list[int], dict[int, Laser]]:
    """Column indices of the sonar units (in unit order), and the lasers by ARIA number."""
    singles, groups = laser_groups(sensors, "the ARIA format")
    sonar: list[int] = []
    for column in singles:
        name, kind = sensors[column].name, sensors[column].kind
        sonar_match = _SONAR_NAME.match(name)
        if not (kind == "sonar" and sonar_match and int(sonar_match.group(1)) == len(sonar)):
            raise _cannot_hold(name)
        sonar.append(column)
    lasers: dict[int, Laser] = {}
    for laser in groups:
        number = _LASER_FRAME.match(laser.frame)
        if number is None or int(number.group(1)) in lasers:
            raise _cannot_hold(sensors[laser.columns[0]].name)
        lasers[int(number.group(1))] = laser
    return sonar, lasers


def _cannot_hold(name: str) -> GridmapError:
    return GridmapError(
        f"the ARIA format cannot hold sensor {name!r}: sonar units are sonar0, sonar1, "
        "... in order and laser beams laser<N>_0, laser<N>_1, ..."
    )


def write_aria_log(log: RangeLog, sensors: tuple[RangeSensor, ...], handle: TextIO) -> None:
    """Write a log of sonar and laser readings; ``sensors`` gives ``log.sensor_names``' geometry.

    Sonar units must be named ``sonar0`` .. ``sonarN-1`` in order, as ARIA numbers them, and
    laser beams ``laser<N>_0`` .. in order, at one position and evenly spaced in angle (the
    ``sick<N>pose:`` and ``sick<N>conf:`` lines hold nothing else), or it is refused.
    Laser beams with no echo (at or beyond the laser's maximum range) are written as the
    maximum range, which the ``sick<N>maxRange:`` header line gives, never as 0 (ARIA's "no
    reading", which a reader drops).
    """
    names = list(log.sensor_names)
    if names != [s.name for s in sensors]:
        raise GridmapError("sensor geometry does not match the log's sensors")
    sonar, lasers = _layout(sensors)
    if len({sensors[c].max_range_m for c in sonar}) > 1:
        raise GridmapError("the ARIA sonar format has one sonarMaxRange for all units")
    check_metadata_lines(log.metadata)
    if not np.isfinite(log.readings.range_m).all():
        raise GridmapError(
            "the ARIA format holds ranges in whole mm, not infinity (write no echo as the "
            "sensor's maximum range)"
        )

    poses, truth, readings = log.poses, log.truth, log.readings
    row_of = np.searchsorted(poses.stamp_ns, readings.stamp_ns)
    inside = row_of < len(poses)
    if not inside.all() or not np.array_equal(poses.stamp_ns[row_of], readings.stamp_ns):
        raise GridmapError("the ARIA format keeps readings in pose blocks: a reading has no pose")
    if truth is not None and not np.array_equal(truth.stamp_ns, poses.stamp_ns):
        raise GridmapError("the ARIA format needs robotGlobal poses at the odometry stamps")
    max_range = np.asarray([s.max_range_m for s in sensors], dtype=np.float64)
    mm = np.round(readings.range_m * 1000.0).astype(np.int64)
    # no echo at the maximum in whole mm, rounded up so that it still reads as no echo
    no_echo_mm = np.ceil(np.round(max_range * 1000.0, 6)).astype(np.int64)
    no_echo = (readings.range_m >= max_range[readings.sensor]) & np.isin(
        readings.sensor, [c for laser in lasers.values() for c in laser.columns]
    )
    table = np.zeros((len(poses), len(names)), dtype=np.int64)  # 0 = no reading
    table[row_of, readings.sensor] = np.where(no_echo, no_echo_mm[readings.sensor], mm)

    handle.write("LaserOdometryLog\n#Created by gridmap\n")
    for key, value in log.metadata.items():
        handle.write(f"# {key}: {value}\n")
    handle.write("version: 4\n")
    for number, laser in sorted(lasers.items()):
        handle.write(
            f"sick{number}pose: {_num(laser.x_m * 1000.0)} {_num(laser.y_m * 1000.0)} 0\n"
            f"sick{number}conf: {_num(math.degrees(laser.first_yaw_rad))} "
            f"{_num(math.degrees(laser.last_yaw_rad))} {len(laser.columns)}\n"
            f"sick{number}minRange: {_num(laser.range_min_m * 1000.0)}\n"
            f"sick{number}maxRange: {_num(laser.range_max_m * 1000.0)}\n"
        )
    handle.write("locationTypes: robot" + (" robotGlobal\n" if truth is not None else "\n"))
    for unit, column in enumerate(sonar):
        s = sensors[column]
        handle.write(
            f"sonarUnit: {unit} {_num(s.x_m * 1000.0)} {_num(s.y_m * 1000.0)} "
            f"{_num(math.degrees(s.yaw_rad))}\n"
        )
    if sonar:
        handle.write(f"sonarMaxRange: {_num(sensors[sonar[0]].max_range_m * 1000.0)}\n")
    for i in range(len(poses)):
        handle.write(f"logTime: {ns_to_seconds_text(int(poses.stamp_ns[i]))}\n")
        handle.write(f"robot: {_pose(poses.x_m[i], poses.y_m[i], poses.theta_rad[i])}\n")
        if truth is not None:
            handle.write(f"robotGlobal: {_pose(truth.x_m[i], truth.y_m[i], truth.theta_rad[i])}\n")
        if sonar:
            handle.write("sonar: " + " ".join(str(v) for v in table[i, sonar]) + "\n")
        for number, laser in sorted(lasers.items()):
            beams = list(laser.columns)
            handle.write(f"sick{number}: " + " ".join(str(v) for v in table[i, beams]) + "\n")


def save_aria_log(log: RangeLog, sensors: tuple[RangeSensor, ...], path: Path) -> None:
    """Write ``log`` to ``path`` atomically (nothing is left behind on failure)."""
    with (
        atomic_write(path, "the log") as tmp,
        open(tmp, "w", encoding="ascii", newline="\n") as out,
    ):
        write_aria_log(log, sensors, out)
