"""A log whose stamps do not advance (one printed time for every record, spaced by a microsecond
by its reader) measures no time: calibrate fits no stamp lag on it
(poses/calibration/windows.py)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from gridmap_cli.poses.calibration.calibrate import calibrate
from gridmap_cli.poses.calibration.windows import compare_windows, truth_at_odometry
from gridmap_cli.records import RangeLog, stamps_advance
from tests.helpers import log_with_truth


def wandering(seed: int = 3, records: int = 6000, walk: float = 0.03) -> RangeLog:
    """A robot at 0.4 m/s (10 Hz) whose turn rate changes from record to record; its odometry's
    heading takes a random error of ``walk`` rad per sqrt(rad) turned."""
    rng = np.random.default_rng(seed)
    truth: list[tuple[float, float, float]] = []
    odometry: list[tuple[float, float, float]] = []
    x = y = th = ox = oy = oth = 0.0
    for k in range(records):
        truth.append((x, y, th))
        odometry.append((ox, oy, oth))
        turn = 0.15 * math.sin(k / 37.0) + 0.1 * float(rng.standard_normal())
        x, y, th = x + 0.04 * math.cos(th), y + 0.04 * math.sin(th), th + turn
        ox, oy = ox + 0.04 * math.cos(oth), oy + 0.04 * math.sin(oth)
        oth += turn + walk * math.sqrt(abs(turn)) * float(rng.standard_normal())
    return log_with_truth(truth, odometry)


def still(log: RangeLog) -> RangeLog:
    """``log`` with every record one microsecond after the last, as a reader spaces a log
    that prints one time for all of them."""
    stamps = np.arange(len(log.poses), dtype=np.int64) * 1000 + 1_000_000_000_000_000_000
    assert log.truth is not None
    return dataclasses.replace(
        log,
        poses=dataclasses.replace(log.poses, stamp_ns=stamps),
        truth=dataclasses.replace(log.truth, stamp_ns=stamps.copy()),
        readings=dataclasses.replace(log.readings, stamp_ns=stamps.copy()),
    )


def test_the_stamps_advance_test() -> None:
    assert stamps_advance(0, 100_000_000, 11)  # 10 Hz
    assert not stamps_advance(0, 10_000, 11)  # a microsecond apart
    assert stamps_advance(0, 0, 2)  # too few to tell


def test_stamps_that_do_not_advance_give_no_turn_rate_and_so_no_lag() -> None:
    log = wandering()
    windows = compare_windows(*truth_at_odometry(log))
    assert windows.turn_rate_change is not None and np.any(windows.turn_rate_change)
    frozen = compare_windows(*truth_at_odometry(still(log)))
    assert frozen.turn_rate_change is not None and not np.any(frozen.turn_rate_change)
    # the same windows otherwise: only the lag, which needs time, is gone
    assert np.array_equal(frozen.heading_error_rad, windows.heading_error_rad)


def test_calibrate_fits_the_same_biases_on_still_stamps() -> None:
    moving, frozen = calibrate(wandering()), calibrate(still(wandering()))
    for key in ("distance_scale_bias", "turn_scale_bias", "heading_drift_bias_rad_per_m"):
        assert getattr(frozen.model, key) == pytest.approx(getattr(moving.model, key), abs=2e-3)
