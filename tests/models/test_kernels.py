"""The compiled kernels (the C extension) give the numpy reference's grid: within 1e-9 in
log-odds as issue 10 asks, and in fact bit for bit, for sonar cones and for rays, in and off the
grid."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from gridmap_cli import extensions
from gridmap_cli.evaluation.spread_map import spread_layer
from gridmap_cli.mapping import expected
from gridmap_cli.mapping.grid import GridSpec, LogOddsAccumulator
from gridmap_cli.mapping.models import kernels
from gridmap_cli.mapping.models.ray import RaySegments, accumulate_rays
from gridmap_cli.mapping.models.standard import (
    SectorEvidence,
    accumulate_sectors,
    accumulate_sectors_numpy,
)
from gridmap_cli.poses.sync import SensorReadings
from gridmap_cli.poses.uncertainty.pose_uncertainty import PoseUncertainty
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


def _both(monkeypatch: pytest.MonkeyPatch, add: object) -> tuple[LogOddsAccumulator, ...]:
    grids = []
    for choice in ("numpy", "compiled"):
        monkeypatch.setattr(extensions, "KERNELS", choice)
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
    monkeypatch.setattr(extensions, "KERNELS", "numpy")
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
    monkeypatch.setattr(extensions, "KERNELS", "compiled")
    module = kernels.compiled()
    assert module is not None and module.__name__ == "gridmap_cli.mapping.models._ckernels"
    monkeypatch.setattr(extensions, "KERNELS", "auto")
    assert kernels.compiled() is module
    monkeypatch.setattr(extensions, "KERNELS", "numpy")
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
            m, grid.scale, 0, values, counts,
        )  # fmt: skip
    with pytest.raises(ValueError, match="count_sums"):
        _ckernels.sector_batch(
            0.0, 0.0, 0.05, SPEC.width, SPEC.height, m, m, m, m, m, m, j, j, m, m, m, m,
            grid.scale, 0, values, counts[:-1],
        )  # fmt: skip
    with pytest.raises(ValueError, match="window of whole grid rows"):
        _ckernels.sector_batch(
            0.0, 0.0, 0.05, SPEC.width, SPEC.height, m, m, m, m, m, m, j, j, m, m, m, m,
            grid.scale, 1, values, counts,
        )  # fmt: skip
    with pytest.raises(ValueError, match="outside"):
        _ckernels.sector_batch(
            0.0, 0.0, 0.05, SPEC.width, SPEC.height, m, m, m, m, m, m, j, j + 1, m,
            np.full(3, 100.0), m, m, grid.scale, 0, values, counts,
        )  # fmt: skip
    with pytest.raises(ValueError, match="read-only"):
        values.flags.writeable = False
        _ckernels.sector_batch(
            0.0, 0.0, 0.05, SPEC.width, SPEC.height, m, m, m, m, m, m, j, j, m, m, m, m,
            grid.scale, 0, values, counts,
        )  # fmt: skip


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
        monkeypatch.setattr(extensions, "KERNELS", choice)
        grid = LogOddsAccumulator(spec)
        for ev in batches:
            far = dataclasses.replace(ev, x_m=ev.x_m * 8.0, y_m=ev.y_m * 8.0)
            accumulate_sectors(grid, far)
        grids.append(grid)
    ref, fast = grids
    assert np.count_nonzero(ref.observations()) > 0
    assert np.array_equal(ref.log_odds(), fast.log_odds())
    assert np.array_equal(ref.observations(), fast.observations())


def _motion(rng: np.random.Generator, keys: int) -> expected.Motion:
    rot = rng.normal(0.0, 0.6, keys)
    rot[0] = 0.0  # one key pose that does not move
    txy = rng.normal(0.0, 0.8, 2 * keys)
    txy[[0, keys]] = 0.0
    return expected.Motion(rot, np.cos(rot), np.sin(rot), txy)


def test_moved_sector_kernel_equals_the_numpy_reference(monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(11)
    motion = _motion(rng, 9)
    batches = [(expected.Cones.of(_sectors(rng, n)), rng.integers(0, 9, n)) for n in (700, 5)]
    cells: list[int] = []

    def add(grid: LogOddsAccumulator) -> None:
        cells.append(sum(expected.cast_sectors(grid, c, k, motion) for c, k in batches))

    ref, fast = _both(monkeypatch, add)
    assert cells[0] == cells[1] > 0
    assert np.array_equal(ref.log_odds(), fast.log_odds())
    assert np.array_equal(ref.observations(), fast.observations())


def test_unmoved_cones_map_as_the_standard_model() -> None:
    ev = _sectors(np.random.default_rng(5), 800)
    a, b = LogOddsAccumulator(SPEC), LogOddsAccumulator(SPEC)
    still = expected.Motion(np.zeros(1), np.ones(1), np.zeros(1), np.zeros(2))
    n = expected.cast_sectors_numpy(a, expected.Cones.of(ev), np.zeros(800, np.int64), still)
    assert n == accumulate_sectors_numpy(b, ev)
    assert np.array_equal(a.log_odds(), b.log_odds())
    assert np.array_equal(a.observations(), b.observations())


def test_moved_ray_kernel_equals_the_numpy_reference(monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(12)
    n = 2000
    x0 = np.round(rng.uniform(-3.5, 2.0, n), 2)
    y0 = np.round(rng.uniform(-2.5, 2.5, n), 2)
    angle = rng.uniform(-math.pi, math.pi, n)
    length = rng.uniform(0.0, 6.0, n)
    length[:3] = 0.0
    seg = RaySegments(
        x0, y0, x0 + length * np.cos(angle), y0 + length * np.sin(angle), rng.random(n) < 0.7
    )
    motion = _motion(rng, 6)
    owner = rng.integers(0, 6, n)
    cells: list[int] = []

    def add(grid: LogOddsAccumulator) -> None:
        cells.append(expected.cast_rays(grid, seg, owner, motion, -0.1, 0.05))

    ref, fast = _both(monkeypatch, add)
    assert cells[0] == cells[1] > 0
    assert np.array_equal(ref.log_odds(), fast.log_odds())
    assert np.array_equal(ref.observations(), fast.observations())


def test_the_moved_kernels_refuse_a_key_pose_that_is_not_there() -> None:
    from gridmap_cli.mapping.models import _ckernels  # type: ignore[attr-defined]

    grid = LogOddsAccumulator(SPEC)
    values, counts = grid.difference_arrays()
    m = np.zeros(2)
    bad = np.array([0, 1], dtype=np.int64)  # one key pose: index 1 is out of range
    one, two = np.ones(1), np.zeros(2)
    with pytest.raises(ValueError, match="owner"):
        _ckernels.moved_sector_batch(
            0.0, 0.0, 0.05, SPEC.width, SPEC.height, m, m, m, m, m, m, m, m, m, m, bad, one,
            one, two, grid.scale, values, counts,
        )  # fmt: skip
    with pytest.raises(ValueError, match="owner"):
        _ckernels.moved_ray_batch(
            0.0, 0.0, 0.05, SPEC.width, SPEC.height, m, m, m, m, bad, bad, one, one, two, -0.4,
            0.8, grid.scale, values, counts,
        )  # fmt: skip


def test_spread_layer_kernel_equals_the_numpy_reference(monkeypatch: pytest.MonkeyPatch) -> None:
    """The pose-spread layer's compiled sums are the numpy path's, rays in and off the grid."""
    rng = np.random.default_rng(11)
    n = 3000
    laser = RangeSensor("laser_0", 0.0, 0.0, 0.0, 0.0, 0.1, 6.0, kind="laser")
    readings = SensorReadings(
        stamp_ns=np.sort(rng.integers(0, 1000, n)).astype(np.int64),
        sensor=np.zeros(n, np.int32),
        range_m=rng.uniform(0.0, 8.0, n),
        x_m=np.round(rng.uniform(-4.0, 3.0, n), 2),
        y_m=rng.uniform(-3.0, 3.0, n),
        theta_rad=rng.uniform(-math.pi, math.pi, n),
        sensors=(laser,),
    )
    cov = np.zeros((2, 3, 3))
    cov[1, 0, 0] = cov[1, 1, 1] = 0.3**2
    stamps = np.array([0, 1000], dtype=np.int64)
    uncertainty = PoseUncertainty(stamps, np.zeros(2), np.zeros(2), cov)
    layers = []
    for choice in ("numpy", "compiled"):
        monkeypatch.setattr(extensions, "KERNELS", choice)
        layers.append(spread_layer(SPEC, iter([readings]), uncertainty))
    assert np.isfinite(layers[0]).sum() > 1000
    np.testing.assert_array_equal(layers[0], layers[1])
