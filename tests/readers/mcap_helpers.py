"""Helpers for the MCAP reader tests: merging real recordings, ROS message definitions.

The ROS 2 definitions are those gridmap's own writer uses (``writers/ros2_msgdefs.py``), plus the
few types it never writes; the ROS 1 ones are written out below. Both come with their
dependencies after ``MSG:`` separators, as rosbag and rosbag2 store them, so tests can write ROS 1
and ROS 2 messages with the mcap support packages' writers.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from mcap.reader import make_reader
from mcap.writer import Writer

from gridmap_cli.writers.ros2_msgdefs import message_definition

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "mcap"
S = 1_000_000_000


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


def turn(yaw: float) -> dict[str, float]:
    """The quaternion of a rotation by ``yaw`` (rad) about z, as a message's nested dict."""
    return {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)}


def stamp1(ns: int) -> dict[str, Any]:
    return {"secs": ns // 1_000_000_000, "nsecs": ns % 1_000_000_000}


def stamp2(ns: int) -> dict[str, Any]:
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


_SEP = "\n" + "=" * 80 + "\nMSG: "

# ROS 1 definitions (rosbag stores the full text: the type, then each dependency after a ``MSG:``
# separator). Time is a builtin, the Header has a sequence number, Range has no variance.
_R1 = {
    "std_msgs/Header": "uint32 seq\ntime stamp\nstring frame_id",
    "geometry_msgs/Point": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Point32": "float32 x\nfloat32 y\nfloat32 z",
    "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Quaternion": "float64 x\nfloat64 y\nfloat64 z\nfloat64 w",
    "geometry_msgs/Pose": "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation",
    "geometry_msgs/PoseWithCovariance": "geometry_msgs/Pose pose\nfloat64[36] covariance",
    "geometry_msgs/Twist": "geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular",
    "geometry_msgs/TwistWithCovariance": "geometry_msgs/Twist twist\nfloat64[36] covariance",
    "geometry_msgs/Transform": "geometry_msgs/Vector3 translation\n"
    "geometry_msgs/Quaternion rotation",
    "geometry_msgs/TransformStamped": "std_msgs/Header header\nstring child_frame_id\n"
    "geometry_msgs/Transform transform",
    "nav_msgs/Odometry": "std_msgs/Header header\nstring child_frame_id\n"
    "geometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist",
    "tf/tfMessage": "geometry_msgs/TransformStamped[] transforms",
    "geometry_msgs/PoseWithCovarianceStamped": "std_msgs/Header header\n"
    "geometry_msgs/PoseWithCovariance pose",
    "sensor_msgs/Range": "uint8 ULTRASOUND=0\nuint8 INFRARED=1\nstd_msgs/Header header\n"
    "uint8 radiation_type\nfloat32 field_of_view\nfloat32 min_range\nfloat32 max_range\n"
    "float32 range",
    "sensor_msgs/LaserScan": "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\n"
    "float32 angle_increment\nfloat32 time_increment\nfloat32 scan_time\nfloat32 range_min\n"
    "float32 range_max\nfloat32[] ranges\nfloat32[] intensities",
    "sensor_msgs/ChannelFloat32": "string name\nfloat32[] values",
    "sensor_msgs/PointCloud": "std_msgs/Header header\ngeometry_msgs/Point32[] points\n"
    "sensor_msgs/ChannelFloat32[] channels",
}

# ROS 2 types that gridmap's writer has no definition of (writers/ros2_msgdefs.py holds the rest)
_R2_MORE = {
    "geometry_msgs/Point32": "float32 x\nfloat32 y\nfloat32 z",
    "geometry_msgs/PoseStamped": "std_msgs/Header header\ngeometry_msgs/Pose pose",
    "geometry_msgs/PoseWithCovarianceStamped": "std_msgs/Header header\n"
    "geometry_msgs/PoseWithCovariance pose",
    "sensor_msgs/ChannelFloat32": "string name\nfloat32[] values",
    "sensor_msgs/PointCloud": _R1["sensor_msgs/PointCloud"],
}


def _uses(text: str) -> list[str]:
    """The message types (``pkg/Type``) a definition's fields use, in order."""
    types = [line.split()[0].split("[")[0] for line in text.splitlines()]
    return list(dict.fromkeys(t for t in types if "/" in t))


def ros2_definition(name: str) -> str:
    """Full ROS 2 message definition text of ``pkg/Type`` with its dependencies."""
    if name not in _R2_MORE:
        return message_definition(name)
    # each type used, with the types it uses in turn (none of them shares one here)
    parts = [_R2_MORE[name]]
    parts += [f"{dep}\n{_R2_MORE.get(dep) or message_definition(dep)}" for dep in _uses(parts[0])]
    return _SEP.join(parts)


def _deps(name: str, seen: list[str]) -> None:
    for dep in _uses(_R1[name]):
        if dep not in seen:
            seen.append(dep)
            _deps(dep, seen)


def ros1_definition(name: str) -> str:
    """Full ROS 1 message definition text (as rosbag stores it)."""
    seen: list[str] = []
    _deps(name, seen)
    return _SEP.join([_R1[name]] + [f"{dep}\n{_R1[dep]}" for dep in seen])


def ros1_class(name: str) -> Any:
    """A genpy message class for ``pkg/Type``, for mcap_ros1's writer."""
    from mcap_ros1._vendor.genpy.dynamic import generate_dynamic

    return generate_dynamic(name, ros1_definition(name))[name]


def _fill(msg: Any, values: dict[str, Any]) -> None:
    """Set a genpy message's fields from nested dicts (lists of dicts become messages)."""
    types = dict(zip(msg.__slots__, msg._slot_types, strict=True))
    for key, value in values.items():
        if isinstance(value, dict):
            _fill(getattr(msg, key), value)
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            element = ros1_class(types[key].split("[")[0])
            items = []
            for entry in value:
                item = element()
                _fill(item, entry)
                items.append(item)
            setattr(msg, key, items)
        else:
            setattr(msg, key, value)


class Recording:
    """Writes a small ROS 1 or ROS 2 MCAP with the mcap support packages' writers.

    ``write(topic, "sensor_msgs/Range", log_time_ns, {...})`` takes the message as nested dicts;
    :meth:`header` and :meth:`stamp` spell header stamps for the ROS version.
    """

    def __init__(self, path: Path, ros: int = 2) -> None:
        from mcap_ros1.writer import Writer as Ros1Writer
        from mcap_ros2.writer import Writer as Ros2Writer

        self.ros = ros
        self.handle = open(path, "wb")  # noqa: SIM115 - closed by close()
        self.writer: Any = Ros2Writer(self.handle) if ros == 2 else Ros1Writer(self.handle)
        self.schemas: dict[str, Any] = {}

    def stamp(self, ns: int) -> dict[str, int]:
        return stamp2(ns) if self.ros == 2 else stamp1(ns)

    def header(self, ns: int, frame: str) -> dict[str, Any]:
        return {"stamp": self.stamp(ns), "frame_id": frame}

    def transform(
        self, ns: int, parent: str, child: str, x: float, y: float, yaw: float, z: float = 0.0
    ) -> dict[str, Any]:
        return {
            "header": self.header(ns, parent),
            "child_frame_id": child,
            "transform": {"translation": {"x": x, "y": y, "z": z}, "rotation": turn(yaw)},
        }

    def write(self, topic: str, type_name: str, log_time: int, values: dict[str, Any]) -> None:
        if self.ros == 2:
            schema = self.schemas.get(type_name)
            if schema is None:
                schema = self.writer.register_msgdef(
                    type_name.replace("/", "/msg/", 1), ros2_definition(type_name)
                )
                self.schemas[type_name] = schema
            self.writer.write_message(topic, schema, values, log_time=log_time,
                                      publish_time=log_time)  # fmt: skip
        else:
            msg = ros1_class(type_name)()
            _fill(msg, values)
            self.writer.write_message(topic, msg, log_time=log_time)

    def close(self) -> None:
        self.writer.finish()
        self.handle.close()

    def __enter__(self) -> Recording:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def odometry(rec: Recording, ns: int, x: float, y: float, yaw: float,
             frame: str = "odom", child: str = "base_link") -> dict[str, Any]:  # fmt: skip
    """An Odometry message as nested dicts."""
    return {
        "header": rec.header(ns, frame),
        "child_frame_id": child,
        "pose": {"pose": {"position": {"x": x, "y": y, "z": 0.0}, "orientation": turn(yaw)}},
    }


def sonar_range(rec: Recording, ns: int, frame: str, value: float, fov: float = 0.5,
                rmin: float = 0.1, rmax: float = 3.0) -> dict[str, Any]:  # fmt: skip
    """A sensor_msgs/Range message as nested dicts."""
    return {
        "header": rec.header(ns, frame),
        "radiation_type": 0,
        "field_of_view": fov,
        "min_range": rmin,
        "max_range": rmax,
        "range": value,
    }


def drive(rec: Recording, steps: int = 11, topic: str = "/odom", child: str = "base_link") -> None:
    """Odometry along x at 0.1 m per 0.1 s from t = 1 s."""
    for k in range(steps):
        ns = S + k * S // 10
        rec.write(topic, "nav_msgs/Odometry", ns, odometry(rec, ns, 0.1 * k, 0.0, 0.0, child=child))


def static_tf(rec: Recording, *transforms: dict[str, object], topic: str = "/tf_static") -> None:
    """Static transforms (from :meth:`Recording.transform`) at t = 1 s."""
    type_name = "tf2_msgs/TFMessage" if rec.ros == 2 else "tf/tfMessage"
    rec.write(topic, type_name, S, {"transforms": list(transforms)})


def one_sonar_log(
    path: Path,
    frame: str = "s0",
    mount: tuple[str, str] | None = ("base_link", "s0"),
    topics: tuple[str, ...] = ("/sonar",),
    odom_topics: dict[str, int] | None = None,
) -> Path:
    """ROS 2: an identity static transform ``mount`` (parent, child; None: no TF), odometry
    (:func:`drive` on each of ``odom_topics``, topic -> messages; default 11 on /odom) and one
    1 m reading of sonar ``frame`` at t = 1 s on each of ``topics``."""
    with Recording(path) as rec:
        if mount is not None:
            static_tf(rec, rec.transform(0, *mount, 0.0, 0.0, 0.0))
        for topic, steps in (odom_topics or {"/odom": 11}).items():
            drive(rec, steps=steps, topic=topic)
        for topic in topics:
            rec.write(topic, "sensor_msgs/Range", S, sonar_range(rec, S, frame, 1.0))
    return path
