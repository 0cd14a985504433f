"""Long MCAP recordings read without holding their range readings: checked once, read per pass.

As for long CSV logs (:mod:`~gridmap_cli.readers.text.csv_stream`): a build goes through the
readings
twice and never needs them all at once. A single MCAP file of :data:`STREAM_FROM_BYTES` or more
gets a checking pass that reads it as the held reader does (:func:`~gridmap_cli.readers.
ros_recording.read_recording`: pose tracks, TF, sensors, every check), except that its range
topic (``sensor_msgs/Range``, or ``sensor_msgs/LaserScan``: a sensor a beam) is decoded here
chunk by chunk through the message indexes (:mod:`~gridmap_cli.readers.ros.mcap.bulk`), each
chunk's readings counted and let go. Each later pass decodes the range topic's
messages again, chunk by chunk, and gives the readings the held reader's
:meth:`~gridmap_cli.readers.ros.messages.MessageAccumulator.finish` gives: by stamp, ties by
sensor, the same sensor indexes and values, bit for bit.

That order comes chunk by chunk only when no chunk holds a reading stamped before one of an
earlier chunk (header stamps can disagree with log time); the checking pass makes sure of it.
Anything else unusual leaves the recording to the held reader, which reads it (and reports what
is wrong) as it always has: several range topics or channels, a range type other than
``sensor_msgs/Range`` and ``LaserScan``, several laser frames (or beams whose sensors are not
consecutive), gridmap's JSON channels, a channel the bulk decoder cannot take, an unindexed
file, a laser whose scans change their geometry, an error anywhere.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import GridmapError, InputFileError
from gridmap_cli.readers.options import ReadOptions
from gridmap_cli.readers.ros.batches import _frames, _stamps, add_columns, scan_beams
from gridmap_cli.readers.ros.bulk import Columns, Layout, decode, lexsort_order
from gridmap_cli.readers.ros.mcap.bulk import (
    _chunk_data,
    _message_index,
    _raw,
    bulk_enabled,
    decode_piece,
)
from gridmap_cli.readers.ros.mcap.channels import DAMAGED, message_type, open_reader, read_summary
from gridmap_cli.readers.ros.mcap.log import McapSource, library_decoders
from gridmap_cli.readers.ros.messages import MessageAccumulator, float32_decimal
from gridmap_cli.readers.ros.recording import read_recording
from gridmap_cli.readers.ros.topics import Plan
from gridmap_cli.records import RangeLog, RangeReadings, ReadingStream

#: Files of this size or more stream their range readings. The bench's hour of 16 sonars as ROS 2
#: MCAP is 18 MB (576,000 readings); held, its readings cost about 40 bytes each at the peak
#: (the decoded columns, the accumulator's arrays, the sorted log): 64 MiB of MCAP is about 3.5
#: hours of that ring, some 80 MiB of readings, where the second decode of the range topic
#: (about 0.3 s an hour) is worth the memory; below it a held read is as fast as ever.
STREAM_FROM_BYTES = 64 << 20
#: A laser's beams cost about 5 bytes of MCAP each (float32 ranges) against the same 40 held:
#: 8 MiB of scans is some 1.6 million beams, about 200 MiB of peak held (a simulated half hour
#: of a 181-beam laser at 10 Hz, 18 MB, peaked at 445 MiB held, 126 MiB streamed, for no more
#: CPU), so a recording with a LaserScan channel streams from here.
SCAN_STREAM_FROM_BYTES = 8 << 20
RANGE_TYPE = "sensor_msgs/Range"
SCAN_TYPE = "sensor_msgs/LaserScan"


class _Unusual(Exception):
    """The recording is not one this reader streams: the held reader reads it."""


def stream_from_bytes(scans: bool = False) -> int:
    """The size from which a recording streams: lower when it holds laser scans."""
    default = SCAN_STREAM_FROM_BYTES if scans else STREAM_FROM_BYTES
    return default


def _has_scans(path: Path) -> bool:
    """Whether the recording's summary names a ``sensor_msgs/LaserScan`` channel (False for
    a file that does not say: the held reader reads it, and reports any damage)."""
    try:
        with open(path, "rb") as handle:
            summary = read_summary(path, open_reader(path, handle))
    except (GridmapError, *DAMAGED):
        return False
    if summary is None:
        return False
    return any(
        message_type(summary.schemas.get(ch.schema_id)) == SCAN_TYPE
        for ch in summary.channels.values()
    )


def read_streamed(path: Path, options: ReadOptions) -> RangeLog | None:
    """The MCAP recording at ``path`` with its readings streamed (:attr:`RangeLog.stream`);
    None when it is small or anything is unusual, for the held reader to read (and report)."""
    try:
        size = path.stat().st_size
        if not bulk_enabled():
            return None
        if size < stream_from_bytes() and (
            size < stream_from_bytes(scans=True) or not _has_scans(path)
        ):
            return None
        seen = _stat(path)
        check = _Check(path)
        source = McapSource(path)
        source.verify()  # before the checking pass reads the range topic's chunks
        read = read_recording([source], options, ranges_apart=check.read)
        return check.log(read.log, seen)
    except (_Unusual, GridmapError, OSError):
        return None


def _stat(path: Path) -> tuple[int, int]:
    st = path.stat()
    return st.st_size, st.st_mtime_ns


@dataclasses.dataclass
class _Chunk:
    """A chunk holding range messages: its offset and the channel's message index record's."""

    start: int
    index_at: int


class _Check:
    """The checking pass over the range topic: state for :meth:`log` afterwards."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.acc: MessageAccumulator | None = None
        self.chunks: list[_Chunk] = []
        self.channel_id = 0
        self.cdr = True
        self.type_name = RANGE_TYPE
        # per accumulator key (sensor frame): readings, first and last stamp
        self.counts = np.zeros(0, np.int64)
        self.first_ns = np.zeros(0, np.int64)
        self.last_ns = np.zeros(0, np.int64)

    def read(self, acc: MessageAccumulator, plan: Plan) -> None:
        """Read the plan's one ``sensor_msgs/Range`` or ``sensor_msgs/LaserScan`` topic into
        ``acc`` chunk by chunk, keeping the counts and stamps of its readings, not the readings
        (a bad scan raises the held reader's error here)."""
        self.acc = acc
        if len(plan.range_topics) != 1 or plan.sensors_topic is not None:
            raise _Unusual
        topic = plan.range_topics[0]
        path = self.path
        decoder_for = library_decoders(path)
        try:
            with open(path, "rb") as handle:
                reader = open_reader(path, handle)
                summary = read_summary(path, reader)
                if summary is None or not summary.chunk_indexes or summary.statistics is None:
                    raise _Unusual
                ids = [i for i, ch in summary.channels.items() if ch.topic == topic]
                if len(ids) != 1:
                    raise _Unusual
                ch = summary.channels[ids[0]]
                schema = summary.schemas.get(ch.schema_id)
                type_name = message_type(schema)
                if type_name not in (RANGE_TYPE, SCAN_TYPE) or ch.message_encoding not in (
                    "cdr",
                    "ros1",
                ):
                    raise _Unusual
                self.channel_id, self.cdr = ch.id, ch.message_encoding == "cdr"
                self.type_name = type_name
                found = 0
                latest: int | None = None
                chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
                for ordinal, ci in enumerate(chunks):
                    if ch.id not in ci.message_index_offsets:
                        continue
                    entries = _message_index(path, handle, ci.message_index_offsets, [ch.id])
                    if entries is None:
                        raise _Unusual
                    index = entries[ch.id]
                    if len(index) == 0:
                        continue
                    found += len(index)
                    buf = np.frombuffer(_chunk_data(path, handle, ci.chunk_start_offset), np.uint8)
                    cols = decode_piece(buf, index, ordinal, ch, schema, type_name, decoder_for)
                    del buf
                    add_columns(acc, str(path), topic, type_name, cols)
                    stamp, key, _, _ = acc.r_chunks.pop()
                    if acc.r_chunks or acc.r_stamp:
                        raise _Unusual
                    if len(stamp):
                        # each chunk's readings after every earlier chunk's: sorted chunk by chunk
                        if latest is not None and int(stamp.min()) < latest:
                            raise _Unusual
                        latest = int(stamp.max())
                        self._count(stamp, key, len(acc.keys))
                    self.chunks.append(
                        _Chunk(ci.chunk_start_offset, ci.message_index_offsets[ch.id])
                    )
                if found != summary.statistics.channel_message_counts.get(ch.id, 0):
                    raise _Unusual
        except Layout:
            raise _Unusual from None
        except DAMAGED:
            raise _Unusual from None

    def _count(self, stamp: npt.NDArray[np.int64], key: npt.NDArray[np.int64], n_keys: int) -> None:
        grow = n_keys - len(self.counts)
        if grow > 0:
            self.counts = np.concatenate((self.counts, np.zeros(grow, np.int64)))
            self.first_ns = np.concatenate((self.first_ns, np.full(grow, np.iinfo(np.int64).max)))
            self.last_ns = np.concatenate((self.last_ns, np.full(grow, np.iinfo(np.int64).min)))
        self.counts += np.bincount(key, minlength=n_keys)
        np.minimum.at(self.first_ns, key, stamp)
        np.maximum.at(self.last_ns, key, stamp)

    def log(self, held: RangeLog, seen: tuple[int, int]) -> RangeLog:
        """The checked log with its readings streamed."""
        acc = self.acc
        if acc is None or len(held.readings) or not self.chunks:
            raise _Unusual
        names = {name: i for i, name in enumerate(held.sensor_names)}
        n_sensors = len(held.sensor_names)
        sensor_of_key = np.array([names[k] for k in acc.keys], dtype=np.int32)
        counts = np.zeros(n_sensors, np.int64)
        first_ns = np.zeros(n_sensors, np.int64)
        last_ns = np.zeros(n_sensors, np.int64)
        n = len(self.counts)
        counts[sensor_of_key[:n]] = self.counts
        first_ns[sensor_of_key[:n]] = self.first_ns
        last_ns[sensor_of_key[:n]] = self.last_ns
        if not counts.sum():
            raise _Unusual
        max_r = None
        if held.sensors:
            by_name = {s.name: s.max_range_m for s in held.sensors}
            max_r = np.array([by_name.get(name, np.inf) for name in held.sensor_names])
        readings_of: Callable[[Columns], RangeReadings]
        if self.type_name == SCAN_TYPE:
            readings_of = partial(_scan_readings, *self._beams(names), max_r)
        else:
            sensor_of_frame = {k: int(sensor_of_key[i]) for i, k in enumerate(acc.keys)}
            readings_of = partial(_readings, sensor_of_frame=sensor_of_frame, max_r=max_r)
        again = partial(
            _read_again,
            self.path,
            seen,
            self.channel_id,
            self.cdr,
            self.type_name,
            [(c.start, c.index_at) for c in self.chunks],
            readings_of,
        )
        index = np.arange(n_sensors, dtype=np.int32)
        stream = ReadingStream(again, counts, first_ns, last_ns, index)
        return dataclasses.replace(held, stream=stream)

    def _beams(self, names: dict[str, int]) -> tuple[dict[str, int], dict[str, int]]:
        """The one laser frame's first beam sensor index and beam count; several laser frames,
        scans of several geometries, or beams whose sensors are not consecutive, are left to
        the held reader."""
        assert self.acc is not None
        scans = self.acc.scans
        if len(scans) != 1 or self.acc.sonars:
            raise _Unusual
        ((frame, scan),) = scans.items()
        if scan.book.varied:
            raise _Unusual
        first = names.get(f"{frame}_0")
        if first is None or [names.get(f"{frame}_{j}") for j in range(scan.count)] != list(
            range(first, first + scan.count)
        ):
            raise _Unusual
        return {frame: first}, {frame: scan.count}


def _read_again(
    path: Path,
    seen: tuple[int, int],
    channel_id: int,
    cdr: bool,
    type_name: str,
    chunks: list[tuple[int, int]],
    readings_of: Callable[[Columns], RangeReadings],
) -> Iterator[RangeReadings]:
    """The checked recording's readings, decoded again chunk by chunk and sorted as
    :meth:`MessageAccumulator.finish` sorts them; a chunk's readings of its last stamp wait for
    the next chunk's (a block never splits one stamp's readings)."""
    changed = InputFileError(path, "the file changed while gridmap read it")
    if _stat(path) != seen:
        raise changed
    tail = RangeReadings.empty()
    try:
        with open(path, "rb") as handle:
            for ordinal, (start, index_at) in enumerate(chunks):
                entries = _message_index(path, handle, {channel_id: index_at}, [channel_id])
                if entries is None:
                    raise changed
                buf = np.frombuffer(_chunk_data(path, handle, start), np.uint8)
                cols = _decode(buf, entries[channel_id], ordinal, cdr, type_name)
                del buf
                block = readings_of(cols)
                del cols
                if len(block) == 0:
                    continue
                if len(tail) and int(block.stamp_ns.min()) < int(tail.stamp_ns[0]):
                    raise changed
                both = RangeReadings(
                    np.concatenate((tail.stamp_ns, block.stamp_ns)),
                    np.concatenate((tail.sensor, block.sensor)),
                    np.concatenate((tail.range_m, block.range_m)),
                )
                order = lexsort_order((both.sensor, both.stamp_ns))  # stable: ties as held
                if order is not None:
                    both = RangeReadings(
                        both.stamp_ns[order], both.sensor[order], both.range_m[order]
                    )
                cut = int(np.searchsorted(both.stamp_ns, both.stamp_ns[-1], "left"))
                if cut:
                    yield both.part(slice(0, cut))
                tail = both.part(slice(cut, None))
    except (Layout, *DAMAGED):
        raise changed from None
    if len(tail):
        yield tail


def _decode(
    buf: npt.NDArray[np.uint8], index: Any, ordinal: int, cdr: bool, type_name: str
) -> Columns:
    return decode(type_name, _raw(buf, index["offset"].astype(np.int64), ordinal), cdr)


def _readings(
    cols: Columns, *, sensor_of_frame: dict[str, int], max_r: npt.NDArray[np.float64] | None
) -> RangeReadings:
    """One chunk's readings as ``ros_batches._ranges`` keeps them and ``finish`` turns them
    into the log's: float32 decimals, no echo at the sensor's maximum range."""
    a = cols.arrays
    index, frames = _frames(cols)
    sensor = np.array([sensor_of_frame[f] for f in frames], dtype=np.int32)[index]
    rmax = a["max"].astype(np.float64)
    value = a["range"].astype(np.float64)
    with np.errstate(invalid="ignore"):
        keep = ~np.isnan(value) & (value >= 0.0)
        value = np.where(value >= rmax, np.inf, value)
    rng = float32_decimal(value[keep])
    sensor = sensor[keep]
    if max_r is not None and len(rng):
        rng = np.where(np.isinf(rng), max_r[sensor], rng)
    return RangeReadings(_stamps(cols)[keep], sensor, rng)


def _scan_readings(
    first_sensor: dict[str, int],
    beams: dict[str, int],
    max_r: npt.NDArray[np.float64] | None,
    cols: Columns,
) -> RangeReadings:
    """One chunk's scans as ``ros_batches._scans`` keeps their beams and ``finish`` turns them
    into the log's: beam ``j`` of a frame is sensor ``first_sensor[frame] + j``; float32
    decimals; no echo (at or beyond the scan's ``range_max``) at the beam's maximum range (the
    first scan's). A scan of another frame or beam count than the checking pass saw raises
    :class:`Layout` (the file changed)."""
    a = cols.arrays
    n = len(cols)
    index, frames = _frames(cols)
    count = a["count"].astype(np.int64)
    if any(f not in beams for f in frames):
        raise Layout("a laser frame the checking pass did not see")
    if n and not np.array_equal(count, np.array([beams[f] for f in frames])[index]):
        raise Layout("a scan with another beam count than the checking pass saw")
    base = np.array([first_sensor[f] for f in frames], dtype=np.int64)[index]
    row, beam, value = scan_beams(cols, count)
    rng = float32_decimal(value)
    sensor = (base[row] + beam).astype(np.int32)
    if max_r is not None and len(rng):
        rng = np.where(np.isinf(rng), max_r[sensor], rng)
    return RangeReadings(_stamps(cols)[row], sensor, rng)
