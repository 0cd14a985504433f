"""What an MCAP file holds: channels, types, counts, time span, metadata.

The survey reads only the file's summary section (or, for a file written without one, walks the
records once without decoding messages). Which of the topics gridmap uses is decided by
:mod:`gridmap_cli.readers.ros.topics`, alike for every ROS container.
"""

from __future__ import annotations

import struct
from collections import Counter
from collections.abc import Iterable
from pathlib import Path
from typing import IO

import yaml
from mcap.decoder import DecoderFactory
from mcap.exceptions import McapError
from mcap.reader import SeekingReader
from mcap.records import Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.summary import Summary

from gridmap_cli.errors import InputFileError
from gridmap_cli.readers.ros.topics import ChannelInfo, Survey, fold_type, qos_text

MAGIC = b"\x89MCAP0\r\n"

#: Metadata record holding gridmap's own key/value header (robot, world, seed...).
METADATA_NAME = "gridmap"

#: Exceptions the mcap library and its decoders raise on damaged input.
DAMAGED = (McapError, struct.error, EOFError, ValueError, KeyError, IndexError, OSError)


def sniff(head: bytes) -> bool:
    """True if the first bytes are the MCAP magic."""
    return head.startswith(MAGIC)


def message_type(schema: Schema | None) -> str:
    """Type name, ROS 2 style folded (``nav_msgs/msg/Odometry`` -> ``nav_msgs/Odometry``)."""
    return "" if schema is None else fold_type(schema.name)


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
                    qos=_qos(ch),
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
                storage="mcap",
                compression=", ".join(
                    sorted({ci.compression or "none" for ci in summary.chunk_indexes})
                ),
                files=((str(path), path.stat().st_size),),
            )
    except OSError as exc:
        raise InputFileError(path, f"cannot read: {exc.strerror or exc}") from exc


def _qos(channel: Channel) -> str:
    """The QoS rosbag2 wrote into a channel's metadata (``offered_qos_profiles``, YAML), short;
    a ROS 1 channel's ``latching``."""
    text = channel.metadata.get("offered_qos_profiles", "")
    if text:
        try:
            profiles = yaml.safe_load(text)
        except yaml.YAMLError:
            return ""
        return qos_text(profiles if isinstance(profiles, list) else [])
    return "latched" if channel.metadata.get("latching") == "1" else ""


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
            qos=_qos(ch),
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
        storage="mcap",
        files=((str(path), path.stat().st_size),),
    )
