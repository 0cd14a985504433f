"""The compiled kernels (the C extension) give the numpy reference's grid: within 1e-9 in
log-odds as issue 10 asks, and in fact bit for bit, for standard and error-aware sonar cones and
for rays, in and off the grid."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest

from gridmap_cli.mapping.grid import FrequencyAccumulator, GridSpec, LogOddsAccumulator
from gridmap_cli.mapping.models import kernels
from gridmap_cli.mapping.models.error_aware import ErrorAwareParams, ErrorAwareSonarModel
from gridmap_cli.mapping.models.ray import RaySegments, accumulate_rays
from gridmap_cli.mapping.models.standard import (
    SectorEvidence,
    StandardSonarParams,
    accumulate_sectors,
    accumulate_sectors_numpy,
)
from gridmap_cli.poses.sync import SensorReadings
from gridmap_cli.robot import RangeSensor

SPEC = GridSpec(-3.05, -2.0, 0.05, 97, 83)


def _sectors(rng: np.random.Generator, n: int) -> SectorEvidence:
    reach = rng.uniform(0.0, 5.0, n)
    inner = np.maximum(reach - rng.uniform(0.0, 0.3, n), 0.0)
    # some readings without occupied evidence (no echo), some exactly on cell boundaries
    outer_value = np.where(rng.random(n) < 0.3, 0.0, 0.85)
    x = np.round(rng.uniform(-4.0, 3.0, n), 2)
    return SectorEvidence(
        x_m=x,
        y_m=rng.uniform(-3.0, 3.0, n),
        theta_rad=np.concatenate([[0.0, math.pi / 2, -math.pi, -math.pi / 2], rng.uniform(
            -math.pi, math.pi, n - 4)]),
        half_width_rad=np.full(n, math.radians(12.5)),
        inner_m=inner,
        inner_value=np.where(outer_value != 0.0, -0.405 - 0.85, -0.405),
        outer_m=reach,
        outer_value=outer_value,
    )  # fmt: skip


def assert_counts_equal_the_reference(
    monkeypatch: pytest.MonkeyPatch, model: Any, batches: list[SensorReadings], spec: GridSpec
) -> tuple[FrequencyAccumulator, FrequencyAccumulator]:
    """Map ``batches`` with an error-aware model on numpy and compiled kernels; the counts
    must be equal bit for bit, across at least two trust classes. Returns (numpy, compiled)."""
    grids, updates = [], []
    for choice in ("numpy", "compiled"):
        monkeypatch.setenv("GRIDMAP_KERNELS", choice)
        grid = FrequencyAccumulator(spec)
        updates.append(sum(model.accumulate(grid, b) for b in batches))
        grids.append(grid)
    ref, fast = grids
    assert updates[0] == updates[1] > 0
    assert len(ref._closed) >= 2  # several trust classes did arrive
    assert np.array_equal(ref.observations(), fast.observations())
    assert np.array_equal(ref.looks(), fast.looks())
    assert np.array_equal(ref.hits(), fast.hits())
    return ref, fast


def _both(monkeypatch: pytest.MonkeyPatch, add: object) -> tuple[LogOddsAccumulator, ...]:
    grids = []
    for choice in ("numpy", "compiled"):
        monkeypatch.setenv("GRIDMAP_KERNELS", choice)
        grid = LogOddsAccumulator(SPEC)
        add(grid)  # type: ignore[operator]
        grids.append(grid)
    return grids[0], grids[1]


def test_sector_kernel_equals_the_numpy_reference(monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(7)
    batches = [_sectors(rng, n) for n in (500, 5, 2000)]
    cells: list[int] = []

    def add(grid: LogOddsAccumulator) -> None:
        cells.append(sum(accumulate_sectors(grid, ev) for ev in batches))

    ref, fast = _both(monkeypatch, add)
    assert cells[0] == cells[1] > 0
    assert np.abs(ref.log_odds() - fast.log_odds()).max() <= 1e-9
    assert np.array_equal(ref.log_odds(), fast.log_odds())
    assert np.array_equal(ref.observations(), fast.observations())


def test_numpy_reference_is_what_accumulate_sectors_runs_without_numba(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    ev = _sectors(np.random.default_rng(1), 300)
    monkeypatch.setenv("GRIDMAP_KERNELS", "numpy")
    a, b = LogOddsAccumulator(SPEC), LogOddsAccumulator(SPEC)
    assert accumulate_sectors(a, ev) == accumulate_sectors_numpy(b, ev)
    assert np.array_equal(a.log_odds(), b.log_odds())


def test_ray_kernel_equals_the_numpy_reference(monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(3)
    n = 3000
    x0 = np.round(rng.uniform(-3.5, 2.0, n), 2)  # many on cell boundaries
    y0 = np.round(rng.uniform(-2.5, 2.5, n), 2)
    angle = rng.uniform(-math.pi, math.pi, n)
    angle[:8] = [0.0, math.pi / 2, math.pi, -math.pi / 2, math.pi / 4, 0.0, 0.0, 1.0]
    length = rng.uniform(0.0, 6.0, n)
    length[5] = 0.0
    seg = RaySegments(
        x0, y0, x0 + length * np.cos(angle), y0 + length * np.sin(angle), rng.random(n) < 0.7
    )
    inside = RaySegments(seg.x0_m * 0.1, seg.y0_m * 0.1, seg.x0_m * 0.2, seg.y0_m * 0.2, seg.echo)
    cells: list[int] = []

    def add(grid: LogOddsAccumulator) -> None:
        cells.append(accumulate_rays(grid, seg, -0.405, 0.85))
        cells.append(accumulate_rays(grid, inside, -0.405, 0.85))

    ref, fast = _both(monkeypatch, add)
    assert cells[:2] == cells[2:]
    assert np.abs(ref.log_odds() - fast.log_odds()).max() <= 1e-9
    assert np.array_equal(ref.log_odds(), fast.log_odds())
    assert np.array_equal(ref.observations(), fast.observations())


def test_the_extension_is_built_and_chosen(monkeypatch: pytest.MonkeyPatch) -> None:
    # the dev install builds it (gcc and the Python headers are on every machine we test on):
    # a missing extension would leave every other test here comparing numpy with itself
    monkeypatch.setenv("GRIDMAP_KERNELS", "compiled")
    module = kernels.compiled()
    assert module is not None and module.__name__ == "gridmap_cli.mapping.models._ckernels"
    monkeypatch.setenv("GRIDMAP_KERNELS", "auto")
    assert kernels.compiled() is module
    monkeypatch.setenv("GRIDMAP_KERNELS", "numpy")
    assert kernels.compiled() is None


def test_a_kernel_refuses_arrays_of_the_wrong_size() -> None:
    from gridmap_cli.mapping.models import _ckernels  # type: ignore[attr-defined]

    grid = LogOddsAccumulator(SPEC)
    values, counts = grid.difference_arrays()
    m = np.zeros(3)
    j = np.zeros(3, dtype=np.int64)
    with pytest.raises(ValueError, match="y: expected 3 items"):
        _ckernels.sector_batch(
            0.0, 0.0, 0.05, SPEC.width, SPEC.height, m, np.zeros(2), m, m, m, m, j, j, m, m, m,
            m, values, counts,
        )  # fmt: skip
    with pytest.raises(ValueError, match="count_sums"):
        _ckernels.sector_batch(
            0.0, 0.0, 0.05, SPEC.width, SPEC.height, m, m, m, m, m, m, j, j, m, m, m, m,
            values, counts[:-1],
        )  # fmt: skip
    with pytest.raises(ValueError, match="read-only"):
        values.flags.writeable = False
        _ckernels.sector_batch(
            0.0, 0.0, 0.05, SPEC.width, SPEC.height, m, m, m, m, m, m, j, j, m, m, m, m,
            values, counts,
        )  # fmt: skip


def _readings(rng: np.random.Generator, n: int, sensors: int) -> SensorReadings:
    """Sonar readings along a drive: distance and rotation grow, so trust classes follow one
    another; some no-echo readings, some on cell boundaries."""
    d = np.cumsum(rng.uniform(0.0, 0.2, n))
    return SensorReadings(
        stamp_ns=np.arange(n, dtype=np.int64),
        sensor=rng.integers(0, sensors, n).astype(np.int32),
        range_m=np.where(rng.random(n) < 0.2, 5.0, rng.uniform(0.05, 4.9, n)),
        x_m=np.round(rng.uniform(-2.0, 2.0, n), 2),
        y_m=rng.uniform(-2.0, 2.0, n),
        theta_rad=np.concatenate([[0.0, math.pi / 2, -math.pi, -math.pi / 2], rng.uniform(
            -math.pi, math.pi, n - 4)]),
        sensors=tuple(
            RangeSensor(f"s{i}", 0.0, 0.0, 0.0, math.radians(25), 0.1, 5.0)
            for i in range(sensors)
        ),
        distance_m=d,
        rotation_rad=np.cumsum(rng.uniform(0.0, 0.1, n)),
    )  # fmt: skip


def test_error_aware_kernel_equals_the_numpy_reference(monkeypatch: pytest.MonkeyPatch) -> None:
    from gridmap_cli.poses.odometry_error import OdometryError

    odometry = OdometryError(
        range_m_per_m=0.01, range_m_per_sqrt_m=0.02, bearing_rad_per_rad=0.02,
        bearing_rad_per_sqrt_rad=0.02, heading_drift_rad_per_m=0.003,
    )  # fmt: skip
    model = ErrorAwareSonarModel(StandardSonarParams(), ErrorAwareParams(), odometry, 0.05)
    rng = np.random.default_rng(11)
    # batches crossing several trust classes (the pose error reaches metres)
    batches = [_readings(rng, n, 4) for n in (700, 5, 1500)]
    offset = 0.0
    for b in batches:
        assert b.distance_m is not None
        b.distance_m[:] += offset
        offset = float(b.distance_m[-1])
    ref, fast = assert_counts_equal_the_reference(monkeypatch, model, batches, SPEC)
    assert np.abs(ref.looks() - fast.looks()).max() <= 1e-9
    assert np.array_equal(ref.occupancy_map().prob, fast.occupancy_map().prob, equal_nan=True)


@pytest.mark.parametrize(
    "spec",
    [GridSpec(-7.0, -7.0, 0.05, 280, 280), GridSpec(-3.0, -2.5, 0.05, 110, 90)],
    ids=["within", "cut-by-the-grid"],
)
def test_error_aware_laser_kernel_equals_the_numpy_reference(
    monkeypatch: pytest.MonkeyPatch, spec: GridSpec
) -> None:
    from gridmap_cli.mapping.models.error_aware_ray import ErrorAwareRayModel, ScanLayout
    from gridmap_cli.poses.odometry_error import OdometryError
    from gridmap_cli.robot import laser_beams

    beams = laser_beams("laser", 0.1, 0.0, 0.0, -90.0, 90.0, 37, 0.05, 4.0)
    sensors = tuple(beams)
    layout = ScanLayout.of(sensors, np.ones(len(sensors), dtype=bool))
    odometry = OdometryError(
        range_m_per_m=0.01, range_m_per_sqrt_m=0.02, bearing_rad_per_rad=0.02,
        bearing_rad_per_sqrt_rad=0.02, heading_drift_rad_per_m=0.003,
    )  # fmt: skip
    model = ErrorAwareRayModel(ErrorAwareParams(), odometry, layout, 0.05)
    rng = np.random.default_rng(4)
    batches: list[SensorReadings] = []
    travelled = 0.0
    for scans in (20, 1, 40):
        n = scans * len(sensors)
        stamp = np.repeat(np.arange(scans, dtype=np.int64) + len(batches) * 100, len(sensors))
        pose = rng.uniform(-2.0, 2.0, (scans, 3))
        sensor = np.tile(np.arange(len(sensors), dtype=np.int32), scans)
        yaw = np.array([s.yaw_rad for s in sensors])[sensor]
        d = travelled + np.repeat(np.cumsum(rng.uniform(0.0, 2.0, scans)), len(sensors))
        travelled = float(d[-1])
        batches.append(
            SensorReadings(
                stamp_ns=stamp, sensor=sensor,
                # no echo (4.0) for some beams, some ranges on cell boundaries
                range_m=np.where(rng.random(n) < 0.15, 4.0, np.round(rng.uniform(0.1, 3.9, n), 2)),
                x_m=np.repeat(pose[:, 0], len(sensors)), y_m=np.repeat(pose[:, 1], len(sensors)),
                theta_rad=np.repeat(pose[:, 2], len(sensors)) + yaw, sensors=sensors,
                distance_m=d, rotation_rad=d * 0.3,
            )
        )  # fmt: skip
    assert_counts_equal_the_reference(monkeypatch, model, batches, spec)


def test_a_small_batch_on_a_large_grid_moves_only_what_it_touched(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # few runs for the rows they span: the kernel adds only the entries its runs touched
    # (the sparse path of its difference arrays), which must still equal the reference
    spec = GridSpec(-40.0, -40.0, 0.05, 1600, 1600)
    rng = np.random.default_rng(21)
    batches = [_sectors(rng, 5) for _ in range(3)]
    grids = []
    for choice in ("numpy", "compiled"):
        monkeypatch.setenv("GRIDMAP_KERNELS", choice)
        grid = LogOddsAccumulator(spec)
        for ev in batches:
            far = dataclasses.replace(ev, x_m=ev.x_m * 8.0, y_m=ev.y_m * 8.0)
            accumulate_sectors(grid, far)
        grids.append(grid)
    ref, fast = grids
    assert np.count_nonzero(ref.observations()) > 0
    assert np.array_equal(ref.log_odds(), fast.log_odds())
    assert np.array_equal(ref.observations(), fast.observations())


def test_error_aware_sonar_and_laser_in_one_batch_equal_the_numpy_reference(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # the mixed model adds each trust class's sonar runs, then its laser runs, in one sum:
    # the kernel must take both in one call, in that order, to give the same bits
    from gridmap_cli.mapping.models.error_aware_mixed import ErrorAwareMixedModel
    from gridmap_cli.mapping.models.error_aware_ray import ErrorAwareRayModel, ScanLayout
    from gridmap_cli.poses.odometry_error import OdometryError
    from gridmap_cli.robot import laser_beams

    sonars = tuple(
        RangeSensor(f"s{i}", 0.1, 0.0, math.radians(a), math.radians(25), 0.1, 5.0)
        for i, a in enumerate((-90, -30, 0, 30, 90))
    )
    sensors = sonars + tuple(laser_beams("laser", 0.1, 0.0, 0.0, -90.0, 90.0, 19, 0.05, 4.0))
    narrow = np.array([s.kind == "laser" for s in sensors])
    odometry = OdometryError(
        range_m_per_m=0.01, range_m_per_sqrt_m=0.02, bearing_rad_per_rad=0.02,
        bearing_rad_per_sqrt_rad=0.02, heading_drift_rad_per_m=0.003,
    )  # fmt: skip
    params = ErrorAwareParams()
    model = ErrorAwareMixedModel(
        ErrorAwareSonarModel(StandardSonarParams(), params, odometry, 0.05),
        ErrorAwareRayModel(params, odometry, ScanLayout.of(sensors, narrow), 0.05),
        narrow,
    )
    rng = np.random.default_rng(8)
    batches: list[SensorReadings] = []
    travelled = 0.0
    for scans in (15, 1, 30):
        n = scans * len(sensors)
        sensor = np.tile(np.arange(len(sensors), dtype=np.int32), scans)
        pose = np.repeat(rng.uniform(-2.0, 2.0, (scans, 3)), len(sensors), axis=0)
        yaw = np.array([s.yaw_rad for s in sensors])[sensor]
        d = travelled + np.repeat(np.cumsum(rng.uniform(0.0, 2.0, scans)), len(sensors))
        travelled = float(d[-1])
        batches.append(
            SensorReadings(
                stamp_ns=np.repeat(np.arange(scans, dtype=np.int64) + 100 * len(batches),
                                   len(sensors)),
                sensor=sensor,
                range_m=np.where(rng.random(n) < 0.15, np.array(
                    [s.max_range_m for s in sensors])[sensor], rng.uniform(0.2, 3.9, n)),
                x_m=pose[:, 0], y_m=pose[:, 1], theta_rad=pose[:, 2] + yaw, sensors=sensors,
                distance_m=d, rotation_rad=d * 0.3,
            )
        )  # fmt: skip
    assert_counts_equal_the_reference(
        monkeypatch, model, batches, GridSpec(-4.0, -4.5, 0.05, 170, 160)
    )
