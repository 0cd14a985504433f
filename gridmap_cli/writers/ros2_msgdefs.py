"""ROS 2 message definitions that gridmap writes into MCAP files as ``ros2msg`` schemas.

An MCAP schema of encoding ``ros2msg`` holds the message's own definition followed by every type
it uses, each introduced by a line of 80 ``=`` and ``MSG: <package>/<Type>``: the concatenated
form rosbag2 writes, so that readers decode the data without a ROS installation. The fields are
those of ROS 2 Jazzy (``sensor_msgs/Range`` there ends with ``variance``, added after Humble);
the comments of the ROS sources are left out, since no reader needs them.
"""

from __future__ import annotations

#: Field lines of each type, by its name without ``/msg/``. Types in the same package are named
#: as the package's own definitions name them (without the package prefix).
_FIELDS: dict[str, str] = {
    "builtin_interfaces/Time": "int32 sec\nuint32 nanosec\n",
    "std_msgs/Header": "builtin_interfaces/Time stamp\nstring frame_id\n",
    "geometry_msgs/Point": "float64 x\nfloat64 y\nfloat64 z\n",
    "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z\n",
    "geometry_msgs/Quaternion": "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    "geometry_msgs/Pose": "Point position\nQuaternion orientation\n",
    "geometry_msgs/PoseWithCovariance": "Pose pose\nfloat64[36] covariance\n",
    "geometry_msgs/Twist": "Vector3 linear\nVector3 angular\n",
    "geometry_msgs/TwistWithCovariance": "Twist twist\nfloat64[36] covariance\n",
    "geometry_msgs/Transform": "Vector3 translation\nQuaternion rotation\n",
    "geometry_msgs/TransformStamped": (
        "std_msgs/Header header\nstring child_frame_id\nTransform transform\n"
    ),
    "nav_msgs/Odometry": (
        "std_msgs/Header header\n"
        "string child_frame_id\n"
        "geometry_msgs/PoseWithCovariance pose\n"
        "geometry_msgs/TwistWithCovariance twist\n"
    ),
    "nav_msgs/MapMetaData": (
        "builtin_interfaces/Time map_load_time\n"
        "float32 resolution\n"
        "uint32 width\n"
        "uint32 height\n"
        "geometry_msgs/Pose origin\n"
    ),
    "nav_msgs/OccupancyGrid": "std_msgs/Header header\nMapMetaData info\nint8[] data\n",
    "tf2_msgs/TFMessage": "geometry_msgs/TransformStamped[] transforms\n",
    "sensor_msgs/Range": (
        "std_msgs/Header header\n"
        "uint8 ULTRASOUND=0\n"
        "uint8 INFRARED=1\n"
        "uint8 radiation_type\n"
        "float32 field_of_view\n"
        "float32 min_range\n"
        "float32 max_range\n"
        "float32 range\n"
        "float32 variance\n"
    ),
    "sensor_msgs/LaserScan": (
        "std_msgs/Header header\n"
        "float32 angle_min\n"
        "float32 angle_max\n"
        "float32 angle_increment\n"
        "float32 time_increment\n"
        "float32 scan_time\n"
        "float32 range_min\n"
        "float32 range_max\n"
        "float32[] ranges\n"
        "float32[] intensities\n"
    ),
}

_PRIMITIVES = {
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
    "int32", "uint32", "int64", "uint64", "string", "wstring",
}  # fmt: skip

_SEPARATOR = "=" * 80


def _used_types(name: str) -> list[str]:
    """Types ``name``'s fields use, in the order they first appear (fully qualified)."""
    package = name.split("/")[0]
    used: list[str] = []
    for line in _FIELDS[name].splitlines():
        field_type = line.split()[0].split("[")[0]
        if field_type in _PRIMITIVES or "=" in line.split()[1]:
            continue
        full = field_type if "/" in field_type else f"{package}/{field_type}"
        if full not in used:
            used.append(full)
    return used


def message_definition(schema_name: str) -> str:
    """The concatenated definition of ``schema_name`` (``nav_msgs/msg/Odometry``) as rosbag2
    stores it: the type's fields, then each type it uses once, depth first in order of use."""
    name = schema_name.replace("/msg/", "/")
    if name not in _FIELDS:
        raise KeyError(f"no message definition for {schema_name}")
    order: list[str] = []

    def visit(type_name: str) -> None:
        for dep in _used_types(type_name):
            if dep not in order:
                order.append(dep)
                visit(dep)

    visit(name)
    parts = [_FIELDS[name]]
    parts.extend(f"\n{_SEPARATOR}\nMSG: {dep}\n{_FIELDS[dep]}" for dep in order)
    return "".join(parts)
