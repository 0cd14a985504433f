"""Write ROS 1 bags and rosbag2 folders for tests, from the messages of a ROS 2 MCAP file.

The bytes of each message are kept (CDR for rosbag2; converted to ROS 1 serialisation by the
``rosbags`` type store for ROS 1 bags), and so are the log times: what ``rosbag record`` of the
same run would hold.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable, Iterable
from pathlib import Path

from mcap.reader import make_reader
from rosbags.convert.converter import convert
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Bag2Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore


def _typestore(source: Path) -> Typestore:
    """A type store of exactly the message definitions the MCAP file carries."""
    store = get_typestore(Stores.EMPTY)
    with open(source, "rb") as handle:
        summary = make_reader(handle).get_summary()
    assert summary is not None
    for schema in summary.schemas.values():
        store.register(get_types_from_msg(schema.data.decode(), schema.name))
    return store


def _messages(source: Path, keep: Callable[[str], bool]) -> Iterable[tuple[str, str, int, bytes]]:
    with open(source, "rb") as handle:
        for schema, channel, message in make_reader(handle).iter_messages(log_time_order=True):
            if keep(channel.topic):
                assert schema is not None
                yield channel.topic, schema.name, message.log_time, message.data


def write_bag(source: Path, target: Path, keep: Callable[[str], bool] = lambda topic: True) -> Path:
    """A ROS 1 bag of the ``keep`` topics of the ROS 2 MCAP ``source``: written as rosbag2, then
    converted by ``rosbags`` (its ``rosbags-convert``), which turns ROS 2 headers and times into
    ROS 1's and writes each message's ROS 1 definition."""
    folder = write_rosbag2(source, target.with_name(target.stem + "_ros2"), keep)
    convert(
        [folder], target, "", 1, None, "none",
        default_typestore=None, typestore=get_typestore(Stores.ROS1_NOETIC),
        exclude_topics=(), include_topics=(), exclude_msgtypes=(), include_msgtypes=(),
    )  # fmt: skip
    shutil.rmtree(folder)
    return target


def write_rosbag2(
    source: Path,
    target: Path,
    keep: Callable[[str], bool] = lambda topic: True,
    storage: StoragePlugin = StoragePlugin.SQLITE3,
    rename: dict[str, str] | None = None,
    compression: str = "none",
) -> Path:
    """A rosbag2 folder (sqlite3 or MCAP storage) of the ``keep`` topics of ``source``, topics
    renamed as ``rename`` says, zstd-compressed by ``compression`` (none, file, message)."""
    store = _typestore(source)
    writer = Bag2Writer(target, version=8, storage_plugin=storage)
    if compression != "none":
        from rosbags.rosbag2 import CompressionFormat, CompressionMode

        writer.set_compression(CompressionMode[compression.upper()], CompressionFormat.ZSTD)
    with writer:
        connections = {}
        for topic, msgtype, log_time, data in _messages(source, keep):
            conn = connections.get(topic)
            if conn is None:
                name = (rename or {}).get(topic, topic)
                conn = connections[topic] = writer.add_connection(name, msgtype, typestore=store)
            writer.write(conn, log_time, data)
    return target
