"""Writers: the end of the flow, turning a finished map or a log into files.

Map images with their map_server YAML (:mod:`.map_image`), the map as an MCAP OccupancyGrid
(:mod:`.map_mcap`), the pose-spread layer beside a map (:mod:`.spread_layer`), the preview with
tracks (:mod:`.preview`), logs as CSV, ARIA or MCAP
(:mod:`.csv_log`, :mod:`.aria_log`, :mod:`.mcap_log`, with :mod:`.convert` choosing among them)
and tracks as TUM or CSV (:mod:`.trajectory`). Every file is written beside its target and
renamed (:mod:`gridmap_cli.atomic`).

May import: the core, :mod:`gridmap_cli.robot`, :mod:`gridmap_cli.mapping` (grids),
:mod:`gridmap_cli.poses` (sync, for conversion) and the readers' format helpers.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gridmap_cli.errors import GridmapError, OutputExistsError, UsageError
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import RangeSensor

_LASER_BEAM = re.compile(r"^(.+)_(\d+)$")


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


@dataclass(frozen=True)
class Laser:
    """A scanning laser: beams (columns of the log) ``<frame>_0`` .. in order, at one position
    with one range interval, evenly spaced in angle. Angles in radians, in the base frame."""

    frame: str
    columns: tuple[int, ...]
    x_m: float
    y_m: float
    first_yaw_rad: float  # beam 0
    last_yaw_rad: float  # the last beam
    yaw_rad: float  # the middle of the scan, (first + last) / 2: the laser frame's heading
    angle_min_rad: float  # beam 0 relative to ``yaw_rad``
    angle_increment_rad: float  # 0 for a one-beam laser
    range_min_m: float
    range_max_m: float


def laser_groups(sensors: tuple[RangeSensor, ...], target: str) -> tuple[list[int], list[Laser]]:
    """Columns of the sensors that are not laser beams, and the scanning lasers, in column order.

    A laser is every kind-``laser`` sensor named ``<frame>_<i>`` with the same ``<frame>``; beam
    indices must run 0, 1, ... in column order, share position and range interval, and be evenly
    spaced (as a robot description's ``first_deg``/``last_deg``/``samples`` make them), or
    :class:`GridmapError` says that ``target`` (``"a LaserScan"``) needs them so.
    """
    beams: dict[str, list[tuple[int, int]]] = {}  # frame -> (column, beam index)
    singles: list[int] = []
    for column, s in enumerate(sensors):
        match = _LASER_BEAM.match(s.name)
        if s.kind == "laser" and match:
            beams.setdefault(match.group(1), []).append((column, int(match.group(2))))
        else:
            singles.append(column)
    lasers: list[Laser] = []
    for frame, numbered in beams.items():
        columns = [c for c, _ in numbered]
        if [i for _, i in numbered] != list(range(len(numbered))):
            raise GridmapError(
                f"laser {frame!r}: beams must be named {frame}_0, {frame}_1, ... in order "
                f"to be written as {target}"
            )
        members = [sensors[c] for c in columns]
        first = members[0]
        same = all(
            (m.x_m, m.y_m, m.min_range_m, m.max_range_m)
            == (first.x_m, first.y_m, first.min_range_m, first.max_range_m)
            for m in members
        )
        yaws = np.asarray([m.yaw_rad for m in members], dtype=np.float64)
        step = (yaws[-1] - yaws[0]) / (len(yaws) - 1) if len(yaws) > 1 else 0.0
        even = np.allclose(yaws, yaws[0] + step * np.arange(len(yaws)), rtol=0.0, atol=1e-9)
        if not (same and even):
            raise GridmapError(
                f"laser {frame!r}: {target} needs beams at one position with one range "
                "interval, evenly spaced in angle"
            )
        middle = 0.5 * (float(yaws[0]) + float(yaws[-1]))
        lasers.append(
            Laser(
                frame,
                tuple(columns),
                first.x_m,
                first.y_m,
                float(yaws[0]),
                float(yaws[-1]),
                middle,
                float(yaws[0]) - middle,
                float(step),
                first.min_range_m,
                first.max_range_m,
            )
        )
    return singles, lasers
