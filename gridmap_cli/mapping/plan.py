"""What a build has settled before it maps a reading (:class:`BuildPlan`), and what it needs of a
sensor model (:class:`SensorModel`).

Its own module so that the pipeline, which makes plans, and the shards, which map them on one
process or several, both import it and not each other.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import InputFileError
from gridmap_cli.mapping.grid import GridSpec
from gridmap_cli.poses.sync import SensorReadings, SyncStats, select_readings, synchronise
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import RobotDescription


class SensorModel(Protocol):
    """What the pipeline needs of a sensor model."""

    def bounds(self, readings: SensorReadings) -> tuple[float, float, float, float]:
        """Box (xmin, ymin, xmax, ymax), metres, holding every cell the readings can touch."""
        ...

    def accumulate(self, grid: Any, readings: SensorReadings) -> int:
        """Add the readings' evidence to ``grid`` (a :class:`LogOddsAccumulator`); returns the
        number of cell updates."""
        ...


@dataclass(frozen=True)
class BuildPlan:
    """What build has settled before it maps a reading: the sync's result, each sensor model
    and the kind of sensor it maps, and the grid that holds them all. :meth:`parts` gives the
    readings, synchronised again chunk by chunk, to the models."""

    sync: SyncStats
    models: list[tuple[SensorModel, str]]  # (model, "ray" | "sonar" | "all")
    spec: GridSpec
    log: RangeLog
    robot: RobotDescription | None
    chunks: list[tuple[int, int]]  # [start, stop) of log readings, cut where the stamp changes
    narrow: npt.NDArray[np.bool_]  # per sensor: mapped as a ray
    chunk_readings: int  # the size the chunks were cut at (the pipeline's SYNC_CHUNK_READINGS)
    #: distance and rotation driven at each pose (:func:`odometry_error.travelled`)
    travelled: tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]] | None = None

    def parts(self) -> Iterator[tuple[SensorModel, SensorReadings]]:
        """Each model with its share of the readings, chunk after chunk, in time order: the
        log's chunks again (read again from the file when the log streams them)."""
        chunks = self.log.reading_chunks(self.chunk_readings)
        for (start, stop), chunk in itertools.zip_longest(self.chunks, chunks):
            if chunk is None or len(chunk) != stop - start:
                raise InputFileError(self.log.source, "the file changed while gridmap read it")
            readings, _ = synchronise(self.log, self.robot, chunk, self.travelled)
            yield from split_by_kind(self.models, self.narrow, readings)


def split_by_kind(
    models: list[tuple[SensorModel, str]], narrow: npt.NDArray[np.bool_], readings: SensorReadings
) -> Iterator[tuple[SensorModel, SensorReadings]]:
    """Each model with the readings of its kind: rays (``narrow`` sensors), sonar or all."""
    is_ray = narrow[readings.sensor]
    for model, kind in models:
        if kind == "all":
            part = readings
        else:
            part = select_readings(readings, is_ray if kind == "ray" else ~is_ray)
        if len(part) > 0:
            yield model, part
