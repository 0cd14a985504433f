"""The map grid: its geometry (:class:`GridSpec`) and the log-odds accumulator.

Cell (i, j) is column i, row j; row 0 is the bottom of the map (smallest y), as in the map_server
convention where ``origin`` is the world pose of the lower-left corner of cell (0, 0). Arrays of
cells are indexed ``[row, column]``, i.e. shape (height, width).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import MapSizeError

#: Probabilities the summed log-odds are clamped to when a map is finished: OctoMap's default
#: clamping thresholds (docs/sensor-model.md says why, and why once at the end).
DEFAULT_CLAMP_P = (0.01, 0.7)

#: Refuse maps larger than this many cells unless asked: 1e8 cells is 10 km x 10 km at 1 m, or
#: 500 m x 500 m at 5 cm; a bigger map almost always means absurd coordinates in the log.
DEFAULT_MAX_CELLS = 100_000_000


@dataclass(frozen=True)
class GridSpec:
    """Geometry of a grid: lower-left corner (metres, world frame), cell size and shape in cells."""

    origin_x_m: float
    origin_y_m: float
    resolution_m: float
    width: int
    height: int

    @property
    def shape(self) -> tuple[int, int]:
        """(height, width): the shape of an array of cells."""
        return (self.height, self.width)

    def world_to_cell(
        self, x_m: npt.NDArray[np.float64], y_m: npt.NDArray[np.float64]
    ) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
        """Column and row of the cells containing world points (may fall outside the grid)."""
        col = np.floor((np.asarray(x_m) - self.origin_x_m) / self.resolution_m).astype(np.int64)
        row = np.floor((np.asarray(y_m) - self.origin_y_m) / self.resolution_m).astype(np.int64)
        return col, row

    def cell_center(
        self, col: npt.NDArray[np.int64], row: npt.NDArray[np.int64]
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """World coordinates (metres) of the centres of cells."""
        x = self.origin_x_m + (np.asarray(col, dtype=np.float64) + 0.5) * self.resolution_m
        y = self.origin_y_m + (np.asarray(row, dtype=np.float64) + 0.5) * self.resolution_m
        return x, y

    @classmethod
    def covering(
        cls,
        xmin_m: float,
        ymin_m: float,
        xmax_m: float,
        ymax_m: float,
        resolution_m: float,
        margin_m: float = 0.0,
        max_cells: int = DEFAULT_MAX_CELLS,
    ) -> GridSpec:
        """The smallest grid aligned to multiples of the resolution that covers a box plus margin.

        Aligning the origin to a multiple of the resolution makes maps of overlapping logs share
        cell boundaries. Raises :class:`MapSizeError` when the grid would exceed ``max_cells``.
        """
        if not (resolution_m > 0.0 and math.isfinite(resolution_m)):
            raise MapSizeError(
                f"resolution must be a positive number of metres, got {resolution_m}"
            )
        box = (xmin_m, ymin_m, xmax_m, ymax_m)
        if not all(math.isfinite(v) for v in box) or xmin_m > xmax_m or ymin_m > ymax_m:
            raise MapSizeError(f"the data has no finite extent: {box}")
        x0 = math.floor((xmin_m - margin_m) / resolution_m)
        y0 = math.floor((ymin_m - margin_m) / resolution_m)
        x1 = math.ceil((xmax_m + margin_m) / resolution_m)
        y1 = math.ceil((ymax_m + margin_m) / resolution_m)
        width, height = max(x1 - x0, 1), max(y1 - y0, 1)
        if width * height > max_cells:
            raise MapSizeError(
                f"the data spans {xmax_m - xmin_m:.6g} m x {ymax_m - ymin_m:.6g} m "
                f"(x {xmin_m:.6g}..{xmax_m:.6g}, y {ymin_m:.6g}..{ymax_m:.6g}), "
                f"{width} x {height} cells at {resolution_m} m: more than {max_cells} cells; "
                "check the log for absurd coordinates or use a coarser --resolution"
            )
        # round away float noise (-2.6500000000000004) so the YAML origin reads as it should
        return cls(
            round(x0 * resolution_m, 9), round(y0 * resolution_m, 9), resolution_m, width, height
        )


@dataclass(frozen=True)
class OccupancyMap:
    """A finished map: occupancy probability per cell.

    ``prob``: shape (height, width), row 0 at the bottom, values in [0, 1]; NaN marks a cell no
    reading ever touched (unknown).
    """

    spec: GridSpec
    prob: npt.NDArray[np.float64]


def logodds(p: float) -> float:
    """log(p / (1 - p))."""
    return math.log(p / (1.0 - p))


class SpanSums:
    """Sums of values over runs of cells, kept as a per-row difference array.

    A run ``[col0, col1]`` of row ``r`` with value ``v`` adds ``v`` at ``(r, col0)`` and ``-v`` at
    ``(r, col1 + 1)``; one cumulative sum along each row at the end gives every cell its total.
    The cost of a run is O(1), not its number of cells, and sums do not depend on order. Integer
    sums (counts) are exact: the weights are whole numbers far below 2**53.
    """

    def __init__(self, spec: GridSpec, dtype: type[np.float64] | type[np.int64]) -> None:
        self.spec = spec
        self._stride = spec.width + 1
        self._sums = np.zeros(spec.height * self._stride, dtype=dtype)

    def add(
        self,
        row: npt.NDArray[np.int64],
        col0: npt.NDArray[np.int64],
        col1: npt.NDArray[np.int64],
        value: npt.NDArray[np.float64] | npt.NDArray[np.int64],
    ) -> None:
        """Add ``value[k]`` to every cell of run k; all arrays shape (S,)."""
        if row.shape[0] == 0:
            return
        base = row * self._stride
        delta = np.bincount(
            np.concatenate([base + col0, base + col1 + 1]),
            weights=np.concatenate([value, -value]).astype(np.float64),
            minlength=self._sums.shape[0],
        )
        if self._sums.dtype == np.int64:
            self._sums += np.rint(delta).astype(np.int64)
        else:
            self._sums += delta

    def difference_array(self) -> npt.NDArray[Any]:
        """The running difference array itself, shape (height * (width + 1),), row-major: for
        compiled kernels, which must add to it exactly as :meth:`add` does."""
        return self._sums

    def total(self) -> npt.NDArray[Any]:
        """The sum per cell, shape (height, width)."""
        grid = self._sums.reshape(self.spec.height, self._stride)
        return np.cumsum(grid, axis=1)[:, : self.spec.width]


class LogOddsAccumulator:
    """Sums log-odds evidence over runs of cells (:class:`SpanSums`).

    The cost of a reading is its number of rows, not its number of cells. Observation counts
    (how many readings touched a cell) are kept the same way, in integers, so "never observed" is
    exact. Because log-odds updates are sums, the result does not depend on reading order.
    """

    def __init__(self, spec: GridSpec) -> None:
        self.spec = spec
        self._values = SpanSums(spec, np.float64)
        self._counts = SpanSums(spec, np.int64)

    def add_values(
        self,
        row: npt.NDArray[np.int64],
        col0: npt.NDArray[np.int64],
        col1: npt.NDArray[np.int64],
        value: npt.NDArray[np.float64],
    ) -> None:
        """Add ``value[k]`` to every cell of run k; all arrays shape (S,)."""
        self._values.add(row, col0, col1, value)

    def add_observations(
        self, row: npt.NDArray[np.int64], col0: npt.NDArray[np.int64], col1: npt.NDArray[np.int64]
    ) -> None:
        """Count one observation in every cell of each run; arrays shape (S,)."""
        self._counts.add(row, col0, col1, np.ones(row.shape[0], dtype=np.int64))

    def difference_arrays(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
        """The value and count difference arrays (:meth:`SpanSums.difference_array`)."""
        return self._values.difference_array(), self._counts.difference_array()

    def log_odds(self) -> npt.NDArray[np.float64]:
        """Summed log-odds per cell, shape (height, width)."""
        return self._values.total().astype(np.float64, copy=False)

    def observations(self) -> npt.NDArray[np.int64]:
        """Number of readings that touched each cell, shape (height, width)."""
        return self._counts.total().astype(np.int64, copy=False)

    def occupancy_map(self, clamp_p: tuple[float, float] = DEFAULT_CLAMP_P) -> OccupancyMap:
        """Probabilities from the log-odds clamped to ``clamp_p`` (min, max); never observed: NaN.

        Raises ValueError unless 0 < min < 0.5 < max < 1.
        """
        if not 0.0 < clamp_p[0] < 0.5 < clamp_p[1] < 1.0:
            raise ValueError("clamp probabilities must satisfy 0 < min < 0.5 < max < 1")
        lo, hi = logodds(clamp_p[0]), logodds(clamp_p[1])
        clamped = np.clip(self.log_odds(), lo, hi)
        prob = 1.0 - 1.0 / (1.0 + np.exp(clamped))
        prob[self.observations() == 0] = np.nan
        return OccupancyMap(self.spec, prob)
