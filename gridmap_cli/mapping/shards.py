"""A build's readings mapped on one process or several (``gridmap build --jobs N``), the map
the same to the byte whatever N is.

Both modes sum log-odds (the error-aware maps are standard maps, of sampled tracks or with faded
evidence). Each sensor model's share of each chunk of synchronised readings
(:meth:`~gridmap_cli.mapping.plan.BuildPlan.parts`) is cut into shards of at most
:data:`SHARD_READINGS` readings (at a change of stamp, as batches are). The grid's sums are
integers (fixed-point log-odds and counts, :class:`~gridmap_cli.mapping.grid.LogOddsAccumulator`),
exact in any order and any grouping, so ``--jobs 1`` maps every batch straight into the grid (no
shard-sized copy of it), and with N > 1 each worker maps a shard into zeroed difference arrays of
the whole grid (:func:`log_odds_shard`) that the main process adds: the same bits either way.
Each shard in flight costs one grid (12 bytes a cell). Nothing is clamped per shard: the summed
log-odds are clamped once, when the map is finished
(:meth:`~gridmap_cli.mapping.grid.LogOddsAccumulator.occupancy_map`), as ``--fuse`` clamps its
total.
A log of one shard maps exactly as it did before shards.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from itertools import islice
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
import numpy.typing as npt

from gridmap_cli.mapping.grid import GridSpec, LogOddsAccumulator
from gridmap_cli.poses.sync import SensorReadings, select_readings

if TYPE_CHECKING:
    from gridmap_cli.mapping.plan import BuildPlan

#: Readings per log-odds shard. Fixed, not derived from N: the shards decide the order of the
#: float sums. Each shard costs one pass over the grid's difference arrays (a 1000 x 1000 grid:
#: about 2 ms), so an hour of sonar (576,000 readings) is 6 shards.
SHARD_READINGS = 100_000

#: Tasks handed to the workers ahead of the one the main process waits for, per worker: enough
#: to keep them busy, few enough that finished shards do not pile up in memory.
AHEAD_PER_WORKER = 2

T = TypeVar("T")


def batch_bounds(stamp_ns: npt.NDArray[np.int64], size: int) -> list[tuple[int, int]]:
    """Consecutive [start, stop) batches of about ``size`` readings, each cut where the stamp
    changes, so a scan's beams (one stamp) stay in one batch. A single stamp holding more than
    ``size`` readings is kept whole."""
    n = stamp_ns.shape[0]
    bounds = []
    start = 0
    while start < n:
        stop = min(start + size, n)
        if stop < n:
            # move the cut forward to the first reading of a new stamp
            stop = int(np.searchsorted(stamp_ns, stamp_ns[stop - 1], side="right"))
            stop = max(stop, start + 1)
        bounds.append((start, stop))
        start = stop
    return bounds


def in_order(fn: Callable[..., T], tasks: Iterable[tuple[Any, ...]], jobs: int) -> Iterator[T]:
    """``fn(*task)`` of every task, yielded in the order of ``tasks``: here when ``jobs`` is 1,
    else on ``jobs`` local processes with at most :data:`AHEAD_PER_WORKER` tasks each ahead.
    ``tasks`` is read as results are taken, so only the tasks in flight are held."""
    if jobs <= 1:
        for task in tasks:
            yield fn(*task)
        return
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        queued = iter(tasks)
        ahead = islice(queued, jobs * AHEAD_PER_WORKER)
        pending: deque[Future[T]] = deque(pool.submit(fn, *task) for task in ahead)
        while pending:
            result = pending.popleft().result()
            for task in islice(queued, 1):
                pending.append(pool.submit(fn, *task))
            yield result


def _accumulate_here(
    plan: BuildPlan,
    grid: LogOddsAccumulator,
    batch_size: int,
    progress: Callable[[int], object] | None,
) -> int:
    updates = 0
    for model, part in plan.parts():
        for start, stop in batch_bounds(part.stamp_ns, SHARD_READINGS):
            shard = select_readings(part, slice(start, stop))
            for lo, hi in batch_bounds(shard.stamp_ns, batch_size):
                updates += model.accumulate(grid, select_readings(shard, slice(lo, hi)))
            if progress is not None:
                progress(len(shard))
    return updates


def log_odds_shard(
    spec: GridSpec, model: Any, readings: SensorReadings, batch_size: int, grid_readings: int
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.uint32], int, int]:
    """One shard's evidence: the value and count difference arrays of a zeroed grid over
    ``spec`` (fixed point for ``grid_readings`` readings, as the main grid's) after the shard's
    batches (shape ``(height * (width + 1),)``), the cell updates and the readings mapped."""
    grid = LogOddsAccumulator(spec, grid_readings)
    updates = 0
    for start, stop in batch_bounds(readings.stamp_ns, batch_size):
        updates += model.accumulate(grid, select_readings(readings, slice(start, stop)))
    values, counts = grid.difference_arrays()
    return values, counts, updates, len(readings)


def accumulate_log_odds(
    plan: BuildPlan,
    grid: LogOddsAccumulator,
    batch_size: int,
    jobs: int,
    progress: Callable[[int], object] | None = None,
) -> int:
    """Add every reading of ``plan`` to ``grid`` shard by shard; returns the cell updates.

    A shard is a model's share of one chunk of :meth:`BuildPlan.parts`, cut at
    :data:`SHARD_READINGS`. On one process the batches go straight into ``grid``."""
    if jobs <= 1:
        return _accumulate_here(plan, grid, batch_size, progress)
    tasks = (
        (grid.spec, model, select_readings(part, slice(start, stop)), batch_size, grid.readings)
        for model, part in plan.parts()
        for start, stop in batch_bounds(part.stamp_ns, SHARD_READINGS)
    )
    values, counts = grid.difference_arrays()
    updates = 0
    for shard_values, shard_counts, n, mapped in in_order(log_odds_shard, tasks, jobs):
        values += shard_values
        counts += shard_counts
        updates += n
        if progress is not None:
            progress(mapped)
    return updates
