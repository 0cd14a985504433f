"""Several logs of one place fused into one map (``gridmap build --fuse``).

Each log is read and mapped on its own into a partial grid of log-odds sums and observation
counts, over the cells its own readings reach. The partial grids of all logs are then added
cell by cell: a cell's fused log-odds is the sum of what every log's readings said of it, so the
map is what one robot making all the readings would have built, clamped once at the end.

The logs must share a frame: ``--pose global`` (each log's reference track is in the site's
frame), or one ``--initial-pose X,Y,YAW_DEG`` per log placing the log's first pose in a common
frame. Grids are aligned to multiples of the resolution, so partial grids sit on the fused grid
at whole-cell offsets and no cell is resampled.

Order does not matter, to the byte: floating-point sums depend on the order of the terms, so the
partial grids are sorted by the SHA-256 of their logs' content and added pairwise as a balanced
tree (:func:`tree_pairs`). Any order of the logs on the command line, and any executor (local,
or a Dask cluster reducing the tree on its workers), gives the same map.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import GridmapError, MapSizeError, UsageError, naming, naming_style
from gridmap_cli.mapping.grid import (
    DEFAULT_CLAMP_P,
    DEFAULT_MAX_CELLS,
    GridSpec,
    LogOddsAccumulator,
    OccupancyMap,
    logodds,
)
from gridmap_cli.mapping.pipeline import BuildOptions, accumulate, plan_build
from gridmap_cli.mapping.selection import Selection
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.records import RangeLog
from gridmap_cli.runs.build import BuildHooks
from gridmap_cli.runs.content import content_hash


@dataclass(frozen=True)
class FuseJob:
    """One log of a fused build and how to read it; picklable, for any executor."""

    log: Path
    log_format: str | None
    read_options: ReadOptions
    pose: str
    initial_pose: tuple[float, float, float] | None  # (x_m, y_m, yaw_rad) of the first pose
    selection: Selection
    robot_spec: str | None
    options: BuildOptions
    #: how its errors name what was given (the command line's flags, from a worker process)
    naming: str = field(default_factory=naming_style)


@dataclass(frozen=True)
class Partial:
    """Evidence of one or more logs: log-odds sums and observation counts over ``spec``.

    ``log_odds`` float64 and ``counts`` int64, shape ``spec.shape``; ``keys`` are the content
    hashes of the logs in it, in the order they were added; ``notes`` what the user should read.
    """

    spec: GridSpec
    log_odds: npt.NDArray[np.float64]
    counts: npt.NDArray[np.int64]
    keys: tuple[str, ...]
    readings: int
    notes: tuple[str, ...] = ()


def parse_initial_pose(text: str) -> tuple[float, float, float]:
    """``X,Y,YAW_DEG`` (metres, degrees) -> (x_m, y_m, yaw_rad); :class:`UsageError` else."""
    parts = text.split(",")
    try:
        x, y, yaw = (float(p) for p in parts)
    except ValueError:
        raise UsageError(
            f"--initial-pose {text!r}: expected X,Y,YAW_DEG (metres, degrees), e.g. 2.5,-1,90"
        ) from None
    if not all(math.isfinite(v) for v in (x, y, yaw)):
        raise UsageError(f"--initial-pose {text!r}: not finite")
    return x, y, math.radians(yaw)


def content_key(log: Path) -> str:
    """SHA-256 of a log's content (a rosbag2 folder: its files' names and contents)."""
    return content_hash(log)[0]


def partial_of(job: FuseJob) -> Partial:
    """Read and map one log into its own partial grid (runs wherever the executor puts it)."""
    from gridmap_cli.runs.build import BuildRequest, pose_stage

    request = BuildRequest(
        inputs=(job.log,), robot=job.robot_spec, options=job.options, pose=job.pose,
        selection=job.selection, log_format=job.log_format, read_options=job.read_options,
        initial_pose=job.initial_pose, stream=False,
    )  # fmt: skip
    with naming(job.naming):
        placed = pose_stage(request, BuildHooks(read=_read_one))
    plan = plan_build(placed.log, placed.robot, job.options)
    grid = LogOddsAccumulator(plan.spec, plan.sync.used)
    accumulate(plan, grid, job.options)
    notes = tuple(f"{job.log}: {note}" for note in placed.warnings)
    return Partial(plan.spec, grid.log_odds(), grid.observations(), (content_key(job.log),),
                   plan.sync.used, notes)  # fmt: skip


def _read_one(paths: Sequence[Path], log_format: str | None, options: ReadOptions) -> RangeLog:
    """One log, read by its own reader (never merged as a recording)."""
    from gridmap_cli.readers import read_log

    return read_log(paths[0], log_format, options)


def union_spec(a: GridSpec, b: GridSpec, max_cells: int = DEFAULT_MAX_CELLS) -> GridSpec:
    """The smallest grid holding both (same resolution, origins on multiples of it)."""
    res = a.resolution_m
    if not math.isclose(res, b.resolution_m, rel_tol=0, abs_tol=1e-12):
        raise GridmapError(f"cannot fuse grids of {res} m and {b.resolution_m} m")
    ax, ay, bx, by = (round(v / res) for v in (a.origin_x_m, a.origin_y_m, b.origin_x_m,
                                                 b.origin_y_m))  # fmt: skip
    x0, y0 = min(ax, bx), min(ay, by)
    x1, y1 = max(ax + a.width, bx + b.width), max(ay + a.height, by + b.height)
    width, height = x1 - x0, y1 - y0
    if width * height > max_cells:
        raise MapSizeError(
            f"the fused logs span {width} x {height} cells at {res} m: more than {max_cells} "
            "cells; are the logs in one frame (--pose global or --initial-pose)?"
        )
    return GridSpec(round(x0 * res, 9), round(y0 * res, 9), res, width, height)


def _offset(inner: GridSpec, outer: GridSpec) -> tuple[int, int]:
    res = outer.resolution_m
    return (round(inner.origin_y_m / res) - round(outer.origin_y_m / res),
            round(inner.origin_x_m / res) - round(outer.origin_x_m / res))  # fmt: skip


def combine(a: Partial, b: Partial) -> Partial:
    """The evidence of ``a`` and ``b`` together, on the union of their grids."""
    spec = union_spec(a.spec, b.spec)
    log_odds = np.zeros(spec.shape, dtype=np.float64)
    counts = np.zeros(spec.shape, dtype=np.int64)
    for part in (a, b):
        r, c = _offset(part.spec, spec)
        window = (slice(r, r + part.spec.height), slice(c, c + part.spec.width))
        log_odds[window] += part.log_odds
        counts[window] += part.counts
    return Partial(spec, log_odds, counts, a.keys + b.keys, a.readings + b.readings,
                   a.notes + b.notes)  # fmt: skip


def tree_pairs(n: int) -> list[list[tuple[int, int]]]:
    """The pairs added at each level of a balanced tree over ``n`` items: level k pairs
    neighbours of level k-1's results (an odd one out is carried up as it is)."""
    levels = []
    while n > 1:
        levels.append([(i, i + 1) for i in range(0, n - 1, 2)])
        n = (n + 1) // 2
    return levels


def canonical(partials: Sequence[Partial]) -> list[Partial]:
    """Partials sorted by their logs' content hashes; the same log twice is an error (its
    evidence would count double)."""
    ordered = sorted(partials, key=lambda p: p.keys)
    check_distinct([p.keys for p in ordered])
    return ordered


def check_distinct(keys: Sequence[tuple[str, ...]]) -> None:
    """Refuse the same log content given twice (its evidence would count double)."""
    if len(set(keys)) != len(keys):
        raise UsageError("--fuse got the same log content twice: its evidence would count double")


def reduce_tree(
    partials: Sequence[Partial], add: Callable[[Partial, Partial], Partial] = combine
) -> Partial:
    """Add the partials (already :func:`canonical`) pairwise as :func:`tree_pairs` says."""
    level = list(partials)
    for pairs in tree_pairs(len(level)):
        merged = [add(level[i], level[j]) for i, j in pairs]
        if len(level) % 2:
            merged.append(level[-1])
        level = merged
    return level[0]


def fused_map(total: Partial, clamp_p: tuple[float, float] = DEFAULT_CLAMP_P) -> OccupancyMap:
    """The finished map of the fused evidence, clamped as a single build clamps."""
    lo, hi = logodds(clamp_p[0]), logodds(clamp_p[1])
    prob = 1.0 - 1.0 / (1.0 + np.exp(np.clip(total.log_odds, lo, hi)))
    prob[total.counts == 0] = np.nan
    return OccupancyMap(total.spec, prob)
