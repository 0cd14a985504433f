"""A scan the odometry lost (a turn it never counted, as when its messages stop while the robot
turns): the scan matcher finds it again on its local map by the correlative search, instead of
keeping the odometry's step and bending every pose after it."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from gridmap_cli.geometry import compose, inverse
from gridmap_cli.poses.correction.relocate import typical_fit
from gridmap_cli.poses.correction.scan_match import FALLBACK, ScanMatchParams, match_log
from gridmap_cli.records import PoseTrack, RangeLog
from tests.test_scan_match import errors, laser_robot, room_world, run

#: the turn the odometry misses, far beyond the matcher's retries and heading bound
MISSED_RAD = math.radians(60.0)


def missed_turn(log: RangeLog, at_s: float, turn_rad: float) -> RangeLog:
    """``log`` with its odometry turned by ``turn_rad`` about its pose at ``at_s`` from then
    on: an increment of the odometry that says the robot turned when it did not."""
    odo = log.poses
    t = (odo.stamp_ns - odo.stamp_ns[0]) / 1e9
    k = int(np.searchsorted(t, at_s))
    px, py, pth = odo.x_m[k - 1], odo.y_m[k - 1], odo.theta_rad[k - 1]
    ix, iy, ith = inverse(px, py, pth)
    rx, ry, rth = compose(ix, iy, ith, odo.x_m[k:], odo.y_m[k:], odo.theta_rad[k:])
    x, y, th = compose(*compose(px, py, pth, 0.0, 0.0, turn_rad), rx, ry, rth)
    poses = PoseTrack(
        stamp_ns=odo.stamp_ns,
        x_m=np.concatenate([odo.x_m[:k], x]),
        y_m=np.concatenate([odo.y_m[:k], y]),
        theta_rad=np.concatenate([odo.theta_rad[:k], th]),
    )
    return dataclasses.replace(log, poses=poses)


@pytest.fixture(scope="module")
def lost_turn() -> RangeLog:
    log = run(room_world(), [[2, 1.5], [10, 1.5], [10, 6.5]], drift=1.0)
    return missed_turn(log, at_s=8.0, turn_rad=MISSED_RAD)


def test_a_turn_the_odometry_missed_is_found_again(lost_turn: RangeLog) -> None:
    match = match_log(lost_turn, laser_robot())
    ex, ey, eth = errors(lost_turn, match.track)
    assert np.hypot(ex, ey).max() < 0.15
    assert np.abs(eth).max() < math.radians(2.0)
    assert match.fallbacks == 0


def test_without_the_search_the_turn_bends_the_track(lost_turn: RangeLog) -> None:
    """The same log with the search switched off: the step falls back to the odometry and
    every pose after it is turned by the missed 60 degrees (what the test above guards)."""
    match = match_log(lost_turn, laser_robot(), ScanMatchParams(search_rad=0.0))
    _, _, eth = errors(lost_turn, match.track)
    assert np.abs(eth).max() > math.radians(30.0)
    assert np.count_nonzero(match.status == FALLBACK) >= 1


def test_typical_fit_is_the_lower_quartile_once_there_are_enough() -> None:
    fractions = np.array([np.nan, 0.1, *np.linspace(0.5, 1.0, 21), 0.2])
    assert typical_fit(fractions, 0.5) == pytest.approx(0.625)  # fallbacks and NaN left out
    assert typical_fit(fractions[:6], 0.5) == 1.0  # too few matches: only a perfect fit passes
