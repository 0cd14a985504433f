"""Log readers: one module per format, one registry to pick among them.

Resolution order (as imageio and rosbags do it): an explicit ``--format``, then the file's
extension, then a cheap sniff of its first bytes. "Not my format" raises
:class:`~gridmap_cli.errors.UnknownFormatError`; a file of a known format that is broken raises
:class:`~gridmap_cli.errors.InputFileError` from the reader itself.

A gzip-compressed text log (``x.log.gz``, ``x.csv.gz``, ``x.2d.gz``) is resolved by its inner
extension, else by sniffing the decompressed head, and read from the decompressed text.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from gridmap_cli.errors import InputFileError, UnknownFormatError, UsageError
from gridmap_cli.readers import aria_log, carmen_log, compressed, csv_log, mcap_log
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.records import RangeLog


@dataclass(frozen=True)
class LogFormat:
    """A log format gridmap reads: its name, extensions, sniffer and reader."""

    name: str
    extensions: tuple[str, ...]
    sniff: Callable[[bytes], bool]
    reader: Callable[[Path, ReadOptions], RangeLog]
    #: Text formats: a reader of an open text handle (named in errors), and the encoding the
    #: format is read in; used for gzip-compressed logs. None for binary formats.
    text_reader: Callable[[TextIO, str, ReadOptions], RangeLog] | None = None
    encoding: str = "utf-8"
    #: Extensions other tools use too (``.log``): taken only when no format's sniff claims the
    #: file, so that an ARIA log named ``run.log`` still reads as ARIA.
    weak_extensions: tuple[str, ...] = ()

    def read(self, path: Path, options: ReadOptions | None = None) -> RangeLog:
        """Read ``path`` (gzip-compressed or not) into the canonical record stream."""
        options = options or ReadOptions()
        if not compressed.is_gzip(path):
            return self.reader(path, options)
        if self.text_reader is None:
            raise InputFileError(path, f"gzip-compressed {self.name} logs are not supported")
        return self.text_reader(compressed.open_text(path, self.encoding), str(path), options)


def _read_csv(path: Path, options: ReadOptions) -> RangeLog:
    options.refuse_topic_flags("CSV")
    return csv_log.read_csv_log(path)


def _read_aria(path: Path, options: ReadOptions) -> RangeLog:
    options.refuse_topic_flags("ARIA")
    return aria_log.read_aria_log(path)


def _read_carmen(path: Path, options: ReadOptions) -> RangeLog:
    options.refuse_topic_flags("CARMEN")
    return carmen_log.read_carmen_log(path)


def _text_csv(handle: TextIO, name: str, options: ReadOptions) -> RangeLog:
    options.refuse_topic_flags("CSV")
    return csv_log.read_csv_log(handle, name)


def _text_aria(handle: TextIO, name: str, options: ReadOptions) -> RangeLog:
    options.refuse_topic_flags("ARIA")
    return aria_log.read_aria_log(handle, name)


def _text_carmen(handle: TextIO, name: str, options: ReadOptions) -> RangeLog:
    options.refuse_topic_flags("CARMEN")
    return carmen_log.read_carmen_log(handle, name)


FORMATS: tuple[LogFormat, ...] = (
    LogFormat("csv", (".csv",), csv_log.sniff, _read_csv, _text_csv, "utf-8-sig"),
    LogFormat("aria", (".2d",), aria_log.sniff, _read_aria, _text_aria, "latin-1"),
    LogFormat("mcap", (".mcap",), mcap_log.sniff, mcap_log.read_mcap_log),
    LogFormat(
        "carmen",
        carmen_log.EXTENSIONS,
        carmen_log.sniff,
        _read_carmen,
        _text_carmen,
        "latin-1",
        carmen_log.WEAK_EXTENSIONS,
    ),
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
    gzipped = compressed.is_gzip(path)
    suffix = compressed.inner_suffix(path) if gzipped else path.suffix.lower()
    candidates = [f for f in FORMATS if f.text_reader is not None or not gzipped]
    binary = [f for f in FORMATS if f not in candidates and suffix in f.extensions]
    if binary:
        raise InputFileError(path, f"gzip-compressed {binary[0].name} logs are not supported")
    for fmt in candidates:
        if suffix in fmt.extensions:
            return fmt
    if gzipped:
        head = compressed.head(path, _SNIFF_BYTES)
    else:
        try:
            with open(path, "rb") as handle:
                head = handle.read(_SNIFF_BYTES)
        except OSError as exc:
            raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from exc
    for fmt in candidates:
        if fmt.sniff(head):
            return fmt
    for fmt in candidates:
        if suffix in fmt.weak_extensions:
            return fmt  # its reader says what is broken, with the line
    known = ", ".join(f"{f.name} ({' '.join(f.extensions + f.weak_extensions)})" for f in FORMATS)
    raise UnknownFormatError(path, known)


def read_log(
    path: Path, format_name: str | None = None, options: ReadOptions | None = None
) -> RangeLog:
    """Read any supported log into the canonical record stream."""
    return resolve_format(path, format_name).read(path, options)
