"""The canonical record stream every reader produces and every later stage consumes.

Columnar (numpy arrays, one entry per record) because a one-hour log holds hundreds of thousands
of readings and every later stage works on them in vectorised batches. Stamps are integer
nanoseconds; everything else is SI (metres, radians). Arrays are time-ordered.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import InputFileError
from gridmap_cli.robot import RangeSensor

#: Where each reader finds a log's ground truth, for the error when a log has none.
TRUTH_SOURCES = (
    "CSV true_x, true_y, true_theta columns, ARIA robotGlobal: lines in every block, a CARMEN "
    "log's TRUEPOS lines or corrected poses, or a ROS recording's reference: --pose-topic, a "
    "ground_truth topic, TF map -> base or /amcl_pose"
)


@dataclass(frozen=True)
class PoseTrack:
    """A time series of planar poses, shape (N,) each.

    ``stamp_ns`` is strictly increasing; ``x_m``, ``y_m`` in metres and ``theta_rad`` in radians
    give the pose of the robot base in the track's frame (odometry frame for odometry, world frame
    for ground truth).
    """

    stamp_ns: npt.NDArray[np.int64]
    x_m: npt.NDArray[np.float64]
    y_m: npt.NDArray[np.float64]
    theta_rad: npt.NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.stamp_ns.shape[0])

    @classmethod
    def from_rows(
        cls, stamp_ns: npt.NDArray[np.int64], rows: Sequence[tuple[float, float, float]]
    ) -> PoseTrack:
        """A track from (x_m, y_m, theta_rad) rows, one per stamp."""
        arr = np.asarray(rows, dtype=np.float64).reshape(len(rows), 3)
        return cls(
            stamp_ns=stamp_ns,
            x_m=np.ascontiguousarray(arr[:, 0]),
            y_m=np.ascontiguousarray(arr[:, 1]),
            theta_rad=np.ascontiguousarray(arr[:, 2]),
        )


@dataclass(frozen=True)
class RangeReadings:
    """Range readings, shape (M,) each, ordered by stamp (ties in sensor order).

    ``sensor`` indexes :attr:`RangeLog.sensor_names`. ``range_m`` is positive and never NaN; a
    range at or beyond the sensor's maximum, ``+inf`` included (a CSV's ``inf``, REP 117's "no
    detection"), means "no echo": sync caps it at the maximum, writers with sensor geometry write
    the maximum. Absent readings (empty or NaN in a log) are not records at all.
    """

    stamp_ns: npt.NDArray[np.int64]
    sensor: npt.NDArray[np.int32]
    range_m: npt.NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.stamp_ns.shape[0])

    def part(self, sl: slice) -> RangeReadings:
        """The readings ``sl`` picks (views, not copies)."""
        return RangeReadings(self.stamp_ns[sl], self.sensor[sl], self.range_m[sl])

    @classmethod
    def empty(cls) -> RangeReadings:
        return cls(np.empty(0, np.int64), np.empty(0, np.int32), np.empty(0, np.float64))


def cut_chunks(blocks: Iterable[RangeReadings], size: int) -> Iterator[RangeReadings]:
    """The readings of ``blocks``, in order, in chunks of about ``size``, each cut where the
    stamp changes (a scan's beams stay in one chunk); a single stamp holding more than ``size``
    readings is kept whole. The cuts are :func:`gridmap_cli.mapping.shards.batch_bounds`' over all
    the readings at once, whatever the blocks are, provided no block splits one stamp's
    readings: the chunks of a log read again block by block are the held log's, reading for
    reading, so every sum over them is the same to the bit."""
    pending: list[RangeReadings] = []  # whole blocks, fewer than ``size`` readings in all
    held = 0
    for block in blocks:
        if len(block) == 0:
            continue
        pending.append(block)
        held += len(block)
        if held < size:
            continue
        buf = _joined(pending)
        start = 0
        while len(buf) - start >= size:
            # the stamp at the cut ends in this buffer: no block splits a stamp
            stop = int(np.searchsorted(buf.stamp_ns, buf.stamp_ns[start + size - 1], "right"))
            yield buf.part(slice(start, stop))
            start = stop
        pending = [buf.part(slice(start, None))] if start < len(buf) else []
        held = len(buf) - start
    if pending:
        yield _joined(pending)


def _joined(parts: list[RangeReadings]) -> RangeReadings:
    if len(parts) == 1:
        return parts[0]
    return RangeReadings(
        np.concatenate([p.stamp_ns for p in parts]),
        np.concatenate([p.sensor for p in parts]),
        np.concatenate([p.range_m for p in parts]),
    )


@dataclass(frozen=True)
class ReadingStream:
    """Range readings not held in memory: read again from their file for every pass.

    ``blocks()`` reads them, in order, as :class:`RangeReadings` whose ``sensor`` indexes the
    file's own sensors, no block splitting one stamp's readings. The reader's checking pass
    found, per file sensor (shape (S,)): ``counts``, the readings; ``first_ns`` and
    ``last_ns``, the stamps of its first and last reading (meaningless where the count is 0).
    ``index`` maps a file sensor to the log's (-1: left out, :func:`with_sensors`).
    """

    blocks: Callable[[], Iterator[RangeReadings]]
    counts: npt.NDArray[np.int64]
    first_ns: npt.NDArray[np.int64]
    last_ns: npt.NDArray[np.int64]
    index: npt.NDArray[np.int32]

    def __len__(self) -> int:
        return int(self.counts[self.index >= 0].sum())

    def span_ns(self) -> tuple[int, int]:
        """Stamps of the first and last reading kept (ns); the stream holds at least one."""
        kept = (self.index >= 0) & (self.counts > 0)
        return int(self.first_ns[kept].min()), int(self.last_ns[kept].max())

    def with_sensors(self, new_index: npt.NDArray[np.int32]) -> ReadingStream:
        """The stream with the log's sensor ``i`` re-indexed to ``new_index[i]`` (-1: left
        out), as :func:`gridmap_cli.mapping.selection.keep_sensors` does to held readings."""
        kept = self.index >= 0
        index = np.full_like(self.index, -1)
        index[kept] = new_index[self.index[kept]]
        return ReadingStream(self.blocks, self.counts, self.first_ns, self.last_ns, index)

    def readings(self) -> Iterator[RangeReadings]:
        """The readings, block by block, indexed by the log's sensors."""
        identity = bool((self.index == np.arange(len(self.index))).all())
        for block in self.blocks():
            if identity:
                yield block
                continue
            mapped = self.index[block.sensor]
            rows = mapped >= 0
            yield RangeReadings(block.stamp_ns[rows], mapped[rows], block.range_m[rows])


@dataclass(frozen=True)
class MovedStamps:
    """Stamps a reader moved so that time increases, shape (K,) each: ``stamp_ns`` as the
    records carry them (increasing), ``logged_ns`` as the file printed them. A benchmark that
    names poses by the file's stamps (the SLAM relations) looks them up by ``logged_ns``."""

    stamp_ns: npt.NDArray[np.int64]
    logged_ns: npt.NDArray[np.int64]


@dataclass(frozen=True)
class RangeLog:
    """Everything a reader learned from one log file.

    ``sensors`` holds the mounting geometry of those sensors the log itself describes (any
    subset of ``sensor_names``, matched by name); the robot description supplies the rest.
    ``truth`` is a ground-truth (or reference) track in the world frame, when the log has one;
    ``build`` ignores it. ``metadata`` holds the log's own key/value header.
    ``names_are_columns``: the sensor names are free-form table columns (CSV), so a name that
    neither the log nor the robot describes may be some other measurement (a battery voltage):
    :func:`gridmap_cli.mapping.selection.ignore_other_columns` leaves it out with a note. Elsewhere
    a
    sensor is a sensor, and one without mounting geometry is an error.

    ``stream``: set when the readings are not held but read again from the file at each pass
    (a long log, :data:`gridmap_cli.readers.ReadOptions.stream`); ``readings`` is then empty,
    and :attr:`reading_count`, :meth:`reading_span` and :meth:`reading_chunks` are the ways in.

    ``odometry_missing``: set (to the reason) when ``poses`` holds no odometry a map could be
    built from (a corrected CARMEN log whose ODOM lines only repeat its corrected poses).
    Only a caller that asked for a stream gets one.
    """

    source: str
    poses: PoseTrack
    readings: RangeReadings
    sensor_names: tuple[str, ...]
    sensors: tuple[RangeSensor, ...] | None = None
    truth: PoseTrack | None = None
    metadata: dict[str, str] = field(default_factory=dict)
    names_are_columns: bool = False
    stream: ReadingStream | None = None
    odometry_missing: str | None = None
    #: the stamps the reader moved so that time increases (a CARMEN log whose stamps go back),
    #: with what the file said; None when every stamp is the file's own
    moved_stamps: MovedStamps | None = None

    @property
    def reading_count(self) -> int:
        """The number of range readings, held or streamed."""
        return len(self.readings) if self.stream is None else len(self.stream)

    def reading_span(self) -> tuple[int, int]:
        """Stamps of the earliest and latest range reading (ns); the log holds at least one."""
        if self.stream is not None:
            return self.stream.span_ns()
        return int(self.readings.stamp_ns.min()), int(self.readings.stamp_ns.max())

    def reading_chunks(self, size: int) -> Iterator[RangeReadings]:
        """The range readings in time order, in :func:`cut_chunks`' chunks of about ``size``:
        views of the held readings, or read again from the file."""
        if self.stream is None:
            return cut_chunks([self.readings], size)
        return cut_chunks(self.stream.readings(), size)

    def require_truth(self, purpose: str) -> PoseTrack:
        """The ground-truth track; :class:`InputFileError` naming the log if it has none.

        ``purpose`` ends the message, saying what needed the truth ("evaluate needs the true
        path"): ``<source>: the log has no ground truth (<where readers find it>); <purpose>``.
        """
        if self.truth is None:
            raise InputFileError(
                self.source, f"the log has no ground truth ({TRUTH_SOURCES}); {purpose}"
            )
        return self.truth


#: Stamps at or after this (2001-09-09) are taken as Unix epoch times when shown to people;
#: smaller ones are seconds since some start (simulation time, a log's own clock).
EPOCH_FROM_NS = 1_000_000_000 * 1_000_000_000


#: Records closer than this on average (0.1 ms: 10 kHz) are stamps that do not advance; a reader
#: may space equal stamps by a microsecond to keep them ordered.
MIN_STEP_NS = 100_000


def stamps_advance(first_ns: int, last_ns: int, records: int) -> bool:
    """Whether ``records`` stamps from ``first_ns`` to ``last_ns`` measure time: fewer than 3
    always do; more must average at least :data:`MIN_STEP_NS` apart."""
    return records < 3 or last_ns - first_ns >= (records - 1) * MIN_STEP_NS


def stamp_text(stamp_ns: int) -> str:
    """A stamp for people: UTC date and time for epoch stamps, else seconds."""
    if stamp_ns >= EPOCH_FROM_NS:
        when = datetime.fromtimestamp(stamp_ns // 1_000_000_000, tz=UTC)
        frac = (stamp_ns % 1_000_000_000) // 1_000_000
        return f"{when:%Y-%m-%d %H:%M:%S}.{frac:03d} UTC"
    return f"{stamp_ns / 1e9:.3f} s"


def span_text(first_ns: int, last_ns: int) -> str:
    """A time span for people: ``start to end (duration)``."""
    end = stamp_text(last_ns)
    start = stamp_text(first_ns)
    if start[:10] == end[:10] and first_ns >= EPOCH_FROM_NS:
        end = end[11:]  # same day: the date once
    return f"{start} to {end} ({(last_ns - first_ns) / 1e9:.1f} s)"
