"""`--pose slam` round a ring of long, featureless corridors (issue 20): the scan matcher learns
the odometry's distance scale where the walls pin every direction and uses it where they do not,
and the pose graph lets a loop closure stretch a corridor instead of bending the track."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from gridmap_cli.poses.correction.pose_graph import largest_bend
from gridmap_cli.poses.correction.scan_match import (
    DEGENERATE,
    FALLBACK,
    ScanMatchParams,
    laser_scans,
    match_log,
)
from gridmap_cli.poses.correction.slam import (
    SlamParams,
    SlamResult,
    sequential_edges,
    slam_scans,
)
from gridmap_cli.poses.sync import interpolate_pose, sensors_for_log
from gridmap_cli.poses.track_error import track_error
from gridmap_cli.records import PoseTrack, RangeLog
from gridmap_cli.sim.path import WaypointPath
from gridmap_cli.sim.simulate import simulate
from tests.test_scan_match import RES, laser_robot, wall, world_from

#: the simulator's scale error at --drift 2: the odometry reports 2 % too far
SCALE_ERROR = 0.02


def corridor_ring() -> np.ndarray:
    """A ring of corridors 2.4 m wide round a 30 x 4 m block: the long ones 33 m of bare wall,
    longer than the laser's 8 m reach ahead can see the end of."""
    mask = np.zeros((int(11 / RES), int(38 / RES)), dtype=bool)
    wall(mask, 1.0, 1.0, 37.0, 1.1)
    wall(mask, 1.0, 9.9, 37.0, 10.0)
    wall(mask, 1.0, 1.0, 1.1, 10.0)
    wall(mask, 36.9, 1.0, 37.0, 10.0)
    wall(mask, 3.5, 3.5, 34.5, 7.5)
    return mask


@pytest.fixture(scope="module")
def ring_run() -> RangeLog:
    path = WaypointPath(
        waypoints=np.array([[2.3, 2.3], [35.7, 2.3], [35.7, 8.7], [2.3, 8.7], [2.3, 2.3],
                            [12.0, 2.3]]),
        speed_m_s=1.0,
    )  # fmt: skip
    return simulate(
        world_from(corridor_ring()), path, laser_robot(), rate_hz=5.0, seed=5, drift=2.0
    )


def run_slam(log: RangeLog, **changes: float) -> SlamResult:
    match_params = ScanMatchParams()
    if "scale_min_m" in changes:
        match_params = dataclasses.replace(match_params, scale_min_m=changes.pop("scale_min_m"))
    scans = laser_scans(log, sensors_for_log(log, laser_robot()), match_params)
    return slam_scans(scans, log.poses, SlamParams(**changes), match_params)


def rms(log: RangeLog, result: SlamResult, which: str) -> tuple[float, float]:
    """APE of the slam or scan-matched track against the truth after the best rigid fit (as
    evo_ape -a): position RMS (m) and heading RMS (deg)."""
    track = result.track if which == "slam" else result.scan_matched.track
    assert log.truth is not None
    x, y, th, _ = interpolate_pose(log.truth, track.stamp_ns)
    error = track_error(track, PoseTrack(track.stamp_ns, x, y, th))
    return error.ape_rmse_m, error.ape_heading_deg


def length_error_m(log: RangeLog, track: PoseTrack) -> float:
    """How much longer ``track``'s path is than the true one over the same stamps (m)."""
    assert log.truth is not None
    x, y, _, _ = interpolate_pose(log.truth, track.stamp_ns)
    return float(
        np.hypot(np.diff(track.x_m), np.diff(track.y_m)).sum()
        - np.hypot(np.diff(x), np.diff(y)).sum()
    )


def test_the_odometry_scale_is_learned_and_keeps_the_corridors_their_length(
    ring_run: RangeLog,
) -> None:
    result = run_slam(ring_run)
    match = result.scan_matched
    assert np.count_nonzero(match.status == DEGENERATE) > 0.5 * len(match.track)
    # learned where the corners pin every direction (the realised scale carries the random
    # distance error too, hence the margin)
    assert abs(match.distance_scale - 1 / (1 + SCALE_ERROR)) < 0.01
    # without it the odometry's 2 % lengthens the 67 m of bare corridor by a metre: the
    # learned scale takes most of that out
    unscaled = match_log(ring_run, laser_robot(), ScanMatchParams(scale_min_m=math.inf))
    assert unscaled.distance_scale == 1.0
    too_long = length_error_m(ring_run, unscaled.track)
    assert too_long > 0.9
    assert abs(length_error_m(ring_run, match.track)) < 0.5 * too_long
    assert result.closures and result.warning is None
    assert rms(ring_run, result, "slam")[0] < 0.3


def test_edges_along_a_corridor_are_loose_along_it_only() -> None:
    """Keyframe edges over degenerate scans get the extra sigma along the scans' weak axis (in
    the later node's frame); a track bent along it counts for less in the bend check."""
    n = 11
    local = np.column_stack([np.linspace(0, 2, n), np.zeros(n), np.full(n, math.pi / 2)])
    weak = np.tile([1.0, 0.0], (n, 1))  # the map's x, the robot's -y
    weak[0] = np.nan
    status = np.full(n, DEGENERATE, dtype=np.int8)
    params = SlamParams()
    nodes = np.array([0, 5, 10])
    edges = sequential_edges(local, status, nodes, params, weak)
    iso = sequential_edges(local, status, nodes, params)
    assert [e.weak_sigma_m for e in edges] == pytest.approx([params.degenerate_sigma_per_m] * 2)
    assert all(abs(e.weak_axis[1]) == pytest.approx(1.0) for e in edges)
    assert all(e.weak_sigma_m == 0.0 for e in iso)
    bent = local[nodes].copy()
    bent[2, 0] += 0.2  # node 2 moved along the corridor
    assert largest_bend(bent, edges) < 0.5 * largest_bend(bent, iso)
    across = local[nodes].copy()
    across[2, 1] += 0.2  # ...and across it: as stiff as ever
    assert largest_bend(across, edges) == pytest.approx(largest_bend(across, iso))


def test_a_fallback_in_a_turn_loosens_its_edge_by_the_odometry_turn() -> None:
    """A scan that fell back took the odometry's step: its edge's heading sigma widens with the
    turn that scan made (the odometry's error grows with it), not only with the path."""
    n = 6
    turning = np.column_stack([np.zeros(n), np.zeros(n), np.linspace(0.0, 0.5, n)])
    status = np.zeros(n, dtype=np.int8)
    params = SlamParams()
    nodes = np.array([0, 5])
    matched = sequential_edges(turning, status, nodes, params)[0]
    status[3] = FALLBACK  # one step of 0.1 rad taken from the odometry
    fell = sequential_edges(turning, status, nodes, params)[0]
    base = params.fallback_scale * matched.sigma_theta_rad
    assert fell.sigma_theta_rad == pytest.approx(base + params.fallback_sigma_theta_per_rad * 0.1)
    # on a straight drive the fallback adds no turn term
    straight = np.column_stack([np.linspace(0.0, 1.0, n), np.zeros(n), np.zeros(n)])
    plain = sequential_edges(straight, np.zeros(n, dtype=np.int8), nodes, params)[0]
    fell_straight = sequential_edges(straight, status, nodes, params)[0]
    assert fell_straight.sigma_theta_rad == pytest.approx(
        params.fallback_scale * plain.sigma_theta_rad
    )
