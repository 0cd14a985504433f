"""Motion from the scans alone (gridmap_cli/poses/correction/scan_odometry.py): the track a laser
without odometry gives follows the true path, through turns the constant-velocity prediction does
not see coming."""

from __future__ import annotations

import math

import numpy as np

from gridmap_cli.geometry import wrap_angle
from gridmap_cli.poses.correction.relocate import half_share
from gridmap_cli.poses.correction.scan_match import ScanMatchParams, laser_scans
from gridmap_cli.poses.correction.scan_odometry import (
    ScanOdometryParams,
    _Keyframes,
    far_apart,
    scan_odometry,
)
from gridmap_cli.poses.sync import interpolate_pose, sensors_for_log
from gridmap_cli.records import PoseTrack
from gridmap_cli.robot import load_robot
from gridmap_cli.sim.path import WaypointPath
from gridmap_cli.sim.simulate import simulate
from tests.test_pioneer_bag import LOOP
from tests.test_scan_match import room_world


def test_fast_turns_are_followed_from_the_scans_alone() -> None:
    """The room loop at 1 m/s turning 180 degrees a second: each corner starts with a step of
    18 degrees the last step did not predict, and ends with one it predicts wrongly. The track,
    placed at the first true pose, stays on the true path (within 1.3 cm and 0.13 degrees
    here)."""
    robot = load_robot("p3at-lms200")
    path = WaypointPath(np.asarray(LOOP, dtype=np.float64), speed_m_s=1.0,
                        turn_rate_rad_s=math.pi)  # fmt: skip
    log = simulate(room_world(), path, robot, seed=5, drift=1.0)
    scans = laser_scans(log, sensors_for_log(log, robot), ScanMatchParams())
    track = scan_odometry(scans)
    truth = log.truth
    assert truth is not None
    tx, ty, tth, _ = interpolate_pose(truth, track.stamp_ns)
    c, s = math.cos(tth[0]), math.sin(tth[0])
    x = tx[0] + c * track.x_m - s * track.y_m
    y = ty[0] + s * track.x_m + c * track.y_m
    heading = wrap_angle(track.theta_rad + tth[0] - tth)
    assert np.abs(np.diff(np.unwrap(tth))).max() > math.radians(15)  # the turns are there
    assert np.hypot(x - tx, y - ty).max() < 0.05
    assert np.degrees(np.abs(heading)).max() < 0.5


def test_a_match_that_fits_worse_than_usual_is_searched_for() -> None:
    """GICP from a start turned 45 degrees off lands near the true heading but off the pose,
    with half the scan's points on the local map; fitting worse than the log's scans usually
    do (``bar``), the correlative search around the prediction finds the pose where the scan
    fits as well as usual."""
    robot = load_robot("p3at-lms200")
    path = WaypointPath(np.asarray(LOOP, dtype=np.float64), speed_m_s=1.0,
                        turn_rate_rad_s=math.pi)  # fmt: skip
    log = simulate(room_world(), path, robot, seed=5, drift=1.0)
    scans = laser_scans(log, sensors_for_log(log, robot), ScanMatchParams())
    truth = log.truth
    assert truth is not None
    tx, ty, tth, _ = interpolate_pose(truth, scans.stamp_ns)
    found = {}
    for bar in (0.0, 0.95):  # none asked for; then the fit the scans here reach
        keyframes = _Keyframes(ScanOdometryParams())
        for k in range(5):
            keyframes.offer(scans.points[k], (float(tx[k]), float(ty[k]), float(tth[k])))
        off = (float(tx[6]), float(ty[6]), float(tth[6]) + math.radians(45.0))
        found[bar] = keyframes.match(scans.points[6], [off, off], bar)
    alone, searched = found[0.0], found[0.95]
    assert alone is not None and searched is not None
    assert alone[1] < 0.6  # held, but only just
    (x, y, th), fit = searched
    assert fit >= 0.95
    assert math.hypot(x - tx[6], y - ty[6]) < 0.05
    assert abs(math.degrees(float(wrap_angle(th - tth[6])))) < 1.0


def _straight(steps_m: list[float]) -> PoseTrack:
    x = np.concatenate([[0.0], np.cumsum(steps_m)])
    zero = np.zeros(len(x))
    return PoseTrack(stamp_ns=np.arange(len(x), dtype=np.int64), x_m=x, y_m=zero, theta_rad=zero)


def test_scans_further_apart_than_the_inlier_band_are_warned_of() -> None:
    band = ScanOdometryParams().inlier_m
    warning = far_apart(_straight([1.0] * 20))
    assert warning is not None and "the scans are 1.00 m apart" in warning
    assert f"{band:g} m inlier band" in warning
    # a full-rate laser: a few centimetres a scan, and long stops, nothing to warn of
    assert far_apart(_straight([0.05] * 200 + [0.0] * 500)) is None
    # a robot that stood still or a single scan: no step at all
    assert far_apart(_straight([0.0] * 10)) is None
    assert far_apart(_straight([])) is None
    # stops do not hide the spacing of the scans where it drove
    assert far_apart(_straight([0.0] * 1000 + [0.6] * 30)) is not None


def test_half_share_is_the_length_half_the_total_is_made_of() -> None:
    # 1 + 1 + 1 + 10: the 10 alone is more than half of 13
    assert half_share(np.array([1.0, 10.0, 1.0, 1.0])) == 10.0
    assert half_share(np.array([2.0, 2.0, 2.0])) == 2.0
    assert half_share(np.array([0.0, 0.0, 3.0])) == 3.0
