"""Writer for MCAP logs (``schemas/mcap-log.md``): a RangeLog as JSON or ROS 2 messages.

Two encodings:

- ``json``: gridmap's own channels (``/sensors``, ``/odom``, ``/ground_truth``, ``/range``) with
  the JSON Schemas of ``schemas/`` embedded as the MCAP schemas. Numbers are written by Python's
  ``json`` (shortest round-trip form), so a log read back holds the very same doubles.
- ``ros2``: standard ROS 2 messages in CDR (``nav_msgs/msg/Odometry``, ``tf2_msgs/msg/TFMessage``
  on ``/tf`` and ``/tf_static``, ``sensor_msgs/msg/Range``, ``sensor_msgs/msg/LaserScan``), with
  the ``ros2`` profile and the concatenated message definitions rosbag2 writes.

Both are chunked (chunks of at most 1 MiB, zstd-compressed: the ``mcap`` library's defaults),
indexed and end with a summary; chunk and data-section CRCs are written. Every message's
log_time and publish_time is its own stamp and the header names ``gridmap-cli`` without a
version, so the same log always gives the same bytes (with the same zstd). The log's metadata
goes into one MCAP Metadata record named ``gridmap``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterator
from importlib import resources
from pathlib import Path
from typing import IO, Any

import numpy as np
import numpy.typing as npt
from mcap.writer import CompressionType, Writer
from mcap_ros2._dynamic import serialize_dynamic

from gridmap_cli.atomic import atomic_write
from gridmap_cli.errors import GridmapError
from gridmap_cli.readers.ros.frames import Quaternion, quaternion_of_yaw
from gridmap_cli.readers.ros.mcap.channels import METADATA_NAME
from gridmap_cli.records import PoseTrack, RangeLog
from gridmap_cli.robot import RangeSensor
from gridmap_cli.writers import Laser, laser_groups
from gridmap_cli.writers.ros2_msgdefs import message_definition

ENCODINGS = ("json", "ros2")

#: The Header record's library field: no version, so that releases write the same bytes.
LIBRARY = "gridmap-cli"

ODOM_FRAME = "odom"
BASE_FRAME = "base_link"
WORLD_FRAME = "world"

#: The JSON message types and the topics they go on.
JSON_SCHEMAS = ("gridmap.RangeSensor", "gridmap.Pose2D", "gridmap.RangeReading")

_INT32_MAX = 2**31 - 1
# sensor_msgs/msg/Range radiation types
_ULTRASOUND = 0
_INFRARED = 1


def json_schema_text(name: str) -> bytes:
    """The JSON Schema of a gridmap message type (``gridmap.Pose2D``) as shipped in the package;
    the files are ``schemas/<name>.schema.json`` of the repository."""
    resource = resources.files("gridmap_cli") / "schemas" / f"{name}.schema.json"
    return resource.read_bytes()


def mcap_writer(stream: IO[bytes]) -> Writer:
    """An MCAP writer as gridmap writes every file: zstd chunks, chunk and data CRCs."""
    return Writer(
        stream,
        compression=CompressionType.ZSTD,
        enable_crcs=True,
        enable_data_crcs=True,
    )


def _check_log(log: RangeLog, sensors: tuple[RangeSensor, ...]) -> None:
    names = tuple(s.name for s in sensors)
    if names != tuple(log.sensor_names):
        raise GridmapError(
            f"sensor geometry for {list(names)[:4]}... does not match the log's sensors "
            f"{list(log.sensor_names)[:4]}..."
        )
    if len(log.poses) == 0:
        raise GridmapError(f"{log.source}: the log has no odometry to write")
    for key, value in log.metadata.items():
        if not isinstance(key, str) or not isinstance(value, str):
            raise GridmapError(f"metadata {key!r}: {value!r} is not a string pair")


def _first_stamp(log: RangeLog) -> int:
    """The earliest stamp of the log (the first odometry stamp in every simulated log)."""
    firsts = [int(log.poses.stamp_ns[0])]
    if log.truth is not None and len(log.truth):
        firsts.append(int(log.truth.stamp_ns[0]))
    if len(log.readings):
        firsts.append(int(log.readings.stamp_ns[0]))
    return min(firsts)


def _events(groups: list[npt.NDArray[np.int64]]) -> Iterator[tuple[int, int, int]]:
    """Merge stamped groups: (stamp, group, index) in stamp order, ties in group then index order.

    ``groups[g]`` holds the stamps of group g's items, in their own order.
    """
    stamps = np.concatenate([np.asarray(g, dtype=np.int64) for g in groups])
    group = np.concatenate([np.full(len(g), k, dtype=np.int64) for k, g in enumerate(groups)])
    index = np.concatenate([np.arange(len(g), dtype=np.int64) for g in groups])
    order = np.lexsort((index, group, stamps))
    for k in order:
        yield int(stamps[k]), int(group[k]), int(index[k])


# --- JSON encoding ----------------------------------------------------------------------------


def _json_time(stamp_ns: int) -> dict[str, int]:
    sec, nsec = divmod(stamp_ns, 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def _dumps(message: dict[str, Any]) -> bytes:
    try:
        return json.dumps(message, separators=(",", ":"), allow_nan=False).encode("utf-8")
    except ValueError as exc:  # NaN or infinity, which JSON cannot hold
        raise GridmapError(f"a non-finite number cannot be written as JSON: {message}") from exc


def _write_json(log: RangeLog, sensors: tuple[RangeSensor, ...], writer: Writer) -> None:
    writer.start(profile="", library=LIBRARY)
    schema_ids = {
        name: writer.register_schema(name, "jsonschema", json_schema_text(name))
        for name in JSON_SCHEMAS
    }

    def channel(topic: str, schema: str) -> int:
        return writer.register_channel(topic, "json", schema_ids[schema])

    sensors_ch = channel("/sensors", "gridmap.RangeSensor")
    odom_ch = channel("/odom", "gridmap.Pose2D")
    truth_ch = channel("/ground_truth", "gridmap.Pose2D") if log.truth is not None else None
    range_ch = channel("/range", "gridmap.RangeReading")
    writer.add_metadata(METADATA_NAME, dict(log.metadata))

    t0 = _first_stamp(log)
    for seq, s in enumerate(sensors):
        message = {
            "timestamp": _json_time(t0),
            "name": s.name,
            "kind": s.kind,
            "x": float(s.x_m),
            "y": float(s.y_m),
            "yaw": float(s.yaw_rad),
            "beam_width": float(s.beam_width_rad),
            "min_range": float(s.min_range_m),
            "max_range": float(s.max_range_m),
        }
        writer.add_message(sensors_ch, t0, _dumps(message), t0, sequence=seq)

    def pose(track: PoseTrack, i: int, frame: str) -> bytes:
        return _dumps(
            {
                "timestamp": _json_time(int(track.stamp_ns[i])),
                "frame_id": frame,
                "child_frame_id": BASE_FRAME,
                "x": float(track.x_m[i]),
                "y": float(track.y_m[i]),
                "theta": float(track.theta_rad[i]),
            }
        )

    poses, truth, readings = log.poses, log.truth, log.readings
    names = log.sensor_names
    empty = np.zeros(0, dtype=np.int64)
    groups = [poses.stamp_ns, truth.stamp_ns if truth is not None else empty, readings.stamp_ns]
    for stamp, group, i in _events(groups):
        if group == 0:
            writer.add_message(odom_ch, stamp, pose(poses, i, ODOM_FRAME), stamp, sequence=i)
        elif group == 1 and truth is not None and truth_ch is not None:
            writer.add_message(truth_ch, stamp, pose(truth, i, WORLD_FRAME), stamp, sequence=i)
        else:
            column = int(readings.sensor[i])
            value = float(readings.range_m[i])
            data = _dumps({"timestamp": _json_time(stamp), "sensor": names[column], "range": value})
            writer.add_message(range_ch, stamp, data, stamp, sequence=i)


# --- ROS 2 encoding ---------------------------------------------------------------------------


def qos_profiles_yaml(depth: int, durability: str) -> str:
    """An ``offered_qos_profiles`` channel entry, so that ``ros2 bag play`` offers the same QoS
    (transient-local for ``/tf_static`` and ``/map``, so that late subscribers get them)."""
    forever = "    sec: 9223372036\n    nsec: 854775807\n"
    return (
        f"- history: keep_last\n  depth: {depth}\n  reliability: reliable\n"
        f"  durability: {durability}\n"
        f"  deadline:\n{forever}  lifespan:\n{forever}  liveliness: automatic\n"
        f"  liveliness_lease_duration:\n{forever}  avoid_ros_namespace_conventions: false"
    )


def ros_time(stamp_ns: int) -> dict[str, int]:
    """A ``builtin_interfaces/Time`` of integer ns; :class:`GridmapError` past int32 seconds."""
    sec, nanosec = divmod(stamp_ns, 1_000_000_000)
    if not -(2**31) <= sec <= _INT32_MAX:
        raise GridmapError(f"stamp {stamp_ns} ns does not fit a ROS 2 time (int32 seconds)")
    return {"sec": sec, "nanosec": nanosec}


def ros_quaternion(q: Quaternion) -> dict[str, float]:
    """A ``geometry_msgs/Quaternion`` of an (x, y, z, w) quaternion."""
    x, y, z, w = q
    return {"x": x, "y": y, "z": z, "w": w}


def _transform(
    stamp: dict[str, int], parent: str, child: str, x: float, y: float, theta: float
) -> dict[str, Any]:
    return {
        "header": {"stamp": stamp, "frame_id": parent},
        "child_frame_id": child,
        "transform": {
            "translation": {"x": float(x), "y": float(y), "z": 0.0},
            "rotation": ros_quaternion(quaternion_of_yaw(theta)),
        },
    }


def _odometry(
    stamp: dict[str, int], frame: str, x: float, y: float, theta: float
) -> dict[str, Any]:
    zeros = [0.0] * 36
    return {
        "header": {"stamp": stamp, "frame_id": frame},
        "child_frame_id": BASE_FRAME,
        "pose": {
            "pose": {
                "position": {"x": float(x), "y": float(y), "z": 0.0},
                "orientation": ros_quaternion(quaternion_of_yaw(theta)),
            },
            "covariance": zeros,
        },
        "twist": {
            "twist": {
                "linear": {"x": 0.0, "y": 0.0, "z": 0.0},
                "angular": {"x": 0.0, "y": 0.0, "z": 0.0},
            },
            "covariance": zeros,
        },
    }


class _Ros2Channels:
    """Schemas, channels and CDR encoders of a ROS 2 MCAP being written."""

    def __init__(self, writer: Writer) -> None:
        self.writer = writer
        self._schemas: dict[str, int] = {}
        self._by_schema: dict[str, Callable[[Any], bytes]] = {}
        self._by_channel: dict[int, Callable[[Any], bytes]] = {}

    def channel(self, topic: str, schema_name: str, qos: str) -> int:
        if schema_name not in self._schemas:
            text = message_definition(schema_name)
            self._schemas[schema_name] = self.writer.register_schema(
                schema_name, "ros2msg", text.encode("utf-8")
            )
            self._by_schema[schema_name] = serialize_dynamic(schema_name, text)[schema_name]
        channel_id = self.writer.register_channel(
            topic, "cdr", self._schemas[schema_name], metadata={"offered_qos_profiles": qos}
        )
        self._by_channel[channel_id] = self._by_schema[schema_name]
        return channel_id

    def write(self, channel_id: int, stamp_ns: int, message: Any, sequence: int) -> None:
        data = self._by_channel[channel_id](message)
        self.writer.add_message(channel_id, stamp_ns, data, stamp_ns, sequence=sequence)


def _write_ros2(log: RangeLog, sensors: tuple[RangeSensor, ...], writer: Writer) -> None:
    singles, lasers = laser_groups(sensors, "a LaserScan")
    writer.start(profile="ros2", library=LIBRARY)
    ch = _Ros2Channels(writer)
    volatile = qos_profiles_yaml(10, "volatile")
    tf_static = ch.channel(
        "/tf_static", "tf2_msgs/msg/TFMessage", qos_profiles_yaml(1, "transient_local")
    )
    odom = ch.channel("/odom", "nav_msgs/msg/Odometry", volatile)
    tf = ch.channel("/tf", "tf2_msgs/msg/TFMessage", volatile)
    truth_ch = (
        ch.channel("/ground_truth", "nav_msgs/msg/Odometry", volatile)
        if log.truth is not None
        else None
    )
    sonar = ch.channel("/sonar", "sensor_msgs/msg/Range", volatile) if singles else None
    scan = ch.channel("/scan", "sensor_msgs/msg/LaserScan", volatile) if lasers else None
    writer.add_metadata(METADATA_NAME, dict(log.metadata))

    t0 = _first_stamp(log)
    stamp0 = ros_time(t0)
    mounts = [
        _transform(stamp0, BASE_FRAME, sensors[c].name, sensors[c].x_m, sensors[c].y_m,
                   sensors[c].yaw_rad)
        for c in singles
    ] + [
        _transform(stamp0, BASE_FRAME, laser.frame, laser.x_m, laser.y_m, laser.yaw_rad)
        for laser in lasers
    ]  # fmt: skip
    ch.write(tf_static, t0, {"transforms": mounts}, 0)

    poses, truth, readings = log.poses, log.truth, log.readings
    is_single = np.zeros(len(sensors), dtype=bool)
    is_single[singles] = True
    single_rows = np.flatnonzero(is_single[readings.sensor])
    # one scan per laser and stamp at which any of its beams has a reading
    scans: list[tuple[int, Laser]] = []
    for laser in lasers:
        rows = np.flatnonzero(np.isin(readings.sensor, laser.columns))
        for stamp in np.unique(readings.stamp_ns[rows]):
            scans.append((int(stamp), laser))
    # _events would emit them in time order anyway; sorting (stably: lasers in order within a
    # stamp) makes the index, the /scan message's sequence number, count up in time as well
    scans.sort(key=lambda scan: scan[0])
    empty = np.zeros(0, dtype=np.int64)
    groups = [
        poses.stamp_ns,
        truth.stamp_ns if truth is not None else empty,
        readings.stamp_ns[single_rows],
        np.asarray([s for s, _ in scans], dtype=np.int64),
    ]
    # readings of one stamp, for building scans: a row range per stamp
    stamp_lo = np.searchsorted(readings.stamp_ns, groups[3], side="left")
    stamp_hi = np.searchsorted(readings.stamp_ns, groups[3], side="right")
    for stamp, group, i in _events(groups):
        when = ros_time(stamp)
        if group == 0:
            x, y, th = poses.x_m[i], poses.y_m[i], poses.theta_rad[i]
            ch.write(odom, stamp, _odometry(when, ODOM_FRAME, x, y, th), i)
            moved = _transform(when, ODOM_FRAME, BASE_FRAME, x, y, th)
            ch.write(tf, stamp, {"transforms": [moved]}, i)
        elif group == 1 and truth is not None and truth_ch is not None:
            x, y, th = truth.x_m[i], truth.y_m[i], truth.theta_rad[i]
            ch.write(truth_ch, stamp, _odometry(when, WORLD_FRAME, x, y, th), i)
        elif group == 2 and sonar is not None:
            row = int(single_rows[i])
            s = sensors[int(readings.sensor[row])]
            message = {
                "header": {"stamp": when, "frame_id": s.name},
                "radiation_type": _ULTRASOUND if s.kind == "sonar" else _INFRARED,
                "field_of_view": float(s.beam_width_rad),
                "min_range": float(s.min_range_m),
                "max_range": float(s.max_range_m),
                "range": float(readings.range_m[row]),
                "variance": 0.0,
            }
            ch.write(sonar, stamp, message, i)
        elif group == 3 and scan is not None:
            laser = scans[i][1]
            ranges = np.full(len(laser.columns), np.nan)  # NaN: no reading of that beam
            beam_of = {c: b for b, c in enumerate(laser.columns)}
            for row in range(int(stamp_lo[i]), int(stamp_hi[i])):
                beam = beam_of.get(int(readings.sensor[row]))
                if beam is not None:
                    value = float(readings.range_m[row])
                    # REP 117: +inf is "no return within range"
                    ranges[beam] = math.inf if value >= laser.range_max_m else value
            message = {
                "header": {"stamp": when, "frame_id": laser.frame},
                "angle_min": laser.angle_min_rad,
                "angle_max": laser.angle_min_rad
                + laser.angle_increment_rad * (len(laser.columns) - 1),
                "angle_increment": laser.angle_increment_rad,
                "time_increment": 0.0,
                "scan_time": 0.0,
                "range_min": laser.range_min_m,
                "range_max": laser.range_max_m,
                "ranges": [float(v) for v in ranges],
                "intensities": [],
            }
            ch.write(scan, stamp, message, i)


def write_mcap_log(
    log: RangeLog, sensors: tuple[RangeSensor, ...], stream: IO[bytes], encoding: str = "json"
) -> None:
    """Write ``log`` as MCAP to a binary stream; ``sensors`` gives ``log.sensor_names``' geometry.

    Raises :class:`GridmapError` for an unknown encoding, sensors that do not match the log's, or
    data the encoding cannot hold (laser beams that do not make a LaserScan, stamps beyond the
    int32 seconds of ROS 2 time).
    """
    if encoding not in ENCODINGS:
        raise GridmapError(f"unknown MCAP encoding '{encoding}' (known: {', '.join(ENCODINGS)})")
    _check_log(log, sensors)
    writer = mcap_writer(stream)
    if encoding == "json":
        _write_json(log, sensors, writer)
    else:
        _write_ros2(log, sensors, writer)
    writer.finish()  # type: ignore[no-untyped-call]


def save_mcap_log(
    log: RangeLog, sensors: tuple[RangeSensor, ...], path: Path, encoding: str | None = "json"
) -> None:
    """Write ``log`` to ``path`` atomically (nothing is left behind on failure); ``encoding``
    None is ``json``."""
    with atomic_write(path, "the log") as tmp, open(tmp, "wb") as handle:
        write_mcap_log(log, sensors, handle, encoding or "json")
