"""ROS 1 bag channels read in bulk: chunk by chunk through the bag's index, decoded with numpy.

A ROS 1 bag (format 2.0) ends with its connections and one Chunk Info record per chunk; each
chunk is followed by Index Data records giving, per connection, every message's time and offset
in the decompressed chunk. So a topic's messages are found without walking the chunk, and
:mod:`~gridmap_cli.readers.ros.bulk` decodes them all at once. A connection is read in bulk when
its type is one of :data:`~gridmap_cli.readers.ros.bulk.BULK_TYPES` and its MD5 sum is the
standard definition's (so the layout is known); anything else, or anything unexpected in the
file, is left to the ``rosbags`` reader, message by message, which raises the precise error.
"""

from __future__ import annotations

import bz2
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

import numpy as np
import numpy.typing as npt

from gridmap_cli.readers.ros import bulk as ros_bulk
from gridmap_cli.readers.ros.bulk import Columns, Layout, Raw
from gridmap_cli.readers.ros.mcap.bulk import Batch
from gridmap_cli.readers.ros.topics import ChannelInfo, Survey, fold_type

#: MD5 sums of the standard ROS 1 definitions whose layout ros_bulk knows.
STANDARD_MD5 = {
    "sensor_msgs/Range": "c005c34273dc426c67a020a87bc24148",
    "sensor_msgs/LaserScan": "90c7ef2dc6895d81024acba2ac42f369",
    "nav_msgs/Odometry": "cd5e73d190d741a2f92e81eda573aca7",
    "tf2_msgs/TFMessage": "94810edda583a504dfda3829e70d7eec",
    "tf/tfMessage": "94810edda583a504dfda3829e70d7eec",
}

_INDEX_ENTRY = np.dtype([("secs", "<u4"), ("nsecs", "<u4"), ("offset", "<u4")])


def _record(handle: IO[bytes]) -> tuple[dict[str, bytes], int] | None:
    """The header fields of the record at the handle, and its data length (the handle is left
    at the data). None at the end of the file."""
    head = handle.read(4)
    if len(head) < 4:
        return None
    size = int.from_bytes(head, "little")
    raw = handle.read(size)
    if len(raw) != size:
        raise Layout("truncated record header")
    fields: dict[str, bytes] = {}
    at = 0
    while at < size:
        n = int.from_bytes(raw[at : at + 4], "little")
        name, sep, value = raw[at + 4 : at + 4 + n].partition(b"=")
        if not sep:
            raise Layout("record header field without '='")
        fields[name.decode("ascii", "replace")] = value
        at += 4 + n
    data = handle.read(4)
    if len(data) < 4:
        raise Layout("truncated record")
    return fields, int.from_bytes(data, "little")


def _u(value: bytes) -> int:
    return int.from_bytes(value, "little")


def read_bulk(path: Path, topics: Sequence[str]) -> tuple[list[Batch], list[str]]:
    """The topics that can be read in bulk, read; and the topics left for ``rosbags``."""
    try:
        return _read(path, topics)
    except (Layout, OSError, ValueError, KeyError, EOFError):
        return [], list(topics)


@dataclass
class _Index:
    """What a bag's index section says: connections (id -> topic, folded type, MD5 sum,
    latching), chunks (position, first and last message time) and messages per connection."""

    conns: dict[int, tuple[str, str, str, bool]] = field(default_factory=dict)
    chunks: list[tuple[int, int, int]] = field(default_factory=list)
    counts: dict[int, int] = field(default_factory=dict)


def _time(value: bytes) -> int:
    return _u(value[:4]) * 1_000_000_000 + _u(value[4:8])


def _index(handle: IO[bytes]) -> _Index:
    if handle.read(13) != b"#ROSBAG V2.0\n":
        raise Layout("not a bag")
    found = _record(handle)
    if found is None or _u(found[0].get("op", b"")) != 0x03:
        raise Layout("no bag header")
    index_pos = _u(found[0]["index_pos"])
    conn_count, chunk_count = _u(found[0]["conn_count"]), _u(found[0]["chunk_count"])
    if index_pos == 0:
        raise Layout("unindexed bag")
    handle.seek(index_pos)
    out = _Index()
    while (found := _record(handle)) is not None:
        fields, size = found
        data = handle.read(size)
        op = _u(fields.get("op", b""))
        if op == 0x07:
            info = _fields(data)
            out.conns[_u(fields["conn"])] = (
                fields["topic"].decode(),
                fold_type(info["type"].decode()),
                info.get("md5sum", b"").decode(),
                info.get("latching", b"0") == b"1",
            )
        elif op == 0x06:
            start, end = _time(fields["start_time"]), _time(fields["end_time"])
            out.chunks.append((_u(fields["chunk_pos"]), start, end))
            pairs = np.frombuffer(data, dtype="<u4").reshape(-1, 2)
            for conn, n in pairs.tolist():
                out.counts[conn] = out.counts.get(conn, 0) + n
    if len(out.conns) != conn_count or len(out.chunks) != chunk_count:
        raise Layout("the index section is not what the bag header says (truncated?)")
    return out


def survey_bag(path: Path) -> Survey | None:
    """A ROS 1 bag's survey from its index section alone (what ``rosbags`` reports, without
    indexing every message); None when the bag is not as expected."""
    try:
        with open(path, "rb") as handle:
            index = _index(handle)
            kinds = set()
            for chunk_pos, _, _ in index.chunks:
                handle.seek(chunk_pos)
                found = _record(handle)
                if found is None or _u(found[0].get("op", b"")) != 0x05:
                    raise Layout("no chunk where the index says")
                kinds.add(found[0]["compression"].decode())
    except (Layout, OSError, ValueError, KeyError, UnicodeDecodeError):
        return None
    counts: dict[str, int] = {}
    first: dict[str, tuple[str, bool]] = {}
    for conn in sorted(index.conns):
        topic, type_name, _, latching = index.conns[conn]
        counts[topic] = counts.get(topic, 0) + index.counts.get(conn, 0)
        first.setdefault(topic, (type_name, latching))
    channels = tuple(
        ChannelInfo(topic, type_name, "ros1msg", "ros1", counts[topic], "latched" if lat else "")
        for topic, (type_name, lat) in first.items()
    )
    total = sum(counts.values())
    return Survey(
        path=str(path),
        profile="ros1",
        library="rosbag (format 2.0)",
        channels=channels,
        start_ns=min(c[1] for c in index.chunks) if total else None,
        end_ns=max(c[2] for c in index.chunks) if total else None,
        message_count=total,
        metadata={},
        indexed=True,
        storage="rosbag 2.0",
        compression=", ".join(sorted(kinds)),
        files=((str(path), path.stat().st_size),),
    )


def _read(path: Path, topics: Sequence[str]) -> tuple[list[Batch], list[str]]:
    wanted = set(topics)
    with open(path, "rb") as handle:
        index = _index(handle)
        conns, counts = index.conns, index.counts
        chunks = [c[0] for c in index.chunks]
        by_topic: dict[str, list[int]] = {}
        for conn, (topic, _, _, _) in conns.items():
            if topic in wanted:
                by_topic.setdefault(topic, []).append(conn)
        bulk_topics = sorted(
            t
            for t, ids in by_topic.items()
            if len({conns[i][1] for i in ids}) == 1
            and all(STANDARD_MD5.get(conns[i][1]) == conns[i][2] for i in ids)
        )
        use = {i for t in bulk_topics for i in by_topic[t]}
        parts: dict[int, list[Columns]] = {i: [] for i in use}
        seen = dict.fromkeys(use, 0)
        for ordinal, chunk_pos in enumerate(sorted(chunks)):
            handle.seek(chunk_pos)
            chunk = _record(handle)
            if chunk is None or _u(chunk[0].get("op", b"")) != 0x05:
                raise Layout("no chunk where the index says")
            fields, size = chunk
            data = _decompress(fields["compression"].decode(), handle.read(size))
            buf = np.frombuffer(data, dtype=np.uint8)
            while True:  # the chunk's index data records follow it
                where = handle.tell()
                found = _record(handle)
                if found is None or _u(found[0].get("op", b"")) != 0x04:
                    handle.seek(where)
                    break
                ifields, isize = found
                if _u(ifields.get("ver", b"")) != 1:
                    raise Layout("index data of another version")
                entries = np.frombuffer(handle.read(isize), dtype=_INDEX_ENTRY)
                conn = _u(ifields["conn"])
                if conn not in use or len(entries) == 0:
                    continue
                seen[conn] += len(entries)
                log_ns = entries["secs"].astype(np.int64) * 1_000_000_000 + entries["nsecs"]
                order = np.lexsort((entries["offset"], log_ns))
                raw = _raw(buf, entries["offset"].astype(np.int64)[order], log_ns[order], ordinal)
                parts[conn].append(ros_bulk.decode(conns[conn][1], raw, cdr=False))
        batches = []
        for topic in bulk_topics:
            ids = by_topic[topic]
            if any(seen[i] != counts.get(i, 0) for i in ids):
                raise Layout("the index does not account for every message")
            pieces = [c for i in ids for c in parts[i]]
            if pieces:
                type_name = conns[ids[0]][1]
                batches.append(Batch(str(path), topic, type_name, ros_bulk.concat(pieces)))
    done = {b.topic for b in batches}
    return batches, [t for t in topics if t not in done]


def _fields(data: bytes) -> dict[str, bytes]:
    out: dict[str, bytes] = {}
    at = 0
    while at + 4 <= len(data):
        n = int.from_bytes(data[at : at + 4], "little")
        name, _, value = data[at + 4 : at + 4 + n].partition(b"=")
        out[name.decode("ascii", "replace")] = value
        at += 4 + n
    return out


def _decompress(kind: str, data: bytes) -> bytes:
    if kind == "none":
        return data
    if kind == "bz2":
        return bz2.decompress(data)
    if kind == "lz4":
        import lz4.frame

        out: bytes = lz4.frame.decompress(data)
        return out
    raise Layout(f"chunk compression {kind}")


def _raw(
    buf: npt.NDArray[np.uint8], offset: npt.NDArray[np.int64], log_ns: npt.NDArray[np.int64],
    ordinal: int,
) -> Raw:  # fmt: skip
    """Message data records at ``offset`` in a decompressed chunk -> their data."""
    if np.any(offset + 4 > len(buf)):
        raise Layout("index points past the chunk")
    header_len = buf[offset[:, None] + np.arange(4)].view("<u4").reshape(-1).astype(np.int64)
    at = offset + 4 + header_len
    if np.any(at + 4 > len(buf)):
        raise Layout("record header past the chunk")
    length = buf[at[:, None] + np.arange(4)].view("<u4").reshape(-1).astype(np.int64)
    if np.any(at + 4 + length > len(buf)):
        raise Layout("message past the chunk")
    return Raw(buf, at + 4, length, log_ns, (np.int64(ordinal) << 32) + offset)
