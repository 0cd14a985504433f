"""A scan the odometry lost: found again on the local map by the correlative search, instead of
keeping the odometry's step and turning every pose after it. Two ways to lose one: the odometry
misjudges a turn by more than the matcher's retries cover, and its messages stop while the
robot turns (a corrected CARMEN log then has no motion at all across the gap)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from gridmap_cli.geometry import compose, inverse
from gridmap_cli.poses.correction.relocate import (
    TypicalFit,
    odometry_gaps,
    typical_fit,
    usual_interval,
)
from gridmap_cli.poses.correction.scan_match import FALLBACK, ScanMatchParams, match_log
from gridmap_cli.records import PoseTrack, RangeLog
from tests.test_scan_match import errors, laser_robot, room_world, run

#: the robot reaches the corner (10, 1.5) at 16 s and turns 90 degrees in place at 40 deg/s:
#: the gap (11 of the odometry's 0.1 s intervals, so a gap to the matcher) loses the last 0.3 m
#: of the drive and 20 degrees of the turn, beyond the matcher's 15-degree bound and 16-degree
#: retries
CORNER_S = (15.4, 16.5)


def reanchored(odo: PoseTrack, keep: np.ndarray, a: int, k: int, turn_rad: float) -> PoseTrack:
    """``odo`` at ``keep`` (mask), its poses from index ``k`` on carried rigidly so that pose
    ``k`` lies where pose ``a`` does, turned by ``turn_rad`` (``a == k``: pose ``k`` turned in
    place; ``a < k``: the motion from ``a`` to ``k`` lost but for the turn)."""
    px, py, pth = odo.x_m[a], odo.y_m[a], odo.theta_rad[a]
    ix, iy, ith = inverse(odo.x_m[k], odo.y_m[k], odo.theta_rad[k])
    rx, ry, rth = compose(ix, iy, ith, odo.x_m[k:], odo.y_m[k:], odo.theta_rad[k:])
    x, y, th = compose(*compose(px, py, pth, 0.0, 0.0, turn_rad), rx, ry, rth)
    out = PoseTrack(
        stamp_ns=odo.stamp_ns,
        x_m=np.concatenate([odo.x_m[:k], x]),
        y_m=np.concatenate([odo.y_m[:k], y]),
        theta_rad=np.concatenate([odo.theta_rad[:k], th]),
    )
    return PoseTrack(out.stamp_ns[keep], out.x_m[keep], out.y_m[keep], out.theta_rad[keep])


@pytest.fixture(scope="module")
def corner_run() -> RangeLog:
    return run(room_world(), [[2, 1.5], [10, 1.5], [10, 6.5]], drift=1.0)


@pytest.fixture(scope="module")
def misjudged(corner_run: RangeLog) -> RangeLog:
    """The odometry turns 25 degrees too far in one step of a straight drive: beyond the
    matcher's 15-degree bound and its 16-degree retries."""
    odo = corner_run.poses
    t = (odo.stamp_ns - odo.stamp_ns[0]) / 1e9
    k = int(np.searchsorted(t, 8.0))
    poses = reanchored(odo, np.ones(len(odo), dtype=bool), k, k, math.radians(-25.0))
    return dataclasses.replace(corner_run, poses=poses)


@pytest.fixture(scope="module")
def gap(corner_run: RangeLog) -> RangeLog:
    """Neither odometry nor scans while the robot turns the corner, and the odometry after it
    carried on from where it stopped: across the gap it says the robot stood still."""
    odo = corner_run.poses
    t = (odo.stamp_ns - odo.stamp_ns[0]) / 1e9
    inside = (t > CORNER_S[0]) & (t < CORNER_S[1])
    a, k = (
        int(np.searchsorted(t, CORNER_S[0], side="right")) - 1,
        int(np.searchsorted(t, CORNER_S[1])),
    )
    poses = reanchored(odo, ~inside, a, k, 0.0)
    r = corner_run.readings
    rt = (r.stamp_ns - odo.stamp_ns[0]) / 1e9
    kept = ~((rt > CORNER_S[0]) & (rt < CORNER_S[1]))
    readings = dataclasses.replace(
        r, stamp_ns=r.stamp_ns[kept], sensor=r.sensor[kept], range_m=r.range_m[kept]
    )
    return dataclasses.replace(corner_run, poses=poses, readings=readings)


@pytest.mark.parametrize("which", ["misjudged", "gap"])
def test_a_lost_turn_is_found_again(which: str, request: pytest.FixtureRequest) -> None:
    log: RangeLog = request.getfixturevalue(which)
    match = match_log(log, laser_robot())
    ex, ey, eth = errors(log, match.track)
    assert np.hypot(ex, ey).max() < 0.15
    assert np.abs(eth).max() < math.radians(2.0)
    # without the search the step falls back to the odometry: every later pose is turned
    blind = match_log(log, laser_robot(), ScanMatchParams(search_rad=0.0))
    _, _, blind_eth = errors(log, blind.track)
    assert np.count_nonzero(blind.status == FALLBACK) >= 1
    assert np.abs(blind_eth).max() > math.radians(10.0)


def test_a_clock_that_stamps_in_bursts_has_gaps_only_where_it_stops() -> None:
    # odometry at 2 Hz, each message stamped with four more within a millisecond (as a clock
    # that runs in bursts does), scans at 10 Hz, and the odometry silent for 10 s in the middle
    waits = np.arange(0.0, 60.0, 0.5)
    waits = waits[(waits < 30.0) | (waits >= 40.0)]
    odometry_s = (waits[:, None] + np.arange(5) * 2e-4).ravel()
    scans_s = np.arange(0.05, 59.5, 0.1)
    gap = odometry_gaps((odometry_s * 1e9).astype(np.int64), (scans_s * 1e9).astype(np.int64))
    # the usual interval is the wait between bursts, not the spacing inside one
    assert usual_interval((odometry_s * 1e9).astype(np.int64)) == pytest.approx(0.5e9, rel=0.01)
    across = (scans_s > 29.5) & (scans_s < 40.5)
    assert gap[across].any()
    assert not gap[~across].any()


def test_the_running_typical_fit_is_typical_fit_at_every_step() -> None:
    """Asked after each match, the running value is numpy's percentile of the fits so far,
    bit for bit: fallbacks (under the floor) and NaN left out, 1.0 before there are enough."""
    rng = np.random.default_rng(3)
    fits = rng.uniform(0.3, 1.0, 400)
    fits[rng.random(400) < 0.1] = np.nan
    fits[:5] = [0.9, 0.95, 0.6, 0.4, 0.97]
    running = TypicalFit(0.5)
    values = []
    for k, fraction in enumerate(fits):
        assert running.value() == typical_fit(fits[:k], 0.5), k
        values.append(running.value())
        running.add(float(fraction))
    assert values[0] == 1.0 and min(values) < 0.8  # both branches were compared
