"""Whole simulated logs (:mod:`gridmap_cli.sim.simulate`)."""

from __future__ import annotations

import numpy as np
import pytest

from gridmap_cli.errors import InputFileError
from gridmap_cli.geometry import compose, inverse, wrap_angle
from gridmap_cli.mapping.grid import GridSpec
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import load_robot
from gridmap_cli.sim.path import parse_path_yaml
from gridmap_cli.sim.simulate import simulate
from gridmap_cli.sim.world import World

PATH = """\
gridmap-path: 1
waypoints:
  - [1.0, 1.0]
  - [4.0, 1.0]
  - [4.0, 3.0]
  - [1.0, 3.0]
laps: 2
"""


@pytest.fixture
def room() -> World:
    """A 5 m x 4 m room with 10 cm walls and a pillar."""
    spec = GridSpec(0.0, 0.0, 0.05, 100, 80)
    occ = np.zeros(spec.shape, dtype=bool)
    occ[:2, :] = occ[-2:, :] = True
    occ[:, :2] = occ[:, -2:] = True
    occ[36:44, 46:54] = True
    return World(occ, spec)


def run(world: World, **kwargs: object) -> RangeLog:
    return simulate(world, parse_path_yaml(PATH, "room.yaml"), load_robot("p3at"), **kwargs)  # type: ignore[arg-type]


def test_log_contents(room: World) -> None:
    log = run(room, seed=3, drift=1.5)
    robot = load_robot("p3at")
    assert log.sensor_names == robot.names()
    assert log.sensors is None
    assert log.metadata == {"robot": "p3at", "seed": "3", "drift": "1.5"}
    assert log.truth is not None
    assert len(log.poses) == len(log.truth)
    np.testing.assert_array_equal(log.poses.stamp_ns, log.truth.stamp_ns)
    assert (log.truth.x_m[0], log.truth.y_m[0]) == (1.0, 1.0)  # world frame
    assert (log.poses.x_m[0], log.poses.y_m[0], log.poses.theta_rad[0]) == (0.0, 0.0, 0.0)
    assert len(log.readings) == 16 * len(log.poses)
    # inside a closed room most sonars hear a wall
    assert np.mean(log.readings.range_m < 4.335) > 0.5


def test_same_seed_same_log_different_seed_different_log(room: World) -> None:
    a = run(room, seed=11)
    b = run(room, seed=11)
    c = run(room, seed=12)
    for x, y in [
        (a.poses.x_m, b.poses.x_m),
        (a.poses.theta_rad, b.poses.theta_rad),
        (a.readings.range_m, b.readings.range_m),
        (a.readings.stamp_ns, b.readings.stamp_ns),
    ]:
        np.testing.assert_array_equal(x, y)
    assert not np.array_equal(a.poses.x_m, c.poses.x_m)
    assert not np.array_equal(a.readings.range_m, c.readings.range_m)
    assert a.truth is not None and c.truth is not None
    np.testing.assert_array_equal(a.truth.x_m, c.truth.x_m)  # the seed only changes the errors


def test_drift_zero_odometry_is_truth_relative_to_start(room: World) -> None:
    log = run(room, drift=0.0)
    t = log.truth
    assert t is not None
    ix, iy, ith = inverse(t.x_m[0], t.y_m[0], t.theta_rad[0])
    ex, ey, eth = compose(ix, iy, ith, t.x_m, t.y_m, t.theta_rad)
    np.testing.assert_allclose(log.poses.x_m, ex, atol=1e-9)
    np.testing.assert_allclose(log.poses.y_m, ey, atol=1e-9)
    np.testing.assert_allclose(wrap_angle(log.poses.theta_rad - eth), 0.0, atol=1e-9)


def test_more_drift_more_odometry_error(room: World) -> None:
    def end_error(drift: float) -> float:
        log = run(room, drift=drift, seed=1)
        t = log.truth
        assert t is not None
        ix, iy, ith = inverse(t.x_m[0], t.y_m[0], t.theta_rad[0])
        ex, ey, _ = compose(ix, iy, ith, t.x_m[-1], t.y_m[-1], t.theta_rad[-1])
        return float(np.hypot(log.poses.x_m[-1] - ex, log.poses.y_m[-1] - ey))

    assert end_error(0.0) < 1e-9 < end_error(1.0) < end_error(3.0)


def test_duration_sets_the_length(room: World) -> None:
    log = run(room, duration_s=30.0, rate_hz=5.0)
    assert len(log.poses) == 150


def test_a_path_through_an_obstacle_is_refused(room: World) -> None:
    # a pillar in the middle of the room, and a path straight through it
    occupied = np.array(room.occupied)
    col, row = room.spec.world_to_cell(np.array([2.0]), np.array([1.5]))
    occupied[row[0] - 2 : row[0] + 3, col[0] - 2 : col[0] + 3] = True
    world = World(occupied, room.spec)
    path = parse_path_yaml("gridmap-path: 1\nwaypoints: [[0.7, 1.5], [3.3, 1.5]]\n", "through.yaml")
    with pytest.raises(InputFileError, match=r"through.yaml: the path drives through an obstacle"):
        simulate(world, path, load_robot("p3at"), seed=0)
