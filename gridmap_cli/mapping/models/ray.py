"""The ray model for narrow-beam range sensors (lasers): evidence along each beam's line.

A reading of range z from a sensor at (x, y) with beam direction theta is the segment from
(x, y) to (x + z cos theta, y + z sin theta). ``docs/sensor-model.md`` gives the reasons:

* every cell the segment crosses before its end, including cells it only clips at a corner:
  free evidence ``l_free = logit(p_free)``;
* the cell containing the end point: occupied evidence ``l_occ = logit(p_occupied)``;
* beyond the end point: nothing.

A reading at the sensor's maximum range means no echo: free evidence in every cell of the
segment of length ``min(max_range, no_echo_free_m)``, and never occupied evidence. The cap
(:data:`LASER_NO_ECHO_FREE_M` unless ``--no-echo-free`` says) is gmapping's ``maxUrange``: a
beam that saw nothing saw nothing for sure only so far. A reading beyond ``max_range_m``
(``--max-range``, slam_toolbox's ``max_laser_range``) is cut to free space up to it.

Free-only segments (no echo, or cut) never set the map's bounds: the bounds hold the echoes
and the sensor positions, and free space beyond them is clipped to the map, so that a few long
beams through a door do not grow a building's map by tens of metres.

The cells are those of an exact grid traversal (Amanatides and Woo, 1987), computed row by row
instead of step by step: a segment is monotonic in y, so it crosses its rows in order, and its
part inside one row covers the run of columns between the columns where it enters and leaves
that row. The crossings are x values on the row boundaries; consecutive rows share the crossing
between them, so the runs chain into the same 4-connected walk Amanatides and Woo's stepping
gives. Everything is vectorised over rays and rows: no Python loop over rays or cells.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from gridmap_cli.mapping.grid import GridSpec, LogOddsAccumulator, logodds
from gridmap_cli.mapping.models.kernels import compiled
from gridmap_cli.poses.sync import SensorReadings

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]
B = npt.NDArray[np.bool_]

#: Rows (runs) per internal chunk: bounds the temporary arrays to a few hundred MB whatever
#: batch the caller hands over (a 5 m ray at 5 cm cells spans up to 101 rows).
_ROWS_PER_CHUNK = 2_000_000


#: Metres of free space a laser's no-echo reading clears by default (gmapping's maxUrange):
#: indoors, a beam that came back with nothing went through a door, or met glass or a black
#: surface (a SICK then writes its error code, 81.91 m). Clearing the whole 8 m of such a beam
#: erases furniture and thins walls that other beams saw; 2 m still clears the space next to the
#: robot that the beam surely crossed (measurements: docs/sensor-model.md).
LASER_NO_ECHO_FREE_M = 2.0


@dataclass(frozen=True)
class RayParams:
    """Parameters of the ray model; defaults and their reasons in docs/sensor-model.md.

    ``no_echo_free_m``: metres of free space a no-echo reading clears, capped at the sensor's
    maximum range; ``math.inf`` means the full maximum range, 0 ignores no-echo readings.
    ``max_range_m``: readings beyond it are cut to free space up to it (no occupied end).
    The clamp is not here: one grid has one clamp (BuildOptions.clamp_p).
    """

    p_occupied: float = 0.7
    p_free: float = 0.4
    no_echo_free_m: float = LASER_NO_ECHO_FREE_M
    max_range_m: float = math.inf

    def __post_init__(self) -> None:
        if not 0.5 < self.p_occupied < 1.0:
            raise ValueError(f"p_occupied must be in (0.5, 1), got {self.p_occupied}")
        if not 0.0 < self.p_free < 0.5:
            raise ValueError(f"p_free must be in (0, 0.5), got {self.p_free}")
        if not self.no_echo_free_m >= 0:  # NaN fails too; inf is allowed
            raise ValueError(
                f"the no-echo free range must be >= 0 metres, got {self.no_echo_free_m}"
            )
        if not self.max_range_m > 0:  # NaN fails too; inf (no cut) is allowed
            raise ValueError(f"the maximum range must be > 0 metres, got {self.max_range_m}")


@dataclass(frozen=True)
class RaySegments:
    """The segment of each reading, shape (M,) each: from (x0_m, y0_m) to (x1_m, y1_m).

    ``echo``: the end point is a reflector (occupied evidence there); otherwise the whole
    segment is free space. A segment of length 0 without echo contributes nothing.
    """

    x0_m: F64
    y0_m: F64
    x1_m: F64
    y1_m: F64
    echo: B


@dataclass(frozen=True)
class RowRuns:
    """Runs of cells ``[col0, col1]`` (inclusive) in ``row``; all shape (S,).

    Every run lies inside the grid and is non-empty; the runs of one segment are consecutive and
    ordered by row. ``segment``: the index of the segment each run belongs to (models that weigh
    each reading differently, such as the error-aware one, need it).
    """

    row: I64
    col0: I64
    col1: I64
    segment: I64

    def cells(self) -> int:
        """Number of cells the runs cover."""
        return int((self.col1 - self.col0 + 1).sum())


def _grid_units(spec: GridSpec, x_m: F64, y_m: F64) -> tuple[F64, F64]:
    return (x_m - spec.origin_x_m) / spec.resolution_m, (y_m - spec.origin_y_m) / spec.resolution_m


@dataclass(frozen=True)
class RayRows:
    """Per segment, shape (M,) each: what :func:`row_runs` expands into runs. The segment is
    walked upwards from (ua, va) to (ub, vb) in grid units; rows ``ra + p`` for ``p`` in
    ``p_lo .. p_lo + counts - 1`` lie in the grid; ``off`` and ``slope`` place the crossings."""

    ra: I64
    rb: I64
    p_lo: I64
    counts: I64
    off: F64
    slope: F64
    ua: F64
    ub: F64
    inside: bool  # every segment with runs lies within the grid's columns: no clipping


def ray_rows(spec: GridSpec, seg: RaySegments) -> RayRows:
    """The per-segment part of :func:`row_runs` (shared with the compiled kernel)."""
    u0, v0 = _grid_units(spec, seg.x0_m, seg.y0_m)
    u1, v1 = _grid_units(spec, seg.x1_m, seg.y1_m)
    # the set of cells does not depend on the direction of travel: walk every segment upwards
    # from (ua, va) to (ub, vb)
    down = v1 < v0
    ua, va = np.where(down, u1, u0), np.where(down, v1, v0)
    ub, vb = np.where(down, u0, u1), np.where(down, v0, v1)
    ra_f = np.floor(va)
    ra = ra_f.astype(np.int64)
    rb = np.floor(vb).astype(np.int64)
    # rows ra + p for p = p_lo .. p_hi lie in the grid
    p_lo = np.maximum(-ra, 0)
    p_hi = np.minimum(rb, spec.height - 1) - ra
    active = seg.echo | (u0 != u1) | (v0 != v1)
    counts = np.where(active, np.maximum(p_hi - p_lo + 1, 0), 0)
    # The segment enters row ra + p (p >= 1) on v = ra + p, at u = ua + (p + off) * slope with
    # off = ra - va in (-1, 0] (exact). Written this way the rounding error stays near
    # eps * |ub - ua| even for nearly horizontal segments, whose slope is huge. With va == vb
    # there is one row and no crossing, so the slope is never used.
    dv = vb - va
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = np.where(dv > 0.0, (ub - ua) / dv, 0.0)
    has = counts > 0
    inside = (np.minimum(ua, ub) >= 0.0) & (np.maximum(ua, ub) < spec.width)
    return RayRows(ra, rb, p_lo, counts, ra_f - va, slope, ua, ub, bool(inside[has].all()))


def row_runs(spec: GridSpec, seg: RaySegments) -> RowRuns:
    """The cells each segment crosses, as one run of columns per grid row, cut to the grid.

    A cell is crossed when the segment meets it, with the map's half-open cell convention (a
    point on a boundary belongs to the cell above / to the right). Where a segment passes exactly
    through a cell corner, one of the two cells beside the corner is included, as in Amanatides
    and Woo's traversal. Segments of length 0 give their one cell when they have an echo and
    nothing otherwise.
    """
    rows = ray_rows(spec, seg)
    ra, rb, p_lo, counts = rows.ra, rows.rb, rows.p_lo, rows.counts
    off, slope, ua, ub = rows.off, rows.slope, rows.ua, rows.ub
    total = int(counts.sum())
    starts = np.cumsum(counts) - counts
    p = np.arange(total, dtype=np.int64) - np.repeat(starts - p_lo, counts)
    pf = p.astype(np.float64)
    off_r, s_r, ua_r = np.repeat(off, counts), np.repeat(slope, counts), np.repeat(ua, counts)
    # where each run enters and leaves its row: the same expression for the boundary two rows
    # share, so consecutive runs chain without gaps or overlaps
    u_in = (pf + off_r) * s_r + ua_r
    pf += 1.0
    u_out = (pf + off_r) * s_r + ua_r
    has = counts > 0
    first = has & (p_lo == 0)
    u_in[starts[first]] = ua[first]
    last = has & (ra + p_lo + counts - 1 == rb)  # the run of the segment's own last row
    u_out[(starts + counts - 1)[last]] = ub[last]
    c_in = np.floor(u_in).astype(np.int64)
    c_out = np.floor(u_out).astype(np.int64)
    col0 = np.minimum(c_in, c_out)
    col1 = np.maximum(c_in, c_out)
    row = np.repeat(ra, counts) + p
    segment = np.repeat(np.arange(counts.shape[0], dtype=np.int64), counts)
    if rows.inside:
        return RowRuns(row, col0, col1, segment)
    keep = (col1 >= 0) & (col0 <= spec.width - 1)
    return RowRuns(
        row[keep],
        np.maximum(col0[keep], 0),
        np.minimum(col1[keep], spec.width - 1),
        segment[keep],
    )


def end_cells(spec: GridSpec, seg: RaySegments) -> tuple[I64, I64]:
    """(row, col) of the end cells of the segments with echo that lie in the grid."""
    u1, v1 = _grid_units(spec, seg.x1_m, seg.y1_m)
    col = np.floor(u1).astype(np.int64)
    row = np.floor(v1).astype(np.int64)
    keep = seg.echo & (col >= 0) & (col < spec.width) & (row >= 0) & (row < spec.height)
    return row[keep], col[keep]


def _take(seg: RaySegments, sl: slice) -> RaySegments:
    return RaySegments(seg.x0_m[sl], seg.y0_m[sl], seg.x1_m[sl], seg.y1_m[sl], seg.echo[sl])


class RayModel:
    """The ray model over batches of synchronised readings (readings of narrow-beam sensors)."""

    name = "ray"

    def __init__(self, params: RayParams, resolution_m: float) -> None:
        self.params = params
        self.resolution_m = resolution_m
        self.l_occ = logodds(params.p_occupied)
        self.l_free = logodds(params.p_free)

    def segments(self, readings: SensorReadings) -> RaySegments:
        """The segment each reading's beam covered (odometry frame, metres)."""
        z = readings.range_m
        zmax = readings.per_sensor("max_range_m")
        echo = z < zmax
        length = np.where(echo, z, np.minimum(zmax, self.params.no_echo_free_m))
        cut = length > self.params.max_range_m  # beyond --max-range: free space up to it
        if cut.any():
            echo = echo & ~cut
            length = np.minimum(length, self.params.max_range_m)
        return RaySegments(
            x0_m=readings.x_m,
            y0_m=readings.y_m,
            x1_m=readings.x_m + length * np.cos(readings.theta_rad),
            y1_m=readings.y_m + length * np.sin(readings.theta_rad),
            echo=echo,
        )

    def bounds(self, readings: SensorReadings) -> tuple[float, float, float, float]:
        """Box (xmin, ymin, xmax, ymax) holding every start point and every echo: free-only
        segments (no echo, or cut at ``max_range_m``) are clipped to the map, never grow it."""
        if len(readings) == 0:
            raise ValueError("no readings")
        seg = self.segments(readings)
        xs = np.concatenate([seg.x0_m, seg.x1_m[seg.echo]])
        ys = np.concatenate([seg.y0_m, seg.y1_m[seg.echo]])
        return float(xs.min()), float(ys.min()), float(xs.max()), float(ys.max())

    def accumulate(self, grid: LogOddsAccumulator, readings: SensorReadings) -> int:
        """Add the evidence of ``readings`` to ``grid``; returns the number of cell updates."""
        return accumulate_rays(grid, self.segments(readings), self.l_free, self.l_occ)


def accumulate_rays(grid: LogOddsAccumulator, seg: RaySegments, l_free: float, l_occ: float) -> int:
    """Add free runs and occupied end cells of ``seg`` to ``grid``; returns cells touched."""
    n = seg.echo.shape[0]
    if n == 0:
        return 0
    # chunks of about _ROWS_PER_CHUNK rows: a ray spans |floor(v1) - floor(v0)| + 1 rows
    _, v0 = _grid_units(grid.spec, seg.x0_m, seg.y0_m)
    _, v1 = _grid_units(grid.spec, seg.x1_m, seg.y1_m)
    cum_rows = np.cumsum(np.abs(np.floor(v1) - np.floor(v0)) + 1.0)
    marks = np.arange(1, int(cum_rows[-1]) // _ROWS_PER_CHUNK + 1) * float(_ROWS_PER_CHUNK)
    at = np.searchsorted(cum_rows, marks)  # sorted: drop repeats without np.unique (numpy.ma)
    cuts = at[np.concatenate([[True], at[1:] != at[:-1]])].tolist() if at.size else []
    updates = 0
    for lo, hi in itertools.pairwise([0, *cuts, n]):
        if hi > lo:
            updates += _accumulate_chunk(grid, _take(seg, slice(lo, hi)), l_free, l_occ)
    return updates


def _accumulate_chunk(
    grid: LogOddsAccumulator, seg: RaySegments, l_free: float, l_occ: float
) -> int:
    """The compiled kernel when it pays (:mod:`gridmap_cli.mapping.models.kernels`), else numpy: the
    same grid bit for bit."""
    kernels = compiled()
    if kernels is None:
        runs = row_runs(grid.spec, seg)
        grid.add_observations(runs.row, runs.col0, runs.col1)
        # every crossed cell gets l_free; the end cell, one of them, is then raised to l_occ
        grid.add_values(runs.row, runs.col0, runs.col1, np.full(runs.row.shape[0], l_free))
        cells = runs.cells()
    else:
        rows = ray_rows(grid.spec, seg)
        values, observations = grid.difference_arrays()
        cells = int(
            kernels.ray_batch(
                grid.spec.width, rows.ra, rows.rb, rows.p_lo, rows.counts, rows.off, rows.slope,
                rows.ua, rows.ub, not rows.inside, l_free, grid.scale, grid.rows[0], values,
                observations,
            )
        )  # fmt: skip
    end_row, end_col = end_cells(grid.spec, seg)
    grid.add_values(end_row, end_col, end_col, np.full(end_row.shape[0], l_occ - l_free))
    return cells
