"""Write a simulated run as the ROS 1 bag a Pioneer 3-DX running ROSARIA and a SICK driver
records (``rosbag record -a``), with the ``rosbags`` library's ROS 1 writer.

What such a bag holds, as the drivers write it:

- ``/RosAria/pose``: ``nav_msgs/Odometry``, frame ``odom``, child ``base_link``, ~10 Hz;
- ``/tf``: ``tf2_msgs/TFMessage`` with ``odom -> base_link`` at the odometry's stamps (ROSARIA
  broadcasts it) and, unless left out, ``base_link -> laser`` every 0.1 s (ROS 1's
  ``static_transform_publisher`` republishes on ``/tf``);
- ``/scan``: ``sensor_msgs/LaserScan``, 181 beams over 180 degrees, ``range_max`` where no echo
  came back (the SICK LMS200 reports its maximum), a few beams ``inf`` or ``nan``;
- ``/RosAria/sonar`` (``sensor_msgs/PointCloud``, frame ``base_link``), when asked: one point per
  sonar at the end of its reading, 5 m out where no echo came back (ARIA's maximum);
- ``/RosAria/battery_voltage`` (``std_msgs/Float64``): a topic gridmap ignores;
- optionally the odometry again on a second topic (``/odom``), as a robot running two drivers.

Messages are stamped with the run's stamps; log times trail them by 5 ms (the recorder's
latency), so header stamps and log times differ as on a robot.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import numpy.typing as npt
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from gridmap_cli.records import RangeLog
from gridmap_cli.robot import load_robot

STORE = get_typestore(Stores.ROS1_NOETIC)
# rosbags' Noetic store lacks tf2_msgs; its one-line definition, as tf2_msgs ships it
STORE.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms",
                                  "tf2_msgs/msg/TFMessage"))  # fmt: skip
T = STORE.types
LATENCY_NS = 5_000_000
#: the bag's clock: wall time (2020-09-13), where the simulated run's starts at 0
START_NS = 1_600_000_000 * 1_000_000_000


def _stamp(ns: int) -> object:
    return T["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def _header(seq: int, ns: int, frame: str) -> object:
    return T["std_msgs/msg/Header"](seq=seq, stamp=_stamp(ns), frame_id=frame)


def _quaternion(yaw: float) -> object:
    return T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


def _tilted(yaw: float, pitch: float, roll: float) -> object:
    """The quaternion of yaw, then pitch, then roll (ROS's rpy)."""
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    return T["geometry_msgs/msg/Quaternion"](
        x=sr * cp * cy - cr * sp * sy,
        y=cr * sp * cy + sr * cp * sy,
        z=cr * cp * sy - sr * sp * cy,
        w=cr * cp * cy + sr * sp * sy,
    )


def _transform(
    ns: int, parent: str, child: str, x: float, y: float, yaw: float, pitch: float = 0.0,
    roll: float = 0.0,
) -> object:  # fmt: skip
    rotation = _quaternion(yaw) if pitch == roll == 0.0 else _tilted(yaw, pitch, roll)
    return T["geometry_msgs/msg/TransformStamped"](
        header=_header(0, ns, parent),
        child_frame_id=child,
        transform=T["geometry_msgs/msg/Transform"](
            translation=T["geometry_msgs/msg/Vector3"](x=x, y=y, z=0.0),
            rotation=rotation,
        ),
    )


def write_pioneer_bag(
    log: RangeLog,
    target: Path,
    *,
    laser_frame: str = "laser",
    mounting: tuple[float, float, float] | None = (0.16, 0.0, 0.0),
    laser_name: str = "laser1",
    sonar: bool = False,
    second_odometry: str | None = None,
    odometry: bool = True,
    interleave: int = 1,
    turning: bool = True,
    skewed: int = -1,
    range_max: float = 8.0,
    laser_tilt: tuple[float, float] = (0.0, 0.0),
    clockwise: bool = False,
    zeros: float = 0.0,
    multi_echo: bool = False,
    vertical: bool = False,
) -> Path:
    """``log`` (a simulated run with one laser, ``laser_name``, beams ``laser_name_0``...) as a
    ROSARIA + SICK bag at ``target``. ``mounting``: the ``base_link -> laser`` transform (x, y,
    yaw) published on ``/tf``, or None for a bag without it. ``sonar``: write the log's sonars
    (``sonar0``...) as RosAria's point cloud; ``second_odometry``: a topic to repeat the odometry
    on; ``odometry`` False leaves out the odometry (``/RosAria/pose`` and ``odom -> base_link``):
    a laser alone. ``interleave`` > 1: the laser sends scans of ``interleave`` start angles in
    turn, each a ``1 / interleave`` step on from the last, every other one a beam short (as a
    SICK LMS in its interlaced modes): a scan's ranges are the world's along its own beams,
    from ``log``'s ``laser_name`` beams at the same stamp by the nearest beam of the
    simulation's beams: ``log``'s laser must have ``180 * interleave + 1`` beams over 180
    degrees, of which scan ``j`` of a turn takes beams ``j``, ``j + interleave``, ...;
    ``turning`` False gives every scan the first start angle (the same laser, constant). Scan
    number ``skewed`` gets an ``angle_max`` ten steps off its ranges. ``range_max``: the scans'
    ``range_max`` field (a driver's bad one, say). ``laser_tilt``: the laser's pitch and roll
    (rad) in its ``base_link -> laser`` transform; a roll of pi mounts it upside down, and its
    ranges are written mirrored, as such a laser sees the world. ``clockwise``: each scan
    from its left end to its right (``angle_min`` pi/2, a negative ``angle_increment``), as
    some drivers send them; the same beams. ``zeros``: the share of beams, at random, that read
    0.0 (a driver's "no reading" with ``range_min`` 0). ``multi_echo``: the scans as
    ``sensor_msgs/MultiEchoLaserScan``, each beam's range its first echo and a second one 1.5 m
    behind it (a beam of NaN no echo at all, one of inf the one echo inf). ``vertical``: a
    second laser, ``vertical_laser`` on ``/vertical_scan``, its TF mounting pitched 90 degrees
    (a backpack's), sending the same scans."""
    beams = [i for i, name in enumerate(log.sensor_names) if name.startswith(f"{laser_name}_")]
    order = np.argsort([int(log.sensor_names[i].rsplit("_", 1)[1]) for i in beams])
    beam_of = np.full(len(log.sensor_names), -1)
    beam_of[np.asarray(beams)[order]] = np.arange(len(beams))
    n_beams = len(beams)
    fine = math.pi / (n_beams - 1)  # the simulation's step
    step = fine * interleave  # each scan's
    r = log.readings
    stamps = np.unique(r.stamp_ns)
    p = log.poses
    rng = np.random.default_rng(7)
    with Writer(target) as bag:
        odom = (
            bag.add_connection("/RosAria/pose", "nav_msgs/msg/Odometry", typestore=STORE)
            if odometry
            else None
        )
        tf = bag.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=STORE)
        scan_type = "MultiEchoLaserScan" if multi_echo else "LaserScan"
        scan = bag.add_connection("/scan", f"sensor_msgs/msg/{scan_type}", typestore=STORE)
        upright = (
            bag.add_connection("/vertical_scan", f"sensor_msgs/msg/{scan_type}", typestore=STORE)
            if vertical
            else None
        )
        volts = bag.add_connection("/RosAria/battery_voltage", "std_msgs/msg/Float64",
                                   typestore=STORE)  # fmt: skip
        cloud = bag.add_connection("/RosAria/sonar", "sensor_msgs/msg/PointCloud",
                                   typestore=STORE) if sonar else None  # fmt: skip
        odom2 = (
            bag.add_connection(second_odometry, "nav_msgs/msg/Odometry", typestore=STORE)
            if second_odometry
            else None
        )
        messages: list[tuple[int, object, object]] = []
        cov = np.zeros(36)
        for k in range(len(p)):
            ns = START_NS + int(p.stamp_ns[k])
            x, y, th = float(p.x_m[k]), float(p.y_m[k]), float(p.theta_rad[k])
            pose = T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0), orientation=_quaternion(th)
            )
            twist = T["geometry_msgs/msg/Twist"](
                linear=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                angular=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
            )
            msg = T["nav_msgs/msg/Odometry"](
                header=_header(k, ns, "odom"),
                child_frame_id="base_link",
                pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=cov),
                twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=cov),
            )
            if odom is not None:
                messages.append((ns + LATENCY_NS, odom, msg))
            if odom2 is not None:
                messages.append((ns + LATENCY_NS, odom2, msg))
            moving = [_transform(ns, "odom", "base_link", x, y, th)] if odometry else []
            if mounting is not None:
                moving.append(_transform(ns, "base_link", laser_frame, *mounting, *laser_tilt))
            if upright is not None:
                moving.append(_transform(ns, "base_link", "vertical_laser", 0.0, 0.0, 0.0,
                                         math.pi / 2, 0.0))  # fmt: skip
            if moving:
                messages.append(
                    (ns + LATENCY_NS, tf, T["tf2_msgs/msg/TFMessage"](transforms=moving))
                )
            if k % 10 == 0:
                messages.append((ns + LATENCY_NS, volts, T["std_msgs/msg/Float64"](data=12.6)))
        cuts = np.searchsorted(r.stamp_ns, stamps, side="left")
        ends = np.searchsorted(r.stamp_ns, stamps, side="right")
        for seq, (ns, a, b) in enumerate(zip(stamps, cuts, ends, strict=True)):
            every = np.full(n_beams, 8.0, dtype=np.float32)
            idx = beam_of[r.sensor[a:b]]
            ok = idx >= 0
            every[idx[ok]] = np.minimum(r.range_m[a:b][ok], 8.0)
            turn = seq % interleave if turning else 0
            ranges = every
            if interleave > 1:
                ranges = np.ascontiguousarray(every[turn::interleave][: 180 + (turn == 0)])
            if math.cos(laser_tilt[1]) < 0.0:  # upside down: the beams sweep right to left
                ranges = np.ascontiguousarray(ranges[::-1])
            n_scan = len(ranges)
            odd = rng.random(n_scan) < 0.01  # the odd beam reads inf or nan
            ranges[odd & (rng.random(n_scan) < 0.5)] = np.inf
            ranges[odd & ~np.isinf(ranges)] = np.nan
            if zeros > 0.0:  # drawn only then: the other bags keep their odd beams
                ranges[rng.random(n_scan) < zeros] = 0.0
            first = -math.pi / 2 + turn * fine
            amin = first if interleave > 1 else -math.pi / 2
            amax = first + (n_scan - 1) * step if interleave > 1 else math.pi / 2
            inc = step
            if clockwise:
                ranges, amin, amax, inc = np.ascontiguousarray(ranges[::-1]), amax, amin, -step
            fields = {
                "header": _header(seq, START_NS + int(ns), laser_frame),
                "angle_min": amin,
                "angle_max": amax + (10 * inc if seq == skewed else 0.0),
                "angle_increment": inc,
                "time_increment": 0.0,
                "scan_time": 0.1,
                "range_min": 0.0,
                "range_max": range_max,
            }
            if multi_echo:
                echo = T["sensor_msgs/msg/LaserEcho"]
                msg = T["sensor_msgs/msg/MultiEchoLaserScan"](
                    **fields,
                    ranges=[echo(echoes=_echoes(float(v))) for v in ranges],
                    intensities=[],
                )
            else:
                msg = T["sensor_msgs/msg/LaserScan"](
                    **fields, ranges=ranges, intensities=np.zeros(0, dtype=np.float32)
                )
            messages.append((START_NS + int(ns) + LATENCY_NS, scan, msg))
            if upright is not None:
                fields["header"] = _header(seq, START_NS + int(ns), "vertical_laser")
                messages.append((START_NS + int(ns) + LATENCY_NS, upright,
                                 type(msg)(**{**fields, "ranges": msg.ranges,
                                              "intensities": msg.intensities})))  # fmt: skip
        if cloud is not None:
            messages.extend(_sonar_clouds(log, cloud))
        messages.sort(key=lambda m: m[0])
        for log_time, conn, msg in messages:
            bag.write(conn, log_time, STORE.serialize_ros1(msg, conn.msgtype))
    return target


def _echoes(value: float) -> npt.NDArray[np.float32]:
    """A beam's echoes for a multi-echo scan whose first echo reads ``value``: none for NaN, the
    one for inf, else it and a second 1.5 m behind."""
    if math.isnan(value):
        return np.zeros(0, dtype=np.float32)
    if math.isinf(value):
        return np.array([value], dtype=np.float32)
    return np.array([value, value + 1.5], dtype=np.float32)


def _sonar_clouds(log: RangeLog, conn: object) -> list[tuple[int, object, object]]:
    """RosAria's ``/RosAria/sonar``: per stamp, the end point of each sonar's reading."""
    sonars = sorted(
        (i for i, n in enumerate(log.sensor_names) if n.startswith("sonar")),
        key=lambda i: int(log.sensor_names[i][5:]),
    )
    robot = load_robot(log.metadata.get("robot", "p3at-lms200")).by_name()
    r = log.readings
    out = []
    for seq, ns in enumerate(np.unique(r.stamp_ns)):
        a, b = np.searchsorted(r.stamp_ns, [ns, ns + 1])
        ranges = dict(zip(r.sensor[a:b].tolist(), r.range_m[a:b].tolist(), strict=True))
        points = []
        for i in sonars:
            s = robot[log.sensor_names[i]]
            rng = min(ranges.get(i, 5.0), 5.0)
            points.append(T["geometry_msgs/msg/Point32"](
                x=s.x_m + rng * math.cos(s.yaw_rad), y=s.y_m + rng * math.sin(s.yaw_rad), z=0.0
            ))  # fmt: skip
        msg = T["sensor_msgs/msg/PointCloud"](
            header=_header(seq, START_NS + int(ns), "base_link"), points=points, channels=[]
        )
        out.append((START_NS + int(ns) + LATENCY_NS, conn, msg))
    return out
