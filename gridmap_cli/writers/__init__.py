"""Writers: the end of the flow, turning a finished map or a log into files."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from gridmap_cli.errors import GridmapError, OutputExistsError, UsageError
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import RangeSensor


def check_output(path: Path, force: bool) -> None:
    """Refuse an output that is a directory, or that exists without ``force``; call before any
    work. Raises :class:`UsageError` / :class:`OutputExistsError`."""
    if path.is_dir():
        raise UsageError(f"{path} is a directory")
    if path.exists() and not force:
        raise OutputExistsError(path)


def check_metadata_lines(metadata: dict[str, str]) -> None:
    """Refuse metadata that cannot be written as ``# key: value`` header lines."""
    for key, value in metadata.items():
        if not key or ":" in key or any(c in key + value for c in "\r\n"):
            raise GridmapError(f"metadata {key!r}: {value!r} cannot be a '# key: value' line")


def no_echo_at_max_range(log: RangeLog, sensors: tuple[RangeSensor, ...]) -> RangeLog:
    """``log`` with every infinite range replaced by its sensor's ``max_range_m``.

    ``sensors`` gives the geometry of ``log.sensor_names`` (same order). A CSV log may spell "no
    echo" as ``inf``; every format gridmap writes with sensor geometry spells it as the maximum
    range (JSON has no infinity, ARIA ranges are whole millimetres, ``sensor_msgs/Range`` says
    ``max_range``), so the conversion happens here, once. Finite ranges are left as they are.
    """
    ranges = log.readings.range_m
    infinite = np.isinf(ranges)
    if not infinite.any():
        return log
    if len(sensors) != len(log.sensor_names):
        raise GridmapError(
            f"sensor geometry for {len(sensors)} sensors does not match the log's "
            f"{len(log.sensor_names)} sensors"
        )
    max_range = np.asarray([s.max_range_m for s in sensors], dtype=np.float64)
    capped = np.where(infinite, max_range[log.readings.sensor], ranges)
    readings = dataclasses.replace(log.readings, range_m=capped)
    return dataclasses.replace(log, readings=readings)
