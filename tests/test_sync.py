from __future__ import annotations

import math

import numpy as np
import pytest

from gridmap_cli.errors import GridmapError, naming
from gridmap_cli.geometry import compose
from gridmap_cli.poses.odometry_error import travelled_at
from gridmap_cli.poses.sync import interpolate_pose, stamp_groups, synchronise
from gridmap_cli.records import PoseTrack, RangeLog, RangeReadings
from gridmap_cli.robot import RangeSensor, RobotDescription

S = 1_000_000_000


def track(stamps_s, xs, ys, ths) -> PoseTrack:
    return PoseTrack(
        np.asarray([round(t * S) for t in stamps_s], dtype=np.int64),
        np.asarray(xs, float),
        np.asarray(ys, float),
        np.asarray(ths, float),
    )


def test_interpolates_linearly_and_flags_outside() -> None:
    t = track([0, 1, 2], [0, 1, 3], [0, 0, 2], [0, 0, 0])
    x, y, _, valid = interpolate_pose(t, np.array([-1, 0, S // 2, 3 * S // 2, 2 * S, 3 * S]))
    assert list(valid) == [False, True, True, True, True, False]
    assert x[1:5] == pytest.approx([0, 0.5, 2, 3])
    assert y[1:5] == pytest.approx([0, 0, 1, 2])


def test_heading_interpolates_along_the_short_arc() -> None:
    t = track([0, 1], [0, 0], [0, 0], [math.pi - 0.1, -math.pi + 0.1])
    _, _, th, _ = interpolate_pose(t, np.array([S // 2]))
    assert abs(abs(th[0]) - math.pi) < 1e-9  # through pi, not through 0


def make_log(names=("a", "b")) -> RangeLog:
    readings = RangeReadings(
        stamp_ns=np.array([0, S // 2, S // 2, 5 * S], dtype=np.int64),
        sensor=np.array([0, 0, 1, 1], dtype=np.int32),
        range_m=np.array([1.0, 0.05, 9.0, 1.0]),
    )
    return RangeLog("mem", track([0, 1], [0, 2], [0, 0], [0, math.pi / 2]), readings, names)


ROBOT = RobotDescription(
    "r",
    (
        RangeSensor("a", 0.2, 0.0, 0.0, 0.4, 0.1, 5.0),
        RangeSensor("b", 0.0, 0.1, math.pi / 2, 0.4, 0.1, 5.0),
    ),
)


def test_sensor_pose_is_robot_pose_composed_with_mounting() -> None:
    readings, stats = synchronise(make_log(), ROBOT)
    assert stats.total == 4 and stats.used == 2
    assert stats.outside_odometry == 1 and stats.below_min_range == 1
    # reading 0: robot at origin, heading 0 -> sensor a at (0.2, 0)
    assert readings.x_m[0] == pytest.approx(0.2) and readings.y_m[0] == pytest.approx(0.0)
    # reading 2: robot at (1, 0) heading pi/4 -> sensor b at (1, 0) + R(pi/4) (0, 0.1)
    c = math.cos(math.pi / 4) * 0.1
    assert readings.x_m[1] == pytest.approx(1 - c) and readings.y_m[1] == pytest.approx(c)
    assert readings.theta_rad[1] == pytest.approx(math.pi / 4 + math.pi / 2)
    assert readings.range_m[1] == 5.0  # beyond max range: capped, means no echo


def test_unknown_sensor_names_are_an_error() -> None:
    with pytest.raises(GridmapError, match="'sonar9' not described by robot 'r'"):
        synchronise(make_log(("a", "sonar9")), ROBOT)


def test_missing_robot_is_an_error_naming_the_argument_or_the_flag() -> None:
    with pytest.raises(GridmapError, match="give robot "):
        synchronise(make_log(), None)
    with naming("flags"), pytest.raises(GridmapError, match="give --robot "):
        synchronise(make_log(), None)


def test_readings_sharing_a_stamp_get_the_pose_interpolated_for_each_alone() -> None:
    # synchronise interpolates once per run of equal stamps; the poses must be those of
    # interpolating every reading on its own, bit for bit, including stamps that come back
    rng = np.random.default_rng(2)
    t = track(np.arange(0, 20, 0.1), np.cumsum(rng.uniform(0, 0.1, 200)),
              np.cumsum(rng.uniform(-0.05, 0.05, 200)), rng.uniform(-3.1, 3.1, 200))  # fmt: skip
    stamps = np.sort(rng.integers(-S, 21 * S, 300))
    stamps = np.concatenate([np.repeat(stamps, rng.integers(1, 5, 300)), stamps[:3]])
    first, group = stamp_groups(stamps)
    assert np.array_equal(stamps[first][group], stamps)
    assert len(first) < len(stamps)
    n = len(stamps)
    log = RangeLog(
        "mem", t, RangeReadings(stamps, (np.arange(n) % 2).astype(np.int32), np.full(n, 1.0)),
        ("a", "b"),
    )  # fmt: skip
    readings, stats = synchronise(log, ROBOT)
    x, y, th, valid = interpolate_pose(t, stamps)
    assert stats.used == int(valid.sum()) > 0
    mount = np.array([0.0, math.pi / 2])[log.readings.sensor[valid]]
    assert np.array_equal(readings.theta_rad, compose(x[valid], y[valid], th[valid],
                          np.array([0.2, 0.0])[log.readings.sensor[valid]],
                          np.array([0.0, 0.1])[log.readings.sensor[valid]], mount)[2])  # fmt: skip
    d, r = travelled_at(t, stamps[valid])
    assert np.array_equal(readings.distance_m, d)
    assert np.array_equal(readings.rotation_rad, r)


def test_stamp_groups_of_nothing() -> None:
    first, group = stamp_groups(np.zeros(0, dtype=np.int64))
    assert first.shape == group.shape == (0,)
