"""The ARIA .2d reader: laser logs old and new, the sonar extension, and path:line errors."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.errors import InputFileError
from gridmap_cli.poses.sync import synchronise
from gridmap_cli.readers import read_log, resolve_format
from gridmap_cli.readers.text.aria_log import LASER_MAX_RANGE_M, read_aria_log, sniff
from gridmap_cli.robot import load_robot

V4 = """\
LaserOdometryLog
#Created by ArLaserLogger
version: 4
sick1pose: 160 0 0.00
sick1conf: -90.00 90.00 5
sick1name: Laser_1
scan1pose: 160 0 0 0.00
scan1conf: -90.00 90.00 5
scan1name: Laser_1
locationTypes: robot robotGlobal
someFutureTag: 1 2 3
logTime: 0.000
velocities: 0.00 0.00 0.00
scanId: 0
robot: 0 0 0.00
robotGlobal: 1000 2000 90.00
scan1: 160 -1000  1160 -1000  2160 0  0 0  160 1000
logTime: 0.500
velocities: 100.00 0.00 0.00
scanId: 1
robot: 50 0 10.00
robotGlobal: 1000 2050 100.00
scan1: 160 -1000  1160 -1000  2160 0  1160 1000  160 1000
time: 0.700
robot: 60 0 10.00 0 0
cairn: GoalWithHeading "" ICON_GOALWITHHEADING "goal1"
# End of log
"""

V2 = """\
LaserOdometryLog
#Created by ARIA's ArSickLogger
version: 2
sick1pose: 0 0 0.00
sick1conf: -90 90 3
scan1Id: 1
time: 1.5
velocities: 0 0
robot: 1000 -500 45
sick1: 1000 0 2500
scan1Id: 2
time: 2.25
robot: 1100 -500 45
sick1: 900 1200 2400
"""

SONAR = """\
LaserOdometryLog
version: 4
sonarUnit: 0 147 136 90
sonarUnit: 1 193 119 50
sonarMaxRange: 5000
logTime: 0.1
robot: 0 0 0
sonar: 500 5000
logTime: 0.2
robot: 40 0 0
sonar: 460 1200
"""


def write(tmp_path: Path, text: str, name: str = "run.2d") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_version_4_laser_log(tmp_path: Path) -> None:
    log = read_aria_log(write(tmp_path, V4))
    assert log.sensor_names == tuple(f"laser1_{i}" for i in range(5))
    assert log.sensors is not None
    yaws = [s.yaw_rad for s in log.sensors]
    assert yaws == pytest.approx(np.radians([-90, -45, 0, 45, 90]))
    assert all(s.kind == "laser" and s.beam_width_rad == 0 and s.x_m == 0.16 for s in log.sensors)
    # the goal block (cairn:) is not data; two scans remain
    assert list(log.poses.stamp_ns) == [0, 500_000_000]
    assert log.poses.x_m == pytest.approx([0.0, 0.05])
    assert log.poses.theta_rad == pytest.approx([0.0, math.radians(10)])
    assert log.truth is not None and log.truth.y_m == pytest.approx([2.0, 2.05])
    # end points become ranges from the laser; '0 0' is an ignored reading
    first = log.readings.stamp_ns == 0
    assert list(log.readings.sensor[first]) == [0, 1, 2, 4]
    assert log.readings.range_m[first] == pytest.approx([1.0, math.sqrt(2), 2.0, 1.0])
    assert len(log.readings) == 9
    assert log.metadata["version"] == "4"


def test_version_2_sick_ranges(tmp_path: Path) -> None:
    log = read_aria_log(write(tmp_path, V2))
    assert list(log.poses.stamp_ns) == [1_500_000_000, 2_250_000_000]
    assert log.poses.theta_rad[0] == pytest.approx(math.pi / 4)
    assert log.truth is None
    # a 0 range is no reading
    assert list(log.readings.sensor) == [0, 2, 0, 1, 2]
    assert log.readings.range_m == pytest.approx([1.0, 2.5, 0.9, 1.2, 2.4])


def test_laser_range_lines_make_beams_at_or_beyond_the_maximum_no_echo(tmp_path: Path) -> None:
    """gridmap's sick1minRange/sick1maxRange lines give the laser's range; a beam at or beyond
    the maximum is no echo, stored as exactly the maximum (0 is still no reading)."""
    text = V2.replace(
        "sick1conf: -90 90 3\n", "sick1conf: -90 90 3\nsick1minRange: 20\nsick1maxRange: 2400\n"
    )
    log = read_aria_log(write(tmp_path, text))
    assert log.sensors is not None
    assert {(s.min_range_m, s.max_range_m) for s in log.sensors} == {(0.02, 2.4)}
    assert list(log.readings.sensor) == [0, 2, 0, 1, 2]
    assert list(log.readings.range_m) == [1.0, 2.4, 0.9, 1.2, 2.4]


def test_a_laser_log_without_range_lines_keeps_its_ranges(tmp_path: Path) -> None:
    """ARIA's own logs say nothing of the laser's range: the ranges are taken as written and
    the laser reaches LASER_MAX_RANGE_M, as before gridmap wrote range lines."""
    log = read_aria_log(
        write(tmp_path, V2.replace("sick1: 900 1200 2400", "sick1: 900 1200 40000"))
    )
    assert log.sensors is not None
    assert {(s.min_range_m, s.max_range_m) for s in log.sensors} == {(0.0, LASER_MAX_RANGE_M)}
    assert list(log.readings.range_m) == [1.0, 2.5, 0.9, 1.2, 40.0]


def test_sonar_units_from_the_header(tmp_path: Path) -> None:
    log = read_aria_log(write(tmp_path, SONAR))
    assert log.sensor_names == ("sonar0", "sonar1")
    assert log.sensors is not None
    assert log.sensors[1].x_m == pytest.approx(0.193)
    assert log.sensors[1].yaw_rad == pytest.approx(math.radians(50))
    assert log.sensors[0].max_range_m == 5.0
    assert log.readings.range_m == pytest.approx([0.5, 5.0, 0.46, 1.2])


def test_sonar_without_units_takes_geometry_from_the_robot(tmp_path: Path) -> None:
    text = SONAR.replace("sonarUnit: 0 147 136 90\nsonarUnit: 1 193 119 50\n", "")
    log = read_aria_log(write(tmp_path, text))
    assert log.sensor_names == ("sonar0", "sonar1") and log.sensors == ()
    readings, stats = synchronise(log, load_robot("p3at"))
    assert stats.used == 4
    assert readings.sensors[0] == load_robot("p3at").sensors[0]


def test_registry_picks_the_reader_by_extension_and_by_sniffing(tmp_path: Path) -> None:
    assert resolve_format(write(tmp_path, V4)).name == "aria"
    assert resolve_format(write(tmp_path, V4, "run.log")).name == "aria"
    assert sniff(b"LaserOdometryLog\n#x\n") and not sniff(b"time,x,y,theta\n")
    assert len(read_log(write(tmp_path, V4, "noext")).readings) == 9


def line_of(text: str, marker: str) -> int:
    """1-based line number of the first line containing ``marker``."""
    return text[: text.index(marker)].count("\n") + 1


SCAN2 = "scan1: 160 -1000  1160 -1000  2160 0  1160 1000  160 1000"
NO_CONF = V4.replace("sick1conf: -90.00 90.00 5\n", "").replace("scan1conf: -90.00 90.00 5\n", "")


@pytest.mark.parametrize(
    ("text", "marker", "message"),
    [
        ("version: 4\n", "version", "not an ARIA laser log: expected 'LaserOdometryLog' first"),
        (
            V4.replace("robot: 50 0 10.00", "robot: 50 0"),
            "robot: 50 0",
            "robot: expected 3 numbers",
        ),
        (
            V4.replace("robot: 50 0 10.00", "robot: 50 zero 10"),
            "zero",
            "robot: not a number: 'zero'",
        ),
        (V4.replace("logTime: 0.500", "logTime: half"), "half", "logTime: not a number: 'half'"),
        (
            V4.replace("logTime: 0.500", "logTime: -0.5"),
            "-0.5",
            "time goes backwards: -0.5 s after 0 s (block at line 12)",
        ),
        (V4.replace("logTime: 0.500", "logTime: 0.0"), "logTime: 0.0\n", "time repeats"),
        (V4.replace(SCAN2, "scan1: 160"), "scan1: 160\n", "scan1: expected 5 x y pairs, found 0.5"),
        (V4.replace("robot: 50 0 10.00\n", ""), "logTime: 0.500", "block has no 'robot:' pose"),
        (NO_CONF, "scan1: 160", "laser 1 readings but no sick1conf: header"),
        (V2.replace("sick1: 1000 0 2500", "sick1: 1000 0"), "sick1: 1000 0\n", "expected 3 ranges"),
        (SONAR.replace("sonar: 460 1200", "sonar: 460"), "sonar: 460", "sonar: expected 2 ranges"),
        (SONAR.replace("sonarUnit: 1 193", "sonarUnit: 0 193"), "0 193", "unit 0 declared twice"),
        ("LaserOdometryLog\nversion: 4\nsick1conf: -90 90 3\n", "sick1conf", "no reading blocks"),
        ("LaserOdometryLog\nrobot 1 2 3\n", "robot", "expected 'tag: values'"),
        (V2.replace("sick1conf", "sick1maxRange: 0\nsick1conf"), "sick1max", "must be positive"),
        (
            V2.replace("sick1conf", "sick1minRange: -1\nsick1conf"),
            "sick1min",
            "sick1minRange: must not be negative",
        ),
        (
            V2.replace("sick1conf", "sick1maxRange: 2000\nsick1minRange: 2000\nsick1conf"),
            "sick1min",
            "laser 1: minimum range 2000 mm is not below the maximum range 2000 mm",
        ),
    ],
)
def test_malformed_logs_name_file_and_line(
    tmp_path: Path, text: str, marker: str, message: str
) -> None:
    path = write(tmp_path, text)
    with pytest.raises(InputFileError) as info:
        read_aria_log(path)
    assert str(info.value).startswith(f"{path}:{line_of(text, marker)}: "), str(info.value)
    assert message in str(info.value)


def test_truncated_file_is_reported(tmp_path: Path) -> None:
    cut = V4[: V4.index("scan1: 160 -1000  1160 -1000  2160 0  1160") + 30]
    path = write(tmp_path, cut)
    with pytest.raises(InputFileError, match=r"run.2d:23: scan1: expected 5 x y pairs"):
        read_aria_log(path)
