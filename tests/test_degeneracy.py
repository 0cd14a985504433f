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
    OdometryPrior,
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


def learned_prior(sigma: tuple[float, float, float], n: int = 39) -> OdometryPrior:
    """A prior that has seen ``n`` matches correct the odometry's steps by -``sigma``, 0 and
    ``sigma`` in turn: no steady error, one ``sigma`` of random error."""
    prior = OdometryPrior(min_matches=10)
    for k in range(n):
        prior.add(np.array(sigma) * (k % 3 - 1))
    return prior


def test_the_prior_knows_the_odometry_only_after_enough_matches() -> None:
    prior = OdometryPrior(min_matches=10)
    for _ in range(9):
        prior.add(np.array([0.01, 0.02, -0.03]))
    assert prior.error() is None and prior.usual_turn() == 0.0
    pose = (1.0, 2.0, 0.3)
    # not learned yet: the match as it is (the step error is recorded all the same)
    assert prior.lean(pose, (1.1, 2.0, 0.2), np.eye(6)) == pose
    known = prior.error()
    assert known is not None
    assert known[0] == pytest.approx([0.01, 0.02, -0.03])  # the median: one outlier moves nothing


def test_a_steady_odometry_error_is_taken_out_before_leaning_on_it() -> None:
    """Unequal wheels: every step turns 0.2 degrees too far. A match that cannot see its
    heading takes the odometry's turn less that steady error, not the drifting one."""
    prior = OdometryPrior(min_matches=10)
    for k in range(39):
        prior.add(np.array([math.radians(0.2 + 0.1 * (k % 3 - 1)), 0.0, 0.0]))
    steady, sigma = prior.error() or (np.zeros(3), np.zeros(3))
    assert math.degrees(steady[0]) == pytest.approx(0.2)
    assert math.degrees(sigma[0]) == pytest.approx(0.1)
    prior.done[1][:] = prior.done[2][:] = [-0.01, 0.0, 0.01] * 13  # some spread in x and y
    guess = (0.0, 0.0, math.radians(30.0))
    _, _, th = prior.lean((0.0, 0.0, math.radians(35.0)), guess, round_hall_hessian(1e9, 1.0))
    assert math.degrees(th) == pytest.approx(29.8, abs=0.01)


def round_hall_hessian(position: float, heading: float) -> np.ndarray:
    """small_gicp's Hessian of a match that pins x and y (robot frame) by ``position`` and the
    heading by ``heading`` (information, 1/m^2 and 1/rad^2)."""
    h = np.eye(6)
    h[2, 2] = heading
    h[3, 3] = h[4, 4] = position
    return h


def test_a_match_that_cannot_see_its_heading_keeps_the_odometry_s_turn() -> None:
    """Round walls: the position is held, the heading is not. The odometry turned right (the
    guess), GICP turned 10 degrees more; the heading goes back to the odometry's, the position
    stays the match's."""
    prior = learned_prior((math.radians(0.5), 0.01, 0.01))
    guess = (0.0, 0.0, math.radians(30.0))
    pose = (0.005, 0.0, math.radians(40.0))
    x, y, th = prior.lean(pose, guess, round_hall_hessian(1e9, 1.0))
    assert math.degrees(th) == pytest.approx(30.0, abs=0.01)
    assert (x, y) == pytest.approx((0.005, 0.0), abs=1e-5)


def test_a_match_and_an_odometry_that_disagree_beyond_both_errors_keep_the_match() -> None:
    """Both sure of the position, 5 cm apart where the odometry errs by a centimetre: the
    odometry slipped, and the match is kept whole."""
    prior = learned_prior((math.radians(0.5), 0.01, 0.01))
    pose = (0.05, 0.0, math.radians(40.0))
    guess = (0.0, 0.0, math.radians(30.0))
    assert prior.lean(pose, guess, round_hall_hessian(1e9, 1.0)) == pose


def test_a_match_that_holds_every_direction_is_left_as_it_is() -> None:
    prior = learned_prior((math.radians(0.5), 0.01, 0.01))
    pose = (0.05, -0.02, math.radians(40.0))
    x, y, th = prior.lean(pose, (0.0, 0.0, math.radians(30.0)), round_hall_hessian(1e9, 1e9))
    assert (x, y) == pytest.approx(pose[:2], abs=1e-3)
    assert math.degrees(th) == pytest.approx(40.0, abs=0.01)


@given(st.floats(-math.pi, math.pi))
def test_leaning_moves_the_position_in_the_robot_frame(heading: float) -> None:
    """A match that holds nothing (x, y in the robot frame, heading) takes the guess whole,
    whatever way the robot faces."""
    prior = learned_prior((math.radians(0.5), 0.01, 0.01))
    guess = (1.0, 2.0, heading)
    pose = (1.3, 1.8, heading + 0.01)
    x, y, th = prior.lean(pose, guess, round_hall_hessian(1e-6, 1e-6))
    assert (x, y, th) == pytest.approx(guess, abs=1e-6)


def test_on_a_sharp_turn_the_odometry_is_trusted_less() -> None:
    """The matches saw the odometry err by 0.1 degrees a step going straight and by 1 degree on
    10-degree turns: a match that holds the heading to a degree mostly takes the odometry's
    heading on a straight step, and keeps clearly more of its own on a 20-degree turn."""
    prior = OdometryPrior(min_matches=10)
    for k in range(60):
        e, turning = k % 3 - 1, k % 4 == 0
        prior.expect(math.radians(10.0 if turning else 0.0))
        heading = math.radians(1.0 if turning else 0.1 * e)
        prior.lean((0.01 * e, 0.01 * e, heading), (0.0, 0.0, 0.0), np.eye(6) * 1e9)
    hessian = round_hall_hessian(1e9, 1.0 / math.radians(1.0) ** 2)
    pose, guess = (0.0, 0.0, math.radians(22.0)), (0.0, 0.0, math.radians(20.0))
    prior.expect(math.radians(20.0))
    turning = math.degrees(prior.lean(pose, guess, hessian)[2])
    prior.expect(0.0)
    straight = math.degrees(prior.lean(pose, guess, hessian)[2])
    assert straight < 20.6 and turning > straight + 0.5
