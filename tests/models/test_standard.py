"""Shape of the standard inverse sonar model on single readings."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gridmap_cli.mapping.grid import DEFAULT_CLAMP_P, GridSpec, LogOddsAccumulator, logodds
from gridmap_cli.mapping.models.standard import StandardSonarModel, StandardSonarParams
from gridmap_cli.poses.sync import SensorReadings
from gridmap_cli.robot import RangeSensor

SONAR = RangeSensor("s", 0.0, 0.0, 0.0, math.radians(25), 0.15, 4.0)
SPEC = GridSpec(-1.0, -3.0, 0.05, 140, 120)  # x -1..6, y -3..3


def one_reading(range_m: float, theta: float = 0.0, x: float = 0.0) -> SensorReadings:
    return SensorReadings(
        stamp_ns=np.array([0], dtype=np.int64),
        sensor=np.array([0], dtype=np.int32),
        range_m=np.array([range_m]),
        x_m=np.array([x]),
        y_m=np.array([0.0]),
        theta_rad=np.array([theta]),
        sensors=(SONAR,),
    )


def run(readings: SensorReadings, params: StandardSonarParams | None = None):
    params = params or StandardSonarParams()
    grid = LogOddsAccumulator(SPEC)
    model = StandardSonarModel(params, SPEC.resolution_m)
    updates = model.accumulate(grid, readings)
    return grid.log_odds(), grid.observations(), updates, params


def along_axis(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Values of the row through y=0 and the x of each cell centre."""
    row = int((0.0 - SPEC.origin_y_m) / SPEC.resolution_m)  # cell whose centre is at y=0.025
    cols = np.arange(SPEC.width)
    x, _ = SPEC.cell_center(cols, np.full_like(cols, row))
    return values[row], x


def test_echo_gives_free_then_occupied_then_nothing() -> None:
    lo, obs, updates, p = run(one_reading(2.0))
    line, x = along_axis(lo)
    band = p.band_half_m(SPEC.resolution_m)
    free = (x > 0.1) & (x < 2.0 - band - 0.03)
    occ = np.abs(x - 2.0) < band - 0.03
    beyond = x > 2.0 + band + 0.03
    assert np.allclose(line[free], logodds(p.p_free))
    assert np.allclose(line[occ], logodds(p.p_occupied))
    assert np.allclose(line[beyond], 0.0, atol=1e-12)
    assert np.all(line[x < -0.05] == 0.0)  # behind the sensor
    assert updates == int((obs > 0).sum())


def test_no_echo_is_free_only_and_limited() -> None:
    params = StandardSonarParams(no_echo_free_m=1.5)
    lo, obs, _, p = run(one_reading(SONAR.max_range_m), params=params)
    assert lo.max() == 0.0, "a max-range reading must never give occupied evidence"
    line, x = along_axis(lo)
    assert np.allclose(line[(x > 0.1) & (x < 1.45)], logodds(p.p_free))
    assert np.all(line[x > 1.55] == 0.0)
    assert np.all(obs[:, SPEC.world_to_cell(np.array([1.6]), np.array([0.0]))[0][0] :] == 0)


def test_no_echo_free_zero_ignores_no_echo_readings() -> None:
    lo, obs, _, _ = run(one_reading(SONAR.max_range_m), StandardSonarParams(no_echo_free_m=0.0))
    assert not lo.any() and not obs.any()


def test_cells_outside_the_cone_untouched() -> None:
    lo, _, _, _ = run(one_reading(3.0))
    cols, rows = np.meshgrid(np.arange(SPEC.width), np.arange(SPEC.height))
    cx, cy = SPEC.cell_center(cols, rows)
    bearing = np.abs(np.arctan2(cy, cx))
    outside = bearing > math.radians(12.5) + 1e-6
    assert not lo[outside].any()
    assert lo[~outside & (np.hypot(cx, cy) < 2.5)].min() < 0


def test_order_of_readings_does_not_change_the_map() -> None:
    rng = np.random.default_rng(3)
    n = 50
    r = SensorReadings(
        stamp_ns=np.arange(n, dtype=np.int64),
        sensor=np.zeros(n, dtype=np.int32),
        range_m=rng.uniform(0.3, 4.0, n),
        x_m=rng.uniform(0, 2, n),
        y_m=rng.uniform(-1, 1, n),
        theta_rad=rng.uniform(-np.pi, np.pi, n),
        sensors=(SONAR,),
    )
    perm = rng.permutation(n)
    shuffled = SensorReadings(
        r.stamp_ns[perm],
        r.sensor[perm],
        r.range_m[perm],
        r.x_m[perm],
        r.y_m[perm],
        r.theta_rad[perm],
        r.sensors,
    )
    a, oa, _, _ = run(r)
    b, ob, _, _ = run(shuffled)
    assert np.allclose(a, b, atol=1e-12)
    assert np.array_equal(oa, ob)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"p_occupied": 0.4},
        {"p_free": 0.6},
        {"obstacle_thickness_m": 0.0},
        {"no_echo_free_m": -1.0},
    ],
)
def test_params_refuse_nonsense(kwargs: dict) -> None:
    with pytest.raises(ValueError):
        StandardSonarParams(**kwargs)


def test_clamping_bounds_probabilities() -> None:
    grid = LogOddsAccumulator(SPEC)
    model = StandardSonarModel(StandardSonarParams(), SPEC.resolution_m)
    for _ in range(30):
        model.accumulate(grid, one_reading(2.0))
    prob = grid.occupancy_map(DEFAULT_CLAMP_P).prob
    assert np.nanmax(prob) == pytest.approx(DEFAULT_CLAMP_P[1])
    assert np.nanmin(prob) == pytest.approx(DEFAULT_CLAMP_P[0])
    assert np.isnan(prob[0, 0])  # never observed


@pytest.mark.parametrize("clamp", [(0.6, 0.97), (0.12, 0.4), (0.0, 0.97), (0.12, 1.0)])
def test_clamp_refuses_nonsense(clamp: tuple[float, float]) -> None:
    with pytest.raises(ValueError, match="clamp probabilities"):
        LogOddsAccumulator(SPEC).occupancy_map(clamp)
