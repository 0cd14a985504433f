"""The error-aware model for laser rays: the seed paper's eq. 10-12 with the laser's own beta and k.

A laser beam is a ray, and a scan is a fan of rays one angular step apart. docs/sensor-model.md
("Error-aware lasers") derives the model; in short, a reading of range z taken after the
odometry drove d and turned phi has

    sigma_z     = k z + f(d)                       eq. 11, k the laser's relative range error
    sigma_theta = beta / 2 + g(d, phi)             eq. 12, beta = the scan's angular step

and gives, with weight ``w = L^2 / (L^2 + f^2)`` (as the sonar model):

* **hit**: the cells of the wedge of half-angle ``max(sigma_theta, atan(h / z))`` between
  ``z - b`` and ``z + h`` (``b = sqrt(h^2 + sigma_z^2)``) are looked at, with hit
  ``a = (h / b) * (beta0 / sigma_theta)`` so the reading's hit mass is not multiplied by its
  spread (``beta0`` the unspread half-angle);
* **looked through**: the cells of the beam's own line up to ``min_j (z_j - b_j)`` over the beams
  j of the same scan within ``g`` of it. With a heading error of up to g the scan is rotated by up
  to g, so the cell the odometry puts on beam i was really crossed by one of those beams; only
  the nearest of their echoes says for sure that the cell is free. This is the laser form of the
  sonar's "narrowed wedge" (``beta/2 - g``), which a one-step-wide beam would lose at once.

The free part is the ray model's exact traversal, the hit part a sector ring (the sonar model's
machinery), so a reading costs about what a standard ray and a short sector cost.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from gridmap_cli.mapping.grid import FrequencyAccumulator, GridSpec
from gridmap_cli.mapping.models.error_aware import (
    ErrorAwareParams,
    KernelSet,
    OdometrySpread,
    WeightedRuns,
    accumulate_counts,
    trust_class,
    trust_weight,
    weighted_runs,
    within_spread,
)
from gridmap_cli.mapping.models.ray import RaySegments, ray_rows, row_runs
from gridmap_cli.mapping.models.sector import F64, I64, sector_bounds, sector_row_range, sector_rows
from gridmap_cli.poses.sync import SensorReadings
from gridmap_cli.robot import RangeSensor

#: The angular step assumed for a laser beam that belongs to no scan (a lone ray sensor): one
#: degree, the coarsest step of the SICK LMS 200 that the CARMEN logs use.
LONE_BEAM_STEP_RAD = math.radians(1.0)


@dataclass(frozen=True)
class ScanLayout:
    """Which scan each sensor's beam belongs to, shape (S,) over the log's sensors.

    ``scan``: an id shared by the beams of one scanning laser (-1 for a sensor that is no laser
    beam); ``beam``: the beam's index in its scan, ordered by bearing; ``step_rad``: the scan's
    angular step (beta of eq. 12, at least the beam's own width); ``beams``: the most beams of
    any scan.
    """

    scan: I64
    beam: I64
    step_rad: F64
    beams: int

    @classmethod
    def of(cls, sensors: tuple[RangeSensor, ...], narrow: npt.NDArray[np.bool_]) -> ScanLayout:
        """Group the narrow-beam sensors ``<laser>_<i>`` by laser, ordered by yaw."""
        groups: dict[tuple[str, float, float], list[int]] = {}
        for i, s in enumerate(sensors):
            if narrow[i]:
                base, sep, index = s.name.rpartition("_")
                key = (base if sep and index.isdigit() else s.name, s.x_m, s.y_m)
                groups.setdefault(key, []).append(i)
        scan = np.full(len(sensors), -1, dtype=np.int64)
        beam = np.zeros(len(sensors), dtype=np.int64)
        step = np.zeros(len(sensors), dtype=np.float64)
        most = 1
        for g, members in enumerate(groups.values()):
            yaw = np.unwrap(np.array([sensors[i].yaw_rad for i in members]))
            order = np.argsort(yaw, kind="stable")
            gaps = np.diff(yaw[order])
            gaps = gaps[gaps > 1e-9]
            scan_step = float(np.median(gaps)) if gaps.size else LONE_BEAM_STEP_RAD
            for rank, k in enumerate(order):
                i = members[int(k)]
                scan[i] = g
                beam[i] = rank
                step[i] = max(scan_step, sensors[i].beam_width_rad)
            most = max(most, len(members))
        return cls(scan, beam, step, most)


@dataclass(frozen=True)
class RayEvidence:
    """Per-reading geometry and weights, shape (M,) each: the hit ring (wedge ``half_width_rad``
    between ``ring_in_m`` and ``look_m``, hit ``hit``; empty for a no-echo reading) and the
    looked-through segment along the beam up to ``free_m``; every run weighs ``weight``."""

    x_m: F64
    y_m: F64
    theta_rad: F64
    half_width_rad: F64
    ring_in_m: F64
    look_m: F64
    free_m: F64
    hit: F64
    ring_look: F64
    weight: F64


class ErrorAwareRayModel:
    """The error-aware model for readings of narrow-beam sensors (lasers)."""

    name = "error-aware-ray"

    def __init__(
        self,
        params: ErrorAwareParams,
        odometry: OdometrySpread,
        layout: ScanLayout,
        band_half_m: float,
    ) -> None:
        self.params = params
        self.odometry = odometry
        self.layout = layout
        self.h = band_half_m

    def evidence(self, readings: SensorReadings) -> RayEvidence:
        """Spread, hit ring, free reach and weight of each reading (module docstring)."""
        d, phi = readings.distance_m, readings.rotation_rad
        if d is None or phi is None:
            raise ValueError("the error-aware model needs the distance driven for each reading")
        h = self.h
        z = readings.range_m
        zmax = readings.per_sensor("max_range_m")
        echo = z < zmax
        f = np.asarray(self.odometry.f(d), dtype=np.float64)
        g = np.asarray(self.odometry.g(d, phi), dtype=np.float64)
        step = self.layout.step_rad[readings.sensor]
        sigma_z = self.params.laser_relative_error * z + f  # eq. 11
        band = np.sqrt(h * h + sigma_z * sigma_z)
        # the ring is never narrower than the band is deep, so it always holds a cell centre
        # (h is at least half a cell diagonal) however near the echo
        min_half = np.arctan2(h, np.maximum(z, h))
        half0 = np.maximum(0.5 * step, min_half)
        half = np.minimum(np.maximum(0.5 * step + g, min_half), 0.5 * math.pi - 1e-9)  # eq. 12
        # a scan is a fan: widened by g, the rings of about half/half0 neighbouring beams cover
        # each cell, so each beam's ring counts half0/half of a look there (the scan still looks
        # at a wall once per pass), and its hit is the depth share h/b of that
        ring_look = half0 / half
        hit = np.where(echo, h / band, 0.0)
        reach = np.where(echo, z - band, np.minimum(zmax, self.params.laser_no_echo_free_m))
        free = self._nearest_echo_within(readings, np.maximum(reach, 0.0), g / step)
        return RayEvidence(
            x_m=readings.x_m,
            y_m=readings.y_m,
            theta_rad=readings.theta_rad,
            half_width_rad=half,
            ring_in_m=np.where(echo, np.maximum(z - band, 0.0), 0.0),
            look_m=np.where(echo, z + h, 0.0),
            free_m=free,
            hit=hit,
            ring_look=ring_look,
            weight=trust_weight(f, self.params.trust_length_m),
        )

    def _nearest_echo_within(self, readings: SensorReadings, reach: F64, beams: F64) -> F64:
        """Per reading, the least ``reach`` of the readings of its scan (same laser, same stamp)
        whose beam lies within ``beams`` steps (shape (M,)) of its own; beams absent from the
        batch (left out as no echo, or in another batch) do not limit it."""
        n = len(readings)
        if n == 0:
            return reach
        scan_of = self.layout.scan[readings.sensor]
        beam_of = self.layout.beam[readings.sensor]
        width = self.layout.beams
        # one row per (stamp, laser): its beams in a dense table, absent ones at +inf
        key = readings.stamp_ns.astype(np.int64) * (int(scan_of.max()) + 2) + scan_of
        _, row = np.unique(key, return_inverse=True)
        table = np.full((int(row.max()) + 1, width), np.inf)
        table[row, beam_of] = reach
        window = np.ceil(np.maximum(beams, 0.0) - 1e-9).astype(np.int64)
        window = np.minimum(window, width)
        row_window = np.zeros(table.shape[0], dtype=np.int64)
        row_window[row] = window  # one stamp, one pose: one window per row
        from scipy import ndimage  # 0.1 s to import: only error-aware laser builds pay it

        out = table.copy()
        for w in np.unique(row_window):
            if w == 0:
                continue
            rows = row_window == w
            out[rows] = ndimage.minimum_filter1d(
                table[rows], size=int(2 * w + 1), axis=1, mode="constant", cval=np.inf
            )
        nearest: F64 = np.minimum(out[row, beam_of], reach)
        return nearest

    def bounds(self, readings: SensorReadings) -> tuple[float, float, float, float]:
        """Box holding every cell any reading can touch (rings and segments, sensors included)."""
        ev = self.evidence(readings)
        reach = np.maximum(ev.look_m, ev.free_m)
        return sector_bounds(ev.x_m, ev.y_m, ev.theta_rad, ev.half_width_rad, reach)

    def accumulate(self, grid: FrequencyAccumulator, readings: SensorReadings) -> int:
        """Add the readings' counts to ``grid``; returns the number of cell updates."""
        return accumulate_counts(self, grid, readings)

    def kernel_sets(
        self, spec: GridSpec, readings: SensorReadings
    ) -> tuple[KernelSet | None, KernelSet | None]:
        """(sonar, laser) as :func:`accumulate_counts` hands them to the kernel."""
        return None, self.kernel_set(spec, readings)

    def kernel_set(self, spec: GridSpec, readings: SensorReadings) -> KernelSet | None:
        """The readings as the compiled kernel takes them (its ``LASER_NAMES``), with their
        trust classes; None when no reading is within the spread limit."""
        readings = within_spread(readings, self.odometry, self.params.max_heading_spread_rad)
        if len(readings) == 0:
            return None
        ev = self.evidence(readings)
        rows = ray_rows(spec, self._segments(ev))
        # readings without echo have no ring: look_m == 0 gives them no rows
        j0, counts, right, left = sector_row_range(
            spec, ev.y_m, ev.theta_rad, ev.half_width_rad, ev.look_m, inner_m=ev.ring_in_m
        )
        ring_look = ev.weight * ev.ring_look
        arrays: list[F64 | I64] = [
            rows.ra, rows.rb, rows.p_lo, rows.counts, rows.off, rows.slope, rows.ua, rows.ub,
            ev.weight, ev.x_m, ev.y_m, np.sin(right), np.cos(right), np.sin(left),
            np.cos(left), j0, counts, ev.look_m, ev.ring_in_m, ring_look, ring_look * ev.hit,
        ]  # fmt: skip
        # cut to the grid's columns unless every segment lies within them (as row_runs)
        return KernelSet(trust_class(ev.weight), arrays, clip=not rows.inside)

    @staticmethod
    def _segments(ev: RayEvidence) -> RaySegments:
        """The looked-through segment of each reading's beam, up to ``free_m``."""
        c, s = np.cos(ev.theta_rad), np.sin(ev.theta_rad)
        return RaySegments(
            x0_m=ev.x_m,
            y0_m=ev.y_m,
            x1_m=ev.x_m + ev.free_m * c,
            y1_m=ev.y_m + ev.free_m * s,
            echo=np.zeros(len(ev.x_m), dtype=bool),  # free space only: no end cell
        )

    def runs(self, spec: GridSpec, readings: SensorReadings) -> tuple[WeightedRuns, int]:
        """The readings' weighted runs of cells, and the number of cell updates."""
        readings = within_spread(readings, self.odometry, self.params.max_heading_spread_rad)
        if len(readings) == 0:
            return WeightedRuns.empty(), 0
        ev = self.evidence(readings)
        free = row_runs(spec, self._segments(ev))
        echo = ev.look_m > 0.0
        idx = np.flatnonzero(echo)
        wide = sector_rows(
            spec, ev.x_m[idx], ev.y_m[idx], ev.theta_rad[idx], ev.half_width_rad[idx],
            ev.look_m[idx], inner_m=ev.ring_in_m[idx],
        )  # fmt: skip
        outer = wide.spans(ev.look_m[idx])
        inner = wide.spans(ev.ring_in_m[idx])
        runs = weighted_runs(
            [
                (free.segment, free.row, free.col0, free.col1, 1, False),
                (idx[outer.reading], outer.row, outer.col0, outer.col1, 1, True),
                (idx[inner.reading], inner.row, inner.col0, inner.col1, -1, True),
            ],
            ev.weight,
            ev.hit,
            ring_look=ev.ring_look,
        )
        return runs, free.cells() + outer.cells() - inner.cells()
