"""Wires the stages: canonical log -> sync -> sensor model -> grid -> finished map.

Plain functions returning plain results: no printing, no progress bars (the CLI passes a
callback), no file output (writers do that).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import GridmapError, MapSizeError, NoDataError
from gridmap_cli.mapping import expected
from gridmap_cli.mapping.bands import add_sample, mean_in_place, sample_bands
from gridmap_cli.mapping.grid import (
    GridSpec,
    LogOddsAccumulator,
    OccupancyMap,
)
from gridmap_cli.mapping.models.fading import (
    FadedRayModel,
    FadedSonarModel,
    FadeParams,
    PoseSpread,
    scan_steps,
)
from gridmap_cli.mapping.models.ray import RayModel
from gridmap_cli.mapping.models.standard import StandardSonarModel
from gridmap_cli.mapping.options import MAPPING_MODES as MAPPING_MODES
from gridmap_cli.mapping.options import MAX_RESOLUTION_M as MAX_RESOLUTION_M
from gridmap_cli.mapping.options import BuildOptions as BuildOptions
from gridmap_cli.mapping.options import BuildResult as BuildResult
from gridmap_cli.mapping.plan import BuildPlan as BuildPlan
from gridmap_cli.mapping.plan import SensorModel as SensorModel
from gridmap_cli.mapping.plan import split_by_kind
from gridmap_cli.mapping.shards import accumulate_log_odds
from gridmap_cli.mapping.shards import (
    batch_bounds as batch_bounds,  # callers cut batches as build does
)
from gridmap_cli.poses.odometry_error import OdometryError, correct_track, travelled
from gridmap_cli.poses.sync import (
    SensorReadings,
    SyncStats,
    select_readings,
    sensors_for_log,
    synchronise,
)
from gridmap_cli.poses.uncertainty.pose_belief import PoseBelief
from gridmap_cli.poses.uncertainty.pose_uncertainty import (
    PoseUncertainty,
    SampledOffsets,
    StepNoise,
    propagate,
    sample_offsets,
    sample_tracks,
)
from gridmap_cli.records import PoseTrack, RangeLog, cut_chunks, span_text
from gridmap_cli.robot import RangeSensor, RobotDescription

#: Log readings synchronised at a time, by build and by inspect: with the models' bounds kept and
#: the readings let go, a chunk at a time, the synchronised readings never exist for the whole
#: log at once (the hour log's 576,000 were about 40 MiB, three times over).
SYNC_CHUNK_READINGS = 100_000
#: Readings synchronised and bounded at a time in the bounds pass: its minima, maxima and
#: counts are the same for any cut, and the models' bounds of 100,000 sonar readings took
#: 24 MiB of temporaries (the mapping pass keeps the chunks above: its sums follow them).
BOUNDS_CHUNK_READINGS = 25_000


def plan_build(log: RangeLog, robot: RobotDescription | None, options: BuildOptions) -> BuildPlan:
    """Every check :func:`build_map` makes before mapping, with the plan it maps by.

    ``gridmap inspect`` calls this too, so that its verdict is build's own: the errors are
    :func:`build_map`'s (a sensor without mounting, :class:`NoDataError` when no reading can be
    mapped, :class:`MapSizeError` when the data spans an absurd area, a mode that cannot take
    the log's sensors). The readings are synchronised chunk by chunk and only the stats and
    bounds kept: minima and maxima of chunks are the whole's, to the bit.
    """
    if options.mode not in MAPPING_MODES:
        raise GridmapError(f"unknown mapping mode '{options.mode}' (known: {MAPPING_MODES})")
    sensors = sensors_for_log(log, robot)
    narrow = np.array([s.kind == "laser" or s.beam_width_rad <= 0.0 for s in sensors], dtype=bool)
    bounding = _bounding_models(log, sensors, narrow, options)
    size = SYNC_CHUNK_READINGS
    driven = travelled(log.poses) if len(log.poses) else None
    chunks: list[tuple[int, int]] = []
    totals = np.zeros(4, dtype=np.int64)  # total, used, outside odometry, below minimum range
    boxes = []  # (xmin, ymin, xmax, ymax) of each chunk and model
    kinds = np.zeros(2, dtype=bool)  # any ray, any sonar reading kept
    for chunk in log.reading_chunks(size):
        start = chunks[-1][1] if chunks else 0
        chunks.append((start, start + len(chunk)))
        for piece in cut_chunks([chunk], BOUNDS_CHUNK_READINGS):
            readings, chunk_stats = synchronise(log, robot, piece, driven)
            totals += dataclasses.astuple(chunk_stats)
            if len(readings) == 0:
                continue
            is_ray = narrow[readings.sensor]
            kinds |= (bool(is_ray.any()), bool(not is_ray.all()))
            boxes += [
                model.bounds(part) for model, part in split_by_kind(bounding, narrow, readings)
            ]
    stats = SyncStats(*(int(v) for v in totals))
    if stats.used == 0:
        raise NoDataError(_why_empty(log, stats))
    box = np.array(boxes)
    xmin, ymin, _, _ = box.min(axis=0)
    _, _, xmax, ymax = box.max(axis=0)
    try:
        spec = GridSpec.covering(
            xmin, ymin, xmax, ymax, options.resolution_m, options.margin_m, options.max_cells
        )
    except MapSizeError as exc:
        raise MapSizeError(f"{log.source}: {exc}") from exc
    models = _mapping_models(log, sensors, narrow, options, bool(kinds[0]), bool(kinds[1]))
    return BuildPlan(stats, models, spec, log, robot, chunks, narrow, size, driven)


def build_map(
    log: RangeLog,
    robot: RobotDescription | None,
    options: BuildOptions,
    progress: Callable[[int], object] | None = None,
    between_passes: Callable[[], object] | None = None,
) -> BuildResult:
    """Build an occupancy map from a canonical log.

    ``progress`` is called with the number of readings just processed (one call per batch);
    ``between_passes`` once the bounds pass is done, before any mapping (the CLI returns the
    freed heap then). Raises what :func:`plan_build` raises, before any mapping.
    """
    check = None
    if options.check_odometry_error and options.odometry_error is not None:
        # the scan matcher and the fit load only for a build that checks
        from gridmap_cli.poses.calibration.log_check import check_file

        check = check_file(log, robot, options.odometry_error)
        options = dataclasses.replace(
            options, odometry_error=check.model, check_odometry_error=False
        )
    if options.correct_odometry:
        log, options = corrected_for_build(log, options)
    if options.mode == "error-aware" and options.error_samples > 0:
        result = expected_map(log, robot, options, progress, between_passes)
    else:
        plan = plan_build(log, robot, options)
        if between_passes is not None:
            between_passes()
        # both modes sum log-odds: the error-aware mode is the standard one with faded evidence
        result = _one_grid(plan, options, progress)
    return result if check is None else dataclasses.replace(result, odometry_check=check)


def _one_grid(
    plan: BuildPlan, options: BuildOptions, progress: Callable[[int], object] | None
) -> BuildResult:
    """Every reading of ``plan`` summed into one grid, finished as the map."""
    grid = LogOddsAccumulator(plan.spec, plan.sync.used)
    updates = accumulate(plan, grid, options, progress)
    omap, _ = grid.finish(options.clamp_p)
    return BuildResult(map=omap, sync=plan.sync, cell_updates=updates)


def _steady_plan(plan: BuildPlan, uncertainty: PoseUncertainty, limit_rad: float) -> BuildPlan:
    """``plan`` whose models leave out the readings whose heading standard deviation (from
    ``uncertainty``) exceeds ``limit_rad``; ``plan`` itself when there is no limit."""
    if not limit_rad < math.inf:
        return plan
    models: list[tuple[SensorModel, str]] = [
        (_Steady(model, uncertainty, limit_rad), kind) for model, kind in plan.models
    ]
    return dataclasses.replace(plan, models=models)


def corrected_for_build(log: RangeLog, options: BuildOptions) -> tuple[RangeLog, BuildOptions]:
    """``options.correct_odometry``: the log with the odometry's known biases taken out of its
    track (:func:`~gridmap_cli.poses.odometry_error.correct_track`), and options whose
    odometry error is the random part alone: a corrected bias is not blurred again
    (:meth:`~gridmap_cli.poses.odometry_error.OdometryError.random_part`). Raises
    :class:`GridmapError` for a model without signed biases whose systematic magnitudes are not
    0 (a file older than version 3: the sign to correct by is unknown)."""
    model = options.odometry_error
    if model is None:
        raise GridmapError("correcting the odometry needs the odometry error model")
    unsigned = (model.range_m_per_m, model.bearing_rad_per_rad, model.heading_drift_rad_per_m)
    if not model.has_bias and any(unsigned):
        raise GridmapError(
            "the odometry error holds systematic errors without their signs (a file older than "
            "version 3): calibrate again to correct the odometry by them"
        )
    poses = correct_track(log.poses, model)
    fixed = log if poses is log.poses else dataclasses.replace(log, poses=poses)
    return fixed, dataclasses.replace(
        options, odometry_error=model.random_part(), correct_odometry=False
    )


def expected_map(
    log: RangeLog,
    robot: RobotDescription | None,
    options: BuildOptions,
    progress: Callable[[int], object] | None = None,
    between_passes: Callable[[], object] | None = None,
) -> BuildResult:
    """The expected map under the pose belief: the mean probability of the standard maps of
    ``options.error_samples`` tracks drawn from the odometry-error model
    (:func:`~gridmap_cli.poses.uncertainty.pose_uncertainty.sample_offsets`: systematic errors
    drawn once per track, a random error per key step, composed along the path, so every correlation
    along it is kept), on the grid of the standard build (readings a sample moves off it are
    cut); :mod:`gridmap_cli.mapping.expected` says how it costs a few standard builds, not K.
    A cell some samples' readings missed counts as the prior 0.5 in those; a cell none touched
    stays unknown. Perfect odometry is the standard build, to the bit. Readings whose heading
    standard deviation exceeds ``options.error_aware.max_heading_spread_rad`` are left out, as
    in the analytic model. ``progress`` counts the log's readings once; one process maps
    them whatever ``options.jobs`` is.

    With a pose graph's belief (``options.pose_belief``) the tracks are its draws, each mapped
    in full (:func:`_belief_map`): the running sum of the samples' probabilities (8 bytes a
    cell) and one sample's grid, cut into row bands on a large map (:func:`sample_bands`)."""
    if options.pose_belief is not None:
        return _belief_map(log, robot, options, options.pose_belief, progress, between_passes)
    if options.odometry_error is None:
        raise GridmapError(
            "error-aware mode needs the odometry error model (gridmap calibrate writes one)"
        )
    standard = dataclasses.replace(options, mode="standard")
    plan = plan_build(log, robot, standard)
    if between_passes is not None:
        between_passes()
    noise = StepNoise.of(options.odometry_error)
    if noise.is_zero:  # the standard build, to the bit
        return _one_grid(plan, standard, progress)
    heading = propagate(log.poses, noise)
    limit = options.error_aware.max_heading_spread_rad
    cutoff = None
    if limit < math.inf and len(log.poses):
        over = np.flatnonzero(heading.cov[:, 2, 2] > limit * limit)  # never falls: monotone
        if over.size:
            cutoff = int(heading.stamp_ns[over[0]])
    if plan.spec.height * plan.spec.width > FAST_MAP_MAX_CELLS:
        # the fast map keeps a few map-sized arrays per level and sample: past this size it
        # would break the memory bound, so the tracks are mapped one by one, in row bands
        plan = _steady_plan(plan, heading, limit)
        tracks = sample_tracks(log.poses, noise, options.error_samples, options.error_seed)
        return _mean_map(log, plan, standard, tracks, progress)
    offsets = sample_offsets(
        log.poses, noise, options.error_samples, options.error_seed, expected.ANTITHETIC
    )
    casts = expected.collect(plan, heading, offsets, cutoff, progress)
    plan = _sampled_grid(plan, casts, offsets, standard)
    omap, updates = expected.average(plan, casts, offsets, standard.clamp_p)
    return BuildResult(map=omap, sync=plan.sync, cell_updates=updates)


def _sampled_grid(
    plan: BuildPlan, casts: list[expected._Casts], offsets: SampledOffsets, options: BuildOptions
) -> BuildPlan:
    """The plan on a grid grown to hold where the samples' readings land
    (:func:`expected.sample_bounds`), so that its edge cuts no cell the map knows; the
    standard build's grid when they land inside it, or when the grown grid would pass
    :data:`FAST_MAP_MAX_CELLS` (the cut then shows where the samples left the grid)."""
    box = expected.sample_bounds(casts, offsets)
    if box is None:
        return plan
    spec = plan.spec
    x1 = spec.origin_x_m + spec.width * spec.resolution_m
    y1 = spec.origin_y_m + spec.height * spec.resolution_m
    m = options.margin_m
    if (box[0] - m >= spec.origin_x_m and box[1] - m >= spec.origin_y_m
            and box[2] + m <= x1 and box[3] + m <= y1):  # fmt: skip
        return plan
    try:
        grown = GridSpec.covering(
            min(box[0] - m, spec.origin_x_m), min(box[1] - m, spec.origin_y_m),
            max(box[2] + m, x1), max(box[3] + m, y1), spec.resolution_m, 0.0,
            max(FAST_MAP_MAX_CELLS, spec.width * spec.height),
        )  # fmt: skip
    except MapSizeError:
        return plan
    return dataclasses.replace(plan, spec=grown)


#: Cells of the largest map the fast expected map (:mod:`gridmap_cli.mapping.expected`) builds.
#: It takes about 53 bytes a cell (a 50 M cell map: 2.7 GB), so past about 2 M cells it
#: would break the build's bound of 12 bytes a cell plus a fixed 160 MiB (README, "Speed");
#: larger maps take the exact expected map, each track's standard map in row bands, at about
#: the samples' count times the standard build's time.
FAST_MAP_MAX_CELLS = 2 << 20
#: The clamp of each sample's map when the mean is clamped once (``_mean_map``): wide enough
#: that a cell's evidence is kept (p within 1e-9 of 0 or 1 only past a log-odds of 20).
UNCLAMPED_P = (1e-9, 1.0 - 1e-9)


def _belief_map(
    log: RangeLog,
    robot: RobotDescription | None,
    options: BuildOptions,
    belief: PoseBelief,
    progress: Callable[[int], object] | None,
    between_passes: Callable[[], object] | None,
) -> BuildResult:
    """:func:`expected_map` with the tracks drawn from a pose graph's belief; readings whose
    heading standard deviation (the graph's, which falls where a loop closed) exceeds the limit
    are left out one by one."""
    standard = dataclasses.replace(options, mode="standard")
    plan = plan_build(log, robot, standard)
    if between_passes is not None:
        between_passes()
    plan = _steady_plan(plan, belief.uncertainty, options.error_aware.max_heading_spread_rad)
    count = min(options.error_samples, belief.draws.shape[0])
    if count and np.array_equal(
        belief.draws[:count], np.broadcast_to(belief.poses, belief.draws[:count].shape)
    ):
        count = 0  # every draw is the optimum: its standard map, to the bit
    tracks = belief.tracks(log.poses, count) if count else [log.poses]
    return _mean_map(log, plan, standard, tracks, progress, clamp_once=True)


def _mean_map(
    log: RangeLog,
    plan: BuildPlan,
    standard: BuildOptions,
    tracks: list[PoseTrack],
    progress: Callable[[int], object] | None,
    clamp_once: bool = False,
) -> BuildResult:
    """The mean probability of the standard maps of ``log`` placed by each of ``tracks``.

    ``clamp_once``: the samples' probabilities are averaged unclamped and the mean is clamped
    to ``standard.clamp_p``, as the standard map clamps its summed log-odds once at the end.
    Clamping each sample first caps a wall at 0.7 in every sample, 0.05 above the occupied
    threshold, so a wall cell a tenth of the draws put a cell over fell out of a trinary map
    (docs/sensor-model.md, "The pose graph's belief"). One track is its standard map either way."""
    count = len(tracks)
    once = clamp_once and count > 1
    sample_clamp = UNCLAMPED_P if once else standard.clamp_p
    spec = plan.spec
    bands = sample_bands(spec, count)
    # the running sum of the samples' probabilities, negated while no sample has seen the cell
    total = np.zeros(spec.height * spec.width)
    updates = 0
    done = [0, 0]  # readings mapped over all samples and bands, readings reported
    passes = count * len(bands)

    def report(n: int) -> None:  # the caller counts the log's readings once
        done[0] += n
        if progress is not None and done[0] // passes > done[1]:
            progress(done[0] // passes - done[1])
            done[1] = done[0] // passes

    for rows in bands:
        for track in tracks:
            moved = dataclasses.replace(log, poses=track)
            part = dataclasses.replace(plan, log=moved, travelled=travelled(track))
            grid = LogOddsAccumulator(spec, plan.sync.used, rows)
            accumulate(part, grid, standard, report)
            band, band_updates = grid.finish(sample_clamp)
            updates += band_updates
            add_sample(total[rows[0] * spec.width : rows[1] * spec.width], band.prob.ravel())
            del grid, band
    mean_in_place(total, count)
    if once:
        np.clip(total, standard.clamp_p[0], standard.clamp_p[1], out=total)  # NaN stays unknown
    mean = OccupancyMap(spec, total.reshape(spec.shape))
    return BuildResult(map=mean, sync=plan.sync, cell_updates=updates)


class _Steady:
    """A model that maps only the readings whose heading standard deviation is within
    ``limit_rad`` (the covariance of ``uncertainty`` at their stamps)."""

    def __init__(self, model: SensorModel, uncertainty: PoseUncertainty, limit_rad: float) -> None:
        self.model = model
        self.uncertainty = uncertainty
        self.limit_rad = limit_rad

    def bounds(self, readings: SensorReadings) -> tuple[float, float, float, float]:
        return self.model.bounds(readings)

    def accumulate(self, grid: LogOddsAccumulator, readings: SensorReadings) -> int:
        keep = self.uncertainty.at(readings.stamp_ns)[:, 2, 2] <= self.limit_rad**2
        if not keep.any():
            return 0
        return self.model.accumulate(grid, select_readings(readings, keep))


def accumulate(
    plan: BuildPlan,
    grid: LogOddsAccumulator,
    options: BuildOptions,
    progress: Callable[[int], object] | None = None,
) -> int:
    """Add every reading of ``plan`` to ``grid`` on ``options.jobs`` processes; returns the cell
    updates. The grid is the same to the byte for every number of jobs
    (:mod:`gridmap_cli.mapping.shards` says how)."""
    return accumulate_log_odds(plan, grid, options.batch_size, options.jobs, progress)


def _bounding_models(
    log: RangeLog,
    sensors: tuple[RangeSensor, ...],
    narrow: npt.NDArray[np.bool_],
    options: BuildOptions,
) -> list[tuple[SensorModel, str]]:
    """The models whose bounds hold every cell the readings touch, whichever kinds of sensor
    turn out to have readings: the standard models' (the error-aware ones fade, never widen)."""
    standard = dataclasses.replace(options, mode="standard")
    return _mapping_models(log, sensors, narrow, standard, True, True)


def _mapping_models(
    log: RangeLog,
    sensors: tuple[RangeSensor, ...],
    narrow: npt.NDArray[np.bool_],
    options: BuildOptions,
    any_ray: bool,
    any_sonar: bool,
) -> list[tuple[SensorModel, str]]:
    """Each model and the kind of reading it maps; models without readings are left out.

    Narrow-beam sensors (kind "laser" or beam width 0) go to the ray model, the others to the
    sonar model. Log-odds sums do not depend on order, so the models may run one after the other.
    """
    models: list[tuple[SensorModel, str]] = []
    ray = RayModel(options.ray, options.resolution_m)
    sonar = StandardSonarModel(options.sonar, options.resolution_m)
    if options.mode == "error-aware":
        spread = _pose_spread(log, options)
        step = scan_steps(sensors, narrow)
        if any_ray:
            models.append((FadedRayModel(ray, spread, step), "ray"))
        if any_sonar:
            models.append((FadedSonarModel(sonar, spread), "sonar"))
        return models
    if any_ray:
        models.append((ray, "ray"))
    if any_sonar:
        models.append((sonar, "sonar"))
    return models


def _pose_spread(log: RangeLog, options: BuildOptions) -> PoseSpread:
    """The pose covariance along the log's track: the pose graph's (``options.pose_belief``)
    or that carried along the odometry by the odometry-error model."""
    belief = options.pose_belief
    if options.odometry_error is None and belief is None:
        raise GridmapError(
            "error-aware mode needs the odometry error model (gridmap calibrate writes one)"
        )
    model = options.odometry_error or OdometryError()  # with a belief: the sonar's k only
    params = FadeParams(
        trust_length_m=options.error_aware.trust_length_m,
        sonar_relative_error=model.sonar_relative_error,
        laser_relative_error=options.error_aware.laser_relative_error,
        max_heading_spread_rad=options.error_aware.max_heading_spread_rad,
    )
    if belief is not None:
        return PoseSpread(belief.uncertainty, params)
    return PoseSpread(propagate(log.poses, StepNoise.of(model)), params)


def _why_empty(log: RangeLog, stats: SyncStats) -> str:
    if stats.total == 0:
        return f"{log.source}: the log holds no range readings"
    if stats.outside_odometry == stats.total:
        odo = log.poses.stamp_ns
        return (
            f"{log.source}: no odometry during the range readings: the {stats.total} readings "
            f"span {span_text(*log.reading_span())}, the odometry "
            f"{span_text(int(odo[0]), int(odo[-1]))} (recorded at different times?)"
        )
    parts = []
    if stats.outside_odometry:
        parts.append(f"{stats.outside_odometry} outside the odometry's time span")
    if stats.below_min_range:
        parts.append(f"{stats.below_min_range} below their sensor's minimum range")
    return (
        f"{log.source}: none of the {stats.total} range readings can be mapped ({'; '.join(parts)})"
    )
