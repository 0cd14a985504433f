"""What an MCAP file holds (channels, types, counts, time span) and which topics gridmap uses.

The survey reads only the file's summary section (or, for a file written without one, walks the
records once without decoding messages). The plan picks the odometry, ground-truth, TF and range
topics by message type, or as ``--odom-topic`` / ``--range-topic`` say; an ambiguous or missing
choice is an error that lists the topics with their types and message counts.
"""

from __future__ import annotations

import struct
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import IO

from mcap.decoder import DecoderFactory
from mcap.exceptions import McapError
from mcap.reader import SeekingReader
from mcap.records import Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.summary import Summary

from gridmap_cli.errors import GridmapError, InputFileError, UsageError
from gridmap_cli.readers.options import ReadOptions

MAGIC = b"\x89MCAP0\r\n"

#: Message types gridmap reads, by role (ROS 2 names with ``/msg/`` removed).
POSE_TYPES = ("nav_msgs/Odometry", "geometry_msgs/PoseStamped", "gridmap.Pose2D")
TF_TYPES = ("tf/tfMessage", "tf2_msgs/TFMessage")
RANGE_TYPES = (
    "sensor_msgs/Range",
    "sensor_msgs/LaserScan",
    "sensor_msgs/PointCloud",
    "gridmap.RangeReading",
)
SENSOR_TYPES = ("gridmap.RangeSensor",)
#: Topic names holding TF that never changes.
STATIC_TF_TOPICS = ("/tf_static", "tf_static")

#: Exceptions the mcap library and its decoders raise on damaged input.
DAMAGED = (McapError, struct.error, EOFError, ValueError, KeyError, IndexError, OSError)


def sniff(head: bytes) -> bool:
    """True if the first bytes are the MCAP magic."""
    return head.startswith(MAGIC)


def message_type(schema: Schema | None) -> str:
    """Type name, ROS 2 style folded (``nav_msgs/msg/Odometry`` -> ``nav_msgs/Odometry``)."""
    if schema is None:
        return ""
    return schema.name.replace("/msg/", "/")


def is_truth_topic(topic: str) -> bool:
    """Pose topics named like ground truth are the reference track, not odometry."""
    return "ground_truth" in topic


@dataclass(frozen=True)
class ChannelInfo:
    """One channel of an MCAP file. ``count`` is the number of messages on it."""

    topic: str
    type_name: str
    schema_encoding: str
    message_encoding: str
    count: int

    @property
    def role(self) -> str:
        """What gridmap uses it for: odometry, truth, tf, tf_static, range, sensors or ''."""
        if self.type_name in POSE_TYPES:
            return "truth" if is_truth_topic(self.topic) else "odometry"
        if self.type_name in TF_TYPES:
            return "tf_static" if self.topic in STATIC_TF_TOPICS else "tf"
        if self.type_name == "sensor_msgs/PointCloud":
            # PointCloud carries anything; RosAria's sonar topic is the one gridmap knows
            return "range" if "sonar" in self.topic else ""
        if self.type_name in RANGE_TYPES:
            return "range"
        if self.type_name in SENSOR_TYPES:
            return "sensors"
        return ""

    def describe(self) -> str:
        return f"{self.topic} ({self.type_name or 'no schema'}, {self.count} messages)"


@dataclass(frozen=True)
class Survey:
    """An MCAP file's header, channels and time span (log times, ns)."""

    path: str
    profile: str
    library: str
    channels: tuple[ChannelInfo, ...]
    start_ns: int | None
    end_ns: int | None
    message_count: int
    metadata: dict[str, dict[str, str]]
    indexed: bool

    def topic(self, name: str) -> ChannelInfo | None:
        for channel in self.channels:
            if channel.topic == name:
                return channel
        return None

    def listing(self) -> str:
        """All topics with their types and counts, for error messages."""
        if not self.channels:
            return "the file has no channels"
        return "topics: " + "; ".join(c.describe() for c in self.channels)


def open_reader(
    path: Path, handle: IO[bytes], decoder_factories: Iterable[DecoderFactory] = ()
) -> SeekingReader:
    """A seeking reader on an open MCAP file; a file not starting with the magic is an error."""
    try:
        reader = SeekingReader(handle, decoder_factories=decoder_factories)
    except DAMAGED as exc:
        raise InputFileError(path, f"not an MCAP file ({exc})") from exc
    return reader


def read_summary(path: Path, reader: SeekingReader) -> Summary | None:
    """The summary section, or None when the file was written without one."""
    try:
        return reader.get_summary()
    except DAMAGED as exc:
        raise InputFileError(
            path,
            "truncated or damaged MCAP file: no valid footer at the end "
            f"({exc}); was the recording cut short? `mcap recover` can rebuild it",
        ) from exc


def survey_mcap(path: Path) -> Survey:
    """Survey an MCAP file: header, channels with message counts, time span, metadata."""
    try:
        with open(path, "rb") as handle:
            reader = open_reader(path, handle)
            try:
                header = reader.get_header()
            except DAMAGED as exc:
                raise InputFileError(path, f"damaged MCAP header ({exc})") from exc
            summary = read_summary(path, reader)
            if summary is None or summary.statistics is None:
                handle.seek(0)
                return _survey_by_scan(path, handle, header.profile, header.library)
            metadata = _metadata(path, reader)
            stats = summary.statistics
            channels = tuple(
                ChannelInfo(
                    topic=ch.topic,
                    type_name=message_type(summary.schemas.get(ch.schema_id)),
                    schema_encoding=_schema_encoding(summary.schemas.get(ch.schema_id)),
                    message_encoding=ch.message_encoding,
                    count=stats.channel_message_counts.get(ch.id, 0),
                )
                for ch in sorted(summary.channels.values(), key=lambda c: c.id)
            )
            empty = stats.message_count == 0
            return Survey(
                path=str(path),
                profile=header.profile,
                library=header.library,
                channels=channels,
                start_ns=None if empty else stats.message_start_time,
                end_ns=None if empty else stats.message_end_time,
                message_count=stats.message_count,
                metadata=metadata,
                indexed=bool(summary.chunk_indexes),
            )
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from exc


def _schema_encoding(schema: Schema | None) -> str:
    return schema.encoding if schema is not None else ""


def _metadata(path: Path, reader: SeekingReader) -> dict[str, dict[str, str]]:
    try:
        return {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    except DAMAGED as exc:
        raise InputFileError(path, f"damaged metadata record ({exc})") from exc


def _survey_by_scan(path: Path, handle: IO[bytes], profile: str, library: str) -> Survey:
    """Count messages by walking the records (a file written without a summary section)."""
    counts: Counter[int] = Counter()
    channels: dict[int, Channel] = {}
    schemas: dict[int, Schema] = {}
    metadata: dict[str, dict[str, str]] = {}
    start = end = None
    try:
        for record in StreamReader(handle, skip_magic=False).records:
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = record
            elif isinstance(record, Message):
                counts[record.channel_id] += 1
                t = record.log_time
                start = t if start is None else min(start, t)
                end = t if end is None else max(end, t)
            elif isinstance(record, Metadata):
                metadata[record.name] = dict(record.metadata)
    except DAMAGED as exc:
        raise InputFileError(path, f"truncated or damaged MCAP file ({exc})") from exc
    infos = tuple(
        ChannelInfo(
            topic=ch.topic,
            type_name=message_type(schemas.get(ch.schema_id)),
            schema_encoding=_schema_encoding(schemas.get(ch.schema_id)),
            message_encoding=ch.message_encoding,
            count=counts[ch.id],
        )
        for ch in sorted(channels.values(), key=lambda c: c.id)
    )
    return Survey(
        path=str(path),
        profile=profile,
        library=library,
        channels=infos,
        start_ns=start,
        end_ns=end,
        message_count=sum(counts.values()),
        metadata=metadata,
        indexed=False,
    )


class Refusals:
    """Errors that stop a build: a strict read (``build``) raises the first one at once; a lenient
    read (``inspect``) keeps it in :attr:`first` and reads on to show what the file holds."""

    def __init__(self, strict: bool = True) -> None:
        self.strict = strict
        self.first: GridmapError | None = None

    def refuse(self, error: GridmapError) -> None:
        if self.strict:
            raise error
        if self.first is None:
            self.first = error


@dataclass(frozen=True)
class Plan:
    """The topics a read uses.

    ``odom_topic`` is a pose topic, or None when odometry comes from TF (``tf_topics``,
    ``odom_frame`` -> base frame). ``static_topics`` hold the sensor mounting (for ROS 1
    recordings with no static topic: the ``tf_topics``).
    """

    odom_topic: str | None
    truth_topic: str | None
    range_topics: tuple[str, ...]
    tf_topics: tuple[str, ...]
    static_topics: tuple[str, ...]
    sensors_topic: str | None
    odom_frame: str
    base_frame: str | None

    def topics(self) -> list[str]:
        """Every topic the read decodes: /tf only when it carries odometry or mounting."""
        out = [t for t in (self.odom_topic, self.truth_topic, self.sensors_topic) if t]
        out += [*self.range_topics, *self.static_topics]
        if self.odom_topic is None or not self.static_topics:
            out += self.tf_topics
        return list(dict.fromkeys(out))


def plan_topics(survey: Survey, options: ReadOptions, refusals: Refusals | None = None) -> Plan:
    """Choose the topics to read. Raises InputFileError / UsageError listing the topics.

    No odometry or no range topic goes to ``refusals`` (default: strict, raise), so that a
    lenient read (``inspect``) plans a file that has none.
    """
    refuse = (refusals or Refusals()).refuse
    path = survey.path
    by_role: dict[str, list[ChannelInfo]] = {}
    for channel in survey.channels:
        if channel.count > 0:
            by_role.setdefault(channel.role, []).append(channel)
    tf_topics = tuple(c.topic for c in by_role.get("tf", []))
    static_topics = tuple(c.topic for c in by_role.get("tf_static", []))

    odom_topic: str | None
    if options.odom_topic is not None:
        chosen = survey.topic(options.odom_topic)
        if chosen is None:
            raise UsageError(
                f"{path}: --odom-topic {options.odom_topic}: no such topic; {survey.listing()}"
            )
        if chosen.type_name in TF_TYPES:
            odom_topic = None
            tf_topics = (chosen.topic,)
        elif chosen.type_name in POSE_TYPES:
            odom_topic = chosen.topic
        else:
            raise UsageError(
                f"{path}: --odom-topic {chosen.topic} is {chosen.type_name or 'untyped'}, not a "
                f"pose type ({', '.join(POSE_TYPES)}) or TF"
            )
    else:
        candidates = by_role.get("odometry", [])
        if len(candidates) > 1:
            raise InputFileError(
                path,
                "more than one odometry topic: "
                + "; ".join(c.describe() for c in candidates)
                + "; choose one with --odom-topic",
            )
        odom_topic = candidates[0].topic if candidates else None
        if not candidates and not tf_topics:
            refuse(
                InputFileError(
                    path,
                    "no odometry: no nav_msgs/Odometry, geometry_msgs/PoseStamped or "
                    f"gridmap.Pose2D topic and no TF; {survey.listing()}",
                )
            )
    truths = [c.topic for c in by_role.get("truth", []) if c.topic != odom_topic]
    truth_topic = truths[0] if len(truths) == 1 else None

    if options.range_topics:
        ranges = []
        for name in options.range_topics:
            chosen = survey.topic(name)
            if chosen is None:
                raise UsageError(f"{path}: --range-topic {name}: no such topic; {survey.listing()}")
            if chosen.type_name not in RANGE_TYPES:
                raise UsageError(
                    f"{path}: --range-topic {name} is {chosen.type_name or 'untyped'}, not a "
                    f"range type ({', '.join(RANGE_TYPES)})"
                )
            ranges.append(name)
        range_topics = tuple(dict.fromkeys(ranges))
    else:
        range_topics = tuple(c.topic for c in by_role.get("range", []))
        if not range_topics:
            refuse(
                InputFileError(
                    path,
                    "no range readings: no sensor_msgs/Range, LaserScan, PointCloud (sonar) or "
                    f"gridmap.RangeReading topic; {survey.listing()}",
                )
            )
    sensors = by_role.get("sensors", [])
    return Plan(
        odom_topic=odom_topic,
        truth_topic=truth_topic,
        range_topics=range_topics,
        tf_topics=tf_topics,
        static_topics=static_topics,
        sensors_topic=sensors[0].topic if sensors else None,
        odom_frame=options.odom_frame or "odom",
        base_frame=options.base_frame,
    )
