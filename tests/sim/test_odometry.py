"""Drifting wheel odometry (:mod:`gridmap_cli.sim.odometry`)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from gridmap_cli.geometry import compose, inverse, wrap_angle
from gridmap_cli.records import PoseTrack
from gridmap_cli.sim.odometry import OdometryErrorModel, odometry_from_truth
from gridmap_cli.sim.path import WaypointPath, trajectory

NO_ERROR = OdometryErrorModel().scaled(0.0)


def straight_line(length_m: float, heading_rad: float = 0.3, steps: int = 200) -> PoseTrack:
    s = np.linspace(0.0, length_m, steps + 1)
    return PoseTrack(
        stamp_ns=np.arange(steps + 1, dtype=np.int64) * 100_000_000,
        x_m=5.0 + s * math.cos(heading_rad),
        y_m=-2.0 + s * math.sin(heading_rad),
        theta_rad=np.full(steps + 1, heading_rad),
    )


def turn_in_place(angle_rad: float, steps: int = 90) -> PoseTrack:
    return PoseTrack(
        stamp_ns=np.arange(steps + 1, dtype=np.int64) * 100_000_000,
        x_m=np.full(steps + 1, 1.0),
        y_m=np.full(steps + 1, 2.0),
        theta_rad=wrap_angle(2.5 + np.linspace(0.0, angle_rad, steps + 1)),
    )


def test_default_model_is_drift_one() -> None:
    m = OdometryErrorModel()
    assert m.scale_error == 0.01
    assert m.turn_scale_error == 0.02
    assert m.heading_drift_rad_per_m == pytest.approx(math.radians(0.2))
    assert m.sigma_dist_per_sqrt_m == 0.01
    assert m.sigma_turn_per_sqrt_rad == 0.02


def test_scaled_multiplies_every_term() -> None:
    m = OdometryErrorModel()
    twice = m.scaled(2.0)
    for f in dataclasses.fields(m):
        assert getattr(twice, f.name) == pytest.approx(2.0 * getattr(m, f.name))
        assert getattr(m.scaled(0.0), f.name) == 0.0
    with pytest.raises(ValueError):
        m.scaled(-1.0)


def test_drift_zero_is_truth_in_the_first_pose_frame() -> None:
    path = WaypointPath(
        waypoints=np.array([[3.0, 4.0], [6.0, 4.5], [6.0, 8.0], [1.0, 7.0]]),
        closed=True,
        laps=2,
        start_heading_rad=-2.0,
    )
    truth = trajectory(path, rate_hz=10.0)
    odo = odometry_from_truth(truth, NO_ERROR, np.random.default_rng(0))
    ix, iy, ith = inverse(truth.x_m[0], truth.y_m[0], truth.theta_rad[0])
    ex, ey, eth = compose(ix, iy, ith, truth.x_m, truth.y_m, truth.theta_rad)
    np.testing.assert_array_equal(odo.stamp_ns, truth.stamp_ns)
    assert (odo.x_m[0], odo.y_m[0], odo.theta_rad[0]) == (0.0, 0.0, 0.0)
    np.testing.assert_allclose(odo.x_m, ex, atol=1e-9)
    np.testing.assert_allclose(odo.y_m, ey, atol=1e-9)
    np.testing.assert_allclose(wrap_angle(odo.theta_rad - eth), 0.0, atol=1e-9)


def test_scale_error_on_a_straight_line() -> None:
    model = dataclasses.replace(NO_ERROR, scale_error=0.05)
    odo = odometry_from_truth(straight_line(10.0), model, np.random.default_rng(0))
    # the odometry frame is the first pose's: the line runs along +x
    assert odo.x_m[-1] == pytest.approx(10.5)
    assert odo.y_m[-1] == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(odo.theta_rad, 0.0, atol=1e-12)


def test_turn_scale_error_in_place() -> None:
    model = dataclasses.replace(NO_ERROR, turn_scale_error=0.1)
    odo = odometry_from_truth(turn_in_place(math.pi / 2), model, np.random.default_rng(0))
    assert odo.theta_rad[-1] == pytest.approx(1.1 * math.pi / 2)
    np.testing.assert_allclose(odo.x_m, 0.0, atol=1e-12)


def test_heading_drift_bends_a_straight_line() -> None:
    drift = math.radians(1.0)
    model = dataclasses.replace(NO_ERROR, heading_drift_rad_per_m=drift)
    odo = odometry_from_truth(straight_line(10.0, steps=1000), model, np.random.default_rng(0))
    assert odo.theta_rad[-1] == pytest.approx(10.0 * drift)
    # a constant curvature: the end lies on an arc of radius 1 / drift
    radius = 1.0 / drift
    assert odo.y_m[-1] == pytest.approx(radius * (1.0 - math.cos(10.0 * drift)), rel=1e-2)


def test_random_terms_grow_with_the_square_root_of_distance() -> None:
    model = dataclasses.replace(NO_ERROR, sigma_dist_per_sqrt_m=0.02)
    truth = straight_line(9.0, heading_rad=0.0, steps=30)
    ends = np.array(
        [odometry_from_truth(truth, model, np.random.default_rng(s)).x_m[-1] for s in range(400)]
    )
    # std 0.02 * sqrt(9) = 0.06 m, whatever the number of steps
    assert ends.mean() == pytest.approx(9.0, abs=0.01)
    assert ends.std() == pytest.approx(0.06, rel=0.15)


def test_same_generator_state_same_odometry_and_fixed_draws() -> None:
    truth = straight_line(3.0)
    model = OdometryErrorModel()
    a = odometry_from_truth(truth, model, np.random.default_rng(7))
    b = odometry_from_truth(truth, model, np.random.default_rng(7))
    np.testing.assert_array_equal(a.x_m, b.x_m)
    # two arrays of N - 1 normals, whatever the model: the generator ends in the same state
    g1, g2 = np.random.default_rng(3), np.random.default_rng(3)
    odometry_from_truth(truth, model, g1)
    odometry_from_truth(truth, NO_ERROR, g2)
    assert g1.random() == g2.random()
