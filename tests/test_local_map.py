"""A scan matched on the part of it the local map saw (``local_map.match_in_part``)."""

from __future__ import annotations

import numpy as np

from gridmap_cli.poses.correction.local_map import LocalMap, match_in_part
from gridmap_cli.poses.correction.scan_match import ScanMatchParams

PARAMS = ScanMatchParams()
H = np.eye(6)


def _corner() -> np.ndarray:
    """A wall across at x = 4 and one along at y = 2.5, as a robot at the origin facing +x
    sees them (K, 2): enough to pin every direction."""
    across = np.column_stack([np.full(121, 4.0), np.linspace(-2.5, 2.5, 121)])
    along = np.column_stack([np.linspace(0.5, 3.9, 80), np.full(80, 2.5)])
    return np.vstack([across, along])


def _local_map() -> LocalMap:
    local = LocalMap(PARAMS)
    local.add(_corner(), (0.0, 0.0, 0.0))
    return local


def _scan() -> np.ndarray:
    """The corner again and as much behind the robot, where the local map never looked."""
    behind = np.column_stack([np.full(250, -4.0), np.linspace(-3.0, 3.0, 250)])
    return np.vstack([_corner()[::2], behind])


def _fraction(planar: np.ndarray, pose: tuple[float, float, float]) -> float:
    """The inlier fraction of the scan over all of it, as the matcher scores it."""
    local = _local_map()
    assert local.tree2d is not None
    x, y, th = pose
    c, s = np.cos(th), np.sin(th)
    moved = np.column_stack(
        [x + c * planar[:, 0] - s * planar[:, 1], y + s * planar[:, 0] + c * planar[:, 1]]
    )
    dist, _ = local.tree2d.query(moved, distance_upper_bound=PARAMS.inlier_m)
    return float(np.mean(np.isfinite(dist)))


def test_a_scan_half_in_new_space_holds_on_what_the_map_saw_where_two_starts_agree() -> None:
    planar = _scan()
    fraction = _fraction(planar, (0.0, 0.0, 0.0))
    assert fraction < PARAMS.min_inlier_fraction  # under the gate over the whole scan
    gate = PARAMS.min_inlier_fraction
    tried = [(fraction, (0.02, 0.0, 0.0), H, gate), (fraction, (0.0, 0.03, 0.005), H, gate)]
    found = match_in_part(tried, planar, _local_map(), PARAMS)
    assert found is not None
    _, pose, _ = found
    # registered again on the seen part: back on the corner
    assert abs(pose[0]) < 0.02 and abs(pose[1]) < 0.02 and abs(pose[2]) < 0.01


def test_one_start_alone_is_not_enough() -> None:
    planar = _scan()
    fraction = _fraction(planar, (0.0, 0.0, 0.0))
    gate = PARAMS.min_inlier_fraction
    alone = [(fraction, (0.02, 0.0, 0.0), H, gate), (0.1, (0.0, 1.5, 0.4), H, gate)]
    assert match_in_part(alone, planar, _local_map(), PARAMS) is None


def test_a_pose_that_puts_the_seen_part_in_the_maps_free_space_is_refused() -> None:
    planar = _scan()
    gate = PARAMS.min_inlier_fraction
    # a metre short: the wall across lands a metre inside the room the map saw empty
    short = [(0.3, (-1.0, 0.0, 0.0), H, gate), (0.3, (-1.01, 0.0, 0.0), H, gate)]
    assert match_in_part(short, planar, _local_map(), PARAMS) is None
    # the share a turn beyond the heading bound needs (the log's usual fit) is asked too
    tried = [(0.4, (0.0, 0.0, 0.0), H, 1.01), (0.4, (0.01, 0.0, 0.0), H, 1.01)]
    assert match_in_part(tried, planar, _local_map(), PARAMS) is None
