"""Shape of the error-aware sonar model (eq. 10-12) on single readings and small batches."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from gridmap_cli.mapping.grid import FrequencyAccumulator, GridSpec
from gridmap_cli.mapping.models.error_aware import ErrorAwareParams, ErrorAwareSonarModel
from gridmap_cli.mapping.models.sector import F64
from gridmap_cli.mapping.models.standard import StandardSonarParams
from gridmap_cli.poses.sync import SensorReadings
from gridmap_cli.robot import RangeSensor

SONAR = RangeSensor("s", 0.0, 0.0, 0.0, math.radians(25), 0.15, 4.0)
SPEC = GridSpec(-1.0, -4.0, 0.05, 160, 160)  # x -1..7, y -4..4


@dataclass(frozen=True)
class Linear:
    """f = a_f d, g = a_g phi + c_g d: enough of an odometry-error model for these tests."""

    a_f: float = 0.0
    a_g: float = 0.0
    c_g: float = 0.0
    sonar_relative_error: float = 0.01

    def f(self, distance_m: F64) -> F64:
        return self.a_f * distance_m

    def g(self, distance_m: F64, rotation_rad: F64) -> F64:
        return self.a_g * rotation_rad + self.c_g * distance_m


def readings(
    range_m: list[float], distance_m: list[float], rotation_rad: list[float] | None = None
) -> SensorReadings:
    n = len(range_m)
    return SensorReadings(
        stamp_ns=np.arange(n, dtype=np.int64),
        sensor=np.zeros(n, dtype=np.int32),
        range_m=np.asarray(range_m, dtype=np.float64),
        x_m=np.zeros(n),
        y_m=np.zeros(n),
        theta_rad=np.zeros(n),
        sensors=(SONAR,),
        distance_m=np.asarray(distance_m, dtype=np.float64),
        rotation_rad=np.asarray(rotation_rad if rotation_rad is not None else [0.0] * n),
    )


def model(odometry: Linear) -> ErrorAwareSonarModel:
    return ErrorAwareSonarModel(StandardSonarParams(), ErrorAwareParams(), odometry, 0.05)


def grid_of(odometry: Linear, r: SensorReadings) -> FrequencyAccumulator:
    grid = FrequencyAccumulator(SPEC)
    model(odometry).accumulate(grid, r)
    return grid


def test_spread_grows_with_distance_travelled() -> None:
    odo = Linear(a_f=0.02, c_g=0.004)
    ev = model(odo).evidence(readings([2.0, 2.0, 2.0], [0.0, 10.0, 40.0]))
    band = ev.look_m - ev.free_m  # depth of the ring the echo is spread over
    assert band[0] < band[1] < band[2]
    assert ev.half_width_rad[0] < ev.half_width_rad[1] < ev.half_width_rad[2]
    assert ev.hit[0] > ev.hit[1] > ev.hit[2]  # each cell's share of the echo falls
    assert ev.weight[0] > ev.weight[1] > ev.weight[2]  # and the reading counts for less
    # eq. 12: the half-width is beta/2 + g
    assert ev.half_width_rad[2] == pytest.approx(math.radians(12.5) + 0.004 * 40.0)


def test_bearing_spread_grows_with_rotation() -> None:
    odo = Linear(a_g=0.05)
    ev = model(odo).evidence(readings([2.0, 2.0], [5.0, 5.0], [0.0, 6.0]))
    assert ev.half_width_rad[1] == pytest.approx(ev.half_width_rad[0] + 0.3)


def test_evidence_per_reading_is_bounded_by_its_spread() -> None:
    """Spreading an echo in bearing leaves its total hit mass about the same.

    The hit mass summed over the grid (weight 1 when f = 0) stays within the discretisation
    error of the unspread reading's for wedges up to 2.4 times wider; no cell gets more than one
    hit.
    """
    totals = []
    for a_g in (0.0, 0.1, 0.3):
        odo = Linear(a_g=a_g)
        grid = grid_of(odo, readings([3.0], [0.0], [1.0]))
        hits = grid.hits()
        assert hits.max() <= 1.0 + 1e-9
        totals.append(hits.sum())
    # the ring of the unspread beam holds ~ (2h) * z * beta cells; spreading keeps that mass
    assert max(totals) / min(totals) < 1.15


def test_range_spread_never_adds_to_the_echo() -> None:
    """Spread in range, the echo's band is cut at z + h (the beam went no further): the part of
    the spread beyond the measured range is dropped, so a reading's hit mass (divided by its
    weight) falls as the spread grows and never exceeds the unspread reading's. For a 3 m echo
    at least half survives a half-metre spread."""
    trust = ErrorAwareParams().trust_length_m
    unspread = grid_of(Linear(), readings([3.0], [30.0])).hits().sum()
    shares = []
    for a_f in (0.001, 0.0033, 0.0167, 0.05, 0.1):
        f = a_f * 30.0
        weight = trust**2 / (trust**2 + f**2)
        total = grid_of(Linear(a_f=a_f), readings([3.0], [30.0], [1.0])).hits().sum()
        shares.append(total / weight / unspread)
    assert all(share <= 1.05 for share in shares)
    assert shares == sorted(shares, reverse=True)
    assert shares[2] > 0.5  # f = 0.5 m


def test_wide_spread_leaves_no_cell_confidently_occupied() -> None:
    """A hundred readings of one wall with metres of pose error cannot make a cell certain."""
    sharp = grid_of(Linear(), readings([2.0] * 100, [0.0] * 100)).occupancy_map()
    blurred = grid_of(Linear(a_f=0.05), readings([2.0] * 100, [30.0] * 100)).occupancy_map()
    assert np.nanmax(sharp.prob) > 0.9
    assert np.nanmax(blurred.prob) < 0.5


def test_max_range_reading_gives_no_occupied_evidence() -> None:
    odo = Linear(a_f=0.02, a_g=0.05)
    grid = grid_of(odo, readings([4.0, 4.0], [0.0, 20.0], [0.0, 3.0]))
    assert np.all(grid.hits() <= 1e-12)
    omap = grid.occupancy_map()
    seen = ~np.isnan(omap.prob)
    assert seen.any()
    assert np.all(omap.prob[seen] < 0.5)
    # free only up to the no-echo reach (1 m by default), nothing beyond
    _, x = np.meshgrid(np.arange(SPEC.height), np.arange(SPEC.width), indexing="ij")
    cx, _ = SPEC.cell_center(x, x)
    assert np.all(~seen[cx > 1.0 + 0.05])


def test_early_readings_outweigh_late_ones() -> None:
    """Same wall, seen first with a known pose and then many times after 40 m of drift."""
    early = readings([2.0] * 5, [0.0] * 5)
    late = readings([1.6] * 50, [40.0] * 50)  # the drifted odometry puts the wall 40 cm nearer
    odo = Linear(a_f=0.03)
    grid = FrequencyAccumulator(SPEC)
    m = model(odo)
    m.accumulate(grid, early)
    m.accumulate(grid, late)
    omap = grid.occupancy_map()
    row = int((0.0 - SPEC.origin_y_m) / SPEC.resolution_m)
    col_true = int((2.0 - SPEC.origin_x_m) / SPEC.resolution_m)
    col_late = int((1.6 - SPEC.origin_x_m) / SPEC.resolution_m)
    assert omap.prob[row, col_true] > 0.6
    assert omap.prob[row, col_true] > 2 * omap.prob[row, col_late]


def test_no_odometry_error_keeps_the_sonar_spread_only() -> None:
    ev = model(Linear()).evidence(readings([2.0, 4.0 - 1e-6], [50.0, 50.0]))
    h = StandardSonarParams().band_half_m(0.05)
    assert ev.weight == pytest.approx([1.0, 1.0])
    assert ev.half_width_rad == pytest.approx([math.radians(12.5)] * 2)
    # eq. 11 with f = 0: sigma_z = k z, combined with the obstacle band in quadrature
    assert ev.look_m[0] - ev.free_m[0] == pytest.approx(h + math.hypot(h, 0.02))


def test_model_needs_travel() -> None:
    r = readings([2.0], [0.0])
    bare = SensorReadings(r.stamp_ns, r.sensor, r.range_m, r.x_m, r.y_m, r.theta_rad, r.sensors)
    with pytest.raises(ValueError, match="distance driven"):
        model(Linear()).evidence(bare)


def cell_at(distance_m: float, bearing_rad: float) -> tuple[int, int]:
    col, row = SPEC.world_to_cell(
        np.array([distance_m * math.cos(bearing_rad)]),
        np.array([distance_m * math.sin(bearing_rad)]),
    )
    return int(row[0]), int(col[0])


def test_bearing_spread_narrows_what_was_looked_through_and_widens_the_echo() -> None:
    """Free space is claimed only where the beam went whichever way the heading erred (beta/2 -
    g); the echo may have come from anywhere in beta/2 + g."""
    r = readings([3.0], [0.0], [2.0])
    edge = cell_at(1.5, math.radians(10.0))  # inside beta/2 = 12.5 deg, outside 12.5 - 5.7
    wide_echo = cell_at(3.0, math.radians(16.0))  # outside beta/2, inside 12.5 + 5.7
    sharp = grid_of(Linear(), r)
    spread = grid_of(Linear(a_g=0.05), r)  # g = 0.1 rad = 5.7 deg
    assert sharp.looks()[edge] == pytest.approx(1.0)
    assert spread.observations()[edge] == 0 and spread.looks()[edge] == pytest.approx(0.0)
    assert sharp.hits()[wide_echo] == pytest.approx(0.0)
    assert 0.0 < spread.hits()[wide_echo] < 1.0
    # a = (h / b) (beta/2 / sigma_theta), b = sqrt(h^2 + (k z)^2) with k z = 3 cm
    h = StandardSonarParams().band_half_m(0.05)
    a = h / math.hypot(h, 0.03) * math.radians(12.5) / (math.radians(12.5) + 0.1)
    assert spread.hits()[wide_echo] == pytest.approx(spread.looks()[wide_echo] * a)


def test_many_late_readings_cannot_make_a_cell_confidently_free() -> None:
    """Two thousand no-echo readings after 100 m of drift (f = 3 m, weight 0.0099, trust class
    6) look through the same cells. Their weights alone add up to ~20 readings' worth and would
    call the cells free (p < 0.25); bounded to C * 4^-6 = 30 / 4096 looks, they leave the cells
    at the prior: p >= 0.5 / (1 + 30 / 4096).
    """
    late = readings([4.0] * 2000, [100.0] * 2000)
    odo = Linear(a_f=0.03)
    bounded = grid_of(odo, late).occupancy_map()
    unbounded_grid = FrequencyAccumulator(SPEC)
    ErrorAwareSonarModel(
        StandardSonarParams(), ErrorAwareParams(redundant_looks=math.inf), odo, 0.05
    ).accumulate(unbounded_grid, late)
    unbounded = unbounded_grid.occupancy_map()
    seen = ~np.isnan(bounded.prob)
    assert seen.any()
    assert np.nanmin(unbounded.prob) < 0.25
    assert np.nanmin(bounded.prob) >= 0.5 / (1.0 + 30.0 / 4096.0) - 1e-9
    with pytest.raises(ValueError, match="redundant-looks"):
        ErrorAwareParams(redundant_looks=0.0)
