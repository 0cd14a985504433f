"""Simulated sonar readings (:mod:`gridmap_cli.sim.sonar`)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gridmap_cli.mapping.grid import GridSpec
from gridmap_cli.records import PoseTrack
from gridmap_cli.robot import RangeSensor, RobotDescription, load_robot
from gridmap_cli.sim.sonar import simulate_ranges
from gridmap_cli.sim.world import World

RES = 0.05
MAX_RANGE = 4.0


def one_sonar(
    yaw_deg: float = 0.0, x_m: float = 0.2, min_range_m: float = 0.15
) -> RobotDescription:
    sensor = RangeSensor(
        name="front",
        x_m=x_m,
        y_m=0.0,
        yaw_rad=math.radians(yaw_deg),
        beam_width_rad=math.radians(25.0),
        min_range_m=min_range_m,
        max_range_m=MAX_RANGE,
    )
    return RobotDescription(name="test", sensors=(sensor,))


def wall_world() -> World:
    """10 m x 6 m, one wall: the cells with x >= 8 m."""
    spec = GridSpec(0.0, 0.0, RES, 200, 120)
    occ = np.zeros(spec.shape, dtype=bool)
    occ[:, 160:] = True
    return World(occ, spec)


def poses(x: np.ndarray, y: np.ndarray, theta: np.ndarray) -> PoseTrack:
    n = x.shape[0]
    return PoseTrack(
        stamp_ns=np.arange(n, dtype=np.int64) * 100_000_000,
        x_m=np.asarray(x, dtype=np.float64),
        y_m=np.asarray(y, dtype=np.float64),
        theta_rad=np.asarray(theta, dtype=np.float64),
    )


def test_head_on_wall_reads_its_distance() -> None:
    x = np.linspace(4.5, 7.0, 26)
    truth = poses(x, np.full(26, 3.0), np.zeros(26))
    readings = simulate_ranges(wall_world(), truth, one_sonar(), np.random.default_rng(0))
    expected = 8.0 - (x + 0.2)
    # 1 % noise: 4 sigma is at most 13 cm here
    assert np.all(np.abs(readings.range_m - expected) <= 4 * 0.01 * expected + 1e-9)
    exact = simulate_ranges(
        wall_world(), truth, one_sonar(), np.random.default_rng(0), range_noise=0.0
    )
    np.testing.assert_allclose(exact.range_m, expected, atol=1e-9)


def test_nearest_echo_in_the_cone_wins() -> None:
    # facing the wall at 20 deg off its normal: the nearest ray (the cone's edge towards the
    # normal, 7.5 deg off) echoes, closer than the axis ray's distance
    truth = poses(np.array([6.0]), np.array([3.0]), np.array([math.radians(20.0)]))
    r = simulate_ranges(
        wall_world(), truth, one_sonar(x_m=0.0), np.random.default_rng(0), range_noise=0.0
    )
    assert r.range_m[0] == pytest.approx(2.0 / math.cos(math.radians(7.5)), abs=RES)
    assert r.range_m[0] < 2.0 / math.cos(math.radians(20.0))


def test_grazing_wall_reads_max_range() -> None:
    # driving along the wall, 0.5 m from it, with the sonar looking straight ahead (parallel)
    spec = GridSpec(0.0, 0.0, RES, 400, 100)
    occ = np.zeros(spec.shape, dtype=bool)
    occ[:20, :] = True  # smooth wall: y < 1 m
    world = World(occ, spec)
    x = np.linspace(1.0, 14.0, 40)
    truth = poses(x, np.full(40, 1.5), np.zeros(40))
    readings = simulate_ranges(world, truth, one_sonar(), np.random.default_rng(1))
    np.testing.assert_array_equal(readings.range_m, MAX_RANGE)
    # the same wall in front of a sideways-looking sonar echoes
    side = simulate_ranges(
        world, truth, one_sonar(yaw_deg=-90.0, x_m=0.0), np.random.default_rng(1)
    )
    assert np.all(np.abs(side.range_m - 0.5) < 0.05)


def test_critical_angle_controls_oblique_echoes() -> None:
    # beam axis 60 deg off the wall normal: the cone's nearest edge is 47.5 deg off
    truth = poses(np.array([6.0]), np.array([3.0]), np.array([math.radians(60.0)]))
    robot = one_sonar(x_m=0.0)
    gen = np.random.default_rng(0)
    deaf = simulate_ranges(wall_world(), truth, robot, gen, critical_incidence_deg=35.0)
    hears = simulate_ranges(wall_world(), truth, robot, gen, critical_incidence_deg=55.0)
    assert deaf.range_m[0] == MAX_RANGE
    assert hears.range_m[0] < MAX_RANGE


def test_open_space_reads_exactly_max_range() -> None:
    spec = GridSpec(0.0, 0.0, RES, 40, 40)
    world = World(np.zeros(spec.shape, dtype=bool), spec)
    truth = poses(np.array([1.0, 1.0]), np.array([1.0, 1.0]), np.array([0.0, 2.0]))
    robot = load_robot("p3at")
    readings = simulate_ranges(world, truth, robot, np.random.default_rng(0))
    np.testing.assert_array_equal(readings.range_m, robot.sensors[0].max_range_m)


def test_echoes_below_min_range_are_reported() -> None:
    truth = poses(np.array([7.7]), np.array([3.0]), np.array([0.0]))  # wall 0.1 m ahead
    r = simulate_ranges(wall_world(), truth, one_sonar(), np.random.default_rng(0))
    assert 0.0 < r.range_m[0] < 0.15
    assert r.range_m[0] == pytest.approx(0.1, abs=0.01)


def test_noise_keeps_echoes_inside_min_max() -> None:
    # wall just inside max range: large noise must not turn echoes into "no echo"
    x = np.full(200, 8.0 - 0.2 - 3.99)
    truth = poses(x, np.full(200, 3.0), np.zeros(200))
    r = simulate_ranges(wall_world(), truth, one_sonar(), np.random.default_rng(0), range_noise=0.2)
    assert np.all(r.range_m < MAX_RANGE)
    assert np.all(r.range_m >= 0.15)


def test_order_stamps_and_sensor_indices_with_the_p3at() -> None:
    robot = load_robot("p3at")
    n = 7
    truth = poses(np.linspace(2.0, 3.0, n), np.full(n, 3.0), np.linspace(0.0, 1.0, n))
    r = simulate_ranges(wall_world(), truth, robot, np.random.default_rng(0))
    assert len(r) == n * 16
    np.testing.assert_array_equal(r.stamp_ns, np.repeat(truth.stamp_ns, 16))
    np.testing.assert_array_equal(r.sensor, np.tile(np.arange(16), n))
    assert r.sensor.dtype == np.int32
    assert np.all(r.range_m > 0.0)
    assert np.all(r.range_m <= robot.sensors[0].max_range_m)


def test_chunking_does_not_change_the_result(monkeypatch: pytest.MonkeyPatch) -> None:
    from gridmap_cli.sim import sonar, world

    robot = load_robot("p3at")
    n = 50
    truth = poses(np.linspace(2.0, 7.0, n), np.linspace(1.0, 5.0, n), np.linspace(-3.0, 3.0, n))
    whole = simulate_ranges(wall_world(), truth, robot, np.random.default_rng(5))
    monkeypatch.setattr(sonar, "_RAYS_PER_CHUNK", 300)
    monkeypatch.setattr(world, "CAST_CHUNK", 77)
    chunked = simulate_ranges(wall_world(), truth, robot, np.random.default_rng(5))
    np.testing.assert_array_equal(whole.range_m, chunked.range_m)
