"""Writer for gridmap's CSV log layout (``schemas/csv-log.md``): the inverse of the CSV reader.

One row per odometry stamp; a reading must share its stamp with an odometry pose (the layout has
no other place for it). Numbers are written in Python's shortest round-trip form, so reading the
file back gives bit-identical values, and times as exact decimal seconds.
"""

from __future__ import annotations

from pathlib import Path
from typing import TextIO

import numpy as np

from gridmap_cli.atomic import atomic_write
from gridmap_cli.errors import GridmapError
from gridmap_cli.readers.text.csv_log import POSE_COLUMNS, TRUTH_COLUMNS
from gridmap_cli.records import RangeLog
from gridmap_cli.writers import check_metadata_lines

CSV_VERSION_KEY = "gridmap-csv"


def ns_to_seconds_text(stamp_ns: int) -> str:
    """Exact decimal seconds for integer nanoseconds: 1500000000 -> '1.5', 0 -> '0.0'."""
    sign = "-" if stamp_ns < 0 else ""
    whole, frac = divmod(abs(int(stamp_ns)), 1_000_000_000)
    digits = f"{frac:09d}".rstrip("0") or "0"
    return f"{sign}{whole}.{digits}"


def write_csv_log(log: RangeLog, handle: TextIO) -> None:
    """Write ``log`` to an open text handle (newline='' recommended)."""
    poses = log.poses
    n = len(poses)
    names = list(log.sensor_names)
    check_metadata_lines(log.metadata)
    truth = log.truth
    if truth is not None and not np.array_equal(truth.stamp_ns, poses.stamp_ns):
        raise GridmapError("the CSV layout needs ground truth at the odometry stamps")
    for name in names:
        if name in POSE_COLUMNS or name in TRUTH_COLUMNS or "," in name:
            raise GridmapError(f"sensor name {name!r} cannot be a CSV column")
    row_of = np.searchsorted(poses.stamp_ns, log.readings.stamp_ns)
    inside = row_of < n
    matches = np.zeros(len(log.readings), dtype=bool)
    matches[inside] = poses.stamp_ns[row_of[inside]] == log.readings.stamp_ns[inside]
    if not matches.all():
        bad = int(log.readings.stamp_ns[~matches][0])
        raise GridmapError(
            f"a reading at {ns_to_seconds_text(bad)} s has no odometry row with the same stamp; "
            "the CSV layout keeps readings on odometry rows"
        )
    cell = row_of * max(len(names), 1) + log.readings.sensor
    if np.unique(cell).shape[0] != cell.shape[0]:
        raise GridmapError("two readings of one sensor at one stamp cannot share a CSV cell")
    table = np.full((n, len(names)), np.nan)
    table[row_of, log.readings.sensor] = log.readings.range_m

    # the layout's version first; a log read from a CSV carries it in its metadata already
    lines = {CSV_VERSION_KEY: "1", **log.metadata}
    lines[CSV_VERSION_KEY] = "1"
    for key, value in lines.items():
        handle.write(f"# {key}: {value}\n")
    header = list(POSE_COLUMNS) + names + (list(TRUTH_COLUMNS) if log.truth is not None else [])
    handle.write(",".join(header) + "\n")
    for i in range(n):
        fields = [
            ns_to_seconds_text(int(poses.stamp_ns[i])),
            repr(float(poses.x_m[i])),
            repr(float(poses.y_m[i])),
            repr(float(poses.theta_rad[i])),
        ]
        fields.extend("" if v != v else repr(float(v)) for v in table[i])
        if truth is not None:
            fields.extend(repr(float(a[i])) for a in (truth.x_m, truth.y_m, truth.theta_rad))
        handle.write(",".join(fields) + "\n")


def save_csv_log(log: RangeLog, path: Path) -> None:
    """Write ``log`` to ``path`` atomically (nothing is left behind on failure)."""
    with atomic_write(path, "the log") as tmp, open(tmp, "w", encoding="utf-8", newline="") as out:
        write_csv_log(log, out)
