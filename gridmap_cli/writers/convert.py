"""Log output formats and conversion between log formats (``gridmap convert``, ``simulate -o``).

Reading goes through the readers registry (:mod:`gridmap_cli.readers`), so every format it knows
converts; writing goes through :data:`LOG_WRITERS`. What a format cannot hold is refused with an
error that says why, never dropped silently (schemas/*.md describe each format's limits).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from gridmap_cli.errors import GridmapError, UsageError
from gridmap_cli.poses.sync import sensors_for_log
from gridmap_cli.records import RangeLog
from gridmap_cli.robot import RangeSensor, RobotDescription
from gridmap_cli.writers import no_echo_at_max_range
from gridmap_cli.writers.aria_log import save_aria_log
from gridmap_cli.writers.csv_log import CSV_VERSION_KEY, save_csv_log
from gridmap_cli.writers.mcap_log import ENCODINGS, save_mcap_log


@dataclass(frozen=True)
class LogWriter:
    """A log format gridmap writes: its name, extension, and whether it needs sensor geometry."""

    name: str
    extension: str
    needs_sensors: bool
    write: Callable[[RangeLog, tuple[RangeSensor, ...], Path, str | None], None]


# write(log, sensors, path, encoding); CSV needs neither sensors nor encoding, ARIA no encoding
LOG_WRITERS: tuple[LogWriter, ...] = (
    LogWriter("csv", ".csv", False, lambda log, _, path, __: save_csv_log(log, path)),
    LogWriter("aria", ".2d", True, lambda log, sensors, path, _: save_aria_log(log, sensors, path)),
    LogWriter("mcap", ".mcap", True, save_mcap_log),
)


def writer_names() -> list[str]:
    return [w.name for w in LOG_WRITERS]


def output_writer(path: Path, name: str | None, encoding: str | None) -> LogWriter:
    """The writer for ``path``: by ``name``, else by extension; checks ``encoding`` fits it."""
    chosen: LogWriter | None = None
    if name is not None:
        chosen = next((w for w in LOG_WRITERS if w.name == name), None)
        if chosen is None:
            raise UsageError(f"unknown log format '{name}' (known: {', '.join(writer_names())})")
    else:
        chosen = next((w for w in LOG_WRITERS if w.extension == path.suffix.lower()), None)
        if chosen is None:
            known = ", ".join(f"{w.name} ({w.extension})" for w in LOG_WRITERS)
            raise UsageError(
                f"{path}: cannot tell the log format from the name; end it in one of {known} "
                "or give --to"
            )
    if encoding is not None:
        if chosen.name != "mcap":
            raise UsageError(f"--encoding applies to MCAP output only, not {chosen.name}")
        if encoding not in ENCODINGS:
            raise UsageError(f"unknown encoding '{encoding}' (known: {', '.join(ENCODINGS)})")
    return chosen


def write_log(
    log: RangeLog,
    path: Path,
    writer: LogWriter,
    robot: RobotDescription | None,
    encoding: str | None = None,
) -> None:
    """Write ``log`` with ``writer``; sensor geometry from the log itself, else from ``robot``.

    The CSV layout's version key is dropped from the metadata (it describes the file the log was
    read from; the CSV writer writes its own). A reading of ``inf`` (a CSV log's "no echo") is
    written as its sensor's maximum range by every format that has sensor geometry; CSV keeps
    ``inf``.
    """
    sensors = sensors_for_log(log, robot) if writer.needs_sensors else ()
    if sensors:
        log = no_echo_at_max_range(log, sensors)
    if CSV_VERSION_KEY in log.metadata:
        metadata = {k: v for k, v in log.metadata.items() if k != CSV_VERSION_KEY}
        log = dataclasses.replace(log, metadata=metadata)
    try:
        writer.write(log, sensors, path, encoding)
    except GridmapError as exc:
        if str(exc).startswith(str(path)):
            raise
        raise GridmapError(f"{path}: cannot write as {writer.name}: {exc}") from exc
