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

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "mcap"


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


_SEP = "\n" + "=" * 80 + "\nMSG: "

# ROS 2 definitions (rosbag2 stores the full text: the type, then each dependency)
_R2 = {
    "builtin_interfaces/Time": "int32 sec\nuint32 nanosec",
    "std_msgs/Header": "builtin_interfaces/Time stamp\nstring frame_id",
    "geometry_msgs/Point": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Point32": "float32 x\nfloat32 y\nfloat32 z",
    "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Quaternion": "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1",
    "geometry_msgs/Pose": "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation",
    "geometry_msgs/PoseWithCovariance": "geometry_msgs/Pose pose\nfloat64[36] covariance",
    "geometry_msgs/Twist": "geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular",
    "geometry_msgs/TwistWithCovariance": "geometry_msgs/Twist twist\nfloat64[36] covariance",
    "geometry_msgs/Transform": "geometry_msgs/Vector3 translation\n"
    "geometry_msgs/Quaternion rotation",
    "geometry_msgs/TransformStamped": "std_msgs/Header header\nstring child_frame_id\n"
    "geometry_msgs/Transform transform",
    "geometry_msgs/PoseStamped": "std_msgs/Header header\ngeometry_msgs/Pose pose",
    "nav_msgs/Odometry": "std_msgs/Header header\nstring child_frame_id\n"
    "geometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist",
    "tf2_msgs/TFMessage": "geometry_msgs/TransformStamped[] transforms",
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


def _deps(name: str, table: dict[str, str], seen: list[str]) -> None:
    for line in table[name].splitlines():
        field_type = line.split()[0].split("[")[0]
        if field_type in table and field_type not in seen:
            seen.append(field_type)
            _deps(field_type, table, seen)


def ros2_definition(name: str) -> str:
    """Full ROS 2 message definition text of ``pkg/Type`` with its dependencies."""
    seen: list[str] = []
    _deps(name, _R2, seen)
    parts = [_R2[name]] + [f"{dep.replace('/', '/msg/', 1)}\n{_R2[dep]}" for dep in seen]
    return _SEP.join(parts)


# ROS 1: time is a builtin and the Header has a sequence number
_R1 = {k: v for k, v in _R2.items() if k != "builtin_interfaces/Time"}
_R1["std_msgs/Header"] = "uint32 seq\ntime stamp\nstring frame_id"
_R1["tf/tfMessage"] = _R2["tf2_msgs/TFMessage"]
_R1["geometry_msgs/Quaternion"] = "float64 x\nfloat64 y\nfloat64 z\nfloat64 w"  # no defaults


def ros1_definition(name: str) -> str:
    """Full ROS 1 message definition text (as rosbag stores it)."""
    seen: list[str] = []
    _deps(name, _R1, seen)
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
        import math

        return {
            "header": self.header(ns, parent),
            "child_frame_id": child,
            "transform": {
                "translation": {"x": x, "y": y, "z": z},
                "rotation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)},
            },
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
    import math

    return {
        "header": rec.header(ns, frame),
        "child_frame_id": child,
        "pose": {
            "pose": {
                "position": {"x": x, "y": y, "z": 0.0},
                "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)},
            }
        },
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
