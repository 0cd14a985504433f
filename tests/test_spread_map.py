"""The pose spread at which each cell was seen (spread_map.py, evaluate --spread-plot)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.evaluation.spread_map import pose_spread_map, reading_spreads
from gridmap_cli.mapping.grid import GridSpec
from gridmap_cli.poses.odometry_error import OdometryError, save_odometry_error
from gridmap_cli.poses.sync import SensorReadings, select_readings, synchronise
from gridmap_cli.poses.uncertainty.pose_uncertainty import PoseUncertainty, StepNoise, propagate
from gridmap_cli.readers import read_log
from gridmap_cli.robot import RangeSensor, robot_from_log
from tests.helpers import run

SAMPLES = Path(__file__).resolve().parents[1] / "samples"
SAMPLE = SAMPLES / "corridor_loop.csv"
#: The simulator's drift-1 errors (the sample is a drift-1 run), as gridmap calibrate finds them.
DRIFT1 = OdometryError(
    range_m_per_m=0.01,
    range_m_per_sqrt_m=0.01,
    bearing_rad_per_rad=0.02,
    bearing_rad_per_sqrt_rad=0.02,
    heading_drift_rad_per_m=0.0035,
)


def test_two_readings_by_hand() -> None:
    # a laser at the origin looking along +x (2 m, echo) with a known pose, and one looking up
    # when the pose's standard deviations are 0.4 m (x; 0.3 m in y) and 0.04 rad
    laser = RangeSensor(name="laser", x_m=0.0, y_m=0.0, yaw_rad=0.0, beam_width_rad=0.0,
                        min_range_m=0.0, max_range_m=5.0)  # fmt: skip
    readings = SensorReadings(
        stamp_ns=np.array([0, 1], dtype=np.int64),
        sensor=np.zeros(2, dtype=np.int32),
        range_m=np.array([2.0, 2.0]),
        x_m=np.array([0.05, 0.05]),
        y_m=np.array([0.05, 0.05]),
        theta_rad=np.array([0.0, math.pi / 2]),
        sensors=(laser,),
        distance_m=np.array([0.0, 4.0]),
        rotation_rad=np.zeros(2),
    )
    cov = np.zeros((2, 3, 3))
    cov[1] = np.diag([0.4**2, 0.3**2, 0.04**2])
    cov[1, 0, 1] = cov[1, 1, 0] = 0.0
    known = PoseUncertainty(np.array([0, 1], dtype=np.int64), np.zeros(2), np.zeros(2), cov)
    spread = pose_spread_map(GridSpec(0.0, 0.0, 0.1, 30, 30), readings, known)
    # the first reading's row: 0 m; its start cell is also on the second's column: still 0
    assert np.all(spread.position_m[0, :21] == 0.0)
    # the second reading's column above the shared cell: 0.4 m (the ellipse's long axis), 0.04 rad
    assert spread.position_m[1:21, 0] == pytest.approx(np.full(20, 0.4), abs=spread.levels_m)
    assert spread.heading_rad[1:21, 0] == pytest.approx(np.full(20, 0.04), abs=spread.levels_rad)
    # nothing else was crossed
    assert np.count_nonzero(~np.isnan(spread.position_m)) == 21 + 20


def test_the_position_spread_is_the_long_axis_of_a_tilted_ellipse() -> None:
    laser = RangeSensor(name="laser", x_m=0.0, y_m=0.0, yaw_rad=0.0, beam_width_rad=0.0,
                        min_range_m=0.0, max_range_m=5.0)  # fmt: skip
    readings = SensorReadings(
        stamp_ns=np.array([5], dtype=np.int64), sensor=np.zeros(1, dtype=np.int32),
        range_m=np.array([1.0]), x_m=np.zeros(1), y_m=np.zeros(1), theta_rad=np.zeros(1),
        sensors=(laser,),
    )  # fmt: skip
    # axes 0.5 m and 0.1 m, turned 30 degrees
    a = math.radians(30.0)
    r = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    cov = np.zeros((2, 3, 3))
    cov[1, :2, :2] = r @ np.diag([0.25, 0.01]) @ r.T
    cov[1, 2, 2] = 0.09
    track = PoseUncertainty(np.array([0, 10], dtype=np.int64), np.zeros(2), np.zeros(2), cov)
    position, heading = reading_spreads(readings, track)
    # half way in time: half the variance
    assert position[0] == pytest.approx(math.sqrt(0.125))
    assert heading[0] == pytest.approx(math.sqrt(0.045))


def test_readings_sharing_a_stamp_share_the_spread_taken_one_by_one() -> None:
    """Runs of equal stamps (a scan's beams), a stamp coming back after another, and a lone
    reading: each reading's spreads as that reading alone gets them."""
    laser = RangeSensor(name="laser", x_m=0.0, y_m=0.0, yaw_rad=0.0, beam_width_rad=0.0,
                        min_range_m=0.0, max_range_m=5.0)  # fmt: skip
    stamps = np.array([5, 5, 5, 7, 7, 5, 9, 2, 2], dtype=np.int64)
    m = stamps.shape[0]
    readings = SensorReadings(
        stamp_ns=stamps, sensor=np.zeros(m, dtype=np.int32), range_m=np.ones(m),
        x_m=np.zeros(m), y_m=np.zeros(m), theta_rad=np.zeros(m), sensors=(laser,),
    )  # fmt: skip
    cov = np.zeros((3, 3, 3))
    cov[1] = [[0.04, 0.01, 0.0], [0.01, 0.02, 0.0], [0.0, 0.0, 0.01]]
    cov[2] = [[0.09, -0.03, 0.0], [-0.03, 0.16, 0.0], [0.0, 0.0, 0.04]]
    track = PoseUncertainty(np.array([0, 6, 10], dtype=np.int64), np.zeros(3), np.zeros(3), cov)
    position, heading = reading_spreads(readings, track)
    for k in range(m):
        alone = reading_spreads(select_readings(readings, slice(k, k + 1)), track)
        assert position[k] == alone[0][0] and heading[k] == alone[1][0]
    assert len(set(position.tolist())) == 4  # the four stamps give four spreads


@pytest.mark.skipif(not SAMPLE.exists(), reason="no samples")
def test_cells_seen_late_in_a_drifting_run_have_more_spread() -> None:
    log = read_log(SAMPLE)
    readings, _ = synchronise(log, robot_from_log(SAMPLE, log.metadata))
    track = propagate(log.poses, StepNoise.of(DRIFT1))
    spec = GridSpec(-15.0, -15.0, 0.1, 300, 300)
    n = len(readings)
    early = pose_spread_map(spec, select_readings(readings, slice(0, n // 10)), track)
    first_half = pose_spread_map(spec, select_readings(readings, slice(0, n // 2)), track)
    whole = pose_spread_map(spec, readings, track)
    position, _ = reading_spreads(readings, track)
    seen_early = ~np.isnan(early.position_m)
    only_late = np.isnan(first_half.position_m) & ~np.isnan(whole.position_m)
    assert seen_early.sum() > 100 and only_late.sum() > 100
    f_early = whole.position_m[seen_early]
    f_late = whole.position_m[only_late]
    # a cell seen in the first tenth keeps the spread it was seen with, never a later one
    assert f_early.max() <= float(position[: n // 10].max()) + whole.levels_m
    # cells only the second half saw were seen with the second half's spread, all of them
    assert f_late.min() >= float(position[n // 2 :].min()) - whole.levels_m
    # and the pose error grows along the run: the late cells' spread is several times more
    assert np.median(f_late) > 2 * np.median(f_early)


@pytest.mark.skipif(not SAMPLE.exists(), reason="no samples")
def test_cli_spread_plot(tmp_path: Path) -> None:
    odo = tmp_path / "odometry.yaml"
    save_odometry_error(DRIFT1, odo)
    image = tmp_path / "map.png"
    code, _, err = run(
        "build", str(SAMPLE), "-o", str(image), "--mode", "error-aware", "--map-mode", "scale",
        "--odometry-error", str(odo), "-q",
    )  # fmt: skip
    assert code == 0, err
    args = [
        "evaluate", str(image.with_suffix(".yaml")), "--truth",
        str(SAMPLES / "worlds" / "corridor_loop.yaml"), "--log", str(SAMPLE), "-q",
    ]  # fmt: skip
    plot = tmp_path / "spread.png"
    code, _, err = run(*args, "--spread-plot", str(plot), "--odometry-error", str(odo))
    assert code == 0, err
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    code, _, err = run(*args, "--spread-plot", str(plot), "--odometry-error", str(odo))
    assert code == 1 and "exists (use --force to overwrite)" in err
    code, _, err = run(*args, "--spread-plot", str(tmp_path / "s2.png"))
    assert code == 2 and "--spread-plot" in err and "--odometry-error" in err
    code, _, err = run(*args, "--odometry-error", str(odo))
    assert code == 2 and "--odometry-error is for --spread-plot" in err


def test_cli_spread_plot_of_a_log_that_describes_its_own_sensors(tmp_path: Path) -> None:
    # a CARMEN log has no robot preset (its laser lines say what the sensor is): the plot
    # must still be drawn, not silently skipped
    from tests.readers.carmen_helpers import flaser, write
    from tests.readers.test_carmen_log import corrected_log

    log = write(tmp_path, [*corrected_log(), flaser([1.0] * 5, (1.0, 0.1, 0.1), 2.0)])
    odo = tmp_path / "odometry.yaml"
    save_odometry_error(DRIFT1, odo)
    code, _, err = run("build", str(log), "-o", str(tmp_path / "ref.png"), "--pose", "global",
                       "-q")  # fmt: skip
    assert code == 0, err
    code, _, err = run(
        "build", str(log), "-o", str(tmp_path / "map.png"), "--mode", "error-aware",
        "--map-mode", "scale", "--odometry-error", str(odo), "-q",
    )  # fmt: skip
    assert code == 0, err
    plot = tmp_path / "spread.png"
    code, _, err = run(
        "evaluate", str(tmp_path / "map.yaml"), "--truth", str(tmp_path / "ref.yaml"),
        "--log", str(log), "-q", "--spread-plot", str(plot), "--odometry-error", str(odo),
    )  # fmt: skip
    assert code == 0, err
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
