"""The fast expected map (mapping/expected.py) against its oracle, the full standard builds of
the same sampled tracks averaged (expected.exact)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.mapping import expected, expected_oracle
from gridmap_cli.mapping.grid import GridSpec, OccupancyMap
from gridmap_cli.mapping.pipeline import BuildOptions, build_map, plan_build
from gridmap_cli.poses.odometry_error import OdometryError
from gridmap_cli.poses.uncertainty.pose_uncertainty import StepNoise, sample_tracks
from gridmap_cli.readers import read_log
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import load_robot
from gridmap_cli.sim.odometry import OdometryErrorModel

SAMPLES = Path(__file__).resolve().parents[1] / "samples"


@pytest.fixture(scope="module")
def log() -> RangeLog:
    return read_log(SAMPLES / "corridor_loop.csv")


def oracle(
    log: RangeLog, odometry: OdometryError, k: int, seed: int = 0, spec: GridSpec | None = None
) -> OccupancyMap:
    """``spec``: the grid to map on (the fast map's, grown where the samples' readings land);
    default the standard build's."""
    options = BuildOptions(odometry_error=odometry)
    plan = plan_build(log, load_robot("p3at"), options)
    if spec is not None:
        plan = dataclasses.replace(plan, spec=spec)
    tracks = sample_tracks(log.poses, StepNoise.of(odometry), k, seed)
    return expected_oracle.exact(plan, tracks, options.clamp_p, options.batch_size)


def fast(log: RangeLog, odometry: OdometryError, k: int) -> OccupancyMap:
    options = BuildOptions(mode="error-aware", odometry_error=odometry, error_samples=k)
    return build_map(log, load_robot("p3at"), options).map


def test_the_fast_map_is_its_oracle_on_the_same_tracks(
    log: RangeLog, monkeypatch: pytest.MonkeyPatch
) -> None:
    # without antithetic pairs the fast map draws the oracle's tracks (seed 0); what differs
    # is where it casts on coarser cells and the poses next to a key pose. It must be nearer
    # the oracle than the oracle of other draws is (measured: 0.018 against 0.056)
    monkeypatch.setattr(expected, "ANTITHETIC", False)
    odometry = OdometryErrorModel().as_odometry_error()  # the simulator's drift 1
    first = fast(log, odometry, 6)
    a, b, other = first.prob, oracle(log, odometry, 6, spec=first.spec).prob, oracle(
        log, odometry, 6, seed=1, spec=first.spec).prob  # fmt: skip
    # coarse cells decide at their centres whether a sample saw a cell: the borders of what
    # is known move by a few cells
    assert np.count_nonzero(~np.isnan(a) & ~np.isnan(b)) >= 0.98 * np.count_nonzero(~np.isnan(b))
    known = ~np.isnan(a) & ~np.isnan(b) & ~np.isnan(other)
    assert np.abs(a[known] - b[known]).mean() < 0.5 * np.abs(other[known] - b[known]).mean()


def test_an_error_along_the_path_only_still_blurs_as_the_oracle(
    log: RangeLog, monkeypatch: pytest.MonkeyPatch
) -> None:
    # a distance scale error moves poses along the path and never across it: a reading there
    # is not "the same in every sample", and coarse cells would shift it across the path
    monkeypatch.setattr(expected, "ANTITHETIC", False)
    zero = OdometryError(*([0.0] * len(dataclasses.fields(OdometryError))))
    odometry = dataclasses.replace(zero, range_m_per_m=0.05)
    walls = [int(np.count_nonzero(m.prob >= 0.65)) for m in (fast(log, odometry, 8),
             oracle(log, odometry, 8))]  # fmt: skip
    standard = int(np.count_nonzero(build_map(log, load_robot("p3at"), BuildOptions()).map.prob
                                    >= 0.65))  # fmt: skip
    assert abs(walls[0] - walls[1]) <= 0.05 * walls[1]
    assert walls[0] < 0.5 * standard


def test_a_map_too_large_for_the_fast_map_is_the_oracle_in_row_bands(
    log: RangeLog, monkeypatch: pytest.MonkeyPatch
) -> None:
    # past FAST_MAP_MAX_CELLS the tracks are mapped one by one (memory bounded by the map): the
    # oracle's map (its grid sums in fixed point, the oracle's in floats: 1e-9 apart), and
    # the same bits whether a sample is mapped in one band or in several
    from gridmap_cli.mapping import bands, pipeline

    odometry = OdometryErrorModel().as_odometry_error()
    monkeypatch.setattr(pipeline, "FAST_MAP_MAX_CELLS", 0)
    whole = fast(log, odometry, 4)
    monkeypatch.setattr(bands, "SAMPLE_GRID_FREE_CELLS", 1000)
    banded = fast(log, odometry, 4)
    assert len(bands.sample_bands(banded.spec, 4)) > 1
    assert np.array_equal(banded.prob, whole.prob, equal_nan=True)
    truth = oracle(log, odometry, 4).prob
    assert np.array_equal(np.isnan(banded.prob), np.isnan(truth))
    assert np.nanmax(np.abs(banded.prob - truth)) < 1e-6
    # and not the fast map: that one casts on coarser cells
    monkeypatch.setattr(pipeline, "FAST_MAP_MAX_CELLS", 1 << 40)
    again = fast(log, odometry, 4)
    truth = oracle(log, odometry, 4, spec=again.spec).prob
    assert np.nanmax(np.abs(again.prob - truth)) > 1e-3


def test_levels_cover_the_map_and_upsample_onto_it() -> None:
    spec = GridSpec(-1.0, 2.0, 0.05, 37, 21)
    for level in range(4):
        coarse = expected.level_spec(spec, level)
        assert coarse.width * 2**level >= spec.width and coarse.height * 2**level >= spec.height
        assert (coarse.width - 1) * 2**level < spec.width
        values = np.arange(coarse.width * coarse.height, dtype=float).reshape(coarse.shape)
        up = expected.upsample(values, spec, level)
        assert up.shape == spec.shape
        # map cell (row, col) takes its coarse cell's value
        assert up[spec.height - 1, spec.width - 1] == values[(spec.height - 1) >> level,
                                                             (spec.width - 1) >> level]  # fmt: skip


def test_the_grid_holds_where_the_samples_readings_land(
    log: RangeLog, monkeypatch: pytest.MonkeyPatch
) -> None:
    # the standard build's grid ends 0.2 m past the nominal readings; sampled tracks carry
    # them farther, and a grid that cut them drew a straight edge through the known cells.
    # The grid grows instead: no cell on its edge is known
    from gridmap_cli.mapping import pipeline

    odometry = OdometryErrorModel().as_odometry_error()

    def known_on_edge(prob: np.ndarray) -> int:
        known = ~np.isnan(prob)
        return int(known[0].sum() + known[-1].sum() + known[:, 0].sum() + known[:, -1].sum())

    grown = fast(log, odometry, 8)
    standard = build_map(log, load_robot("p3at"), BuildOptions()).map
    assert grown.spec.width * grown.spec.height > standard.spec.width * standard.spec.height
    assert known_on_edge(grown.prob) == 0
    # on the standard build's grid the samples' readings are cut at its edge
    monkeypatch.setattr(pipeline, "_sampled_grid", lambda plan, *_: plan)
    assert known_on_edge(fast(log, odometry, 8).prob) > 0


def test_the_known_edge_is_drawn_at_the_maps_cells_not_in_blocks() -> None:
    # coarse cells (4x the map's) seen on and below a diagonal: copied onto the map's cells
    # they draw a staircase whose edge jumps 4 cells every 4 rows; spread linearly it is a
    # line that moves by a cell or two a row
    spec = GridSpec(0.0, 0.0, 0.05, 32, 32)
    coarse = expected.level_spec(spec, 2)
    rows, cols = np.indices(coarse.shape)
    count = np.where(rows >= cols, 8, 0)
    seen = expected.known_cells(spec, {2: count > 0})
    edge = np.array([np.flatnonzero(~row)[0] if (~row).any() else spec.width for row in seen])
    blocks = np.array([np.flatnonzero(r == 0)[0] if (r == 0).any() else spec.width
                       for r in expected.upsample(count, spec, 2)])  # fmt: skip
    assert np.abs(np.diff(blocks[4:28])).max() == 4
    assert np.abs(np.diff(edge[4:28])).max() <= 2
    # and it follows the diagonal: within two cells of the blocks' edge everywhere
    assert np.abs(edge - blocks).max() <= 2
