"""Log readers: one module per format, one registry to pick among them.

Resolution order (as imageio and rosbags do it): an explicit ``--format``, then the file's
extension, then a cheap sniff of its first bytes. "Not my format" raises
:class:`~gridmap_cli.errors.UnknownFormatError`; a file of a known format that is broken raises
:class:`~gridmap_cli.errors.InputFileError` from the reader itself.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from gridmap_cli.errors import InputFileError, UnknownFormatError, UsageError
from gridmap_cli.readers import aria_log, csv_log, mcap_log
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.records import RangeLog


@dataclass(frozen=True)
class LogFormat:
    """A log format gridmap reads: its name, extensions, sniffer and reader."""

    name: str
    extensions: tuple[str, ...]
    sniff: Callable[[bytes], bool]
    reader: Callable[[Path, ReadOptions], RangeLog]

    def read(self, path: Path, options: ReadOptions | None = None) -> RangeLog:
        """Read ``path`` into the canonical record stream."""
        return self.reader(path, options or ReadOptions())


def _read_csv(path: Path, options: ReadOptions) -> RangeLog:
    options.refuse_topic_flags("CSV")
    return csv_log.read_csv_log(path)


def _read_aria(path: Path, options: ReadOptions) -> RangeLog:
    options.refuse_topic_flags("ARIA")
    return aria_log.read_aria_log(path)


FORMATS: tuple[LogFormat, ...] = (
    LogFormat("csv", (".csv",), csv_log.sniff, _read_csv),
    LogFormat("aria", (".2d",), aria_log.sniff, _read_aria),
    LogFormat("mcap", (".mcap",), mcap_log.sniff, mcap_log.read_mcap_log),
)

_SNIFF_BYTES = 4096


def format_names() -> list[str]:
    return [f.name for f in FORMATS]


def resolve_format(path: Path, name: str | None = None) -> LogFormat:
    """Pick the reader for ``path``: by ``name``, else by extension, else by sniffing."""
    if name is not None:
        for fmt in FORMATS:
            if fmt.name == name:
                return fmt
        raise UsageError(f"unknown log format '{name}' (known: {', '.join(format_names())})")
    suffix = path.suffix.lower()
    for fmt in FORMATS:
        if suffix in fmt.extensions:
            return fmt
    try:
        with open(path, "rb") as handle:
            head = handle.read(_SNIFF_BYTES)
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from exc
    for fmt in FORMATS:
        if fmt.sniff(head):
            return fmt
    known = ", ".join(f"{f.name} ({' '.join(f.extensions)})" for f in FORMATS)
    raise UnknownFormatError(path, known)


def read_log(
    path: Path, format_name: str | None = None, options: ReadOptions | None = None
) -> RangeLog:
    """Read any supported log into the canonical record stream."""
    return resolve_format(path, format_name).read(path, options)
