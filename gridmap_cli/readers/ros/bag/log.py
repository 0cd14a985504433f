"""Readers for ROS 1 bags (``.bag``) and rosbag2 folders (sqlite3 ``.db3`` or MCAP storage).

Both are read without a ROS installation through the ``rosbags`` library, which deserialises
messages with the definitions the recording stores (ROS 1 bags always store them; a rosbag2
folder from before ROS 2 Iron may not, and then the ROS 2 Humble definitions of the standard
messages are used). A rosbag2 folder with MCAP storage is read with the ``mcap`` library, file by
file, like any MCAP recording. The messages then go the way every ROS recording goes
(:mod:`~gridmap_cli.readers.ros.recording`): same topics, types and frame rules as MCAP, so a bag
and the MCAP that ``mcap convert`` makes of it give the same canonical stream.
"""

from __future__ import annotations

import importlib
import struct
from collections import Counter
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from gridmap_cli.errors import InputFileError
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.readers.ros.bag.integrity import verify_bag
from gridmap_cli.readers.ros.bag.metadata import ROSBAG2_METADATA, ZSTD_MAGIC, read_metadata
from gridmap_cli.readers.ros.mcap.bulk import Batch
from gridmap_cli.readers.ros.mcap.log import McapSource
from gridmap_cli.readers.ros.recording import (
    Message,
    RecordingRead,
    RecordingSource,
    read_recording,
)
from gridmap_cli.readers.ros.topics import ChannelInfo, Survey, fold_type, qos_text
from gridmap_cli.records import RangeLog

#: The first line of every ROS 1 bag (format 2.0, the only one rosbag has written since 2010).
BAG_MAGIC = b"#ROSBAG V2.0\n"


def sniff(head: bytes) -> bool:
    """True for a ROS 1 bag."""
    return head.startswith(BAG_MAGIC)


def is_rosbag2(path: Path) -> bool:
    """True for a rosbag2 folder (a directory holding ``metadata.yaml``)."""
    return path.is_dir() and (path / ROSBAG2_METADATA).is_file()


def _damaged() -> tuple[type[BaseException], ...]:
    """What ``rosbags`` raises on a damaged or unreadable recording (imported on first use)."""
    from rosbags.highlevel import AnyReaderError
    from rosbags.rosbag1 import ReaderError as Bag1Error
    from rosbags.rosbag2 import ReaderError as Bag2Error
    from rosbags.serde import SerdeError

    # rosbags' zstd (compression.zstd, or its backport): a message or file that is not zstd
    zstd_error = importlib.import_module("rosbags.rosbag2.reader").zstd.ZstdError
    return (
        zstd_error,
        AnyReaderError,
        Bag1Error,
        Bag2Error,
        SerdeError,
        struct.error,
        EOFError,
        ValueError,
        KeyError,
        IndexError,
        AssertionError,
        UnicodeDecodeError,
    )


class BagSource:
    """A ROS 1 bag or a sqlite3 rosbag2 folder, read with ``rosbags``."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.kind = "rosbag2" if path.is_dir() else "ROS 1 bag"
        self._verified = False

    def _reader(self) -> Any:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        typestore = get_typestore(Stores.ROS2_HUMBLE if self.path.is_dir() else Stores.ROS1_NOETIC)
        return AnyReader([self.path], default_typestore=typestore)

    def _fail(self, exc: BaseException) -> InputFileError:
        if isinstance(exc, OSError):
            return InputFileError(self.path, f"cannot read: {exc.strerror or exc}")
        return InputFileError(
            self.path, f"truncated or damaged {self.kind} ({type(exc).__name__}: {exc})"
        )

    def _verify(self) -> None:
        if not self._verified and not self.path.is_dir():
            verify_bag(self.path)
        self._verified = True

    def survey(self) -> Survey:
        self._verify()
        if not self.path.is_dir():
            from gridmap_cli.readers.ros.bag.bulk import survey_bag

            quick = survey_bag(self.path)
            if quick is not None:
                return quick
        try:
            with self._reader() as reader:
                counts: Counter[str] = Counter()
                types: dict[str, Any] = {}
                qos: dict[str, str] = {}
                for c in reader.connections:
                    counts[c.topic] += c.msgcount
                    types.setdefault(c.topic, c)
                    qos.setdefault(c.topic, _connection_qos(c))
                ros2 = self.path.is_dir()
                channels = tuple(
                    ChannelInfo(
                        topic=topic,
                        type_name=fold_type(c.msgtype),
                        schema_encoding="ros2msg" if ros2 else "ros1msg",
                        message_encoding="cdr" if ros2 else "ros1",
                        count=counts[topic],
                        qos=qos[topic],
                    )
                    for topic, c in types.items()
                )
                total = sum(counts.values())
                return Survey(
                    path=str(self.path),
                    profile="ros2" if ros2 else "ros1",
                    library="rosbag2 (sqlite3)" if ros2 else "rosbag (format 2.0)",
                    channels=channels,
                    start_ns=reader.start_time if total else None,
                    end_ns=reader.end_time - 1 if total else None,  # rosbags: just after the last
                    message_count=total,
                    metadata={},
                    indexed=True,
                    storage="sqlite3" if ros2 else "rosbag 2.0",
                    compression=_compression(reader.readers[0]),
                    files=_files(self.path),
                )
        except OSError as exc:
            raise self._fail(exc) from exc
        except _damaged() as exc:
            raise self._fail(exc) from exc

    def bulk(self, topics: Sequence[str]) -> tuple[list[Batch], list[str]]:
        """A ROS 1 bag's topics that can be decoded in bulk (:mod:`~gridmap_cli.readers.
        bag_bulk`), decoded; and the topics left for :meth:`messages`."""
        if self.path.is_dir():
            return [], list(topics)
        from gridmap_cli.readers.ros.bag.bulk import read_bulk

        return read_bulk(self.path, topics)

    def messages(self, topics: Sequence[str], every_topic: bool) -> Iterator[Message]:
        self._verify()
        if not topics and not every_topic:
            return  # (rosbags reads every connection when given none)
        wanted = set(topics)
        name = str(self.path)
        try:
            with self._reader() as reader:
                connections = [
                    c for c in reader.connections if every_topic or c.topic in wanted
                ]  # fmt: skip
                seen: Counter[str] = Counter()  # messages of each topic so far: names a bad one
                for con, log_time, raw in reader.messages(connections=connections):
                    seen[con.topic] += 1
                    type_name = fold_type(con.msgtype)
                    if con.topic not in wanted:
                        yield name, con.topic, type_name, log_time, None
                        continue
                    try:
                        msg = reader.deserialize(raw, con.msgtype)
                    except Exception as exc:  # the deserialisers raise anything on bad bytes
                        text = " ".join(str(exc).split())[:200]
                        if bytes(raw[:4]) == ZSTD_MAGIC:
                            text += f"; it is zstd-compressed, and {ROSBAG2_METADATA} says not"
                        raise InputFileError(
                            self.path,
                            f"message {seen[con.topic]} of {con.topic} ({type_name}, log time "
                            f"{log_time / 1e9:.9f} s) does not decode "
                            f"({type(exc).__name__}: {text})",
                        ) from exc
                    yield name, con.topic, type_name, log_time, msg
        except InputFileError:
            raise
        except OSError as exc:
            raise self._fail(exc) from exc
        except _damaged() as exc:
            raise self._fail(exc) from exc


def _connection_qos(connection: Any) -> str:
    """A connection's recorded QoS: rosbag2's offered profiles, ROS 1's latching."""
    ext = connection.ext
    profiles = getattr(ext, "offered_qos_profiles", None)
    if profiles:
        return qos_text(
            [
                {
                    "reliability": getattr(p.reliability, "name", p.reliability),
                    "durability": getattr(p.durability, "name", p.durability),
                    "depth": p.depth,
                }
                for p in profiles
            ]
        ).lower()
    return "latched" if getattr(ext, "latching", 0) else ""


def _compression(reader: Any) -> str:
    """How the messages are compressed: a rosbag2 folder says it in its metadata; a ROS 1 bag
    per chunk (rosbags keeps each chunk's decompressor: bz2, lz4, or none)."""
    if hasattr(reader, "compression_format"):
        fmt = str(getattr(reader.compression_format, "name", reader.compression_format) or "")
        return fmt.lower() or "none"
    kinds = set()
    for chunk in getattr(reader, "chunks", {}).values():
        module = getattr(chunk.decompressor, "__module__", "") or ""
        kinds.add("bz2" if "bz2" in module else "lz4" if "lz4" in module else "none")
    return ", ".join(sorted(kinds))


def _files(path: Path) -> tuple[tuple[str, int], ...]:
    """The files a bag or rosbag2 folder is made of, with their sizes."""
    if path.is_dir():
        return tuple((str(f), f.stat().st_size) for f in sorted(path.iterdir()) if f.is_file())
    return ((str(path), path.stat().st_size),)


def rosbag2_sources(folder: Path) -> list[RecordingSource]:
    """The sources of a rosbag2 folder: its MCAP files, or the folder itself (sqlite3), once
    :func:`~gridmap_cli.readers.ros.bag.metadata.read_metadata` has checked them."""
    meta = read_metadata(folder)
    if meta.storage == "mcap":
        return [McapSource(folder / f) for f in meta.files]
    return [BagSource(folder)]


def sources_of(path: Path) -> list[RecordingSource]:
    """The recording sources of a ``.bag`` file or a rosbag2 folder."""
    if path.is_dir():
        return rosbag2_sources(path)
    return [BagSource(path)]


def read_bag(
    source: str | Path,
    options: ReadOptions | None = None,
    strict: bool = True,
    every_topic: bool = False,
) -> RecordingRead:
    """Read a ROS 1 bag or rosbag2 folder (see :func:`~gridmap_cli.readers.ros.recording.
    read_recording` for the arguments)."""
    return read_recording(sources_of(Path(source)), options, strict, every_topic)


def read_bag_log(source: str | Path, options: ReadOptions | None = None) -> RangeLog:
    """Read a ROS 1 bag or rosbag2 folder into the canonical record stream."""
    return read_bag(source, options).log
