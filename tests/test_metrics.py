"""Wall scores on maps small enough to count by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gridmap_cli.evaluation.metrics import wall_scores, walls_in_map_frame
from gridmap_cli.mapping.grid import GridSpec, OccupancyMap

# a 10 x 10 world at 1 m with one wall along column 5
WORLD = GridSpec(0.0, 0.0, 1.0, 10, 10)
WALLS = np.zeros(WORLD.shape, dtype=bool)
WALLS[:, 5] = True


def test_a_perfect_map_scores_perfectly() -> None:
    prob = np.where(WALLS, 0.9, 0.1)
    s = wall_scores(OccupancyMap(WORLD, prob), WORLD, WALLS)
    assert (s.visible_walls, s.occupied) == (10, 10)
    assert (s.recall, s.erased, s.false_occupied) == (1.0, 0.0, 0.0)
    assert s.free_m2 == 90.0


def test_counts_by_hand() -> None:
    prob = np.full(WORLD.shape, np.nan)
    prob[:, :5] = 0.1  # the left half observed free
    prob[0:4, 5] = 0.9  # four wall cells found
    prob[4:6, 5] = 0.1  # two erased
    prob[6:8, 5] = 0.5  # two seen but undecided
    prob[9, 0] = 0.9  # one invented wall, far from the true one
    s = wall_scores(OccupancyMap(WORLD, prob), WORLD, WALLS)
    # visible: wall cells within 2 cells of an observed cell = all 10; found within one cell:
    # rows 0-4 (row 4 is next to row 3's occupied cell)
    assert s.visible_walls == 10
    assert s.recall == pytest.approx(5 / 10)
    assert s.erased == pytest.approx(2 / 10)
    assert s.occupied == 5 and s.false_occupied == pytest.approx(1 / 5)


def test_map_frame_is_placed_in_the_world_by_its_pose() -> None:
    # a map frame turned by 90 degrees about world (5.5, 0): its x axis runs up world column 5
    spec = GridSpec(0.0, -0.5, 1.0, 10, 1)
    walls = walls_in_map_frame(spec, WORLD, WALLS, (5.5, 0.0, math.pi / 2))
    assert walls.all()
    shifted = walls_in_map_frame(spec, WORLD, WALLS, (7.5, 0.0, math.pi / 2))
    assert not shifted.any()
