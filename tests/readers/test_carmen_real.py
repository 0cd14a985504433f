"""The CARMEN reader on the classic corrected data sets in ../shared/data/carmen (skipped when
absent).

Facts asserted here were read from the files with zcat and awk (see SOURCES.md there).
"""

from __future__ import annotations

import math
from functools import cache
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.poses.odometry_error import travelled
from gridmap_cli.readers import read_log, resolve_format
from gridmap_cli.records import RangeLog

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "carmen"

pytestmark = pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data/carmen is not present")


@cache
def log(name: str) -> RangeLog:
    return read_log(DATA / f"{name}-corrected.log.gz")


def test_resolved_as_gzipped_carmen() -> None:
    assert resolve_format(DATA / "intel-corrected.log.gz").name == "carmen"


@pytest.mark.parametrize(
    ("name", "scans", "odom", "beams", "step_deg", "max_m", "no_echo"),
    [
        ("intel", 910, 14541, 180, 1.0, 80.0, 4172),  # no echo written as 81.83
        ("aces", 440, 7814, 180, 1.0, 50.0, 620),  # clipped at 50: the repeated largest value
        ("freiburg-079", 4791, 9725, 360, 0.5, 80.99, 36004),  # PARAM; no echo 81.91
    ],
)
def test_scans_beams_and_maximum_range(
    name: str, scans: int, odom: int, beams: int, step_deg: float, max_m: float, no_echo: int
) -> None:
    data = log(name)
    assert data.sensor_names == tuple(f"frontlaser_{i}" for i in range(beams))
    assert data.sensors is not None
    assert math.degrees(data.sensors[0].yaw_rad) == pytest.approx(-90.0)
    step = math.degrees(data.sensors[1].yaw_rad - data.sensors[0].yaw_rad)
    assert step == pytest.approx(step_deg)
    assert {s.max_range_m for s in data.sensors} == {max_m}
    assert data.truth is not None and len(data.truth) == scans
    # every ODOM line but the restarts, plus one pose per scan
    assert len(data.poses) == odom
    assert len(np.unique(data.readings.stamp_ns)) == scans
    # the no-echo readings are kept as such (inf): the ray model clears up to its cap
    assert len(data.readings) == scans * beams
    assert int(np.isinf(data.readings.range_m).sum()) == no_echo
    assert f"{no_echo} readings at or beyond it: no echo" in data.metadata["frontlaser"]
    assert np.all(np.diff(data.poses.stamp_ns) > 0) and np.all(np.diff(data.truth.stamp_ns) > 0)
    # both tracks have a pose at every scan's own stamp
    assert np.isin(data.readings.stamp_ns, data.poses.stamp_ns).all()
    assert np.isin(data.readings.stamp_ns, data.truth.stamp_ns).all()


def test_freiburg_laser_is_mounted_behind_the_centre() -> None:
    sensors = log("freiburg-079").sensors
    assert sensors is not None and sensors[0].x_m == -0.04


@pytest.mark.parametrize(("name", "low", "high"), [("intel", 0.95, 1.1), ("aces", 0.95, 1.05),
                                                    ("freiburg-079", 0.85, 1.0)])  # fmt: skip
def test_recovered_odometry_drives_as_far_as_the_corrected_track(
    name: str, low: float, high: float
) -> None:
    """Wrong increments (a jump at each restart) would add the corrections to the odometry's
    path; right ones leave it within a few percent of the corrected path."""
    data = log(name)
    assert data.truth is not None
    odometry_m = float(travelled(data.poses)[0][-1])
    corrected_m = float(travelled(data.truth)[0][-1])
    assert low < odometry_m / corrected_m < high
    steps = np.hypot(np.diff(data.poses.x_m), np.diff(data.poses.y_m))
    assert steps.max() < 0.4  # no jumps: ODOM comes at 5 Hz or more, at walking speed


def test_intel_closes_its_loop_only_with_the_corrected_poses() -> None:
    data = log("intel")
    assert data.truth is not None
    t, p = data.truth, data.poses
    assert math.hypot(t.x_m[-1] - t.x_m[0], t.y_m[-1] - t.y_m[0]) < 2.0
    assert math.hypot(p.x_m[-1] - p.x_m[0], p.y_m[-1] - p.y_m[0]) > 20.0  # raw Pioneer odometry


def test_stamp_quirks_are_repaired_and_said() -> None:
    assert "629 went back" in log("intel").metadata["stamps"]
    assert "0 went back and 440 repeated" in log("aces").metadata["stamps"]
