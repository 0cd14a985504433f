"""The expected map under the pose belief: the mean probability of the standard maps of tracks
drawn from the odometry-error model (docs/sensor-model.md, "The expected map").

Each sample's map is the standard map of its track. Four things make K of them cost about
one more standard build instead of K:

* **One sync.** A sampled track moves every pose owned by a key pose by one rigid motion
  (:class:`~gridmap_cli.poses.uncertainty.pose_uncertainty.SampledOffsets`), and the readings'
  sensor poses move with it; so the readings are synchronised once and each sample moves their
  geometry. * **Cells no finer than the spread.** A reading whose position is uncertain by sigma
  (the smaller principal spread: :func:`levels`) lands, in each sample, somewhere within sigma of
  its nominal cells. Cast on cells up to sigma wide (a grid 2, 4, 8 or 16 times coarser,
  aligned with the map's), the evidence a map cell gets in a sample is the evidence near its
  coarse cell's centre (interpolated linearly between centres): less than a coarse cell off,
  which the sample-to-sample spread of sigma averages out. The evidence keeps the fine map's
  geometry (the obstacle band of the map's resolution, not of the coarse cells), so each map
  cell sees the same evidence with the same probability as in a full-resolution sample; a ray,
  whose cells are a line of cell width, gives its free evidence times the ratio of the cell
  sizes and its end cell's evidence times their squared ratio (the evidence per map cell it
  would spread over). A cast costs its rows, so a coarse cast is cheap.
* **Antithetic pairs.** Samples come in pairs of opposite draws, whose first-order errors
  cancel: the mean converges faster than with independent draws.
* **Cast once what every sample agrees on.** Readings that move by under half a cell are the
  same in every sample: they are cast once and their log-odds added to every sample's before
  the probabilities are taken (the expected map averages probabilities, so they cannot be
  averaged separately).

Moved cones and rays go through compiled kernels (:func:`cast_sectors`, :func:`cast_rays`),
each equal bit for bit to its numpy reference. The oracle is
:func:`~gridmap_cli.mapping.expected_oracle.exact`: K full standard builds. Perfect odometry
is the standard map to the bit (the caller checks).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from gridmap_cli.mapping.grid import LogOddsAccumulator, OccupancyMap, logodds
from gridmap_cli.mapping.levels import finer
from gridmap_cli.mapping.levels import known_cells as known_cells
from gridmap_cli.mapping.levels import level_spec as level_spec
from gridmap_cli.mapping.levels import upsample as upsample
from gridmap_cli.mapping.models.kernels import compiled
from gridmap_cli.mapping.models.ray import RayModel, RaySegments, end_cells, row_runs
from gridmap_cli.mapping.models.sector import rows_of_range
from gridmap_cli.mapping.models.standard import SectorEvidence, StandardSonarModel
from gridmap_cli.mapping.plan import BuildPlan
from gridmap_cli.mapping.shards import batch_bounds
from gridmap_cli.poses.sync import SensorReadings, select_readings
from gridmap_cli.poses.uncertainty.pose_uncertainty import PoseUncertainty, SampledOffsets

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]

#: A reading is cast on cells at most its position spread (standard deviation, the smaller
#: principal axis) divided by this wide.
SPREAD_PER_CELL = 1.0
#: The coarsest cast: cells 2 ** MAX_LEVEL times the map's.
MAX_LEVEL = 4
#: Readings whose spread is under this many map cells are cast once, for every sample.
SHARED_SPREAD_CELLS = 0.5
#: Samples come in antithetic pairs (module docstring).
ANTITHETIC = True
#: Readings per kernel call (each call holds its rows' runs).
BATCH_READINGS = 20_000
#: Rows per ray batch: bounds the runs a batch holds.
BATCH_ROWS = 2_000_000


@dataclass(frozen=True)
class Cones:
    """Sonar sectors as the moved-sector cast takes them, shape (M,) each: apex, the edges'
    directions (right: theta - beta / 2, left: theta + beta / 2) and the nested disks'
    radii and values (:class:`~gridmap_cli.mapping.models.standard.SectorEvidence`)."""

    x_m: F64
    y_m: F64
    sin_r: F64
    cos_r: F64
    sin_l: F64
    cos_l: F64
    outer_m: F64
    outer_value: F64
    inner_m: F64
    inner_value: F64

    @classmethod
    def of(cls, ev: SectorEvidence) -> Cones:
        right = ev.theta_rad - ev.half_width_rad
        left = ev.theta_rad + ev.half_width_rad
        return cls(
            ev.x_m, ev.y_m, np.sin(right), np.cos(right), np.sin(left), np.cos(left),
            ev.outer_m, ev.outer_value, ev.inner_m, ev.inner_value,
        )  # fmt: skip

    def take(self, sl: slice) -> Cones:
        return Cones(*(getattr(self, f.name)[sl] for f in dataclasses.fields(self)))


@dataclass
class _Casts:
    """The nominal geometry of one model's readings at one level, chunk by chunk."""

    model: StandardSonarModel | RayModel
    level: int
    owner: list[I64] = dataclasses.field(default_factory=list)
    sectors: list[Cones] = dataclasses.field(default_factory=list)
    rays: list[RaySegments] = dataclasses.field(default_factory=list)


def levels(
    uncertainty: PoseUncertainty, readings: SensorReadings, resolution_m: float
) -> npt.NDArray[np.int64]:
    """The cast level of each reading, shape (M,).

    -1 (cast once, shared by every sample) when the reading's farthest point moves by under
    :data:`SHARED_SPREAD_CELLS` cells in every direction: the larger principal spread of the
    position plus the range times the heading spread. Else the coarsest level whose cells are
    no wider than the *smaller* principal spread of the position / :data:`SPREAD_PER_CELL`: a
    track whose error has one direction only (a distance scale error moves poses along the
    path) spreads nothing across it, and coarse cells would shift the evidence there."""
    u = uncertainty
    t = (u.stamp_ns - u.stamp_ns[0]).astype(np.float64)
    q = (readings.stamp_ns - u.stamp_ns[0]).astype(np.float64)
    a = np.interp(q, t, u.cov[:, 0, 0])
    b = np.interp(q, t, u.cov[:, 1, 1])
    c = np.interp(q, t, u.cov[:, 0, 1])
    h = np.interp(q, t, u.cov[:, 2, 2])
    mid, half = 0.5 * (a + b), np.sqrt(0.25 * (a - b) ** 2 + c * c)
    small = np.sqrt(np.maximum(mid - half, 0.0)) / resolution_m
    large = np.sqrt(np.maximum(mid + half, 0.0)) / resolution_m
    reach = large + readings.range_m * np.sqrt(np.maximum(h, 0.0)) / resolution_m
    with np.errstate(divide="ignore"):
        level = np.floor(np.log2(np.maximum(small / SPREAD_PER_CELL, 1e-300)))
    level = np.clip(level, 0, MAX_LEVEL).astype(np.int64)
    return np.where(reach < SHARED_SPREAD_CELLS, -1, level)


def collect(
    plan: BuildPlan,
    uncertainty: PoseUncertainty,
    offsets: SampledOffsets,
    cutoff_ns: int | None,
    progress: Callable[[int], object] | None,
) -> list[_Casts]:
    """One pass over the plan's readings: each model's nominal geometry, per level."""
    casts: dict[tuple[int, int], _Casts] = {}
    for model, readings in plan.parts():
        if cutoff_ns is not None:
            readings = select_readings(readings, readings.stamp_ns <= cutoff_ns)
        if len(readings):
            level = levels(uncertainty, readings, plan.spec.resolution_m)
            owner = offsets.owner(readings.stamp_ns)
            for lv in np.unique(level).tolist():
                pick = select_readings(readings, np.flatnonzero(level == lv))
                key = (id(model), lv)
                if not isinstance(model, StandardSonarModel | RayModel):
                    raise TypeError(f"the expected map cannot sample {type(model).__name__}")
                entry = casts.setdefault(key, _Casts(model, lv))
                entry.owner.append(owner[level == lv])
                if isinstance(model, RayModel):
                    entry.rays.append(model.segments(pick))
                else:
                    entry.sectors.append(Cones.of(model.evidence(pick)))
        if progress is not None:
            progress(len(readings))
    return list(casts.values())


def sample_bounds(casts: list[_Casts], offsets: SampledOffsets) -> tuple[float, ...] | None:
    """The box (xmin, ymin, xmax, ymax) that holds where every sample's moved readings land
    (None without moved readings): the readings' box per key pose (sensor positions, sonar
    sectors' disks, echoes' ends, as the models' bounds), moved by each sample's motion of
    that key pose (a rigid motion: the moved box's corners hold the moved readings). A grid
    that covers it cuts no sample's readings (the standard build's grid would cut a straight
    edge where the samples leave it)."""
    keys = offsets.rot_rad.shape[1]
    lo = np.full((2, keys), np.inf)
    hi = np.full((2, keys), -np.inf)
    any_moved = False
    for entry in casts:
        if entry.level < 0:
            continue  # cast once, nominally: inside the standard build's bounds
        for owner, cones in zip(entry.owner if entry.sectors else [], entry.sectors, strict=True):
            r = cones.outer_m
            for axis, v in ((0, cones.x_m), (1, cones.y_m)):
                _extrema(lo[axis], hi[axis], owner, v - r, v + r)
            any_moved = True
        for owner, seg in zip(entry.owner if entry.rays else [], entry.rays, strict=True):
            end = seg.echo.astype(bool)
            for axis, a, b in ((0, seg.x0_m, seg.x1_m), (1, seg.y0_m, seg.y1_m)):
                _extrema(lo[axis], hi[axis], owner, a, a)
                _extrema(lo[axis], hi[axis], owner[end], b[end], b[end])
            any_moved = True
    used = np.isfinite(lo[0])
    if not any_moved or not used.any():
        return None
    lo, hi = lo[:, used], hi[:, used]
    c, s = np.cos(offsets.rot_rad[:, used]), np.sin(offsets.rot_rad[:, used])
    tx, ty = offsets.tx_m[:, used], offsets.ty_m[:, used]
    xs, ys = [], []
    for cx in (lo[0], hi[0]):
        for cy in (lo[1], hi[1]):
            x, y = _moved(cx, cy, c, s, tx, ty)
            xs.append(x)
            ys.append(y)
    x_all, y_all = np.stack(xs), np.stack(ys)
    return float(x_all.min()), float(y_all.min()), float(x_all.max()), float(y_all.max())


def _extrema(lo: F64, hi: F64, owner: I64, low: F64, high: F64) -> None:
    """``lo[k]`` lowered to the least of ``low`` over the readings key pose k owns, ``hi[k]``
    raised to the greatest of ``high``. The readings come in time order, so each key pose's
    are one run: reduced per run (``ufunc.at`` as the fallback)."""
    if owner.shape[0] == 0:
        return
    if np.all(owner[1:] >= owner[:-1]):
        starts = np.flatnonzero(np.concatenate([[True], owner[1:] != owner[:-1]]))
        keys = owner[starts]
        lo[keys] = np.minimum(lo[keys], np.minimum.reduceat(low, starts))
        hi[keys] = np.maximum(hi[keys], np.maximum.reduceat(high, starts))
    else:
        np.minimum.at(lo, owner, low)
        np.maximum.at(hi, owner, high)


def _moved(x: F64, y: F64, c: F64, s: F64, tx: F64, ty: F64) -> tuple[F64, F64]:
    return c * x - s * y + tx, s * x + c * y + ty


@dataclass(frozen=True)
class Motion:
    """One sample's rigid motion of every key pose (:class:`SampledOffsets`), shape (K,)
    each; ``txy`` (2K,) holds tx, then ty (what the compiled kernel takes)."""

    rot: F64
    cos: F64
    sin: F64
    txy: F64

    @classmethod
    def of(cls, offsets: SampledOffsets, sample: int) -> Motion:
        rot = offsets.rot_rad[sample]
        txy = np.concatenate([offsets.tx_m[sample], offsets.ty_m[sample]])
        return cls(rot, np.cos(rot), np.sin(rot), txy)


#: The motion that moves nothing (one key pose, every reading's).
_IDENTITY = Motion(np.zeros(1), np.ones(1), np.zeros(1), np.zeros(2))


def cast(
    grid: LogOddsAccumulator, entry: _Casts, motion: Motion | None, resolution_m: float
) -> int:
    """Add one level's readings to ``grid``, moved by ``motion`` (nominal when None); returns
    the cell updates. ``resolution_m``: the map's cells (the rays' evidence scales with the
    ratio of the cell sizes, module docstring)."""
    if isinstance(entry.model, RayModel):
        return _cast_rays(grid, entry, entry.model, motion, resolution_m)
    updates = 0
    whole = compiled() is not None  # the kernel holds nothing per cone: a chunk in one call
    for owner, cones in zip(entry.owner, entry.sectors, strict=True):
        keys = np.zeros_like(owner) if motion is None else owner
        n = owner.shape[0]
        for start, stop in [(0, n)] if whole else _batches(n):
            sl = slice(start, stop)
            moves = _IDENTITY if motion is None else motion
            updates += cast_sectors(grid, cones.take(sl), keys[sl], moves)
    return updates


def cast_sectors(grid: LogOddsAccumulator, cones: Cones, owner: I64, motion: Motion) -> int:
    """Sonar sectors moved by ``motion`` (``owner``: each one's key pose) into ``grid``, as
    the standard model maps them; returns the outer sectors' cells. The compiled kernel when
    it is built, else :func:`cast_sectors_numpy`: the same grid bit for bit."""
    kernels = compiled()
    if kernels is None:
        return cast_sectors_numpy(grid, cones, owner, motion)
    spec = grid.spec
    values, observations = grid.difference_arrays()
    f64 = np.ascontiguousarray
    return int(
        kernels.moved_sector_batch(
            spec.origin_x_m, spec.origin_y_m, spec.resolution_m, spec.width, spec.height,
            *(f64(getattr(cones, f.name)) for f in dataclasses.fields(cones)),
            f64(owner, dtype=np.int64), f64(motion.cos), f64(motion.sin), f64(motion.txy),
            grid.scale, values, observations,
        )
    )  # fmt: skip


def cast_sectors_numpy(grid: LogOddsAccumulator, cones: Cones, owner: I64, motion: Motion) -> int:
    """:func:`cast_sectors` in numpy: the reference the compiled kernel must equal. The edges
    turn by the angle-sum formulas; a sector spans the rows of its apex and its arc's ends,
    and of the arc's top (bottom) when the wedge holds the +y (-y) direction."""
    spec = grid.spec
    n = motion.cos.shape[0]
    c, s = motion.cos[owner], motion.sin[owner]
    x, y = _moved(cones.x_m, cones.y_m, c, s, motion.txy[owner], motion.txy[n + owner])
    sr, cr = cones.sin_r * c + cones.cos_r * s, cones.cos_r * c - cones.sin_r * s
    sl, cl = cones.sin_l * c + cones.cos_l * s, cones.cos_l * c - cones.sin_l * s
    reach = cones.outer_m
    ys = np.stack([y, y + reach * sr, y + reach * sl])
    ymin = np.where((cr <= 0.0) & (cl >= 0.0), y - reach, ys.min(axis=0))
    ymax = np.where((cr >= 0.0) & (cl <= 0.0), y + reach, ys.max(axis=0))
    res = spec.resolution_m
    j0 = np.clip(np.ceil((ymin - spec.origin_y_m) / res - 0.5), 0, spec.height).astype(np.int64)
    j1 = np.clip(np.floor((ymax - spec.origin_y_m) / res - 0.5), -1, spec.height - 1)
    counts = np.where(reach > 0, np.maximum(j1.astype(np.int64) - j0 + 1, 0), 0)
    rows = rows_of_range(spec, x, y, j0, counts, sr, cr, sl, cl)
    outer = rows.spans(cones.outer_m)
    grid.add_observations(outer.row, outer.col0, outer.col1)
    nonzero = cones.outer_value[outer.reading] != 0.0
    grid.add_values(
        outer.row[nonzero], outer.col0[nonzero], outer.col1[nonzero],
        cones.outer_value[outer.reading][nonzero],
    )  # fmt: skip
    inner = rows.spans(cones.inner_m)
    grid.add_values(inner.row, inner.col0, inner.col1, cones.inner_value[inner.reading])
    return outer.cells()


def _cast_rays(
    grid: LogOddsAccumulator,
    entry: _Casts,
    model: RayModel,
    motion: Motion | None,
    resolution_m: float,
) -> int:
    updates = 0
    ratio = resolution_m / grid.spec.resolution_m
    whole = compiled() is not None  # the kernel holds nothing per ray: a chunk in one call
    for owner, seg in zip(entry.owner, entry.rays, strict=True):
        keys = np.zeros_like(owner) if motion is None else owner
        if whole:
            batches: Iterable[tuple[int, int]] = [(0, owner.shape[0])]
        else:  # a ray's rows: its length in cells and its two end rows (a motion keeps it)
            rows = np.hypot(seg.x1_m - seg.x0_m, seg.y1_m - seg.y0_m) / grid.spec.resolution_m
            batches = _row_batches(rows + 2.0)
        for start, stop in batches:
            sl = slice(start, stop)
            part = RaySegments(seg.x0_m[sl], seg.y0_m[sl], seg.x1_m[sl], seg.y1_m[sl], seg.echo[sl])
            updates += cast_rays(
                grid, part, keys[sl], _IDENTITY if motion is None else motion,
                model.l_free * ratio, model.l_occ * ratio * ratio,
            )  # fmt: skip
    return updates


def cast_rays(
    grid: LogOddsAccumulator,
    seg: RaySegments,
    owner: I64,
    motion: Motion,
    l_free: float,
    l_end: float,
) -> int:
    """Rays moved by ``motion`` (``owner``: each ray's key pose) into ``grid``: ``l_free`` in
    every cell crossed and ``l_end`` in the end cell of an echo. The compiled kernel when it is
    built, else :func:`cast_rays_numpy`: the same grid bit for bit."""
    kernels = compiled()
    if kernels is None:
        return cast_rays_numpy(grid, seg, owner, motion, l_free, l_end)
    spec = grid.spec
    values, observations = grid.difference_arrays()
    f64 = np.ascontiguousarray
    return int(
        kernels.moved_ray_batch(
            spec.origin_x_m, spec.origin_y_m, spec.resolution_m, spec.width, spec.height,
            f64(seg.x0_m), f64(seg.y0_m), f64(seg.x1_m), f64(seg.y1_m),
            seg.echo.astype(np.int64), f64(owner, dtype=np.int64), f64(motion.cos),
            f64(motion.sin), f64(motion.txy), l_free, l_end, grid.scale, values, observations,
        )
    )  # fmt: skip


def cast_rays_numpy(
    grid: LogOddsAccumulator,
    seg: RaySegments,
    owner: I64,
    motion: Motion,
    l_free: float,
    l_end: float,
) -> int:
    """:func:`cast_rays` in numpy: the reference the compiled kernel must equal."""
    n = motion.cos.shape[0]
    c, s, tx, ty = motion.cos[owner], motion.sin[owner], motion.txy[owner], motion.txy[n + owner]
    x0, y0 = _moved(seg.x0_m, seg.y0_m, c, s, tx, ty)
    x1, y1 = _moved(seg.x1_m, seg.y1_m, c, s, tx, ty)
    moved = RaySegments(x0, y0, x1, y1, seg.echo)
    runs = row_runs(grid.spec, moved)
    grid.add_observations(runs.row, runs.col0, runs.col1)
    grid.add_values(runs.row, runs.col0, runs.col1, np.full(runs.row.shape[0], l_free))
    end_row, end_col = end_cells(grid.spec, moved)
    grid.add_values(end_row, end_col, end_col, np.full(end_row.shape[0], l_end - l_free))
    return runs.cells()


def _batches(n: int) -> Iterable[tuple[int, int]]:
    return batch_bounds(np.arange(n, dtype=np.int64), BATCH_READINGS)


def _row_batches(rows: F64) -> Iterable[tuple[int, int]]:
    """Batches of at most :data:`BATCH_READINGS` rays and about :data:`BATCH_ROWS` rows."""
    cum = np.cumsum(rows)
    start, n = 0, rows.shape[0]
    while start < n:
        base = cum[start - 1] if start else 0.0
        stop = int(np.searchsorted(cum, base + BATCH_ROWS, side="right"))
        stop = min(max(stop, start + 1), start + BATCH_READINGS, n)
        yield start, stop
        start = stop


def average(
    plan: BuildPlan,
    casts: list[_Casts],
    offsets: SampledOffsets,
    clamp_p: tuple[float, float],
) -> tuple[OccupancyMap, int]:
    """The mean over samples of each sample's map probabilities; returns it and the updates.

    Per sample, each level's log-odds are added into the next finer level's, coarsest first
    (interpolated linearly, :func:`finer`), so one pass of the map's size per sample takes
    them all; the probabilities are summed as
    ``tanh(l / 2)`` (``p = (1 + tanh(l / 2)) / 2``). Observation counts are kept over all
    samples: a cell is known when some sample's reading touched it."""
    spec = plan.spec
    res = spec.resolution_m
    lo, hi = logodds(clamp_p[0]), logodds(clamp_p[1])
    updates = 0
    by_level: dict[int, list[_Casts]] = {}
    for entry in casts:
        by_level.setdefault(entry.level, []).append(entry)
    grids = {lv: LogOddsAccumulator(level_spec(spec, max(lv, 0))) for lv in by_level}
    shared: F64 | float = 0.0
    observed: dict[int, npt.NDArray[np.bool_]] = {}
    if -1 in by_level:
        for entry in by_level.pop(-1):
            updates += cast(grids[-1], entry, None, res)
        shared = grids[-1].log_odds()
        observed[-1] = grids.pop(-1).observations() > 0  # its 12 bytes a cell let go
    total = np.zeros((spec.height, spec.width))
    order = sorted(by_level, reverse=True)
    for s in range(offsets.count):
        motion = Motion.of(offsets, s)
        summed: F64 | None = None
        for level in range(order[0] if order else -1, -1, -1):
            if summed is not None:
                summed = finer(summed, level_spec(spec, level))
            if level not in by_level:
                continue
            grid = grids[level]
            values, _ = grid.difference_arrays()
            values.fill(0.0)
            for entry in by_level[level]:
                updates += cast(grid, entry, motion, res)
            if summed is None:
                summed = grid.log_odds()
            else:
                summed += grid.log_odds()
        if summed is None:
            summed = np.zeros_like(total)
        summed += shared
        np.clip(summed, lo, hi, out=summed)
        summed *= 0.5
        total += np.tanh(summed, out=summed)
    del shared
    for level in list(grids):
        observed[level] = grids.pop(level).observations() > 0
    seen = known_cells(spec, observed)
    del observed
    # the mean in place: no map-sized temporaries at the peak
    total /= offsets.count
    total *= 0.5
    total += 0.5
    total[~seen] = np.nan
    return OccupancyMap(spec, total), updates
