"""Log readers: one module per format, one registry to pick among them.

Resolution order (as imageio and rosbags do it): an explicit ``--format``, then the file's
extension (a directory: a rosbag2 folder), then a cheap sniff of its first bytes. "Not my
format" raises :class:`~gridmap_cli.errors.UnknownFormatError`; a file of a known format that is
broken raises :class:`~gridmap_cli.errors.InputFileError` from the reader itself.

A gzip-compressed text log (``x.log.gz``, ``x.csv.gz``, ``x.2d.gz``) is resolved by its inner
extension, else by sniffing the decompressed head, and read from the decompressed text.

ROS recordings (MCAP, ROS 1 bags, rosbag2 folders) are made of message sources; several of them
given together are merged by log time into one recording (:func:`read_logs`).

The registry imports no reader of a binary format until a file of it is read: a CSV build must not
pay for the MCAP and bag decoders (``mcap``, ``rosbags``: a third of a small build's time).
"""

from __future__ import annotations

import importlib
import io
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from gridmap_cli.errors import (
    InputFileError,
    MixedLogsError,
    NotRecordingFolderError,
    UnknownFormatError,
    UsageError,
)
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.readers.text import compressed, csv_log, csv_stream
from gridmap_cli.records import RangeLog

if TYPE_CHECKING:
    from gridmap_cli.readers.ros.recording import RecordingSource

#: The first bytes of an MCAP file and of a ROS 1 bag (the readers' own constants, repeated here
#: so that sniffing needs no import of them; tests check that they agree).
MCAP_MAGIC = b"\x89MCAP0\r\n"
BAG_MAGIC = b"#ROSBAG V2.0\n"
ROSBAG2_METADATA = "metadata.yaml"
CARMEN_EXTENSIONS = (".clf",)
#: ``.log`` is CARMEN's usual extension but everyone's: the registry sniffs such files first.
CARMEN_WEAK_EXTENSIONS = (".log",)


@dataclass(frozen=True)
class LogFormat:
    """A log format gridmap reads: its name, extensions, sniffer and reader.

    ``sources`` is set for ROS recordings: the message sources of one path, so that several
    recordings can be read as one. ``text_reader`` is set for text formats: a reader of an open
    text handle (named in errors) in the format's ``encoding``, for gzip-compressed logs.
    ``weak_extensions`` are extensions other tools use too (``.log``): taken only when no
    format's sniff claims the file, so that an ARIA log named ``run.log`` still reads as ARIA.
    ``streamer`` is set for formats that can leave a long log's readings in the file
    (:attr:`ReadOptions.stream`): it gives such a log, or None for the reader to read it held.
    """

    name: str
    extensions: tuple[str, ...]
    sniff: Callable[[bytes], bool]
    reader: Callable[[Path, ReadOptions], RangeLog]
    sources: Callable[[Path], list[RecordingSource]] | None = None
    text_reader: Callable[[TextIO, str, ReadOptions], RangeLog] | None = None
    encoding: str = "utf-8"
    weak_extensions: tuple[str, ...] = ()
    streamer: Callable[[Path, ReadOptions], RangeLog | None] | None = None

    def read(self, path: Path, options: ReadOptions | None = None) -> RangeLog:
        """Read ``path`` (gzip-compressed or not) into the canonical record stream."""
        options = options or ReadOptions()
        if options.stream and self.streamer is not None and not path.is_dir():
            streamed = self.streamer(path, options)
            if streamed is not None:
                return streamed
        if path.is_dir() or not compressed.is_gzip(path):
            return self.reader(path, options)
        if self.text_reader is None:
            raise InputFileError(path, f"gzip-compressed {self.name} logs are not supported")
        return self.text_reader(compressed.open_text(path, self.encoding), str(path), options)


def _read_csv(path: Path, options: ReadOptions) -> RangeLog:
    options.refuse_topic_flags("CSV")
    return csv_log.read_csv_log(path)


def _stream_csv(path: Path, options: ReadOptions) -> RangeLog | None:
    options.refuse_topic_flags("CSV")
    return csv_stream.read_streamed(path, compressed.is_gzip(path))


def _reader_module(name: str) -> Any:
    return importlib.import_module(f"gridmap_cli.readers.text.{name}")


def _lazy_sniff(module: str) -> Callable[[bytes], bool]:
    def sniff(head: bytes) -> bool:
        return bool(_reader_module(module).sniff(head))

    return sniff


def _read_aria(path: Path, options: ReadOptions) -> RangeLog:
    options.refuse_topic_flags("ARIA")
    return _reader_module("aria_log").read_aria_log(path)  # type: ignore[no-any-return]


def _read_carmen(path: Path, options: ReadOptions) -> RangeLog:
    options.refuse_topic_flags("CARMEN")
    return _reader_module("carmen_log").read_carmen_log(path)  # type: ignore[no-any-return]


def _text_csv(handle: TextIO, name: str, options: ReadOptions) -> RangeLog:
    options.refuse_topic_flags("CSV")
    return csv_log.read_csv_log(handle, name)


def _text_aria(handle: TextIO, name: str, options: ReadOptions) -> RangeLog:
    options.refuse_topic_flags("ARIA")
    return _reader_module("aria_log").read_aria_log(handle, name)  # type: ignore[no-any-return]


def _text_carmen(handle: TextIO, name: str, options: ReadOptions) -> RangeLog:
    options.refuse_topic_flags("CARMEN")
    return _reader_module("carmen_log").read_carmen_log(handle, name)  # type: ignore[no-any-return]


def _never(head: bytes) -> bool:
    return False


def _rosbag2_folder(path: Path) -> Path:
    """The folder of a rosbag2 recording given as its folder, metadata.yaml or a .db3 file."""
    return path if path.is_dir() else path.parent


def _is_rosbag2(path: Path) -> bool:
    """True for a rosbag2 folder (a directory holding ``metadata.yaml``)."""
    return path.is_dir() and (path / ROSBAG2_METADATA).is_file()


def _read_sources(sources: list[RecordingSource], options: ReadOptions) -> RangeLog:
    from gridmap_cli.readers.ros.recording import read_recording

    return read_recording(sources, options).log


def _rosbag2_sources(path: Path) -> list[RecordingSource]:
    from gridmap_cli.readers.ros.bag import log as bag_log

    return bag_log.rosbag2_sources(_rosbag2_folder(path))


def _read_rosbag2(path: Path, options: ReadOptions) -> RangeLog:
    return _read_sources(_rosbag2_sources(path), options)


def _mcap_sources(path: Path) -> list[RecordingSource]:
    from gridmap_cli.readers.ros.mcap import log as mcap_log

    return [mcap_log.McapSource(path)]


def _read_mcap(path: Path, options: ReadOptions) -> RangeLog:
    return _read_sources(_mcap_sources(path), options)


def _stream_mcap(path: Path, options: ReadOptions) -> RangeLog | None:
    from gridmap_cli.readers.ros.mcap import stream as mcap_stream

    return mcap_stream.read_streamed(path, options)


def _bag_sources(path: Path) -> list[RecordingSource]:
    from gridmap_cli.readers.ros.bag import log as bag_log

    return [bag_log.BagSource(path)]


def _read_bag(path: Path, options: ReadOptions) -> RangeLog:
    return _read_sources(_bag_sources(path), options)


def _sniff_mcap(head: bytes) -> bool:
    return head.startswith(MCAP_MAGIC)


def _sniff_bag(head: bytes) -> bool:
    return head.startswith(BAG_MAGIC)


FORMATS: tuple[LogFormat, ...] = (
    LogFormat(
        "csv",
        (".csv",),
        csv_log.sniff,
        _read_csv,
        None,
        _text_csv,
        "utf-8-sig",
        streamer=_stream_csv,
    ),
    LogFormat("aria", (".2d",), _lazy_sniff("aria_log"), _read_aria, None, _text_aria, "latin-1"),
    LogFormat("mcap", (".mcap",), _sniff_mcap, _read_mcap, _mcap_sources, streamer=_stream_mcap),
    LogFormat("bag", (".bag",), _sniff_bag, _read_bag, _bag_sources),
    LogFormat("rosbag2", (".db3",), _never, _read_rosbag2, _rosbag2_sources),
    LogFormat(
        "carmen",
        CARMEN_EXTENSIONS,
        _lazy_sniff("carmen_log"),
        _read_carmen,
        None,
        _text_carmen,
        "latin-1",
        CARMEN_WEAK_EXTENSIONS,
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
    if path.is_dir() or path.name == ROSBAG2_METADATA:
        if _is_rosbag2(_rosbag2_folder(path)):
            return _by_name("rosbag2")
        raise NotRecordingFolderError(
            path, f"a directory, but not a rosbag2 folder (no {ROSBAG2_METADATA} in it)"
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
    raise UnknownFormatError(
        path, f"{known}, rosbag2 (a folder with {ROSBAG2_METADATA})", _sniffed(head)
    )


def _sniffed(head: bytes) -> str:
    """What the first bytes of a file no reader claims were, for its error."""
    if not head.strip():
        return "the file is empty"
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError:
        text = ""
    if not text or "\0" in text:
        return f"its first bytes {head[:8]!r} are no MCAP or ROS bag magic"
    line = next(ln.strip() for ln in text.splitlines() if ln.strip())
    shown = line if len(line) <= 40 else line[:37] + "..."
    return (
        f"its first line {shown!r} is no CSV header (time,x,y,theta,...), ARIA log line or "
        "CARMEN message"
    )


def read_log(
    path: Path, format_name: str | None = None, options: ReadOptions | None = None
) -> RangeLog:
    """Read any supported log into the canonical record stream."""
    return resolve_format(path, format_name).read(path, options)


#: The name a log read from standard input goes by in messages.
STDIN_NAME = "<stdin>"


def read_bytes(
    data: bytes,
    name: str = STDIN_NAME,
    format_name: str | None = None,
    options: ReadOptions | None = None,
) -> RangeLog:
    """Read a whole text log held in memory (standard input), plain or gzip-compressed.

    The format is ``format_name``, else sniffed from the first bytes. MCAP files and bags are
    refused: their readers seek through the file, so they need it on disk.
    """
    fmt, text = held_text(data, name, format_name)
    assert fmt.text_reader is not None  # held_text refuses the others
    return fmt.text_reader(io.StringIO(text), name, options or ReadOptions())


def held_text(data: bytes, name: str = STDIN_NAME, format_name: str | None = None) -> tuple[
    LogFormat, str
]:  # fmt: skip
    """The format and decoded text of a text log held in memory (see :func:`read_bytes`)."""
    if data[:2] == compressed.MAGIC:
        data = compressed.decompress_bytes(data, name)
    if format_name is not None:
        fmt = _by_name(format_name)
    else:
        head = data[:_SNIFF_BYTES]
        claims = [f for f in FORMATS if f.sniff(head)]
        if not claims:
            known = ", ".join(f.name for f in FORMATS if f.text_reader is not None)
            raise UsageError(f"{name}: cannot tell the log format; give --format ({known})")
        fmt = claims[0]
    if fmt.text_reader is None:
        raise UsageError(
            f"{name}: {fmt.name} logs cannot be read from standard input (the reader seeks "
            "through the file); give the file's name"
        )
    try:
        return fmt, data.decode(fmt.encoding)
    except UnicodeDecodeError as exc:
        raise InputFileError(name, f"not {fmt.encoding} text ({exc.reason})") from exc


def recording_sources(
    paths: Sequence[Path], format_name: str | None = None
) -> list[RecordingSource] | None:
    """The message sources of ROS recordings, or None for a single log of another format.

    Several paths must all be ROS recordings (MCAP, bag, rosbag2): :class:`MixedLogsError` names
    the first that is not.
    """
    formats = [resolve_format(p, format_name) for p in paths]
    if len(paths) == 1 and formats[0].sources is None:
        return None
    out: list[RecordingSource] = []
    for path, fmt in zip(paths, formats, strict=True):
        if fmt.sources is None:
            raise MixedLogsError(
                f"{path}: several logs are read as one only when all are ROS recordings "
                f"(MCAP, bag, rosbag2 folder); this is a {fmt.name} log"
            )
        out.extend(fmt.sources(path))
    if len(out) > 1:
        from gridmap_cli.readers.repeats import refuse_repeats

        refuse_repeats([Path(source.path) for source in out])
    return out


def read_logs(
    paths: Sequence[Path], format_name: str | None = None, options: ReadOptions | None = None
) -> RangeLog:
    """Read one log, or several ROS recordings merged by log time, into one record stream."""
    if len(paths) == 1 and options is not None and options.stream:
        return read_log(paths[0], format_name, options)  # its streamer, if any, first
    sources = recording_sources(paths, format_name)
    if sources is None:
        return read_log(paths[0], format_name, options)
    return _read_sources(sources, options or ReadOptions())
