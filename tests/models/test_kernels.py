"""The compiled kernels (numba) give the numpy reference's grid: within 1e-9 in log-odds as
issue 10 asks, and in fact bit for bit, for sonar cones and rays, in and off the grid."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gridmap_cli.grid import GridSpec, LogOddsAccumulator
from gridmap_cli.models import kernels
from gridmap_cli.models.ray import RaySegments, accumulate_rays
from gridmap_cli.models.standard import (
    SectorEvidence,
    accumulate_sectors,
    accumulate_sectors_numpy,
)

pytest.importorskip("numba")

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


def test_small_batches_stay_on_numpy_until_the_kernels_are_loaded(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("GRIDMAP_KERNELS", "auto")
    monkeypatch.setattr(kernels, "_module", None)
    monkeypatch.setattr(kernels, "_planned", 0)
    assert kernels.compiled(10) is None
    kernels.plan(kernels.MIN_COMPILED_ITEMS)
    assert kernels.compiled(10) is not None  # the build as a whole is large
    monkeypatch.setattr(kernels, "_module", None)
    kernels.plan(0)
    assert kernels.compiled(kernels.MIN_COMPILED_ITEMS) is not None
    assert kernels.compiled(10) is not None  # loaded: no reason to leave them
    monkeypatch.setenv("GRIDMAP_KERNELS", "numpy")
    assert kernels.compiled(10**9) is None
