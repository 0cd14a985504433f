"""Helpers for the MCAP reader tests: merging real recordings, ROS message definitions.

The definitions below are the standard ROS message layouts written out (with their dependencies
after ``MSG:`` separators, as rosbag and rosbag2 store them), so tests can write ROS 1 and ROS 2
messages with the mcap support packages' writers.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

from mcap.reader import make_reader
from mcap.writer import Writer

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "mcap"


def merge_mcaps(sources: Iterable[Path], target: Path) -> None:
    """Copy every schema, channel and message of ``sources`` into one MCAP, bytes unchanged.

    What ``mcap merge`` does: the messages keep their encoding, data and log times.
    """
    with open(target, "wb") as out:
        writer = Writer(out)
        writer.start(profile="ros1", library="gridmap tests")
        for source in sources:
            with open(source, "rb") as handle:
                reader = make_reader(handle)
                summary = reader.get_summary()
                assert summary is not None
                schema_ids: dict[int, int] = {}
                for sid, schema in summary.schemas.items():
                    schema_ids[sid] = writer.register_schema(
                        schema.name, schema.encoding, schema.data
                    )
                channel_ids: dict[int, int] = {}
                for cid, channel in summary.channels.items():
                    channel_ids[cid] = writer.register_channel(
                        channel.topic,
                        channel.message_encoding,
                        schema_ids.get(channel.schema_id, 0),
                        dict(channel.metadata),
                    )
                for _schema, channel, message in reader.iter_messages(log_time_order=True):
                    writer.add_message(
                        channel_ids[channel.id],
                        message.log_time,
                        message.data,
                        message.publish_time,
                        message.sequence,
                    )
        writer.finish()


def stamp1(ns: int) -> dict[str, Any]:
    return {"secs": ns // 1_000_000_000, "nsecs": ns % 1_000_000_000}


def stamp2(ns: int) -> dict[str, Any]:
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}
