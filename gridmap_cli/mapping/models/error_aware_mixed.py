"""The error-aware mode over a log that mixes sonar cones and laser rays.

Both models write counts into one :class:`~gridmap_cli.mapping.grid.FrequencyAccumulator`, whose
trust
classes must arrive in order (class k's bound is applied when class k + 1 begins). Running the
lasers and then the sonars would bring class 0 back after the lasers closed it, so each batch is
split between the two models and their runs are added together, class by class.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from gridmap_cli.mapping.grid import FrequencyAccumulator, GridSpec
from gridmap_cli.mapping.models.error_aware import (
    ErrorAwareSonarModel,
    KernelSet,
    WeightedRuns,
    accumulate_counts,
)
from gridmap_cli.mapping.models.error_aware_ray import ErrorAwareRayModel
from gridmap_cli.mapping.models.sector import F64
from gridmap_cli.poses.sync import SensorReadings, select_readings


class ErrorAwareMixedModel:
    """Sonar readings to the error-aware sonar model, laser readings to the ray one.

    ``narrow``: per sensor of the log (shape (S,)), whether it is a laser beam.
    """

    name = "error-aware"

    def __init__(
        self,
        sonar: ErrorAwareSonarModel,
        ray: ErrorAwareRayModel,
        narrow: npt.NDArray[np.bool_],
    ) -> None:
        self.sonar = sonar
        self.ray = ray
        self.narrow = narrow
        self.params = sonar.params  # one accumulator, one cap on redundant looks

    def _parts(
        self, readings: SensorReadings
    ) -> list[tuple[ErrorAwareSonarModel | ErrorAwareRayModel, SensorReadings]]:
        """Each model with its share of ``readings``, models without readings left out."""
        sonar, ray = self._split(readings)
        return [(m, p) for m, p in ((self.sonar, sonar), (self.ray, ray)) if len(p)]

    def _split(self, readings: SensorReadings) -> tuple[SensorReadings, SensorReadings]:
        is_ray = self.narrow[readings.sensor]
        return select_readings(readings, ~is_ray), select_readings(readings, is_ray)

    def bounds(self, readings: SensorReadings) -> tuple[float, float, float, float]:
        boxes = [model.bounds(part) for model, part in self._parts(readings)]
        box: F64 = np.array(boxes)
        return (
            float(box[:, 0].min()),
            float(box[:, 1].min()),
            float(box[:, 2].max()),
            float(box[:, 3].max()),
        )

    def accumulate(self, grid: FrequencyAccumulator, readings: SensorReadings) -> int:
        """Add both kinds' counts to ``grid``, trust class by class; returns cell updates."""
        return accumulate_counts(self, grid, readings)

    def kernel_sets(
        self, spec: GridSpec, readings: SensorReadings
    ) -> tuple[KernelSet | None, KernelSet | None]:
        """Both kinds as :func:`accumulate_counts` hands them to the kernel: a class's sonar
        and laser readings go in one call, in the order :meth:`runs` concatenates them."""
        sonar, ray = self._split(readings)
        return (
            self.sonar.kernel_set(spec, sonar) if len(sonar) else None,
            self.ray.kernel_set(spec, ray) if len(ray) else None,
        )

    def runs(self, spec: GridSpec, readings: SensorReadings) -> tuple[WeightedRuns, int]:
        """Both kinds' weighted runs of cells, and the number of cell updates."""
        parts: list[WeightedRuns] = []
        updates = 0
        for model, part in self._parts(readings):
            runs, n = model.runs(spec, part)
            parts.append(runs)
            updates += n
        if not parts:
            return WeightedRuns.empty(), 0
        return WeightedRuns.concatenate(parts), updates
