"""Re-write an MCAP file with some messages or schemas changed, CRCs recomputed: damage that
passes every integrity check and must be caught by the decoders' own limits."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer


def edit_mcap(
    source: Path,
    target: Path,
    message: Callable[[str, bytes], bytes] = lambda topic, data: data,
    schema: Callable[[str, bytes], bytes] = lambda name, data: data,
    compression: CompressionType = CompressionType.ZSTD,
    **writer_options: Any,
) -> Path:
    """Copy ``source`` to ``target`` passing each message's bytes through ``message(topic,
    data)`` and each schema's definition through ``schema(name, data)``; ``compression`` and
    ``writer_options`` (``chunk_size``, ``enable_crcs``, ``enable_data_crcs``) go to the
    writer, data CRCs on unless said otherwise."""
    with open(source, "rb") as handle, open(target, "wb") as out:
        reader = make_reader(handle)
        summary = reader.get_summary()
        assert summary is not None
        header = reader.get_header()
        options = {"enable_data_crcs": True, **writer_options}
        writer = Writer(out, compression=compression, **options)
        writer.start(profile=header.profile, library="gridmap corpus")
        schemas = {
            k: writer.register_schema(s.name, s.encoding, schema(s.name, s.data))
            for k, s in summary.schemas.items()
        }
        channels = {
            k: writer.register_channel(
                c.topic, c.message_encoding, schemas.get(c.schema_id, 0), dict(c.metadata)
            )
            for k, c in summary.channels.items()
        }
        for meta in reader.iter_metadata():
            writer.add_metadata(meta.name, dict(meta.metadata))
        for _, channel, msg in reader.iter_messages(log_time_order=True):
            writer.add_message(
                channels[channel.id], msg.log_time, message(channel.topic, msg.data),
                msg.publish_time,
            )  # fmt: skip
        writer.finish()
    return target
