"""Score a probability map against a ground-truth world: how likely the truth is under the map.

Everything is counted on the *world's* cells, over a region that depends only on the world and
the log, never on the map being scored, so that two maps of one log are scored on the same
cells. For each region cell the map's probability is looked up at the cell's centre, carried
into the map's frame; outside the map or unknown counts as p = 0.5. ``docs/evaluation.md``
defines every score.

Frames: a map built from odometry is in the odometry frame. Its origin is the robot's first
odometry pose, which lies at the robot's first true pose, so the map frame sits in the world at
``truth[0] (+) inverse(odometry[0])`` (:func:`odometry_frame_in_world`); a map built with
``--pose global`` is in the world frame already (identity).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np
import numpy.typing as npt
from scipy import ndimage

from gridmap_cli.errors import GridmapError
from gridmap_cli.evaluation.metrics import world_cells
from gridmap_cli.geometry import compose, inverse
from gridmap_cli.mapping.grid import GridSpec, OccupancyMap, SpanSums
from gridmap_cli.mapping.mapfile import load_map
from gridmap_cli.mapping.models.ray import RaySegments, row_runs
from gridmap_cli.poses.odometry_error import travelled
from gridmap_cli.poses.sync import interpolate_pose
from gridmap_cli.records import PoseTrack, RangeLog
from gridmap_cli.robot import RangeSensor
from gridmap_cli.sim.world import World

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
Pose = tuple[float, float, float]

#: Probabilities are clipped to this range before the logarithm: a map that states p = 0 or 1
#: (a trinary map) and is wrong once would otherwise score an infinite NLL. ln(1000) = 6.9 is
#: then the most one cell can cost.
NLL_CLIP = (0.001, 0.999)
RELIABILITY_BINS = 10
#: Region from a path: true poses kept every this far (or this much turning) along the path.
#: On the three sample logs 0.1 m and 5 deg change the region by at most 0.16 % of its cells,
#: at twice the time.
REGION_STEP_M = 0.2
REGION_STEP_RAD = math.radians(10.0)
_RAYS_PER_CHUNK = 20_000


class EvaluationError(GridmapError):
    """The inputs cannot be scored against each other (an empty region, no truth in the log)."""


@dataclass(frozen=True)
class ProbabilityMap:
    """A map as scored: probability per cell (NaN unknown, shape ``spec.shape``, row 0 at the
    bottom) and the probability at or above which the map calls a cell occupied."""

    spec: GridSpec
    prob: FloatArray
    occupied_thresh: float

    @classmethod
    def from_occupancy_map(cls, omap: OccupancyMap, occupied_thresh: float) -> ProbabilityMap:
        return cls(omap.spec, omap.prob, occupied_thresh)


def load_probability_map(yaml_path: Path) -> ProbabilityMap:
    """A map_server map as the probabilities its file states (see
    :meth:`~gridmap_cli.mapping.mapfile.LoadedMap.stored_probability`; scale maps keep theirs)."""
    loaded = load_map(yaml_path)
    return ProbabilityMap(loaded.spec, loaded.stored_probability(), loaded.occupied_thresh)


@dataclass(frozen=True)
class ReliabilityBin:
    """Region cells whose p lies in [lower, upper) (the last bin includes 1): how many, their
    mean p, and the share of them truly occupied (NaN for an empty bin)."""

    lower: float
    upper: float
    count: int
    mean_predicted: float
    observed_frequency: float


@dataclass(frozen=True)
class Evaluation:
    """Scores of one map over one region (docs/evaluation.md).

    ``cells``: region cells; ``occupied_cells``: of them truly occupied; ``nll``: mean negative
    natural log-likelihood of the truth, p clipped to :data:`NLL_CLIP`; ``brier``: mean squared
    difference between p and the truth (0/1); ``ece``: expected calibration error over
    :data:`RELIABILITY_BINS` bins; ``precision``, ``recall``, ``f1``: occupied cells with one
    cell of tolerance; ``predicted_occupied``: region cells the map calls occupied;
    ``coverage``: share of region cells the map knows. ``p_world``: the map's p on the world
    grid as scored (:func:`map_in_world`: NaN unknown or outside, shape ``world.shape``), for
    drawing; it is left out of :meth:`as_dict` and of equality.
    """

    cells: int
    occupied_cells: int
    nll: float
    brier: float
    ece: float
    reliability: tuple[ReliabilityBin, ...]
    precision: float
    recall: float
    f1: float
    predicted_occupied: int
    coverage: float
    occupied_thresh: float
    p_world: FloatArray = field(repr=False, compare=False)

    def as_dict(self) -> dict[str, object]:
        """The scores as plain values (for JSON): every field but ``p_world``."""
        out: dict[str, object] = {
            f.name: getattr(self, f.name) for f in fields(self) if f.name != "p_world"
        }
        out["reliability"] = [asdict(b) for b in self.reliability]
        return out


def odometry_frame_in_world(log: RangeLog) -> Pose:
    """Pose of the odometry frame in the world: ``truth[0] (+) inverse(odometry[0])``.

    The odometry and the truth are taken at the first odometry stamp the truth covers.
    Raises :class:`~gridmap_cli.errors.InputFileError` for a log without ground truth.
    """
    truth = log.require_truth("evaluate needs the true path")
    odo = log.poses
    k = int(np.searchsorted(odo.stamp_ns, truth.stamp_ns[0], side="left"))
    if k >= len(odo):
        raise EvaluationError(f"{log.source}: the odometry and the ground truth never overlap")
    tx, ty, tth, _ = interpolate_pose(truth, odo.stamp_ns[k : k + 1])
    ix, iy, ith = inverse(odo.x_m[k], odo.y_m[k], odo.theta_rad[k])
    x, y, th = compose(tx[0], ty[0], tth[0], ix, iy, ith)
    return float(x), float(y), float(th)


def sensed_region(
    world: World,
    truth: PoseTrack,
    sensors: Sequence[RangeSensor],
    step_m: float = REGION_STEP_M,
    step_rad: float = REGION_STEP_RAD,
) -> BoolArray:
    """World cells a sensor could have sensed from the true path, shape ``world.spec.shape``.

    From true poses every ``step_m`` metres or ``step_rad`` radians of turning along the path
    (first and last included), each sensor casts rays in the world across its beam (rays no
    more than one cell apart at its maximum range; one ray for a beam width of 0) up to its
    maximum range. Every cell a ray crosses counts (an exact traversal,
    :func:`~gridmap_cli.mapping.models.ray.row_runs`, corners it clips included), and so does the
    occupied cell it stops in. The region depends on the world, the path and the sensors only.
    """
    if len(truth) == 0:
        raise EvaluationError("the true path is empty")
    spec = world.spec
    res = spec.resolution_m
    keep = _path_samples(truth, step_m, step_rad)
    px, py, pth = truth.x_m[keep], truth.y_m[keep], truth.theta_rad[keep]
    ox: list[FloatArray] = []
    oy: list[FloatArray] = []
    angle: list[FloatArray] = []
    reach: list[FloatArray] = []
    for s in sensors:
        if s.beam_width_rad > 0.0:
            n = math.ceil(s.beam_width_rad * s.max_range_m / res) + 1
            offsets = np.linspace(-s.beam_width_rad / 2, s.beam_width_rad / 2, n)
        else:
            offsets = np.zeros(1)
        sx, sy, sth = compose(px, py, pth, s.x_m, s.y_m, s.yaw_rad)
        ox.append(np.repeat(sx, offsets.shape[0]))
        oy.append(np.repeat(sy, offsets.shape[0]))
        angle.append((sth[:, None] + offsets[None, :]).ravel())
        reach.append(np.full(sx.shape[0] * offsets.shape[0], s.max_range_m))
    x0, y0 = np.concatenate(ox), np.concatenate(oy)
    a, rmax = np.concatenate(angle), np.concatenate(reach)
    crossings = SpanSums(spec, np.int64)
    for lo in range(0, x0.shape[0], _RAYS_PER_CHUNK):
        sl = slice(lo, lo + _RAYS_PER_CHUNK)
        _mark_rays(crossings, world, x0[sl], y0[sl], a[sl], rmax[sl])
    return np.asarray(crossings.total() > 0)


def _path_samples(truth: PoseTrack, step_m: float, step_rad: float) -> npt.NDArray[np.int64]:
    """Indices of the poses where the path crosses a multiple of step_m or of step_rad."""
    dist, rot = travelled(truth)
    bucket_d = np.floor(dist / step_m)
    bucket_r = np.floor(rot / step_rad)
    change = np.ones(dist.shape[0], dtype=bool)
    change[1:] = (np.diff(bucket_d) != 0) | (np.diff(bucket_r) != 0)
    change[-1] = True
    return np.flatnonzero(change)


def _mark_rays(
    region: SpanSums,
    world: World,
    x0: FloatArray,
    y0: FloatArray,
    angle: FloatArray,
    rmax: FloatArray,
) -> None:
    """Count in ``region`` the cells rays (shape (R,)) cross up to their first hit, and the
    occupied cell each hit stops in."""
    res = world.spec.resolution_m
    r, _ = world.cast(x0, y0, angle, rmax)
    # carried a hundredth of a cell past the boundary it hit, a ray ends inside the occupied
    # cell it stops in, so its exact traversal takes that cell too
    length = np.where(r < rmax, r + 0.01 * res, r)
    runs = row_runs(
        world.spec,
        RaySegments(
            x0_m=x0,
            y0_m=y0,
            x1_m=x0 + length * np.cos(angle),
            y1_m=y0 + length * np.sin(angle),
            echo=np.ones(r.shape[0], dtype=bool),  # a ray of length 0 still has its one cell
        ),
    )
    region.add(runs.row, runs.col0, runs.col1, np.ones(runs.row.shape[0], dtype=np.int64))


def map_in_world(pmap: ProbabilityMap, world: GridSpec, map_to_world: Pose) -> FloatArray:
    """The map's probability at each world cell's centre, shape ``world.shape``; NaN where the
    map does not know the cell or does not reach it. ``map_to_world``: the map frame's pose."""
    # the world grid seen from the map: the map cell under each world cell's centre
    ix, iy, ith = inverse(*(np.asarray(v, dtype=np.float64) for v in map_to_world))
    row, col, inside = world_cells(world, pmap.spec, (float(ix), float(iy), float(ith)))
    return np.where(inside, pmap.prob[row, col], np.nan)


def evaluate_map(
    pmap: ProbabilityMap,
    walls: BoolArray,
    world: GridSpec,
    region: BoolArray | None = None,
    map_to_world: Pose = (0.0, 0.0, 0.0),
    known: BoolArray | None = None,
) -> Evaluation:
    """Score ``pmap`` against the world's ``walls`` (bool, shape ``world.shape``, row 0 bottom).

    ``region``: world cells to score (same shape); None scores every world cell.
    ``map_to_world``: pose of the map's frame in the world (identity for world-frame maps).
    ``known``: the cells the reference knows (same shape; a reference map built from corrected
    poses leaves cells unknown): only those are scored, since an unknown reference cell is not a
    free one. None: every cell is known (a simulator's world).
    The result also carries the map's p on the world grid (``p_world``), for drawing.
    Raises :class:`EvaluationError` for an empty region and ``ValueError`` for shapes that
    do not match.
    """
    walls = np.asarray(walls, dtype=bool)
    if walls.shape != world.shape:
        raise ValueError(f"walls have shape {walls.shape}, the world grid {world.shape}")
    if region is None:
        region = np.ones(world.shape, dtype=bool)
    if region.shape != world.shape:
        raise ValueError(f"region has shape {region.shape}, the world grid {world.shape}")
    if known is not None:
        if known.shape != world.shape:
            raise ValueError(f"known has shape {known.shape}, the world grid {world.shape}")
        region = region & known
    n = int(region.sum())
    if n == 0:
        raise EvaluationError("the region to score holds no cell")
    p_world = map_in_world(pmap, world, map_to_world)
    known = ~np.isnan(p_world)
    p = np.where(known, p_world, 0.5)[region]
    y = walls[region].astype(np.float64)
    pc = np.clip(p, *NLL_CLIP)
    nll = float(-np.mean(y * np.log(pc) + (1.0 - y) * np.log(1.0 - pc)))
    brier = float(np.mean((p - y) ** 2))
    bins, ece = _reliability(p, y)
    # one cell of tolerance: any of the 8 neighbours (or the cell itself) will do
    square = np.ones((3, 3), dtype=bool)
    predicted = known & (np.where(known, p_world, 0.0) >= pmap.occupied_thresh)
    near_wall = ndimage.binary_dilation(walls, structure=square)
    near_predicted = ndimage.binary_dilation(predicted, structure=square)
    n_pred = int((region & predicted).sum())
    n_true = int((region & walls).sum())
    precision = float((region & predicted & near_wall).sum() / n_pred) if n_pred else math.nan
    recall = float((region & walls & near_predicted).sum() / n_true) if n_true else math.nan
    if not (n_pred and n_true):
        f1 = math.nan
    elif precision + recall == 0.0:
        f1 = 0.0
    else:
        f1 = 2 * precision * recall / (precision + recall)
    return Evaluation(
        cells=n,
        occupied_cells=n_true,
        nll=nll,
        brier=brier,
        ece=ece,
        reliability=bins,
        precision=precision,
        recall=recall,
        f1=f1,
        predicted_occupied=n_pred,
        coverage=float((region & known).sum() / n),
        occupied_thresh=pmap.occupied_thresh,
        p_world=p_world,
    )


def _reliability(p: FloatArray, y: FloatArray) -> tuple[tuple[ReliabilityBin, ...], float]:
    """Reliability table over equal-width bins of p, and the expected calibration error:
    sum over bins of (count / total) * |mean predicted - observed frequency|."""
    k = RELIABILITY_BINS
    idx = np.minimum(np.floor(p * k).astype(np.int64), k - 1)
    count = np.bincount(idx, minlength=k)
    sum_p = np.bincount(idx, weights=p, minlength=k)
    sum_y = np.bincount(idx, weights=y, minlength=k)
    bins = []
    ece = 0.0
    for b in range(k):
        if count[b]:
            mean_p, freq = sum_p[b] / count[b], sum_y[b] / count[b]
            ece += count[b] / p.shape[0] * abs(mean_p - freq)
        else:
            mean_p = freq = math.nan
        bins.append(ReliabilityBin(b / k, (b + 1) / k, int(count[b]), float(mean_p), float(freq)))
    return tuple(bins), float(ece)


@dataclass(frozen=True)
class Truth:
    """A ground-truth world as evaluate uses it: its grid, its walls, the cells it knows (a
    reference map built from corrected poses has unknown cells; a simulator's world none) and a
    ray caster."""

    spec: GridSpec
    walls: BoolArray
    world: World
    known: BoolArray


def load_truth(yaml_path: Path) -> Truth:
    """A world or reference map (map_server YAML, e.g. ``samples/worlds/*.yaml``, or a map built
    with ``--pose global``): occupied cells are walls; unknown cells (and, in a trinary map,
    cells between its thresholds) are not known and are not scored."""
    loaded = load_map(yaml_path)
    walls = loaded.occupied_mask()
    return Truth(loaded.spec, walls, World(walls, loaded.spec), np.asarray(loaded.occupancy >= 0))


#: Below this share of the true path on free cells of the truth world, the log was not there.
MIN_PATH_ON_FREE = 0.9
#: Below this share of the true path on free cells of the truth world, the log was not there.
MIN_PATH_ON_FREE = 0.9


def check_path_in_world(truth: Truth, path: PoseTrack, log_name: str, truth_name: str) -> None:
    """Refuse a truth world in which the log's true path runs through walls or outside it:
    the world of another place (:class:`EvaluationError` naming both files)."""
    if len(path) == 0:
        return
    col, row = truth.spec.world_to_cell(path.x_m, path.y_m)
    inside = (col >= 0) & (row >= 0) & (col < truth.spec.width) & (row < truth.spec.height)
    free = inside.copy()
    free[inside] = ~truth.walls[row[inside], col[inside]]
    share = float(free.mean())
    if share < MIN_PATH_ON_FREE:
        raise EvaluationError(
            f"{log_name}: only {share:.0%} of its true path lies on free cells of the truth "
            f"world {truth_name}: the log was recorded in another place"
        )


#: Below this share of the map's known cells inside the truth world, the two are not of one place.
MIN_SHARE_INSIDE = 0.5


def check_comparable(
    pmap: ProbabilityMap,
    truth: GridSpec,
    map_to_world: Pose,
    map_name: str,
    truth_name: str,
    log_world: str | None = None,
) -> tuple[str, ...]:
    """Refuse a map and a truth world that cannot be of one place; warn of what skews scores.

    Raises :class:`EvaluationError` naming both files when less than :data:`MIN_SHARE_INSIDE`
    of the map's known cells, placed by ``map_to_world``, fall inside the world (another
    place, or the wrong ``--frame``). Returns warnings: resolutions that differ, a log whose
    ``# world:`` (``log_world``) names a world file other than ``truth_name``.
    """
    notes: list[str] = []
    known = ~np.isnan(pmap.prob)
    n_known = int(known.sum())
    if n_known:
        _, _, inside = world_cells(pmap.spec, truth, map_to_world)
        share = int((inside & known).sum()) / n_known
        if share < MIN_SHARE_INSIDE:
            raise EvaluationError(
                f"{map_name}: only {share:.0%} of its known cells fall inside the truth world "
                f"{truth_name} ({truth.width * truth.resolution_m:.1f} x "
                f"{truth.height * truth.resolution_m:.1f} m at origin {truth.origin_x_m:g}, "
                f"{truth.origin_y_m:g}): a map of another place, or the wrong --frame"
            )
    if not math.isclose(pmap.spec.resolution_m, truth.resolution_m, rel_tol=1e-6):
        notes.append(
            f"{map_name}: resolution {pmap.spec.resolution_m:g} m, the truth world "
            f"{truth_name} {truth.resolution_m:g} m: each world cell is scored by the map cell "
            "under its centre, so the scores mix cell sizes"
        )
    if log_world and Path(log_world).name != Path(truth_name).name:
        notes.append(
            f"the log was simulated in {log_world}, but the truth is {truth_name}: another place?"
        )
    return tuple(notes)
