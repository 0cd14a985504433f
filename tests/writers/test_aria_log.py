"""The ARIA .2d writer: what it writes reads back, and what the format cannot hold is refused."""

from __future__ import annotations

import dataclasses
import io
import math
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.errors import GridmapError
from gridmap_cli.readers.text.aria_log import read_aria_log
from gridmap_cli.records import PoseTrack, RangeLog, RangeReadings
from gridmap_cli.robot import RangeSensor, load_robot
from gridmap_cli.writers.aria_log import write_aria_log
from tests.helpers import run

S = 1_000_000_000
POSES = PoseTrack(
    np.array([0, S // 10], dtype=np.int64),
    np.array([0.0, 0.041]),
    np.array([0.0, -0.002]),
    np.array([0.0, math.radians(1.25)]),
)


def log_for(names: tuple[str, ...], rows: list[tuple[int, int, float]]) -> RangeLog:
    readings = RangeReadings(
        np.array([r[0] for r in rows], dtype=np.int64),
        np.array([r[1] for r in rows], dtype=np.int32),
        np.array([r[2] for r in rows], dtype=np.float64),
    )
    return RangeLog("mem", POSES, readings, names, truth=POSES, metadata={"seed": "1"})


def written(log: RangeLog, sensors: tuple[RangeSensor, ...]) -> str:
    out = io.StringIO()
    write_aria_log(log, sensors, out)
    return out.getvalue()


def test_sonar_and_laser_round_trip() -> None:
    robot = load_robot("p3at-lms200")
    names = robot.names()
    laser0, laser90 = names.index("laser1_0"), names.index("laser1_90")
    log = log_for(
        names,
        [
            (0, 0, 1.234),
            (0, 15, 4.335),  # sonar no echo: kept as a range at the maximum
            (0, laser0, 2.5),
            (0, laser90, 8.0),  # laser no echo: written as the maximum, read as no echo
            (S // 10, laser90, 7.999),
        ],
    )
    text = written(log, robot.sensors)
    assert "sick1pose: 160 0 0\nsick1conf: -90 90 181\n" in text
    assert "sick1minRange: 0\nsick1maxRange: 8000\n" in text
    assert "sonarUnit: 15 -144 136 90\nsonarMaxRange: 4335\n" in text
    assert "# seed: 1\n" in text
    back = read_aria_log(io.StringIO(text), "back.2d")
    assert back.metadata["seed"] == "1"
    assert np.array_equal(back.poses.x_m, POSES.x_m)
    assert np.array_equal(back.poses.theta_rad, POSES.theta_rad)
    got = {(int(t), back.sensor_names[k], r) for t, k, r in zip(
        back.readings.stamp_ns, back.readings.sensor, back.readings.range_m, strict=True
    )}  # fmt: skip
    assert got == {
        (0, "sonar0", 1.234),
        (0, "sonar15", 4.335),
        (0, "laser1_0", 2.5),
        (0, "laser1_90", 8.0),
        (S // 10, "laser1_90", 7.999),
    }
    assert back.sensors is not None
    beams = {s.name: s for s in back.sensors}
    assert (beams["laser1_0"].min_range_m, beams["laser1_0"].max_range_m) == (0.0, 8.0)
    assert beams["laser1_0"].yaw_rad == pytest.approx(-math.pi / 2)
    assert beams["laser1_180"].yaw_rad == pytest.approx(math.pi / 2)


@pytest.mark.parametrize(
    ("names", "message"),
    [
        (("sonar1",), "cannot hold sensor 'sonar1'"),
        (("front",), "cannot hold sensor 'front'"),
    ],
)
def test_sensors_the_format_cannot_name_are_refused(names: tuple[str, ...], message: str) -> None:
    sensors = tuple(RangeSensor(n, 0, 0, 0, 0.4, 0.1, 4.0) for n in names)
    with pytest.raises(GridmapError, match=message):
        written(log_for(names, [(0, 0, 1.0)]), sensors)


def test_a_reading_between_poses_is_refused() -> None:
    sensors = (RangeSensor("sonar0", 0, 0, 0, 0.4, 0.1, 4.0),)
    with pytest.raises(GridmapError, match="a reading has no pose"):
        written(log_for(("sonar0",), [(S // 20, 0, 1.0)]), sensors)


def test_an_infinite_range_is_refused_not_written_as_a_huge_negative() -> None:
    """No echo reaches the writer as the maximum range (convert.write_log sees to it); an
    infinity cannot be whole millimetres."""
    sensors = (RangeSensor("sonar0", 0, 0, 0, 0.4, 0.1, 4.0),)
    with pytest.raises(GridmapError, match="not infinity"):
        written(log_for(("sonar0",), [(0, 0, math.inf)]), sensors)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"yaw_rad": 0.3}, "laser 'laser1': the ARIA format needs beams at one position"),
        ({"x_m": 0.2}, "laser 'laser1': the ARIA format needs beams at one position"),
    ],
)
def test_a_laser_that_sick_conf_cannot_describe_is_refused(
    change: dict[str, float], message: str
) -> None:
    """sick<N>pose/conf hold one position and the first and last beam: an irregular laser
    would come back with other geometry, so it is refused rather than written."""
    robot = load_robot("p3at-lms200")
    names = robot.names()
    sensors = list(robot.sensors)
    k = names.index("laser1_90")
    sensors[k] = dataclasses.replace(sensors[k], **change)
    log = log_for(names, [(0, names.index("laser1_0"), 2.5)])
    with pytest.raises(GridmapError, match=message):
        written(log, tuple(sensors))
    # the robot as described writes, with the conf line that makes those very beams
    assert "sick1conf: -90 90 181\n" in written(log, robot.sensors)


def test_laser_beams_out_of_order_are_refused() -> None:
    sensors = (
        RangeSensor("laser1_1", 0, 0, 0.1, 0.0, 0.0, 8.0, kind="laser"),
        RangeSensor("laser1_0", 0, 0, 0.0, 0.0, 0.0, 8.0, kind="laser"),
    )
    names = tuple(s.name for s in sensors)
    with pytest.raises(GridmapError, match=r"beams must be named laser1_0, laser1_1, \.\.\. in"):
        written(log_for(names, [(0, 0, 1.0)]), sensors)


def laser_log(rows: list[tuple[int, int, float]]) -> tuple[RangeLog, tuple[RangeSensor, ...]]:
    """A three-beam laser reaching 0.02-5.5005 m (not whole mm) and its beams' geometry."""
    sensors = tuple(
        RangeSensor(f"laser2_{i}", 0.1, 0.0, (i - 1) * 0.5, 0.0, 0.02, 5.5005, kind="laser")
        for i in range(3)
    )
    return log_for(tuple(s.name for s in sensors), rows), sensors


def test_laser_no_echo_is_written_at_the_maximum_and_read_back_as_no_echo() -> None:
    """A beam at or beyond the maximum (the simulator's exact maximum, a CSV's larger value)
    is no echo: written as the maximum rounded up to whole mm, so that it reads back at or
    beyond sick2maxRange and the reader stores it as exactly the maximum."""
    log, sensors = laser_log([(0, 0, 1.25), (0, 1, 5.5005), (0, 2, 9.0), (S // 10, 0, 5.4)])
    text = written(log, sensors)
    assert "sick2minRange: 20\nsick2maxRange: 5500.5\n" in text
    assert "sick2: 1250 5501 5501\n" in text
    back = read_aria_log(io.StringIO(text), "back.2d")
    assert back.sensors is not None
    assert {(s.min_range_m, s.max_range_m) for s in back.sensors} == {(0.02, 5.5005)}
    assert list(back.readings.sensor) == [0, 1, 2, 0]
    assert list(back.readings.range_m) == [1.25, 5.5005, 5.5005, 5.4]


def test_an_infinite_laser_range_converts_to_the_maximum(tmp_path: Path) -> None:
    """`gridmap convert` of a CSV whose no-echo beams are 'inf' keeps them as no echo."""
    src = tmp_path / "scan.csv"
    src.write_text(
        "# robot: p3at-lms200\ntime,x,y,theta,"
        + ",".join(f"laser1_{i}" for i in range(181))
        + ",sonar0\n0.0,0,0,0,inf,"
        + ",".join(["2.5"] * 179)
        + ",inf,1.5\n"
    )
    out = tmp_path / "scan.2d"
    code, _, err = run("convert", str(src), str(out), "-q")
    assert code == 0, err
    back = read_aria_log(out)
    ranges = dict(zip((back.sensor_names[k] for k in back.readings.sensor),
                      back.readings.range_m.tolist(), strict=True))  # fmt: skip
    assert len(ranges) == 182
    assert (ranges["laser1_0"], ranges["laser1_1"], ranges["laser1_180"]) == (8.0, 2.5, 8.0)
    assert ranges["sonar0"] == 1.5
