"""A closure candidate under the gate, judged on what the target's scans saw."""

from __future__ import annotations

import math

import numpy as np

from gridmap_cli.poses.correction.overlap import (
    contradicts,
    holds_in_part,
    seen_and_holding,
    views,
)


def _scan(wall_x: float, fov: float = math.radians(90.0), beams: int = 181) -> np.ndarray:
    """A robot at the origin facing +x, a wall across at ``wall_x``: the echoes (K, 2)."""
    bearing = np.linspace(-fov, fov, beams)
    r = wall_x / np.cos(bearing)
    keep = r < 20.0
    return np.column_stack([r[keep] * np.cos(bearing[keep]), r[keep] * np.sin(bearing[keep])])


def _noise(share: float = 0.02, count: int = 80, pairs: int = 200) -> np.ndarray:
    """Near pairs whose shares are all ``share`` of ``count`` echoes."""
    return np.column_stack([np.full(pairs, share), np.full(pairs, float(count))])


def test_a_point_is_seen_free_or_unseen_by_where_it_lies_on_the_beam() -> None:
    xyz = np.zeros((1, 3))
    scans = [_scan(4.0)]
    points = np.array(
        [
            [4.0, 0.0],  # on the wall: seen, not free
            [2.0, 0.0],  # in front of the wall: seen and free
            [3.9, 0.0],  # within the wall's depth: seen, not free
            [6.0, 0.0],  # behind the wall: unseen
            [-3.0, 0.0],  # behind the robot, outside its beams: unseen
            [0.2, 0.0],  # nearer than the compared ranges: seen, not free
        ]
    )
    seen, free = views(points, xyz, scans, 0.15)
    assert seen.tolist() == [True, True, True, False, False, True]
    assert free.tolist() == [False, True, False, False, False, False]


def test_the_scans_are_placed_by_their_poses() -> None:
    # the same scan from a robot at (10, 0) facing back (-x): its wall at x = 6
    xyz = np.array([[10.0, 0.0, math.pi]])
    seen, free = views(np.array([[6.0, 0.0], [8.0, 0.0], [4.0, 0.0]]), xyz, [_scan(4.0)], 0.15)
    assert seen.tolist() == [True, True, False]
    assert free.tolist() == [False, True, False]


def _wall_and_behind() -> tuple[np.ndarray, np.ndarray]:
    """The target saw a wall at x = 4 ahead of it; the source saw that wall too (60 points, the
    inliers), and 80 more to the robot's back, where the target never looked."""
    on_wall = np.column_stack([np.full(60, 4.0), np.linspace(-3.0, 3.0, 60)])
    behind = np.column_stack([np.full(80, -4.0), np.linspace(-3.0, 3.0, 80)])
    moved = np.vstack([on_wall, behind])
    return moved, np.arange(len(moved)) < len(on_wall)


def test_a_source_that_goes_on_where_the_target_never_looked_holds() -> None:
    target = (np.zeros((1, 3)), [_scan(4.0)])
    moved, inlier = _wall_and_behind()
    assert inlier.mean() < 0.45  # under the gate over all of the source
    assert holds_in_part(moved, inlier, target, _noise(), 0.45, 0.15)


def test_a_source_across_the_targets_free_space_is_refused() -> None:
    # the same inliers, but half again as many points inside the room the target saw empty
    target = (np.zeros((1, 3)), [_scan(4.0)])
    on_wall = np.column_stack([np.full(60, 4.0), np.linspace(-3.0, 3.0, 60)])
    across = np.column_stack([np.full(30, 2.0), np.linspace(-1.5, 1.5, 30)])
    behind = np.column_stack([np.full(60, -4.0), np.linspace(-3.0, 3.0, 60)])
    moved = np.vstack([on_wall, across, behind])
    inlier = np.arange(len(moved)) < len(on_wall)
    assert not holds_in_part(moved, inlier, target, _noise(), 0.45, 0.15)
    # a log whose own near pairs disagree that much would let it through
    assert holds_in_part(moved, inlier, target, _noise(0.3), 0.45, 0.15)


def test_too_few_inliers_among_what_the_target_saw_is_refused() -> None:
    target = (np.zeros((1, 3)), [_scan(4.0)])
    seen_not_matched = np.column_stack([np.full(60, 4.1), np.linspace(-3.0, 3.0, 60)])
    matched = np.column_stack([np.full(30, 4.0), np.linspace(-1.0, 1.0, 30)])
    moved = np.vstack([matched, seen_not_matched])
    inlier = np.arange(len(moved)) < len(matched)
    assert not holds_in_part(moved, inlier, target, _noise(), 0.45, 0.15)
    assert holds_in_part(moved, inlier, target, _noise(), 0.3, 0.15)


def test_a_target_that_saw_none_of_the_source_holds_nothing() -> None:
    target = (np.zeros((1, 3)), [_scan(4.0)])
    behind = np.column_stack([np.full(50, -4.0), np.linspace(-3.0, 3.0, 50)])
    assert not holds_in_part(behind, np.zeros(50, dtype=bool), target, _noise(), 0.45, 0.15)


def _wall_and_room(across: int) -> tuple[np.ndarray, np.ndarray]:
    """100 points on the target's wall at x = 4 and ``across`` inside the room it saw empty."""
    on_wall = np.column_stack([np.full(100, 4.0), np.linspace(-3.0, 3.0, 100)])
    room = np.column_stack([np.full(across, 2.0), np.linspace(-1.5, 1.5, across)])
    moved = np.vstack([on_wall, room])
    return moved, np.arange(len(moved)) < len(on_wall)


def test_a_source_contradicts_when_its_share_in_free_space_passes_the_level_beyond_chance() -> None:
    target = (np.zeros((1, 3)), [_scan(4.0)])
    # the level is the floor, one point in twenty: 30 of 130 is far past it
    assert contradicts(*_wall_and_room(30), target, _noise(0.0), 0.15)
    # 8 of 108 passes the level, but by less than chance over 108 points gives
    moved, inlier = _wall_and_room(8)
    assert 0.05 * len(moved) < 8
    assert not holds_in_part(moved, inlier, target, _noise(0.0), 0.45, 0.15)
    assert not contradicts(moved, inlier, target, _noise(0.0), 0.15)
    # a log whose own near pairs disagree as much lets the 30 through
    assert not contradicts(*_wall_and_room(30), target, _noise(0.3), 0.15)


def test_a_source_the_target_never_saw_contradicts_nothing() -> None:
    target = (np.zeros((1, 3)), [_scan(4.0)])
    behind = np.column_stack([np.full(50, -4.0), np.linspace(-3.0, 3.0, 50)])
    assert not contradicts(behind, np.zeros(50, dtype=bool), target, _noise(0.0), 0.15)


def test_a_scan_on_the_local_map_holds_on_what_it_saw_before_the_noise_is_known() -> None:
    target = (np.zeros((1, 3)), [_scan(4.0)])
    moved, inlier = _wall_and_behind()
    seen = seen_and_holding(moved, inlier, target, 0.5, 0.15, 20)
    assert seen is not None
    assert seen.tolist() == inlier.tolist()  # the wall is what it saw, not the rest
    # too few points seen to judge: none
    assert seen_and_holding(moved, inlier, target, 0.5, 0.15, 61) is None


def test_a_scan_on_the_local_map_is_held_to_the_free_space_checks_floor() -> None:
    target = (np.zeros((1, 3)), [_scan(4.0)])
    # 4 of 104 in the room it saw empty: within one in twenty
    moved, inlier = _wall_and_room(4)
    assert seen_and_holding(moved, inlier, target, 0.5, 0.15, 20) is not None
    # 8 of 108 passes it: a closure on a log this noisy could pass, a scan here does not
    moved, inlier = _wall_and_room(8)
    assert seen_and_holding(moved, inlier, target, 0.5, 0.15, 20) is None
    assert holds_in_part(moved, inlier, target, _noise(0.08), 0.45, 0.15)
