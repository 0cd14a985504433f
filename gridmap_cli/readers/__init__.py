"""Log readers: one module per format, one registry to pick among them.

Resolution order (as imageio and rosbags do it): an explicit ``--format``, then the file's
extension (a directory: a rosbag2 folder), then a cheap sniff of its first bytes. "Not my
format" raises :class:`~gridmap_cli.errors.UnknownFormatError`; a file of a known format that is
broken raises :class:`~gridmap_cli.errors.InputFileError` from the reader itself.

A gzip-compressed text log (``x.log.gz``, ``x.csv.gz``, ``x.2d.gz``) is resolved by its inner
extension, else by sniffing the decompressed head, and read from the decompressed text.

ROS recordings (MCAP, ROS 1 bags, rosbag2 folders) are made of message sources; several of them
given together are merged by log time into one recording (:func:`read_logs`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from gridmap_cli.errors import InputFileError, UnknownFormatError, UsageError
from gridmap_cli.readers import aria_log, bag_log, carmen_log, compressed, csv_log, mcap_log
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.readers.ros_recording import RecordingSource, read_recording
from gridmap_cli.records import RangeLog


@dataclass(frozen=True)
class LogFormat:
    """A log format gridmap reads: its name, extensions, sniffer and reader.

    ``sources`` is set for ROS recordings: the message sources of one path, so that several
    recordings can be read as one. ``text_reader`` is set for text formats: a reader of an open
    text handle (named in errors) in the format's ``encoding``, for gzip-compressed logs.
    ``weak_extensions`` are extensions other tools use too (``.log``): taken only when no
    format's sniff claims the file, so that an ARIA log named ``run.log`` still reads as ARIA.
    """

    name: str
    extensions: tuple[str, ...]
    sniff: Callable[[bytes], bool]
    reader: Callable[[Path, ReadOptions], RangeLog]
    sources: Callable[[Path], list[RecordingSource]] | None = None
    text_reader: Callable[[TextIO, str, ReadOptions], RangeLog] | None = None
    encoding: str = "utf-8"
    weak_extensions: tuple[str, ...] = ()

    def read(self, path: Path, options: ReadOptions | None = None) -> RangeLog:
        """Read ``path`` (gzip-compressed or not) into the canonical record stream."""
        options = options or ReadOptions()
        if path.is_dir() or not compressed.is_gzip(path):
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


def _never(head: bytes) -> bool:
    return False


def _rosbag2_folder(path: Path) -> Path:
    """The folder of a rosbag2 recording given as its folder, metadata.yaml or a .db3 file."""
    return path if path.is_dir() else path.parent


def _rosbag2_sources(path: Path) -> list[RecordingSource]:
    return bag_log.rosbag2_sources(_rosbag2_folder(path))


def _read_rosbag2(path: Path, options: ReadOptions) -> RangeLog:
    return read_recording(_rosbag2_sources(path), options).log


def _mcap_sources(path: Path) -> list[RecordingSource]:
    return [mcap_log.McapSource(path)]


def _bag_sources(path: Path) -> list[RecordingSource]:
    return [bag_log.BagSource(path)]


FORMATS: tuple[LogFormat, ...] = (
    LogFormat("csv", (".csv",), csv_log.sniff, _read_csv, None, _text_csv, "utf-8-sig"),
    LogFormat("aria", (".2d",), aria_log.sniff, _read_aria, None, _text_aria, "latin-1"),
    LogFormat("mcap", (".mcap",), mcap_log.sniff, mcap_log.read_mcap_log, _mcap_sources),
    LogFormat("bag", (".bag",), bag_log.sniff, bag_log.read_bag_log, _bag_sources),
    LogFormat("rosbag2", (".db3",), _never, _read_rosbag2, _rosbag2_sources),
    LogFormat(
        "carmen",
        carmen_log.EXTENSIONS,
        carmen_log.sniff,
        _read_carmen,
        None,
        _text_carmen,
        "latin-1",
        carmen_log.WEAK_EXTENSIONS,
    ),
)

_SNIFF_BYTES = 4096


def format_names() -> list[str]:
    return [f.name for f in FORMATS]


def _by_name(name: str) -> LogFormat:
    for fmt in FORMATS:
        if fmt.name == name:
            return fmt
    raise UsageError(f"unknown log format '{name}' (known: {', '.join(format_names())})")


def resolve_format(path: Path, name: str | None = None) -> LogFormat:
    """Pick the reader for ``path``: by ``name``, else by extension, else by sniffing."""
    if name is not None:
        return _by_name(name)
    if path.is_dir() or path.name == bag_log.ROSBAG2_METADATA:
        if bag_log.is_rosbag2(_rosbag2_folder(path)):
            return _by_name("rosbag2")
        raise InputFileError(
            path, f"a directory, but not a rosbag2 folder (no {bag_log.ROSBAG2_METADATA} in it)"
        )
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
    known = ", ".join(
        f"{f.name} ({' '.join(f.extensions + f.weak_extensions)})"
        for f in FORMATS
        if f.name != "rosbag2"
    )
    raise UnknownFormatError(path, f"{known}, rosbag2 (a folder with {bag_log.ROSBAG2_METADATA})")


def read_log(
    path: Path, format_name: str | None = None, options: ReadOptions | None = None
) -> RangeLog:
    """Read any supported log into the canonical record stream."""
    return resolve_format(path, format_name).read(path, options)


def recording_sources(
    paths: Sequence[Path], format_name: str | None = None
) -> list[RecordingSource] | None:
    """The message sources of ROS recordings, or None for a single log of another format.

    Several paths must all be ROS recordings (MCAP, bag, rosbag2): :class:`UsageError` names
    the first that is not.
    """
    formats = [resolve_format(p, format_name) for p in paths]
    if len(paths) == 1 and formats[0].sources is None:
        return None
    out: list[RecordingSource] = []
    for path, fmt in zip(paths, formats, strict=True):
        if fmt.sources is None:
            raise UsageError(
                f"{path}: several logs are read as one only when all are ROS recordings "
                f"(MCAP, bag, rosbag2 folder); this is a {fmt.name} log"
            )
        out.extend(fmt.sources(path))
    return out


def read_logs(
    paths: Sequence[Path], format_name: str | None = None, options: ReadOptions | None = None
) -> RangeLog:
    """Read one log, or several ROS recordings merged by log time, into one record stream."""
    sources = recording_sources(paths, format_name)
    if sources is None:
        return read_log(paths[0], format_name, options)
    return read_recording(sources, options).log
