"""poses/correction/degeneracy.py: the weak axis of a match, keeping the odometry along it, the
odometry's distance scale, and how far a stretch of track went along weak axes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gridmap_cli.poses.correction.degeneracy import (
    DistanceScale,
    _clearly_constrained,
    keep_across,
    weak_axis,
    weak_stretch,
)


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
