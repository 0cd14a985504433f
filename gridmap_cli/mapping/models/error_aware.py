"""The error-aware sonar model: the seed paper's eq. 10-12, made into per-cell counts.

Each reading's range and bearing spread grow with the odometry error accumulated since the log
started (eq. 11, 12)::

    sigma_z     = k * z + f(d)            range spread, metres
    sigma_theta = beta / 2 + g(d, phi)    bearing spread (half-width), radians

where ``d`` and ``phi`` are the distance driven and the rotation turned so far. The reading is
then spread over the cells it may have come from, keeping its total evidence constant, and
weighed by how well its pose is known. Cells hold weighted counts of echoes and looks
(:class:`~gridmap_cli.mapping.grid.FrequencyAccumulator`), so redundant readings refine a frequency
instead of piling up log-odds. docs/sensor-model.md derives every step and gives the defaults.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from gridmap_cli.mapping.grid import FrequencyAccumulator, GridSpec
from gridmap_cli.mapping.models.kernels import compiled
from gridmap_cli.mapping.models.sector import F64, I64, sector_bounds, sector_row_range, sector_rows
from gridmap_cli.mapping.models.standard import StandardSonarParams
from gridmap_cli.poses.sync import SensorReadings, select_readings


class OdometrySpread(Protocol):
    """What the model needs of an odometry-error model (eq. 11 and 12)."""

    @property
    def sonar_relative_error(self) -> float:
        """k of eq. 11: the sonar's own relative range error (0.01 for the Polaroid 6500)."""
        ...

    def f(self, distance_m: F64) -> F64:
        """Range spread (metres) after driving ``distance_m``."""
        ...

    def g(self, distance_m: F64, rotation_rad: F64) -> F64:
        """Bearing spread (radians) after driving ``distance_m`` and turning ``rotation_rad``."""
        ...


@dataclass(frozen=True)
class ErrorAwareParams:
    """Parameters of the error-aware model beyond the odometry error; see docs/sensor-model.md.

    ``trust_length_m``: the pose error at which a reading counts half as much as one taken with a
    perfectly known pose (weight ``L^2 / (L^2 + f^2)``).
    ``redundant_looks``: C, bounding what readings of one trust class (weights within a factor of
    two, w in (2^-(k+1), 2^-k]) may add to a cell: C * 4^-k looks, i.e. C readings' worth at the
    class's weight, counted once more at that weight because readings sharing a pose error
    repeat one another's mistake; ``inf`` for no bound (docs/sensor-model.md).
    ``max_heading_spread_rad``: readings whose bearing spread from the odometry, g, exceeds this
    are left out (weight 0) instead of spread over a wedge so wide it says nothing about any one
    cell; ``inf`` keeps every reading (docs/sensor-model.md, "Readings beyond the spread limit").
    ``laser_relative_error``: k of eq. 11 for laser rays (the sonar's is in the odometry-error
    file, where the seed paper put it); ``laser_no_echo_free_m``: metres of free space a laser's
    no-echo reading clears, capped at its maximum range (as ``RayParams.no_echo_free_m``).
    """

    trust_length_m: float = 0.3
    redundant_looks: float = 30.0
    # no limit by default, the paper's behaviour: every limit tried (30, 60, 90 degrees) made
    # the simulated claim and the CARMEN logs worse (docs/sensor-model.md)
    max_heading_spread_rad: float = math.inf
    laser_relative_error: float = 0.005
    laser_no_echo_free_m: float = math.inf

    def __post_init__(self) -> None:
        if not (self.trust_length_m > 0 and math.isfinite(self.trust_length_m)):
            raise ValueError("the trust length must be a positive number of metres")
        if not self.redundant_looks > 0:
            raise ValueError("the redundant-looks bound must be a positive number")
        if not self.max_heading_spread_rad > 0:
            raise ValueError("the heading-spread limit must be a positive angle")
        if not (self.laser_relative_error >= 0 and math.isfinite(self.laser_relative_error)):
            raise ValueError("the laser's relative range error must be a finite number >= 0")
        if not self.laser_no_echo_free_m >= 0:
            raise ValueError("the laser's no-echo free range must be >= 0 metres")


@dataclass(frozen=True)
class SpreadEvidence:
    """Per-reading geometry and weights, shape (M,) each.

    Every reading adds ``weight`` to the observation mass, and ``weight * hit`` to the hit mass,
    of the cells of its wide wedge (``half_width_rad``) between ``free_m`` and ``look_m`` (the
    echo ring); and ``weight`` to the observation mass of the cells of its narrow wedge
    (``free_half_width_rad``) nearer than ``free_m`` (looked through). No-echo readings have
    ``hit == 0`` and ``free_m == look_m``.
    """

    x_m: F64
    y_m: F64
    theta_rad: F64
    half_width_rad: F64
    free_half_width_rad: F64
    free_m: F64
    look_m: F64
    hit: F64
    weight: F64


class ErrorAwareSonarModel:
    """The error-aware model over batches of synchronised readings."""

    name = "error-aware"

    def __init__(
        self,
        sonar: StandardSonarParams,
        params: ErrorAwareParams,
        odometry: OdometrySpread,
        resolution_m: float,
    ) -> None:
        self.sonar = sonar
        self.params = params
        self.odometry = odometry
        self.resolution_m = resolution_m

    def evidence(self, readings: SensorReadings) -> SpreadEvidence:
        """Spread, sector and weights of each reading (docs/sensor-model.md, "Error-aware")."""
        d, phi = readings.distance_m, readings.rotation_rad
        if d is None or phi is None:
            raise ValueError("the error-aware model needs the distance driven for each reading")
        z = readings.range_m
        zmax = readings.per_sensor("max_range_m")
        beam_half = 0.5 * readings.per_sensor("beam_width_rad")
        echo = z < zmax
        f = np.asarray(self.odometry.f(d), dtype=np.float64)
        g = np.asarray(self.odometry.g(d, phi), dtype=np.float64)
        h = self.sonar.band_half_m(self.resolution_m)
        sigma_z = self.odometry.sonar_relative_error * z + f  # eq. 11
        half_width = np.minimum(beam_half + g, 0.5 * math.pi - 1e-9)  # eq. 12, kept convex
        # the obstacle band (half-thickness h) blurred by the range spread
        band = np.sqrt(h * h + sigma_z * sigma_z)
        # one echo's worth of hit mass spread over a band `band/h` times deeper and a wedge
        # `half_width/beam_half` times wider: the evidence a reading carries stays constant
        hit = np.where(echo, (h / band) * (beam_half / half_width), 0.0)
        weight = trust_weight(f, self.params.trust_length_m)
        free = np.where(echo, z - band, np.minimum(zmax, self.sonar.no_echo_free_m))
        look = np.where(echo, z + h, free)
        # looked through whichever way the heading erred: the wedge narrowed by g
        free_half = np.maximum(beam_half - g, 0.0)
        return SpreadEvidence(
            x_m=readings.x_m,
            y_m=readings.y_m,
            theta_rad=readings.theta_rad,
            half_width_rad=half_width,
            free_half_width_rad=free_half,
            free_m=np.maximum(free, 0.0),
            look_m=look,
            hit=hit,
            weight=weight,
        )

    def bounds(self, readings: SensorReadings) -> tuple[float, float, float, float]:
        """Box holding every cell any reading can touch."""
        ev = self.evidence(readings)
        return sector_bounds(ev.x_m, ev.y_m, ev.theta_rad, ev.half_width_rad, ev.look_m)

    def accumulate(self, grid: FrequencyAccumulator, readings: SensorReadings) -> int:
        """Add the readings' counts to ``grid``; returns the number of cell updates."""
        return accumulate_counts(self, grid, readings)

    def kernel_sets(
        self, spec: GridSpec, readings: SensorReadings
    ) -> tuple[KernelSet | None, KernelSet | None]:
        """(sonar, laser) as :func:`accumulate_counts` hands them to the kernel."""
        return self.kernel_set(spec, readings), None

    def kernel_set(self, spec: GridSpec, readings: SensorReadings) -> KernelSet | None:
        """The readings as the compiled kernel takes them (its ``SONAR_NAMES``), with their
        trust classes; None when no reading is within the spread limit."""
        readings = within_spread(readings, self.odometry, self.params.max_heading_spread_rad)
        if len(readings) == 0:
            return None
        ev = self.evidence(readings)
        wide = sector_row_range(
            spec, ev.y_m, ev.theta_rad, ev.half_width_rad, ev.look_m, inner_m=ev.free_m
        )
        narrow = sector_row_range(spec, ev.y_m, ev.theta_rad, ev.free_half_width_rad, ev.free_m)
        arrays: list[F64 | I64] = [ev.x_m, ev.y_m]
        for j0, counts, right, left in (wide, narrow):
            arrays += [np.sin(right), np.cos(right), np.sin(left), np.cos(left), j0, counts]
        arrays += [ev.look_m, ev.free_m, ev.weight, ev.hit]
        return KernelSet(trust_class(ev.weight), arrays)

    def runs(self, spec: GridSpec, readings: SensorReadings) -> tuple[WeightedRuns, int]:
        """The readings' weighted runs of cells, and the number of cell updates."""
        readings = within_spread(readings, self.odometry, self.params.max_heading_spread_rad)
        if len(readings) == 0:
            return WeightedRuns.empty(), 0
        ev = self.evidence(readings)
        # only the rows of the echo ring: nearer rows hold the inner disk alone, which the
        # ring's two spans would add and take away again
        wide = sector_rows(
            spec, ev.x_m, ev.y_m, ev.theta_rad, ev.half_width_rad, ev.look_m, inner_m=ev.free_m
        )
        narrow = sector_rows(spec, ev.x_m, ev.y_m, ev.theta_rad, ev.free_half_width_rad, ev.free_m)
        # the echo ring (free_m, look_m] of the wide wedge: the wide disk (sign +1) less its
        # inner disk (-1), looked at and maybe hit; and the narrow wedge up to free_m (+1),
        # looked through whichever way the pose erred
        outer = wide.spans(ev.look_m)
        parts = (outer, wide.spans(ev.free_m), narrow.spans(ev.free_m))
        signs = (1, -1, 1)
        ring = (True, True, False)
        runs = weighted_runs(
            [
                (p.reading, p.row, p.col0, p.col1, v, r)
                for p, v, r in zip(parts, signs, ring, strict=True)
            ],
            ev.weight,
            ev.hit,
        )
        return runs, outer.cells()


@dataclass(frozen=True)
class KernelSet:
    """One model's share of a batch as the compiled ``spread_batch`` takes it: per-reading
    arrays in the kernel's order, each reading's trust class (M,), and for lasers whether runs
    must be cut to the grid's columns."""

    trust_class: I64
    arrays: list[F64 | I64]
    clip: bool = False

    def of_class(self, k: int, only: bool) -> tuple[npt.NDArray[Any], ...] | None:
        """The arrays of the readings of class ``k`` (all when ``only``), or None if none."""
        if only:
            return tuple(np.ascontiguousarray(a) for a in self.arrays)
        keep = self.trust_class == k
        if not keep.any():
            return None
        return tuple(np.ascontiguousarray(a[keep]) for a in self.arrays)


class CountingModel(Protocol):
    """What :func:`accumulate_counts` needs of an error-aware model (sonar, laser or both)."""

    params: ErrorAwareParams

    def runs(self, spec: GridSpec, readings: SensorReadings) -> tuple[WeightedRuns, int]: ...

    def kernel_sets(
        self, spec: GridSpec, readings: SensorReadings
    ) -> tuple[KernelSet | None, KernelSet | None]: ...


def accumulate_counts(
    model: CountingModel, grid: FrequencyAccumulator, readings: SensorReadings
) -> int:
    """Add a batch's counts to ``grid``; returns the cell updates. The compiled kernel when it
    is built (:mod:`gridmap_cli.mapping.models.kernels`), else the numpy reference, the model's runs
    and :func:`add_runs`: the same grid bit for bit."""
    kernels = compiled()
    if kernels is None:
        runs, updates = model.runs(grid.spec, readings)
        add_runs(grid, runs, model.params.redundant_looks)
        return updates
    sonar, laser = model.kernel_sets(grid.spec, readings)
    return accumulate_sets(kernels, grid, model.params.redundant_looks, sonar, laser)


def accumulate_sets(
    kernels: Any,
    grid: FrequencyAccumulator,
    redundant_looks: float,
    sonar: KernelSet | None = None,
    laser: KernelSet | None = None,
) -> int:
    """Sonar and laser readings of one batch into ``grid``, one kernel call per trust class in
    class order, class k capped at C * 4^-k looks (:func:`add_runs`): the reference's runs in
    the reference's order (each class's sonar runs, then its laser runs, as
    :class:`~gridmap_cli.mapping.models.error_aware_mixed.ErrorAwareMixedModel` concatenates them),
    so the same sums to the bit. Returns the cell updates."""
    sets = [x for x in (sonar, laser) if x is not None]
    if not sets:
        return 0
    classes = np.unique(np.concatenate([x.trust_class for x in sets]))
    only = len(classes) == 1
    spec = grid.spec
    updates = 0
    for k in classes.tolist():
        sums = grid.difference_arrays(cap=redundant_looks * 4.0 ** -float(k))
        updates += int(
            kernels.spread_batch(
                spec.origin_x_m, spec.origin_y_m, spec.resolution_m, spec.width, spec.height,
                None if sonar is None else sonar.of_class(k, only),
                None if laser is None else laser.of_class(k, only),
                laser is not None and laser.clip, *sums,
            )
        )  # fmt: skip
    return updates


@dataclass(frozen=True)
class WeightedRuns:
    """Runs of cells ``[col0, col1]`` of ``row`` with what each adds to every cell it covers,
    shape (S,) each: ``look`` observation mass, ``hit`` hit mass, ``seen`` looks counted (+1, or
    -1 for the inner disk taken away from a ring), and the ``trust_class`` of its reading."""

    row: I64
    col0: I64
    col1: I64
    look: F64
    hit: F64
    seen: I64
    trust_class: I64

    @staticmethod
    def empty() -> WeightedRuns:
        i, f = np.zeros(0, np.int64), np.zeros(0, np.float64)
        return WeightedRuns(i, i, i, f, f, i, i)

    @staticmethod
    def concatenate(parts: Sequence[WeightedRuns]) -> WeightedRuns:
        return WeightedRuns(
            *(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(WeightedRuns))
        )


def within_spread(
    readings: SensorReadings, odometry: OdometrySpread, max_heading_spread_rad: float
) -> SensorReadings:
    """The readings whose bearing spread from the odometry, g, is within the limit: the others
    weigh 0. g only grows as the odometry drives on, so this keeps a prefix of the log."""
    d, phi = readings.distance_m, readings.rotation_rad
    if d is None or phi is None or not math.isfinite(max_heading_spread_rad):
        return readings
    keep = np.asarray(odometry.g(d, phi)) <= max_heading_spread_rad
    return readings if bool(keep.all()) else select_readings(readings, keep)


def trust_weight(f_m: F64, trust_length_m: float) -> F64:
    """``L^2 / (L^2 + f^2)``: how much a reading taken with pose error ``f_m`` counts (M,)."""
    return trust_length_m * trust_length_m / (trust_length_m * trust_length_m + f_m * f_m)


def trust_class(weight: F64) -> I64:
    """Each reading's trust class (M,): class k holds weights in (2^-(k+1), 2^-k]."""
    return np.floor(-np.log2(weight)).astype(np.int64)


def weighted_runs(
    parts: Sequence[tuple[I64, I64, I64, I64, int, bool]],
    weight: F64,
    hit: F64,
    ring_look: F64 | None = None,
) -> WeightedRuns:
    """Runs from ``(reading, row, col0, col1, sign, in_ring)`` parts: each run adds ``sign *
    weight`` looks of its reading (times ``ring_look`` in its ring, when given), and in its ring
    that times the reading's ``hit`` as hit mass. Arrays over readings shape (M,)."""
    looks = []
    hits = []
    for reading, _, _, _, sign, in_ring in parts:
        look = sign * weight[reading]
        if in_ring:
            if ring_look is not None:
                look = look * ring_look[reading]
            hits.append(look * hit[reading])
        else:
            hits.append(np.zeros_like(look))
        looks.append(look)
    reading = np.concatenate([p[0] for p in parts])
    reading_class = trust_class(weight)
    return WeightedRuns(
        row=np.concatenate([p[1] for p in parts]),
        col0=np.concatenate([p[2] for p in parts]),
        col1=np.concatenate([p[3] for p in parts]),
        look=np.concatenate(looks),
        hit=np.concatenate(hits),
        seen=np.concatenate([np.full(len(p[0]), p[4], np.int64) for p in parts]),
        trust_class=reading_class[reading],
    )


def add_runs(grid: FrequencyAccumulator, runs: WeightedRuns, redundant_looks: float) -> None:
    """Add ``runs`` to ``grid``, trust class by class, class k capped at C * 4^-k looks.

    Readings arrive in time order and the weight only falls as the odometry drives on, so
    classes arrive one after another (a batch mostly holds one); the classes of one batch are
    added in increasing order.
    """
    classes = np.unique(runs.trust_class)
    for k in classes:
        keep = slice(None) if len(classes) == 1 else runs.trust_class == k
        grid.add(
            runs.row[keep],
            runs.col0[keep],
            runs.col1[keep],
            look=runs.look[keep],
            hit=runs.hit[keep],
            seen=runs.seen[keep],
            cap=redundant_looks * 4.0 ** -float(k),
        )
