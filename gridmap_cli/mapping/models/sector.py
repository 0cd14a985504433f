"""Geometry shared by the cone-shaped sensor models: which cells a beam sector covers.

A sonar beam of full width ``beta < pi`` is a circular sector: a disk around the sensor cut by a
wedge of half-angle ``beta / 2`` around the beam axis. A sector is convex, so its intersection with
one row of cells is a single run of columns. We enumerate, for every reading, the rows its sector
spans and, per row, the wedge's extent along x; a disk of any radius then cuts that extent to a
column span in O(1). A cell belongs to the sector when its centre does.

Everything is vectorised over readings and rows: no Python loop over readings or cells.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from gridmap_cli.geometry import wrap_angle
from gridmap_cli.mapping.grid import GridSpec

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]


@dataclass(frozen=True)
class ColumnSpans:
    """Runs of cells ``[col0, col1]`` (inclusive) in ``row``, produced by reading ``reading``.

    All shape (S,). Empty runs are already removed.
    """

    reading: I64
    row: I64
    col0: I64
    col1: I64

    def cells(self) -> int:
        """Number of cells the spans cover (counting a cell once per span)."""
        return int((self.col1 - self.col0 + 1).sum())


@dataclass(frozen=True)
class SectorRows:
    """The rows a batch of sectors covers, with the wedge's x-extent in each, shape (P,) each.

    ``lo_m``/``hi_m`` bound ``x - x_sensor`` for cell centres of ``row`` inside the wedge (may be
    +-inf; ``lo_m > hi_m`` when the wedge misses the row).
    """

    spec: GridSpec
    sensor_x_m: F64  # shape (M,), per reading
    reading: I64
    row: I64
    dy_m: F64
    lo_m: F64
    hi_m: F64

    def spans(self, radius_m: F64) -> ColumnSpans:
        """Column spans of each sector's wedge cut by the disk of ``radius_m`` (shape (M,)).

        A radius <= 0 gives no cells for that reading.
        """
        spec = self.spec
        r = radius_m[self.reading]
        d2 = r * r - self.dy_m * self.dy_m
        half = np.sqrt(np.maximum(d2, 0.0))
        lo = np.maximum(self.lo_m, -half)
        hi = np.minimum(self.hi_m, half)
        sx = self.sensor_x_m[self.reading]
        # centre of column i is origin + (i + 0.5) * res; keep centres within [sx + lo, sx + hi]
        c0f = np.ceil((sx + lo - spec.origin_x_m) / spec.resolution_m - 0.5)
        c1f = np.floor((sx + hi - spec.origin_x_m) / spec.resolution_m - 0.5)
        c0 = np.clip(c0f, 0, spec.width - 1).astype(np.int64)
        c1 = np.clip(c1f, 0, spec.width - 1).astype(np.int64)
        keep = (d2 >= 0.0) & (r > 0.0) & (c0f <= c1f) & (c1f >= 0) & (c0f <= spec.width - 1)
        return ColumnSpans(self.reading[keep], self.row[keep], c0[keep], c1[keep])


def _half_plane(a: F64, b: F64, dy: F64) -> tuple[F64, F64]:
    """x-extent of {dx : a dx + b dy >= 0} for each (a, b, dy): (lo, hi), lo > hi when empty."""
    c = -b * dy
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = c / a
    lo = np.where(a > 0, bound, -np.inf)
    hi = np.where(a < 0, bound, np.inf)
    # a == 0: the boundary is horizontal; the whole row is in or out
    flat = a == 0
    inside = b * dy >= 0
    lo = np.where(flat, np.where(inside, -np.inf, np.inf), lo)
    hi = np.where(flat, np.where(inside, np.inf, -np.inf), hi)
    return lo, hi


def sector_row_range(
    spec: GridSpec,
    y_m: F64,
    theta_rad: F64,
    half_width_rad: F64,
    reach_m: F64,
    inner_m: F64 | None = None,
) -> tuple[I64, I64, F64, F64]:
    """First grid row and number of rows of each sector, and its edges' directions (right,
    left), shape (M,) each: the per-reading part of :func:`sector_rows`. With ``inner_m``, the
    rows of the ring between ``inner_m`` and ``reach_m`` only."""
    h = half_width_rad
    right = theta_rad - h
    left = theta_rad + h
    if inner_m is None:
        ends = [y_m]
    else:
        ends = [y_m + inner_m * np.sin(right), y_m + inner_m * np.sin(left)]
    ys = np.stack([*ends, y_m + reach_m * np.sin(right), y_m + reach_m * np.sin(left)])
    ymin = ys.min(axis=0)
    ymax = ys.max(axis=0)
    # the arc bulges past its end points where it crosses straight up or down
    up = np.abs(wrap_angle(np.pi / 2 - theta_rad)) <= h
    down = np.abs(wrap_angle(-np.pi / 2 - theta_rad)) <= h
    ymax = np.where(up, y_m + reach_m, ymax)
    ymin = np.where(down, y_m - reach_m, ymin)

    res = spec.resolution_m
    j0 = np.clip(np.ceil((ymin - spec.origin_y_m) / res - 0.5), 0, spec.height).astype(np.int64)
    j1 = np.clip(np.floor((ymax - spec.origin_y_m) / res - 0.5), -1, spec.height - 1).astype(
        np.int64
    )
    counts = np.where(reach_m > 0, np.maximum(j1 - j0 + 1, 0), 0)
    return j0, counts, right, left


def sector_rows(
    spec: GridSpec,
    x_m: F64,
    y_m: F64,
    theta_rad: F64,
    half_width_rad: F64,
    reach_m: F64,
    inner_m: F64 | None = None,
) -> SectorRows:
    """Enumerate the grid rows covered by sectors (apex, axis, half-width, radius ``reach_m``).

    All inputs shape (M,); half-widths must be in (0, pi/2). Rows outside the grid are skipped.
    ``inner_m``: when given, only the rows of the ring between ``inner_m`` and ``reach_m`` are
    enumerated (the spans of disks smaller than ``inner_m`` are then cut to those rows).
    """
    j0, counts, right, left = sector_row_range(
        spec, y_m, theta_rad, half_width_rad, reach_m, inner_m
    )
    return rows_of_range(spec, x_m, y_m, j0, counts, np.sin(right), np.cos(right), np.sin(left),
                         np.cos(left))  # fmt: skip


def rows_of_range(
    spec: GridSpec,
    x_m: F64,
    y_m: F64,
    j0: I64,
    counts: I64,
    sin_r: F64,
    cos_r: F64,
    sin_l: F64,
    cos_l: F64,
) -> SectorRows:
    """:func:`sector_rows` from each sector's rows (first, count) and its edges' directions
    (right edge: ``sin_r``, ``cos_r``; left: ``sin_l``, ``cos_l``), shape (M,) each."""
    total = int(counts.sum())
    reading = np.repeat(np.arange(x_m.shape[0], dtype=np.int64), counts)
    starts = np.cumsum(counts) - counts
    row = j0[reading] + (np.arange(total, dtype=np.int64) - starts[reading])
    dy = spec.origin_y_m + (row + 0.5) * spec.resolution_m - y_m[reading]

    # wedge = right of the left edge and left of the right edge (convex because 2h < pi)
    lo1, hi1 = _half_plane(-sin_r[reading], cos_r[reading], dy)
    lo2, hi2 = _half_plane(sin_l[reading], -cos_l[reading], dy)
    return SectorRows(
        spec=spec,
        sensor_x_m=x_m,
        reading=reading,
        row=row,
        dy_m=dy,
        lo_m=np.maximum(lo1, lo2),
        hi_m=np.minimum(hi1, hi2),
    )


def sector_bounds(
    x_m: F64, y_m: F64, theta_rad: F64, half_width_rad: F64, reach_m: F64
) -> tuple[float, float, float, float]:
    """Axis-aligned box (xmin, ymin, xmax, ymax) holding every sector, apexes included."""
    if x_m.shape[0] == 0:
        raise ValueError("no sectors")
    h = half_width_rad
    pts_x = [x_m, x_m + reach_m * np.cos(theta_rad - h), x_m + reach_m * np.cos(theta_rad + h)]
    pts_y = [y_m, y_m + reach_m * np.sin(theta_rad - h), y_m + reach_m * np.sin(theta_rad + h)]
    for angle, px, py in ((0.0, 1, 0), (np.pi / 2, 0, 1), (np.pi, -1, 0), (-np.pi / 2, 0, -1)):
        hit = np.abs(wrap_angle(angle - theta_rad)) <= h
        pts_x.append(np.where(hit, x_m + px * reach_m, x_m))
        pts_y.append(np.where(hit, y_m + py * reach_m, y_m))
    xs = np.concatenate(pts_x)
    ys = np.concatenate(pts_y)
    return float(xs.min()), float(ys.min()), float(xs.max()), float(ys.max())
