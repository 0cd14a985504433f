"""Map quality against a ground-truth world: how many walls a map found, erased or invented.

A map is in its own frame (the odometry frame, whose origin is the robot's first true pose, or
the world frame when built with ``--pose global``); ``map_to_world`` is the pose of the map frame
in the world, so every map cell can be looked up in the world map.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy import ndimage

from gridmap_cli.geometry import compose
from gridmap_cli.mapping.grid import GridSpec, OccupancyMap

#: Classification of a probability map: the trinary writer's defaults.
OCCUPIED_P = 0.65
FREE_P = 0.25


@dataclass(frozen=True)
class WallScores:
    """Cell counts and the shares derived from them.

    ``recall``: share of the visible wall cells (true walls within ``visible_within`` cells of
    an observed map cell) that have an occupied map cell within one cell. ``erased``: share of
    the visible wall cells the map calls free. ``false_occupied``: share of the occupied map
    cells more than one cell from any wall. ``free_m2``: area the map calls free.
    """

    visible_walls: int
    occupied: int
    recall: float
    erased: float
    false_occupied: float
    free_m2: float


def world_cells(
    spec: GridSpec, world: GridSpec, map_to_world: tuple[float, float, float]
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.bool_]]:
    """Row, column of the world cell under each map cell's centre, and where that is inside.

    All shape ``spec.shape``; entries outside the world grid are clipped and masked False.
    """
    rows, cols = np.indices(spec.shape)
    cx, cy = spec.cell_center(cols, rows)
    wx, wy, _ = compose(*map_to_world, cx, cy, 0.0)  # type: ignore[arg-type]
    wc, wr = world.world_to_cell(wx, wy)
    inside = (wc >= 0) & (wr >= 0) & (wc < world.width) & (wr < world.height)
    return np.clip(wr, 0, world.height - 1), np.clip(wc, 0, world.width - 1), inside


def walls_in_map_frame(
    spec: GridSpec,
    world: GridSpec,
    walls: npt.NDArray[np.bool_],
    map_to_world: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> npt.NDArray[np.bool_]:
    """The world's occupied cells resampled onto the map's grid, shape ``spec.shape``."""
    wr, wc, inside = world_cells(spec, world, map_to_world)
    return walls[wr, wc] & inside


def wall_scores(
    omap: OccupancyMap,
    world: GridSpec,
    walls: npt.NDArray[np.bool_],
    map_to_world: tuple[float, float, float] = (0.0, 0.0, 0.0),
    visible_within: int = 2,
) -> WallScores:
    """Score ``omap`` against the world's ``walls`` (shape ``world.shape``, row 0 at the bottom).

    ``visible_within``: how many cells from observed space a wall cell may lie and still count
    as visible. 2 admits the back of a two-cell wall, which a sonar's wide band may reach; 1
    keeps only the faces a laser can see.
    """
    prob = omap.prob
    true_wall = walls_in_map_frame(omap.spec, world, walls, map_to_world)
    near_wall = walls_in_map_frame(
        omap.spec, world, ndimage.binary_dilation(walls, iterations=1), map_to_world
    )
    known = ~np.isnan(prob)
    occupied = known & (prob >= OCCUPIED_P)
    free = known & (prob <= FREE_P)
    visible = true_wall & ndimage.binary_dilation(known, iterations=visible_within)
    n_visible = int(visible.sum())
    n_occupied = int(occupied.sum())
    found = visible & ndimage.binary_dilation(occupied, iterations=1)
    return WallScores(
        visible_walls=n_visible,
        occupied=n_occupied,
        recall=float(found.sum() / n_visible) if n_visible else float("nan"),
        erased=float((visible & free).sum() / n_visible) if n_visible else float("nan"),
        false_occupied=float((occupied & ~near_wall).sum() / n_occupied)
        if n_occupied
        else float("nan"),
        free_m2=float(free.sum()) * omap.spec.resolution_m**2,
    )
