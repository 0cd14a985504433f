"""MCAP channels read in bulk: chunk by chunk through the message indexes, decoded with numpy.

An indexed MCAP file (every file gridmap, ``ros2 bag record`` and ``mcap convert`` write) lists
each chunk's messages per channel in a Message Index record: (log time, offset in the
decompressed chunk). So the messages of a channel are found without walking the chunk record by
record, and :mod:`~gridmap_cli.readers.ros.bulk` decodes them all at once. The chunks come from
the integrity walk (:func:`~gridmap_cli.readers.ros.mcap.integrity.verify_mcap`), checked and
decompressed once for both, or, when the file was checked before, are read here with their
CRCs checked. A few MiB of chunks are decoded together (:data:`GROUP_BYTES`): numpy's cost per
call is then small beside the messages'. The first message of each group is also decoded by
the ROS library and compared field by field, so a schema that differs from the standard layout
falls back to message-by-message reading instead of giving wrong values.

A channel is read in bulk when its type is one of :data:`~gridmap_cli.readers.ros.bulk.
BULK_TYPES` with encoding ``cdr`` or ``ros1``, or one of gridmap's JSON types
(:data:`~gridmap_cli.readers.ros.mcap.json_bulk.JSON_TYPES`, encoding ``json``, checked against
``json.loads`` the same way), and the message indexes account for every one of its messages;
the others (and a channel whose bytes are not as expected) are left to the per-message reader.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from mcap.records import Channel, Chunk, Message, Schema
from mcap.stream_reader import get_chunk_data_stream
from mcap.summary import Summary

from gridmap_cli.errors import InputFileError
from gridmap_cli.readers.ros import bulk as ros_bulk
from gridmap_cli.readers.ros.bulk import Columns, IntArray, Layout, Raw
from gridmap_cli.readers.ros.mcap.channels import message_type

#: False turns bulk decoding off: every message through its decoder, the reference path that
#: tests compare the bulk path with.
BULK_DECODE = True

_MESSAGE_INDEX = 0x07
_INDEX_ENTRY = np.dtype([("log_time", "<u8"), ("offset", "<u8")])
_MESSAGE_HEAD = 1 + 8 + 2 + 4 + 8 + 8  # opcode, length, channel id, sequence, log and publish time
#: Bytes of decompressed chunks decoded together: enough messages a decode that numpy's cost per
#: call is small beside theirs (a chunk is often 1 MiB), and small beside a held read's peak.
GROUP_BYTES = 4 << 20


def bulk_enabled() -> bool:
    return BULK_DECODE


@dataclass(frozen=True)
class Batch:
    """Every message of one topic of one file, decoded in bulk, in log-time order."""

    source: str
    topic: str
    type_name: str
    columns: Columns


def read_bulk(
    path: Path,
    handle: Any,
    summary: Summary | None,
    topics: Sequence[str],
    decoder_for: Callable[[Channel, Schema | None], Callable[[bytes], Any]],
    walk: Callable[[Callable[[int, bytes], None]], None] | None = None,
) -> tuple[list[Batch], list[str]]:
    """The topics that can be read in bulk, read; and the topics left to read message by
    message. ``decoder_for`` gives a channel's library decoder (to check the first message of
    each group of chunks).

    ``walk``, when given, goes through the file's chunks in file order and hands each one's
    offset and checked, decompressed records to the function it is given (the integrity walk,
    :func:`~gridmap_cli.readers.ros.mcap.integrity.verify_mcap`): the chunks are then
    decompressed once for both. Without it, the chunks holding the topics are read here."""
    bulk = _BulkRead(path, handle, summary, topics, decoder_for)
    if not bulk.channels:
        if walk is not None:
            walk(lambda start, data: None)
        return [], list(topics)
    if walk is not None:
        walk(bulk.take_chunk)
    else:
        for start in bulk.chunk_at:
            if bulk.wants(start):
                bulk.take_chunk(start, _chunk_data(path, handle, start))
    return bulk.result()


class _BulkRead:
    """A bulk read of some topics of one file, fed its chunks in file order."""

    def __init__(
        self,
        path: Path,
        handle: Any,
        summary: Summary | None,
        topics: Sequence[str],
        decoder_for: Callable[[Channel, Schema | None], Callable[[bytes], Any]],
    ) -> None:
        self.path, self.handle, self.topics = path, handle, list(topics)
        self.decoder_for = decoder_for
        self.channels: dict[int, tuple[Channel, Schema | None, str]] = {}
        self.by_topic: dict[str, list[int]] = {}
        self.chunk_at: dict[int, tuple[int, dict[int, int]]] = {}
        self.counts: dict[int, int] = {}
        if summary is None or not summary.chunk_indexes or summary.statistics is None:
            return
        wanted = set(topics)
        for ch in summary.channels.values():
            if ch.topic not in wanted:
                continue
            self.by_topic.setdefault(ch.topic, []).append(ch.id)
            schema = summary.schemas.get(ch.schema_id)
            type_name = message_type(schema)
            if _bulk_channel(type_name, ch.message_encoding):
                self.channels[ch.id] = (ch, schema, type_name)
        # a topic is read in bulk only if all its channels are
        self.bulk_topics = {
            t for t, ids in self.by_topic.items() if all(i in self.channels for i in ids)
        }
        self.channels = {i: c for i, c in self.channels.items() if c[0].topic in self.bulk_topics}
        chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
        # file order: chunk offset -> (ordinal, each channel's message index record offset)
        self.chunk_at = {
            c.chunk_start_offset: (i, c.message_index_offsets) for i, c in enumerate(chunks)
        }
        self.counts = summary.statistics.channel_message_counts
        self.parts: dict[int, list[Columns]] = {i: [] for i in self.channels}
        self.found = dict.fromkeys(self.channels, 0)
        self.failed: set[int] = set()
        self.group = _Group()
        # a read that cannot go on: no message index where the summary says one is (the topics
        # are then read message by message), or an error, raised once the walk has checked
        # the whole file (damage is named first: the chunks may come before their CRC check)
        self.unindexed = False
        self.error: Exception | None = None

    def wants(self, start: int) -> bool:
        """Whether the chunk at ``start`` holds messages of a channel still read in bulk."""
        at = self.chunk_at.get(start)
        return at is not None and any(i in self.channels and i not in self.failed for i in at[1])

    def take_chunk(self, start: int, data: bytes) -> None:
        """The decompressed records of the chunk at byte ``start`` of the file."""
        if self.unindexed or self.error is not None or not self.wants(start):
            return
        try:
            self._take(start, data)
        except Exception as exc:  # raised by result(), once the walk has found no damage
            self.error = exc

    def _take(self, start: int, data: bytes) -> None:
        ordinal, offsets = self.chunk_at[start]
        todo = [i for i in offsets if i in self.channels and i not in self.failed]
        entries = _message_index(self.path, self.handle, offsets, todo)
        if entries is None:
            self.unindexed = True
            return
        for channel_id, index in entries.items():
            self.found[channel_id] += len(index)
        self.group.add(data, ordinal, entries)
        if self.group.size >= GROUP_BYTES:
            self._decode_group()

    def _decode_group(self) -> None:
        group, self.group = self.group, _Group()
        for channel_id, raw in group.raws():
            if channel_id in self.failed:
                continue
            ch, schema, type_name = self.channels[channel_id]
            try:
                cols = decode_raw(raw(), ch, schema, type_name, self.decoder_for)
            except Layout:
                self.failed.add(channel_id)
                self.parts[channel_id] = []  # read message by message instead
                continue
            self.parts[channel_id].append(cols)

    def result(self) -> tuple[list[Batch], list[str]]:
        """The topics read, and those left to read message by message."""
        if not self.unindexed and self.error is None:
            self._decode_group()
        if self.error is not None:
            raise self.error
        if self.unindexed:
            return [], self.topics
        batches: list[Batch] = []
        done: set[str] = set()
        for topic in sorted(self.bulk_topics):
            ids = self.by_topic[topic]
            if any(i in self.failed or self.found[i] != self.counts.get(i, 0) for i in ids):
                continue
            pieces = [c for i in ids for c in self.parts.pop(i)]  # the parts go once joined
            if not pieces:
                continue
            type_name = self.channels[ids[0]][2]
            batches.append(Batch(str(self.path), topic, type_name, ros_bulk.concat(pieces)))
            done.add(topic)
        return batches, [t for t in self.topics if t not in done]


class _Group:
    """Decompressed chunks decoded together: their records one after another in one buffer,
    and where each channel's message records are in it."""

    def __init__(self) -> None:
        self.chunks: list[bytes] = []
        self.size = 0
        # per channel, per chunk: record offsets in the group, file-order positions, and the
        # bounds of the chunk each record is in
        self.places: dict[int, list[tuple[IntArray, IntArray, IntArray, IntArray]]] = {}

    def add(self, data: bytes, ordinal: int, entries: dict[int, npt.NDArray[np.void]]) -> None:
        """A chunk's records (number ``ordinal`` in file order) and its message index
        ``entries`` per channel."""
        start, end = self.size, self.size + len(data)
        for channel_id, index in entries.items():
            if len(index) == 0:
                continue
            offset = index["offset"].astype(np.int64)
            pos = (np.int64(ordinal) << 32) + offset
            lo, hi = np.full(len(offset), start), np.full(len(offset), end)
            self.places.setdefault(channel_id, []).append((offset + start, pos, lo, hi))
        self.chunks.append(data)
        self.size = end

    def raws(self) -> Iterator[tuple[int, Callable[[], Raw]]]:
        """Each channel's messages in the group, as a function that finds them (and raises
        :class:`Layout` when the channel's index does not point at message records)."""
        if not self.places:
            return
        data = self.chunks[0] if len(self.chunks) == 1 else b"".join(self.chunks)
        self.chunks = []
        buf = np.frombuffer(data, dtype=np.uint8)
        for channel_id, places in self.places.items():
            offset, pos, lo, hi = (np.concatenate(p) for p in zip(*places, strict=True))
            yield channel_id, partial(_records, buf, offset, pos, lo, hi)


def decode_piece(
    buf: npt.NDArray[np.uint8],
    index: npt.NDArray[np.void],
    ordinal: int,
    ch: Channel,
    schema: Schema | None,
    type_name: str,
    decoder_for: Callable[[Channel, Schema | None], Callable[[bytes], Any]],
) -> Columns:
    """One channel's messages in the decompressed chunk ``buf`` (number ``ordinal`` in file
    order), at the message ``index`` entries, decoded in bulk (:func:`decode_raw`)."""
    raw = _raw(buf, index["offset"].astype(np.int64), ordinal)
    return decode_raw(raw, ch, schema, type_name, decoder_for)


def decode_raw(
    raw: Raw,
    ch: Channel,
    schema: Schema | None,
    type_name: str,
    decoder_for: Callable[[Channel, Schema | None], Callable[[bytes], Any]],
) -> Columns:
    """One channel's messages decoded in bulk; the first is decoded by the library too and
    compared. Raises :class:`Layout` when the bulk decoder cannot take them."""
    buf = raw.buf
    json = ch.message_encoding == "json"
    if json:
        from gridmap_cli.readers.ros.mcap import json_bulk  # (msgspec: JSON recordings only)

        cols = json_bulk.decode(type_name, raw)
    else:
        cols = ros_bulk.decode(type_name, raw, ch.message_encoding == "cdr")
    first = bytes(buf[raw.offset[0] : raw.offset[0] + raw.length[0]])
    try:
        msg = decoder_for(ch, schema)(first)
    except InputFileError:
        raise
    except Exception as exc:  # the message-by-message read names the bad message
        raise Layout("the library cannot decode the first message") from exc
    try:
        if json:
            same = json_bulk.matches(type_name, cols, int(raw.pos[0]), msg)
        else:
            same = matches(type_name, cols, int(raw.pos[0]), msg)
    except (AttributeError, TypeError, ValueError, IndexError) as exc:
        # a schema that is not the type's: the message-by-message read names the message
        raise Layout("the library's message lacks the type's fields") from exc
    if not same:
        raise Layout("the library decodes the first message differently")
    return cols


def indexed_messages(
    path: Path, handle: Any, summary: Summary | None, topics: Sequence[str]
) -> list[tuple[Schema | None, Channel, Message]] | None:
    """The messages of ``topics``, found through the message indexes, in the order the
    library's reader yields them (log time, then chunk, then place in the chunk); None when
    the indexes do not account for every message (the library's reader then walks the chunks).

    For the few messages of the topics not read in bulk (a sensor list): the library would
    decode every record of each chunk that holds one of them.
    """
    if summary is None or not summary.chunk_indexes or summary.statistics is None:
        return None
    channels = {i: ch for i, ch in summary.channels.items() if ch.topic in set(topics)}
    counts = summary.statistics.channel_message_counts
    found: list[tuple[int, int, int, Message]] = []
    try:
        for ordinal, ci in enumerate(summary.chunk_indexes):
            todo = [i for i in ci.message_index_offsets if i in channels]
            if not todo:
                continue
            entries = _message_index(path, handle, ci.message_index_offsets, todo)
            if entries is None:
                return None
            buf = np.frombuffer(_chunk_data(path, handle, ci.chunk_start_offset), np.uint8)
            for channel_id, index in entries.items():
                if len(index) == 0:
                    continue
                raw = _raw(buf, index["offset"].astype(np.int64), ordinal)
                spans = zip(raw.offset.tolist(), raw.length.tolist(), strict=True)
                for (start, length), log_ns in zip(spans, raw.log_ns.tolist(), strict=True):
                    data = buf[start : start + length].tobytes()
                    msg = Message(channel_id=channel_id, log_time=log_ns, data=data,
                                  publish_time=log_ns, sequence=0)  # fmt: skip
                    found.append((log_ns, ci.chunk_start_offset, start, msg))
    except (Layout, InputFileError):
        return None
    if any(sum(1 for f in found if f[3].channel_id == i) != counts.get(i, 0) for i in channels):
        return None
    found.sort(key=lambda f: f[:3])
    out = []
    for *_, msg in found:
        channel = channels[msg.channel_id]
        out.append((summary.schemas.get(channel.schema_id), channel, msg))
    return out


def _bulk_channel(type_name: str, message_encoding: str) -> bool:
    """True for the channels decoded in bulk: ROS messages of :data:`~gridmap_cli.readers.
    ros_bulk.BULK_TYPES` and gridmap's JSON messages of
    :data:`~gridmap_cli.readers.ros.mcap.json_bulk.
    JSON_TYPES`."""
    if message_encoding == "json":
        from gridmap_cli.readers.ros.mcap.json_bulk import JSON_TYPES

        return type_name in JSON_TYPES
    return type_name in ros_bulk.BULK_TYPES and message_encoding in ("cdr", "ros1")


def _raw(buf: npt.NDArray[np.uint8], offset: IntArray, ordinal: int) -> Raw:
    """Message records at ``offset`` in one decompressed chunk (number ``ordinal`` in file
    order) -> their data."""
    return _records(buf, offset, (np.int64(ordinal) << 32) + offset, 0, len(buf))


def _records(
    buf: npt.NDArray[np.uint8],
    offset: IntArray,
    pos: IntArray,
    lo: IntArray | int,
    hi: IntArray | int,
) -> Raw:
    """Message records at ``offset`` in ``buf``, each inside its chunk's records [lo, hi),
    ``pos`` their file-order positions -> their data."""
    if np.any(offset < lo) or np.any(offset + _MESSAGE_HEAD > hi):
        raise Layout("message index points past the chunk")
    head = ros_bulk.gather_bytes(buf, offset, 23)  # opcode to log time: one gather a record
    if np.any(ros_bulk.column(head, 0, np.dtype("u1")) != 0x05):
        raise Layout("message index points at something else")
    length = ros_bulk.column(head, 1, np.dtype("<u8")).astype(np.int64) - (_MESSAGE_HEAD - 9)
    log_ns = ros_bulk.column(head, 15, np.dtype("<u8")).astype(np.int64)
    data = offset + _MESSAGE_HEAD
    if np.any(length < 0) or np.any(data + length > hi):
        raise Layout("message runs past the chunk")
    return Raw(buf, data, length, log_ns, pos)


def _message_index(
    path: Path, handle: Any, offsets: dict[int, int], channel_ids: list[int]
) -> dict[int, npt.NDArray[np.void]] | None:
    """Each channel's (log time, offset) entries in a chunk, sorted as the reader yields them:
    by log time, then by place in the chunk."""
    out = {}
    for channel_id in channel_ids:
        handle.seek(offsets[channel_id])
        head = handle.read(1 + 8 + 2 + 4)
        if len(head) < 15 or head[0] != _MESSAGE_INDEX:
            return None
        size = int.from_bytes(head[11:15], "little")
        body = handle.read(size)
        if len(body) != size or size % _INDEX_ENTRY.itemsize:
            raise InputFileError(path, "truncated or damaged MCAP message index")
        entries = np.frombuffer(body, dtype=_INDEX_ENTRY)
        out[channel_id] = entries[np.lexsort((entries["offset"], entries["log_time"]))]
    return out


def _chunk_data(path: Path, handle: Any, start: int) -> bytes:
    """The decompressed records of the chunk at ``start``, CRC checked."""
    from mcap.data_stream import ReadDataStream
    from mcap.exceptions import McapError

    handle.seek(start)
    stream = ReadDataStream(handle)
    try:
        if stream.read1() != 0x06:
            raise InputFileError(path, f"damaged MCAP file: no chunk at byte {start}")
        stream.read8()
        chunk = Chunk.read(stream)
        data, length = get_chunk_data_stream(chunk, validate_crc=True)
        return bytes(data.read(length))
    except McapError as exc:
        raise InputFileError(
            path, f"truncated or damaged MCAP chunk at byte {start} ({type(exc).__name__}: {exc})"
        ) from exc


# ---------------------------------------------------------------------- the library's view
def matches(type_name: str, cols: Columns, pos: int, msg: Any) -> bool:
    """True if the rows of the message at ``pos`` hold what the ROS library decoded from it."""
    a = cols.arrays

    def stamp(header: Any) -> int:
        s = header.stamp
        if hasattr(s, "secs"):
            return int(s.secs) * 1_000_000_000 + int(s.nsecs)
        return int(s.sec) * 1_000_000_000 + int(s.nanosec)

    def same(values: list[Any], expected: list[Any]) -> bool:
        return all(
            (v == e) or (isinstance(e, float) and e != e and v != v)
            for v, e in zip(values, expected, strict=True)
        )

    if type_name in ros_bulk.TF_TYPES:
        rows = np.flatnonzero(a["pos"] == pos)
        if len(rows) != len(msg.transforms):
            return False
        for row, t in zip(rows.tolist(), msg.transforms, strict=True):
            got = [int(a["stamp_ns"][row]), cols.names["parent"][int(a["parent"][row])]]
            got += [cols.names["child"][int(a["child"][row])]]
            got += [float(a[k][row]) for k in ("tx", "ty", "tz", "qx", "qy", "qz", "qw")]
            v, q = t.transform.translation, t.transform.rotation
            want = [stamp(t.header), t.header.frame_id, t.child_frame_id, v.x, v.y, v.z]
            want += [q.x, q.y, q.z, q.w]
            if not same(got, want):
                return False
        return True
    row = int(np.flatnonzero(a["pos"] == pos)[0])
    got = [int(a["stamp_ns"][row]), cols.names["frame"][int(a["frame"][row])]]
    want = [stamp(msg.header), msg.header.frame_id]
    if type_name == "sensor_msgs/Range":
        got += [float(a[k][row]) for k in ("fov", "min", "max", "range")]
        want += [msg.field_of_view, msg.min_range, msg.max_range, msg.range]
    elif type_name == "nav_msgs/Odometry":
        got += [cols.names["child"][int(a["child"][row])]]
        got += [float(a[k][row]) for k in ("x", "y", "qx", "qy", "qz", "qw")]
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        want += [msg.child_frame_id, p.x, p.y, q.x, q.y, q.z, q.w]
    elif type_name == "sensor_msgs/LaserScan":
        keys = ("angle_min", "angle_max", "angle_increment", "range_min", "range_max")
        got += [float(a[k][row]) for k in keys]
        want += [msg.angle_min, msg.angle_max, msg.angle_increment, msg.range_min, msg.range_max]
        start = int(np.sum(a["count"][:row]))
        got += [float(v) for v in cols.ranges[start : start + int(a["count"][row])]]  # type: ignore[index]
        want += [float(v) for v in msg.ranges]
        if int(a["count"][row]) != len(msg.ranges):
            return False
    return same(got, [float(w) if isinstance(w, float) else w for w in want])
