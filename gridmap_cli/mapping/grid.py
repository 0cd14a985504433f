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

    def cell_counts(self, occupied: float, free: float) -> tuple[int, int, int]:
        """Cells observed (not NaN), at or above ``occupied`` and at or below ``free``; counted
        in row strips, with no map-sized temporary."""
        counts = np.zeros(3, dtype=np.int64)
        step = strip_rows(self.spec.width)
        for r0 in range(0, self.prob.shape[0], step):
            part = self.prob[r0 : r0 + step]
            counts += (
                np.count_nonzero(~np.isnan(part)),
                np.count_nonzero(part >= occupied),  # NaN compares False
                np.count_nonzero(part <= free),
            )
        observed, high, low = (int(c) for c in counts)
        return observed, high, low

    def weak_evidence_note(self, occupied: float, free: float) -> str | None:
        """Why a trinary image of this map would be all unknown though readings were mapped:
        no observed cell reaches either threshold (a log of a few readings: each cell holds
        one reading's evidence, which moves p from 0.5 by less than the thresholds ask). None
        when a cell does, or none was observed."""
        observed, high, low = self.cell_counts(occupied, free)
        if observed == 0 or high or low:
            return None
        return (
            f"none of the {observed:,} observed cells passes --occupied {occupied:g} or --free "
            f"{free:g}: the evidence is too weak for any cell to be called occupied or free, so "
            "the trinary map is all unknown (more readings, or --map-mode scale to see the "
            "probabilities)"
        )


def logodds(p: float) -> float:
    """log(p / (1 - p))."""
    return math.log(p / (1.0 - p))


#: The largest |log-odds| one update may add: the fixed-point sums (:class:`LogOddsAccumulator`)
#: are sized for it. logit(1 - 1e-27) is about 62; the models' defaults are below 1.
VALUE_LIMIT = 64.0
#: Readings one grid takes at most: its observation counts are uint32, exact modulo 2**32, so
#: a count is 0 only for a cell no reading touched while fewer readings than this are mapped.
MAX_GRID_READINGS = 2**32 - 1
#: Fraction bits of the fixed-point log-odds: 2**-32 (2.3e-10) per update, unless the log is so
#: long that a cell's total could leave int64 (:func:`value_bits`).
MAX_VALUE_BITS = 32
#: Cells converted at a time when a grid is finished (:meth:`LogOddsAccumulator.finish`): the
#: temporaries are a few of these arrays, never the grid's size.
STRIP_CELLS = 1 << 18


def value_bits(readings: int) -> int:
    """Fraction bits of the fixed-point sums of a grid taking ``readings`` readings.

    A reading adds at most two updates to a cell (the sonar's nested disks; the ray's free run
    and its end cell), each at most :data:`VALUE_LIMIT` = 2**6, so a cell's total stays below
    2 * readings * 2**6 * 2**bits, which must stay below 2**63: 32 bits up to 2**24 readings, one
    fewer for each doubling beyond (24 at the uint32 limit of the counts).
    """
    if readings > MAX_GRID_READINGS:
        raise MapSizeError(
            f"{readings} readings in one map: more than the {MAX_GRID_READINGS} a grid counts"
        )
    return min(MAX_VALUE_BITS, 63 - 1 - 6 - max(int(readings), 1).bit_length())


def strip_rows(width: int) -> int:
    """Rows of a strip of about :data:`STRIP_CELLS` cells (at least one row)."""
    return max(1, STRIP_CELLS // max(width, 1))


class SpanSums:
    """Sums of values over runs of cells, kept as a per-row difference array.

    A run ``[col0, col1]`` of row ``r`` with value ``v`` adds ``v`` at ``(r, col0)`` and ``-v`` at
    ``(r, col1 + 1)``; one cumulative sum along each row at the end gives every cell its total.
    The cost of a run is O(1), not its number of cells. Integer sums are exact in any order
    (unsigned ones modulo their range, as numpy's wrap) and cost no grid-sized temporary;
    float64 sums are added per call, through one ``np.bincount`` over the grid.

    ``rows``: the window ``[row0, row1)`` of the grid held (default: every row); runs in other
    rows are dropped.
    """

    def __init__(
        self, spec: GridSpec, dtype: type[np.generic], rows: tuple[int, int] | None = None
    ) -> None:
        self.spec = spec
        self.rows = (0, spec.height) if rows is None else rows
        if not 0 <= self.rows[0] <= self.rows[1] <= spec.height:
            raise ValueError(f"rows {self.rows} outside a grid of {spec.height} rows")
        self._stride = spec.width + 1
        self._sums = np.zeros((self.rows[1] - self.rows[0]) * self._stride, dtype=dtype)

    def add(
        self,
        row: npt.NDArray[np.int64],
        col0: npt.NDArray[np.int64],
        col1: npt.NDArray[np.int64],
        value: npt.NDArray[Any],
    ) -> None:
        """Add ``value[k]`` to every cell of run k; all arrays shape (S,)."""
        row0, row1 = self.rows
        if (row0, row1) != (0, self.spec.height):
            keep = (row >= row0) & (row < row1)
            row, col0, col1, value = row[keep], col0[keep], col1[keep], value[keep]
        if row.shape[0] == 0:
            return
        base = (row - row0) * self._stride
        at = np.concatenate([base + col0, base + col1 + 1])
        if self._sums.dtype.kind in "iu":
            signed = np.asarray(value).astype(np.int64)
            np.add.at(self._sums, at, np.concatenate([signed, -signed]).astype(self._sums.dtype))
            return
        self._sums += np.bincount(
            at,
            weights=np.concatenate([value, -value]).astype(np.float64),
            minlength=self._sums.shape[0],
        )

    def difference_array(self) -> npt.NDArray[Any]:
        """The running difference array itself, shape (rows * (width + 1),), row-major: for
        compiled kernels, which must add to it exactly as :meth:`add` does."""
        return self._sums

    def total(self) -> npt.NDArray[Any]:
        """The sum per cell of the rows held, shape (rows, width), in the sums' dtype."""
        grid = self._sums.reshape(self.rows[1] - self.rows[0], self._stride)
        return np.cumsum(grid, axis=1, dtype=self._sums.dtype)[:, : self.spec.width]


class LogOddsAccumulator:
    """Sums log-odds evidence over runs of cells (:class:`SpanSums`), in fixed point.

    The cost of a reading is its number of rows, not its number of cells. Each update is rounded
    once to a multiple of 2**-bits (:func:`value_bits`: 2**-32 unless ``readings``, the most
    readings the grid will take, is above 2**24) and summed as int64, so sums are exact and do
    not depend on order or on how the readings are cut into shards; observation counts (how
    many readings touched a cell) are uint32, so "never observed" is exact. That is 12 bytes a
    cell and no grid-sized temporary: :meth:`finish` turns the sums into the map's probabilities
    in place.
    """

    def __init__(
        self,
        spec: GridSpec,
        readings: int = 1 << 24,
        rows: tuple[int, int] | None = None,
    ) -> None:
        self.spec = spec
        self.readings = readings
        self.bits = value_bits(readings)
        self.scale = float(2**self.bits)
        self._values = SpanSums(spec, np.int64, rows)
        self._counts = SpanSums(spec, np.uint32, rows)
        self.rows = self._values.rows

    def add_values(
        self,
        row: npt.NDArray[np.int64],
        col0: npt.NDArray[np.int64],
        col1: npt.NDArray[np.int64],
        value: npt.NDArray[np.float64],
    ) -> None:
        """Add ``value[k]`` (log-odds, |value| <= :data:`VALUE_LIMIT`) to every cell of run k;
        all arrays shape (S,). Raises ValueError for a value beyond the limit or not finite."""
        value = np.asarray(value, dtype=np.float64)
        if value.size and not bool(np.all(np.abs(value) <= VALUE_LIMIT)):
            raise ValueError(f"log-odds evidence outside +-{VALUE_LIMIT}")
        self._values.add(row, col0, col1, np.rint(value * self.scale).astype(np.int64))

    def add_observations(
        self, row: npt.NDArray[np.int64], col0: npt.NDArray[np.int64], col1: npt.NDArray[np.int64]
    ) -> None:
        """Count one observation in every cell of each run; arrays shape (S,)."""
        self._counts.add(row, col0, col1, np.ones(row.shape[0], dtype=np.int64))

    def difference_arrays(self) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.uint32]]:
        """The value (fixed point, :attr:`scale` per log-odds unit) and count difference arrays
        (:meth:`SpanSums.difference_array`) of the rows held (:attr:`rows`)."""
        return self._values.difference_array(), self._counts.difference_array()

    def log_odds(self) -> npt.NDArray[np.float64]:
        """Summed log-odds per cell of the rows held, shape (rows, width)."""
        return self._values.total().astype(np.float64) * (1.0 / self.scale)

    def observations(self) -> npt.NDArray[np.int64]:
        """Number of readings that touched each cell of the rows held, shape (rows, width)."""
        return self._counts.total().astype(np.int64)

    def occupancy_map(self, clamp_p: tuple[float, float] = DEFAULT_CLAMP_P) -> OccupancyMap:
        """Probabilities from the log-odds clamped to ``clamp_p`` (min, max); never observed: NaN.
        The accumulator is left as it was (:meth:`finish` spends it instead, in place).

        Raises ValueError unless 0 < min < 0.5 < max < 1.
        """
        lo, hi = _clamp_log_odds(clamp_p)
        prob = _probability(self.log_odds(), lo, hi)
        prob[self.observations() == 0] = np.nan
        return OccupancyMap(self.spec, prob)

    def finish(self, clamp_p: tuple[float, float] = DEFAULT_CLAMP_P) -> tuple[OccupancyMap, int]:
        """:meth:`occupancy_map`, to the bit, computed strip by strip into the memory of the
        value sums (the counts are let go): the peak is the accumulator's 12 bytes a cell. Also
        returns the cell updates (observations summed over the cells). The map covers the rows
        held (a window's own when :attr:`rows` is not the whole grid). The accumulator cannot
        be used afterwards.
        """
        lo, hi = _clamp_log_odds(clamp_p)
        width, stride = self.spec.width, self.spec.width + 1
        height = self.rows[1] - self.rows[0]
        flat = self._values.difference_array()
        values = flat.reshape(height, stride)
        counts = self._counts.difference_array().reshape(height, stride)
        out = flat.view(np.float64)
        step = strip_rows(stride)
        updates = 0
        for r0 in range(0, height, step):
            r1 = min(height, r0 + step)
            total = np.cumsum(values[r0:r1], axis=1)[:, :width]
            seen = np.cumsum(counts[r0:r1], axis=1, dtype=np.uint32)[:, :width]
            updates += int(seen.sum(dtype=np.uint64))
            prob = _probability(total.astype(np.float64) * (1.0 / self.scale), lo, hi)
            prob[seen == 0] = np.nan
            # rows r0..r1 compacted to width cells: never past the sums not yet read
            out[r0 * width : r1 * width] = prob.ravel()
        self._counts = self._values = None  # type: ignore[assignment]
        prob_all = out[: height * width].reshape(height, width)
        spec = self.spec
        if height != spec.height:
            origin_y = round(spec.origin_y_m + self.rows[0] * spec.resolution_m, 9)
            spec = GridSpec(spec.origin_x_m, origin_y, spec.resolution_m, width, height)
        return OccupancyMap(spec, prob_all), updates


def _clamp_log_odds(clamp_p: tuple[float, float]) -> tuple[float, float]:
    if not 0.0 < clamp_p[0] < 0.5 < clamp_p[1] < 1.0:
        raise ValueError("clamp probabilities must satisfy 0 < min < 0.5 < max < 1")
    return logodds(clamp_p[0]), logodds(clamp_p[1])


def _probability(log_odds: npt.NDArray[np.float64], lo: float, hi: float) -> npt.NDArray[Any]:
    """p of log-odds clamped to [lo, hi]."""
    return 1.0 - 1.0 / (1.0 + np.exp(np.clip(log_odds, lo, hi)))
