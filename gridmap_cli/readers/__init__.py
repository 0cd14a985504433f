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
from gridmap_cli.readers import aria_log, csv_log
from gridmap_cli.records import RangeLog


@dataclass(frozen=True)
class LogFormat:
    """A log format gridmap reads: its name, extensions, sniffer and reader."""

    name: str
    extensions: tuple[str, ...]
    sniff: Callable[[bytes], bool]
    read: Callable[[Path], RangeLog]


FORMATS: tuple[LogFormat, ...] = (
    LogFormat("csv", (".csv",), csv_log.sniff, csv_log.read_csv_log),
    LogFormat("aria", (".2d",), aria_log.sniff, aria_log.read_aria_log),
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


def read_log(path: Path, format_name: str | None = None) -> RangeLog:
    """Read any supported log into the canonical record stream."""
    return resolve_format(path, format_name).read(path)
