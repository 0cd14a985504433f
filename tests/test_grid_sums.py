"""The grid's sums: fixed-point log-odds and uint32 counts, exact in any order, a window of rows
mapping as the whole grid's rows, finished in place as the copying conversion finishes them; the
sampled expected map the same in row bands as in one; map images the same in strips as whole.
Memory itself is measured by ``make bench`` (whole process), not here."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli import extensions
from gridmap_cli.errors import MapSizeError
from gridmap_cli.mapping import bands, pipeline
from gridmap_cli.mapping import grid as grid_module
from gridmap_cli.mapping.grid import (
    MAX_GRID_READINGS,
    VALUE_LIMIT,
    GridSpec,
    LogOddsAccumulator,
    value_bits,
)
from gridmap_cli.mapping.models.ray import RaySegments, accumulate_rays
from gridmap_cli.mapping.models.standard import SectorEvidence, accumulate_sectors
from gridmap_cli.mapping.pipeline import BuildOptions, build_map
from gridmap_cli.poses.odometry_error import OdometryError
from gridmap_cli.readers import read_log
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.robot import load_robot
from gridmap_cli.writers import map_image

SPEC = GridSpec(-3.05, -2.0, 0.05, 97, 83)
SAMPLES = Path(__file__).resolve().parents[1] / "samples"
KERNELS = ["numpy", "compiled"]


def _evidence(rng: np.random.Generator, n: int) -> tuple[SectorEvidence, RaySegments]:
    reach = rng.uniform(0.0, 5.0, n)
    echo = rng.random(n) < 0.7
    sectors = SectorEvidence(
        x_m=rng.uniform(-4.0, 3.0, n),
        y_m=rng.uniform(-3.0, 3.0, n),
        theta_rad=rng.uniform(-math.pi, math.pi, n),
        half_width_rad=np.full(n, math.radians(12.5)),
        inner_m=np.maximum(reach - 0.1, 0.0),
        inner_value=np.where(echo, -0.405 - 0.85, -0.405),
        outer_m=reach,
        outer_value=np.where(echo, 0.85, 0.0),
    )
    x0, y0 = rng.uniform(-3.5, 2.0, n), rng.uniform(-2.5, 2.5, n)
    angle = rng.uniform(-math.pi, math.pi, n)
    rays = RaySegments(x0, y0, x0 + reach * np.cos(angle), y0 + reach * np.sin(angle), echo)
    return sectors, rays


def _mapped(grid: LogOddsAccumulator, n: int = 400) -> LogOddsAccumulator:
    sectors, rays = _evidence(np.random.default_rng(5), n)
    accumulate_sectors(grid, sectors)
    accumulate_rays(grid, rays, -0.405, 0.85)
    return grid


@pytest.mark.parametrize("kernels", KERNELS)
def test_a_window_of_rows_holds_what_the_whole_grid_holds_there(
    monkeypatch: pytest.MonkeyPatch, kernels: str
) -> None:
    monkeypatch.setattr(extensions, "KERNELS", kernels)
    whole = _mapped(LogOddsAccumulator(SPEC))
    assert np.count_nonzero(whole.observations()) > 1000
    for rows in [(0, 30), (30, 31), (31, SPEC.height)]:
        part = _mapped(LogOddsAccumulator(SPEC, rows=rows))
        assert part.difference_arrays()[0].shape == ((rows[1] - rows[0]) * (SPEC.width + 1),)
        assert np.array_equal(part.log_odds(), whole.log_odds()[rows[0] : rows[1]])
        assert np.array_equal(part.observations(), whole.observations()[rows[0] : rows[1]])


def test_the_sums_do_not_depend_on_the_order_of_the_runs() -> None:
    rng = np.random.default_rng(2)
    n = 5000
    row, col0 = rng.integers(0, SPEC.height, n), rng.integers(0, SPEC.width, n)
    col1 = np.minimum(col0 + rng.integers(0, 40, n), SPEC.width - 1)
    value = rng.uniform(-3.0, 3.0, n)
    grids = []
    for order in (np.arange(n), rng.permutation(n), np.arange(n)[::-1]):
        g = LogOddsAccumulator(SPEC)
        for part in np.array_split(order, 7):
            g.add_values(row[part], col0[part], col1[part], value[part])
            g.add_observations(row[part], col0[part], col1[part])
        grids.append(g)
    first = grids[0]
    for other in grids[1:]:
        assert np.array_equal(other.log_odds(), first.log_odds())
        assert np.array_equal(other.observations(), first.observations())
    # exact up to one rounding of each update to 2**-32
    expected = np.zeros(SPEC.shape)
    for r, a, b, v in zip(row, col0, col1, value, strict=True):
        expected[r, a : b + 1] += v
    assert np.abs(first.log_odds() - expected).max() < 1e-6


@pytest.mark.parametrize("kernels", KERNELS)
def test_finishing_in_place_gives_the_copying_conversion_to_the_bit(
    monkeypatch: pytest.MonkeyPatch, kernels: str
) -> None:
    monkeypatch.setattr(extensions, "KERNELS", kernels)
    monkeypatch.setattr(grid_module, "STRIP_CELLS", 500)  # many strips of a few rows
    g = _mapped(LogOddsAccumulator(SPEC), 40)  # some cells left unknown
    copied = g.occupancy_map((0.12, 0.97))
    observations = int(g.observations().sum())
    finished, updates = g.finish((0.12, 0.97))
    assert finished.spec == SPEC
    assert finished.prob.shape == SPEC.shape and finished.prob.flags.c_contiguous
    assert np.array_equal(finished.prob, copied.prob, equal_nan=True)
    assert 0 < np.count_nonzero(np.isnan(finished.prob)) < SPEC.width * SPEC.height
    assert updates == observations > 0


def test_the_grid_holds_12_bytes_a_cell() -> None:
    values, counts = LogOddsAccumulator(SPEC).difference_arrays()
    assert (values.dtype, counts.dtype) == (np.int64, np.uint32)
    assert values.nbytes + counts.nbytes == 12 * SPEC.height * (SPEC.width + 1)


def test_the_fixed_point_keeps_a_long_logs_totals_inside_int64() -> None:
    assert value_bits(100) == value_bits(1 << 23) == 32
    assert value_bits(1 << 24) == 31
    assert value_bits(MAX_GRID_READINGS) == 24
    for readings in (1 << 24, 1 << 28, MAX_GRID_READINGS):
        bits = value_bits(readings)
        assert 2 * readings * VALUE_LIMIT * 2**bits < 2**63
    with pytest.raises(MapSizeError, match="readings in one map"):
        value_bits(MAX_GRID_READINGS + 1)


@pytest.mark.parametrize("kernels", KERNELS)
def test_evidence_beyond_the_limit_is_refused(
    monkeypatch: pytest.MonkeyPatch, kernels: str
) -> None:
    monkeypatch.setattr(extensions, "KERNELS", kernels)
    sectors, rays = _evidence(np.random.default_rng(4), 50)
    with pytest.raises(ValueError, match="outside"):
        accumulate_sectors(
            LogOddsAccumulator(SPEC),
            dataclasses.replace(sectors, inner_value=sectors.inner_m * 0 - 65.0),
        )
    with pytest.raises(ValueError, match="outside"):
        accumulate_rays(LogOddsAccumulator(SPEC), rays, -math.inf, 0.85)


def test_the_sampled_expected_map_is_the_same_in_row_bands(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    robot = load_robot("p3at")
    log = read_log(SAMPLES / "corridor_loop.csv", None, ReadOptions(robot=robot))
    error = OdometryError(range_m_per_m=0.02, heading_drift_rad_per_m=0.003)
    options = BuildOptions(mode="error-aware", odometry_error=error, error_samples=3)
    # the tracks mapped one by one, as on a map too large for the fast expected map
    monkeypatch.setattr(pipeline, "FAST_MAP_MAX_CELLS", 0)
    one = build_map(log, robot, options)
    assert bands.sample_bands(one.map.spec, 3) == [(0, one.map.spec.height)]
    monkeypatch.setattr(bands, "SAMPLE_GRID_FREE_CELLS", 0)
    rows = bands.sample_bands(one.map.spec, 3)
    assert len(rows) >= 3 and rows[0][0] == 0 and rows[-1][1] == one.map.spec.height
    reported: list[int] = []
    banded = build_map(log, robot, options, reported.append)
    assert np.array_equal(banded.map.prob, one.map.prob, equal_nan=True)
    assert banded.cell_updates == one.cell_updates > 0
    assert sum(reported) <= log.reading_count and sum(reported) > 0.9 * log.reading_count
    seen = ~np.isnan(one.map.prob)
    assert 0 < np.count_nonzero(seen) < seen.size


@pytest.mark.parametrize("mode", map_image.MAP_MODES)
def test_map_images_are_the_same_made_in_strips(monkeypatch: pytest.MonkeyPatch, mode: str) -> None:
    rng = np.random.default_rng(9)
    prob = rng.random((37, 23))
    prob[rng.random(prob.shape) < 0.2] = np.nan
    prob[0, :3] = [0.0, 1.0, 0.25]
    whole = map_image.map_pixels(prob, mode, 0.65, 0.25)
    monkeypatch.setattr(map_image, "_STRIP_CELLS", 50)
    assert np.array_equal(map_image.map_pixels(prob, mode, 0.65, 0.25), whole)
    if mode == "trinary":  # top image row is the map's last row
        assert whole[-1, :3].tolist() == [254, 0, 254]
