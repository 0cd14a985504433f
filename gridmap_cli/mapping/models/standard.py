"""The standard inverse sonar model (Elfes; Thrun et al.'s log-odds form).

For a reading of range z from a sensor with beam width beta, the cells whose centres lie inside
the beam sector are updated as follows (``docs/sensor-model.md`` gives the reasons):

* nearer than ``z - t/2``: free evidence ``l_free = logit(p_free)``;
* within ``t/2`` of ``z`` (the obstacle band, ``t`` = obstacle thickness): occupied evidence
  ``l_occ = logit(p_occupied)``;
* beyond ``z + t/2``: nothing (the beam saw no further).

A reading at the sensor's maximum range means no echo: free evidence only, up to
``min(max_range, no_echo_free_m)``, and never occupied evidence.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gridmap_cli.mapping.grid import GridSpec, LogOddsAccumulator, logodds
from gridmap_cli.mapping.models.kernels import compiled
from gridmap_cli.mapping.models.sector import F64, sector_bounds, sector_row_range, sector_rows
from gridmap_cli.poses.sync import SensorReadings


@dataclass(frozen=True)
class StandardSonarParams:
    """Parameters of the standard model; defaults and their reasons in docs/sensor-model.md."""

    p_occupied: float = 0.55
    p_free: float = 0.43
    obstacle_thickness_m: float = 0.10
    no_echo_free_m: float = 1.0

    def __post_init__(self) -> None:
        if not 0.5 < self.p_occupied < 1.0:
            raise ValueError(f"p_occupied must be in (0.5, 1), got {self.p_occupied}")
        if not 0.0 < self.p_free < 0.5:
            raise ValueError(f"p_free must be in (0, 0.5), got {self.p_free}")
        if not (self.obstacle_thickness_m > 0 and math.isfinite(self.obstacle_thickness_m)):
            raise ValueError("obstacle thickness must be a positive number of metres")
        if not (self.no_echo_free_m >= 0 and math.isfinite(self.no_echo_free_m)):
            raise ValueError("the no-echo free range must be >= 0 metres")

    def band_half_m(self, resolution_m: float) -> float:
        """Half the obstacle band: never thinner than a cell diagonal, so no arc has gaps."""
        return 0.5 * max(self.obstacle_thickness_m, math.sqrt(2.0) * resolution_m)


@dataclass(frozen=True)
class SectorEvidence:
    """Per-reading geometry and evidence, shape (M,) each: nested disks cut by the beam wedge.

    Every reading adds ``inner_value`` to cells within ``inner_m`` and ``outer_value`` to cells
    within ``outer_m`` (``inner_m <= outer_m``), so cells in the ring between get ``outer_value``
    and cells inside get both. ``outer_m`` is also the reach whose cells count as observed.
    """

    x_m: F64
    y_m: F64
    theta_rad: F64
    half_width_rad: F64
    inner_m: F64
    inner_value: F64
    outer_m: F64
    outer_value: F64


class StandardSonarModel:
    """The standard model over batches of synchronised readings."""

    name = "standard"

    def __init__(self, params: StandardSonarParams, resolution_m: float) -> None:
        self.params = params
        self.resolution_m = resolution_m
        self.l_occ = logodds(params.p_occupied)
        self.l_free = logodds(params.p_free)

    def evidence(self, readings: SensorReadings) -> SectorEvidence:
        """Sector geometry and log-odds values for each reading."""
        p = self.params
        z = readings.range_m
        zmax = readings.per_sensor("max_range_m")
        half_w = 0.5 * readings.per_sensor("beam_width_rad")
        echo = z < zmax
        band = p.band_half_m(self.resolution_m)
        free_reach = np.where(echo, z - band, np.minimum(zmax, p.no_echo_free_m))
        outer = np.where(echo, z + band, free_reach)
        return SectorEvidence(
            x_m=readings.x_m,
            y_m=readings.y_m,
            theta_rad=readings.theta_rad,
            half_width_rad=half_w,
            inner_m=np.maximum(free_reach, 0.0),
            # inside the free reach the occupied value below is cancelled and replaced by l_free
            inner_value=np.where(echo, self.l_free - self.l_occ, self.l_free),
            outer_m=outer,
            outer_value=np.where(echo, self.l_occ, 0.0),
        )

    def bounds(self, readings: SensorReadings) -> tuple[float, float, float, float]:
        """Box holding every cell any reading can touch."""
        ev = self.evidence(readings)
        return sector_bounds(ev.x_m, ev.y_m, ev.theta_rad, ev.half_width_rad, ev.outer_m)

    def accumulate(self, grid: LogOddsAccumulator, readings: SensorReadings) -> int:
        """Add the evidence of ``readings`` to ``grid``; returns the number of cell updates."""
        ev = self.evidence(readings)
        return accumulate_sectors(grid, ev)


def accumulate_sectors(grid: LogOddsAccumulator, ev: SectorEvidence) -> int:
    """Add nested-sector evidence to ``grid``; returns cells touched (outer sectors).

    The compiled kernel when it pays (:mod:`gridmap_cli.mapping.models.kernels`), else the numpy
    reference, :func:`accumulate_sectors_numpy`: the same grid bit for bit.
    """
    kernels = compiled()
    if kernels is None:
        return accumulate_sectors_numpy(grid, ev)
    spec: GridSpec = grid.spec
    j0, counts, right, left = sector_row_range(
        spec, ev.y_m, ev.theta_rad, ev.half_width_rad, ev.outer_m
    )
    values, observations = grid.difference_arrays()
    f64 = np.ascontiguousarray
    return int(
        kernels.sector_batch(
            spec.origin_x_m, spec.origin_y_m, spec.resolution_m, spec.width, spec.height,
            f64(ev.x_m), f64(ev.y_m), np.sin(right), np.cos(right), np.sin(left), np.cos(left),
            j0, counts, f64(ev.outer_m), f64(ev.outer_value), f64(ev.inner_m),
            f64(ev.inner_value), grid.scale, grid.rows[0], values, observations,
        )
    )  # fmt: skip


def accumulate_sectors_numpy(grid: LogOddsAccumulator, ev: SectorEvidence) -> int:
    """:func:`accumulate_sectors` in numpy: the reference the compiled kernel must equal."""
    spec: GridSpec = grid.spec
    rows = sector_rows(spec, ev.x_m, ev.y_m, ev.theta_rad, ev.half_width_rad, ev.outer_m)
    outer = rows.spans(ev.outer_m)
    grid.add_observations(outer.row, outer.col0, outer.col1)
    nonzero = ev.outer_value[outer.reading] != 0.0
    grid.add_values(
        outer.row[nonzero],
        outer.col0[nonzero],
        outer.col1[nonzero],
        ev.outer_value[outer.reading][nonzero],
    )
    inner = rows.spans(ev.inner_m)
    grid.add_values(inner.row, inner.col0, inner.col1, ev.inner_value[inner.reading])
    return outer.cells()
