"""Where a map's uncertainty comes from: the pose spread at which each cell was seen.

The error-aware map carries the pose covariance along the odometry track
(:mod:`gridmap_cli.poses.uncertainty.pose_uncertainty`); each reading was taken with the covariance
of its stamp. Its spread is drawn as two numbers: the position spread (metres, the standard
deviation along the covariance ellipse's long axis) and the heading spread (radians, the standard
deviation of theta). In an error-aware map a cell that only poorly placed readings looked at stays
grey however many of them there were. This module draws, per cell, the *smallest* position spread of
the readings whose beam crossed the cell (and the heading spread of those readings), so a user
can tell a region that is grey because the pose was lost there from one that is grey because the
sensors disagree. :func:`spread_layer` gives every cell the mean position spread of the
readings whose beams crossed it, weighted by how many crossed it: the layer ``gridmap build``
writes beside an error-aware or a pose graph's map. No file I/O: :mod:`gridmap_cli.cli.evaluate`
reads the log and the odometry error, :mod:`gridmap_cli.evaluation.plot` draws the result.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy import ndimage

from gridmap_cli.mapping.grid import GridSpec, SpanSums
from gridmap_cli.mapping.models.kernels import compiled
from gridmap_cli.mapping.models.ray import RaySegments, ray_rows, row_runs
from gridmap_cli.poses.sync import SensorReadings, select_readings
from gridmap_cli.poses.uncertainty.pose_uncertainty import PoseUncertainty

FloatArray = npt.NDArray[np.float64]


#: Levels the position and the heading spread are each cut into: a cell's spread is exact to
#: within one level, and the cost is one cumulative sum of the grid per level.
SPREAD_LEVELS = 128
#: Rays drawn across a wide beam (a sonar's cone), at most; one for a laser.
MAX_RAYS_PER_BEAM = 9
#: Readings turned into rays at once (memory of one batch of row runs).
_READINGS_PER_CHUNK = 50_000


@dataclass(frozen=True)
class PoseSpreadMap:
    """Per cell of ``spec`` (shape ``spec.shape``, row 0 at the bottom, NaN where no reading's
    beam crossed the cell): ``position_m``, the smallest position spread of the readings that
    crossed it, and ``heading_rad``, the heading spread of those readings. ``levels_m`` and
    ``levels_rad`` are the step of each, the precision of the values."""

    spec: GridSpec
    position_m: FloatArray
    heading_rad: FloatArray
    levels_m: float
    levels_rad: float


def _quantise(values: FloatArray, levels: int) -> tuple[npt.NDArray[np.int64], float]:
    top = float(np.max(values)) if values.size else 0.0
    if not top > 0.0:
        return np.zeros(values.shape, dtype=np.int64), 0.0
    step = top / levels
    return np.floor(values / step).astype(np.int64), step


def _beam_rays(
    readings: SensorReadings, spec: GridSpec
) -> tuple[npt.NDArray[np.int64], RaySegments]:
    """Rays across each reading's beam from its sensor to its range (the echo cell included).

    Returns the reading index of every ray, shape (R,), and the rays."""
    res = spec.resolution_m
    beam = readings.per_sensor("beam_width_rad")
    zmax = readings.per_sensor("max_range_m")
    z = np.minimum(readings.range_m, zmax)
    n_rays = np.minimum(np.ceil(beam * zmax / res).astype(np.int64) + 1, MAX_RAYS_PER_BEAM)
    index: list[npt.NDArray[np.int64]] = []
    angle: list[FloatArray] = []
    for n in np.unique(n_rays):
        pick = np.flatnonzero(n_rays == n)
        frac = np.linspace(-0.5, 0.5, int(n)) if n > 1 else np.zeros(1)
        index.append(np.repeat(pick, frac.shape[0]))
        angle.append((readings.theta_rad[pick, None] + beam[pick, None] * frac[None, :]).ravel())
    idx = np.concatenate(index) if index else np.zeros(0, dtype=np.int64)
    a = np.concatenate(angle) if angle else np.zeros(0)
    # carried a hundredth of a cell past the echo, a ray ends inside the cell it reflected from
    length = np.where(z[idx] < zmax[idx], z[idx] + 0.01 * res, z[idx])
    x0, y0 = readings.x_m[idx], readings.y_m[idx]
    return idx, RaySegments(
        x0_m=x0,
        y0_m=y0,
        x1_m=x0 + length * np.cos(a),
        y1_m=y0 + length * np.sin(a),
        echo=np.ones(idx.shape[0], dtype=bool),
    )


def reading_spreads(
    readings: SensorReadings, uncertainty: PoseUncertainty
) -> tuple[FloatArray, FloatArray]:
    """Each reading's position spread (metres: the square root of the larger eigenvalue of the
    covariance's x-y block) and heading spread (radians: the standard deviation of theta), from
    the covariance at its stamp; shape (M,) each."""
    if len(readings) == 0 or uncertainty.stamp_ns.shape[0] == 0:
        zero = np.zeros(len(readings))
        return zero, zero.copy()
    # a scan's readings share one stamp: the covariance once per run of equal stamps
    stamps = readings.stamp_ns
    starts = np.flatnonzero(np.concatenate([[True], stamps[1:] != stamps[:-1]]))
    runs = np.diff(np.append(starts, stamps.shape[0]))
    cov = uncertainty.at(stamps[starts])
    a, b, c = cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1]
    largest = 0.5 * (a + c) + np.sqrt((0.25 * (a - c) ** 2) + b * b)
    position = np.sqrt(np.maximum(largest, 0.0))
    heading = np.sqrt(np.maximum(cov[:, 2, 2], 0.0))
    return np.repeat(position, runs), np.repeat(heading, runs)


def pose_spread_map(
    spec: GridSpec,
    readings: SensorReadings,
    uncertainty: PoseUncertainty,
    levels: int = SPREAD_LEVELS,
) -> PoseSpreadMap:
    """The smallest pose spread at which each cell of ``spec`` was crossed by a reading's beam.

    ``readings`` in the map's (odometry) frame; ``uncertainty`` the pose covariance along the
    same track (:func:`~gridmap_cli.poses.uncertainty.pose_uncertainty.propagate`). Readings are
    cut into groups of one level of the position spread and one of the heading spread (``levels``
    each, from 0 to the largest); groups are drawn from the smallest position spread up and each
    cell keeps the first group that crossed it, so its values are exact to within one level.
    """
    f, g = reading_spreads(readings, uncertainty)
    qf, step_f = _quantise(f, levels)
    qg, step_g = _quantise(g, levels)
    position = np.full(spec.shape, np.nan)
    heading = np.full(spec.shape, np.nan)
    if len(readings) == 0:
        return PoseSpreadMap(spec, position, heading, step_f, step_g)
    # one group per (level of position, level of heading); drawn in increasing position, then
    # heading
    key = qf * (int(qg.max()) + 1) + qg
    for k in np.unique(key):
        members = np.flatnonzero(key == k)
        crossed = SpanSums(spec, np.int64)
        for lo in range(0, members.shape[0], _READINGS_PER_CHUNK):
            part = members[lo : lo + _READINGS_PER_CHUNK]
            _, rays = _beam_rays(select_readings(readings, part), spec)
            runs = row_runs(spec, rays)
            crossed.add(runs.row, runs.col0, runs.col1, np.ones(runs.row.shape[0], np.int64))
        new = (crossed.total() > 0) & np.isnan(position)
        position[new] = float(np.min(f[members]))
        heading[new] = float(np.min(g[members]))
    return PoseSpreadMap(spec, position, heading, step_f, step_g)


def spread_layer(
    spec: GridSpec,
    chunks: Iterable[SensorReadings],
    uncertainty: PoseUncertainty,
    known: npt.NDArray[np.bool_] | None = None,
) -> FloatArray:
    """Per cell of ``spec`` (shape ``spec.shape``, row 0 at the bottom): the mean position spread
    (metres, one standard deviation along the covariance ellipse's long axis) of the readings
    whose beam crossed the cell, each counted as often as its rays crossed it, so a cell seen
    mostly from well placed poses is well placed; NaN where no ray crossed it.

    ``chunks``: the map's readings (its frame), in any cut: the sums are whole millimetres in
    integers, so the layer does not depend on the cut. ``known`` (``spec.shape``): the map's
    known cells; when given, the layer is NaN outside them, and a known cell no ray crossed
    (between a sonar cone's rays, or reached only by a sampled track) takes the value of the
    nearest crossed cell.
    """
    total = SpanSums(spec, np.int64)
    count = SpanSums(spec, np.int64)
    # a kernel module built before ray_sums existed leaves the work to numpy
    ray_sums = getattr(compiled(), "ray_sums", None)
    for readings in chunks:
        spread_m, _ = reading_spreads(readings, uncertainty)
        spread_mm = np.rint(spread_m * 1000.0).astype(np.int64)
        for lo in range(0, len(readings), _READINGS_PER_CHUNK):
            part = select_readings(readings, slice(lo, lo + _READINGS_PER_CHUNK))
            index, rays = _beam_rays(part, spec)
            if ray_sums is not None:
                # the same integer sums as the numpy path below, without its run arrays
                r = ray_rows(spec, rays)
                ray_sums(
                    spec.width, r.ra, r.rb, r.p_lo, r.counts, r.off, r.slope, r.ua, r.ub,
                    not r.inside, np.ascontiguousarray(spread_mm[index + lo]),
                    total.difference_array(), count.difference_array(),
                )  # fmt: skip
                continue
            runs = row_runs(spec, rays)
            owner = index[runs.segment] + lo
            total.add(runs.row, runs.col0, runs.col1, spread_mm[owner])
            count.add(runs.row, runs.col0, runs.col1, np.ones(owner.shape[0], np.int64))
    crossed = count.total()
    sums = total.total()
    layer = np.full(spec.shape, np.nan)
    hit = crossed > 0
    layer[hit] = sums[hit] / crossed[hit] / 1000.0
    if known is None:
        return layer
    if hit.any() and (known & ~hit).any():
        _, (rows, cols) = ndimage.distance_transform_edt(~hit, return_indices=True)
        gap = known & ~hit
        layer[gap] = layer[rows[gap], cols[gap]]
    layer[~known] = np.nan
    return layer
