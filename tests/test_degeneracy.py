"""poses/correction/degeneracy.py: the weak axis of a match, keeping the odometry along it, the
odometry's distance scale, and how far a stretch of track went along weak axes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from gridmap_cli.poses.correction.degeneracy import (
    DistanceScale,
    _clearly_constrained,
    keep_across,
    unchosen_slide,
    weak_axis,
    weak_stretch,
)
from gridmap_cli.poses.correction.sheet_gicp import placed_points


def corridor_hessian(along_robot_rad: float) -> np.ndarray:
    """small_gicp's Hessian of a match between two walls running ``along_robot_rad`` in the
    robot frame: stiff across them, nothing along."""
    h = np.zeros((6, 6))
    h[:3, :3] = np.eye(3) * 100.0
    across = np.array([-math.sin(along_robot_rad), math.cos(along_robot_rad)])
    h[3:5, 3:5] = 1e4 * np.outer(across, across) + 1e-3 * np.eye(2)
    h[5, 5] = 1.0
    return h


@given(st.floats(-math.pi, math.pi), st.floats(-math.pi, math.pi))
def test_the_weak_axis_is_turned_from_the_robot_frame_into_the_map(
    heading: float, along: float
) -> None:
    """The Hessian's translation is in the robot frame: a corridor straight ahead of a robot
    facing north runs north in the map."""
    axis = weak_axis(corridor_hessian(along), 0.02, heading)
    assert axis is not None
    expected = np.array([math.cos(heading + along), math.sin(heading + along)])
    assert abs(abs(float(axis @ expected)) - 1.0) < 1e-9


def test_a_match_constrained_both_ways_has_no_weak_axis() -> None:
    h = np.eye(6) * 50.0
    h[3, 3] = 10.0  # 0.2 of the other: well over the ratio
    assert weak_axis(h, 0.02, 0.3) is None


def test_keep_across_takes_the_guess_along_and_the_match_across() -> None:
    weak = np.array([0.0, 1.0])  # a corridor running north
    pose = keep_across((1.0, 2.0, 0.1), (1.3, 5.0, 0.2), weak)
    assert pose == pytest.approx((1.3, 2.0, 0.2))


def test_the_distance_scale_needs_enough_matched_travel_and_stays_bounded() -> None:
    scale = DistanceScale(min_m=0.95, max_error=0.05)
    scale.kept(0.5)
    for _ in range(9):
        scale.add((0.098, 0.0), (0.1, 0.0))  # odometry reports 2 % too far
    assert scale.factor == 1.0 and not scale.learned  # 0.9 m of 0.95: not yet
    scale.add((0.098, 0.0), (0.1, 0.0))
    scale.kept(0.5)
    assert scale.learned and scale.factor == pytest.approx(0.98)
    assert scale.blind_m == 0.5  # only what was kept before the scale was known
    wild = DistanceScale(min_m=0.1, max_error=0.05)
    wild.add((0.2, 0.0), (0.1, 0.0))
    assert wild.factor == pytest.approx(1.05)


def test_weak_stretch_sums_the_travel_along_the_axes_in_the_last_pose_frame() -> None:
    poses = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0.5, math.pi / 2]])
    weak = np.array([[np.nan, np.nan], [1, 0], [-1, 0], [np.nan, np.nan]])
    distance, axis = weak_stretch(poses, weak, 0, 3)
    assert distance == pytest.approx(2.0)  # the last step matched: not counted
    # the map's x axis seen from a pose facing +y is its -y axis (either sign)
    assert abs(axis[0]) < 1e-12 and abs(axis[1]) == pytest.approx(1.0)
    assert weak_stretch(poses, np.full((4, 2), np.nan), 0, 3)[0] == 0.0


def test_the_closed_form_shortcut_never_overrules_eigh() -> None:
    """Where the closed-form eigenvalues call a match constrained, LAPACK's do too, including
    matches a hair from the threshold either side."""
    rng = np.random.default_rng(7)
    shortcut = 0
    for trial in range(20000):
        low, high = np.sort(rng.uniform(0, 1, 2)) * 10 ** rng.uniform(-3, 6)
        if trial % 2:
            low = high * 0.002 * (1 + rng.uniform(-1e-9, 1e-9)) * rng.choice([1.0, 2.0])
        a = rng.uniform(0, math.pi)
        turn = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
        hessian = np.zeros((6, 6))
        hessian[3:5, 3:5] = turn @ np.diag([low, high]) @ turn.T
        values = np.linalg.eigvalsh(hessian[3:5, 3:5])
        if _clearly_constrained(hessian, 0.002):
            shortcut += 1
            assert values[1] > 0 and values[0] / values[1] >= 0.002
    assert 5000 < shortcut < 20000  # both paths were taken


def corridor_points(doors_every_m: float | None, end_x_m: float | None) -> np.ndarray:
    """Points 5 cm apart on the two walls of a corridor 2 m wide along x, from -12 to 12 m:
    each wall broken by a 0.4 m door every ``doors_every_m`` (None: none) and the corridor
    closed by an end wall at ``end_x_m`` (None: open)."""
    x = np.arange(-12.0, 12.0, 0.05)
    if doors_every_m is not None:
        x = x[np.mod(x, doors_every_m) >= 0.4]
    if end_x_m is not None:
        x = x[x < end_x_m]
    walls = [np.column_stack([x, np.full_like(x, side)]) for side in (-1.0, 1.0)]
    if end_x_m is not None:
        y = np.arange(-1.0, 1.0, 0.05)
        walls.append(np.column_stack([np.full_like(y, end_x_m), y]))
    return np.vstack(walls)


def seen_from(world: np.ndarray, pose: tuple[float, float, float], reach_m: float) -> np.ndarray:
    """``world`` points within ``reach_m`` of ``pose``, in its frame."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    d = world - np.array(pose[:2])
    local = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])
    return local[np.hypot(local[:, 0], local[:, 1]) <= reach_m]


def fit(scan: np.ndarray, pose: tuple[float, float, float], tree: cKDTree) -> float:
    dist, _ = tree.query(placed_points(scan, pose), distance_upper_bound=0.15)
    return float(np.mean(np.isfinite(dist)))


def test_a_slide_the_scan_does_not_choose_is_taken_back() -> None:
    """Doors every metre: a match slid one door along the corridor fits as well as the
    odometry's place, so the slide is the match's least constrained direction and is taken
    back; the heading and the correction across the corridor stay the match's."""
    world = corridor_points(1.0, None)
    tree = cKDTree(world)
    truth = (0.0, 0.0, 0.0)
    scan = seen_from(world, truth, 8.0)
    slid = (1.0, 0.02, 0.0)
    along = unchosen_slide(corridor_hessian(0.0), scan, slid, truth, tree, 0.15, 1.0)
    assert along is not None and abs(float(along[0])) == pytest.approx(1.0, abs=1e-6)
    assert keep_across(truth, slid, along) == pytest.approx((0.0, 0.02, 0.0), abs=1e-6)


def test_a_slide_to_where_the_scan_fits_better_stands() -> None:
    """The corridor's end wall in view: the odometry's place, 0.8 m short of the match, fits
    worse than the match (a perfect fit, whose share has no spread), so the match stands."""
    world = corridor_points(None, 5.0)
    tree = cKDTree(world)
    truth = (0.0, 0.0, 0.0)
    scan = seen_from(world, truth, 8.0)
    guess = (-0.8, 0.0, 0.0)
    assert fit(scan, guess, tree) < fit(scan, truth, tree) - 0.05
    assert unchosen_slide(corridor_hessian(0.0), scan, truth, guess, tree, 0.15, 1.0) is None


def test_a_small_move_or_one_across_the_weak_direction_is_no_slide() -> None:
    """Within the inlier band, or moved across the corridor (its well constrained direction),
    the match is left as it is even where the odometry's place fits as well."""
    world = corridor_points(1.0, None)
    tree = cKDTree(world)
    scan = seen_from(world, (0.0, 0.0, 0.0), 8.0)
    hessian = corridor_hessian(0.0)
    for guess in ((-0.1, 0.0, 0.0), (0.0, -0.5, 0.0)):
        pose = (0.0, 0.0, 0.0)
        assert unchosen_slide(hessian, scan, pose, guess, tree, 0.15, 1.0) is None


def test_a_slide_longer_than_the_odometry_step_is_left_to_the_match() -> None:
    """The odometry said the robot moved 0.05 m and the match moved it 1 m along the corridor:
    an increment that short (a stop, or odometry stamped in bursts) is no place to go back to,
    however little the scan chooses between the two; with a 1.2 m step it is."""
    world = corridor_points(1.0, None)
    tree = cKDTree(world)
    truth = (0.0, 0.0, 0.0)
    scan = seen_from(world, truth, 8.0)
    slid = (1.0, 0.0, 0.0)
    hessian = corridor_hessian(0.0)
    assert unchosen_slide(hessian, scan, slid, truth, tree, 0.15, 0.05) is None
    assert unchosen_slide(hessian, scan, slid, truth, tree, 0.15, 1.2) is not None


def test_a_slide_that_turns_the_travel_back_is_judged_past_the_step() -> None:
    """The odometry moved the robot 0.1 m forwards (from -0.1 m to the guess at 0): a match
    that puts it 1 m back, behind where it came from, turns its travel against the wheels' and
    is judged by the scan past the step's length (here taken back); the same slide forwards,
    along the odometry's travel, is left to the match as before."""
    world = corridor_points(1.0, None)
    tree = cKDTree(world)
    guess = (0.0, 0.0, 0.0)
    scan = seen_from(world, guess, 8.0)
    hessian = corridor_hessian(0.0)
    back, ahead = (-1.0, 0.0, 0.0), (1.0, 0.0, 0.0)
    assert unchosen_slide(hessian, scan, back, guess, tree, 0.15, 0.1, (-0.1, 0.0)) is not None
    assert unchosen_slide(hessian, scan, ahead, guess, tree, 0.15, 0.1, (-0.1, 0.0)) is None
    assert unchosen_slide(hessian, scan, back, guess, tree, 0.15, 0.1) is None  # no way back known
