"""Decoded ROS messages -> the canonical record stream, whatever container they came from.

The :class:`MessageAccumulator` takes the messages of the topics a
:class:`~gridmap_cli.readers.ros.topics.Plan` chose, in log-time order, as the MCAP, ROS 1 bag and
rosbag2 readers decode them (attribute access on ``mcap_ros1``/``mcap_ros2``/``rosbags`` objects,
dicts for gridmap's JSON channels), and :meth:`MessageAccumulator.finish` turns them into a
:class:`~gridmap_cli.records.RangeLog`:

- odometry: ``nav_msgs/Odometry``, ``geometry_msgs/PoseStamped`` or ``gridmap.Pose2D``; without
  one, the odometry frame -> base transforms on ``/tf``. A pose topic named ``ground_truth`` is the
  reference track. Headings come from the quaternion (``2 atan2(qz, qw)`` for a planar one).
- sensor mounting: static transforms base -> sensor frame on ``/tf_static`` (``/tf`` in ROS 1
  recordings that have no static topic), chained through intermediate frames; else the robot
  description's sensor of the same name (``--robot``); else an error naming the frame.
- ranges: ``sensor_msgs/Range`` (one sensor per frame: field of view, min and max range),
  ``sensor_msgs/LaserScan`` (one ray sensor per beam, ``<frame>_<i>``),
  ``sensor_msgs/PointCloud`` as RosAria publishes sonar (one point per sonar, the echo's position
  in the robot frame; range = distance from the sonar's mount in ``--robot`` to the point), and
  ``gridmap.RangeReading`` with ``gridmap.RangeSensor`` descriptions.

Stamps are the messages' header stamps (``timestamp`` in JSON); a zero stamp falls back to the
message's log time. Frame ids are compared without a leading ``/``. ``docs/reading-ros.md``
states these rules for users.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import InputFileError
from gridmap_cli.geometry import wrap_angle
from gridmap_cli.readers.ros.frames import (
    FrameTree,
    Transform,
    TransformBuffer,
    TransformSeries,
    frame_name,
    yaw_of,
)
from gridmap_cli.readers.ros.topics import Plan, Refusals
from gridmap_cli.records import PoseTrack, RangeLog, RangeReadings
from gridmap_cli.robot import RangeSensor, RobotDescription


def _stamp_ns(stamp: Any) -> int:
    """Integer nanoseconds of a ROS 1 / ROS 2 time or a JSON ``{"sec", "nsec"}`` object."""
    if isinstance(stamp, dict):
        return int(stamp["sec"]) * 1_000_000_000 + int(stamp["nsec"])
    if hasattr(stamp, "secs"):
        return int(stamp.secs) * 1_000_000_000 + int(stamp.nsecs)
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _quaternion(q: Any) -> tuple[float, float, float, float]:
    return float(q.x), float(q.y), float(q.z), float(q.w)


def _transform(t: Any) -> Transform:
    v = t.translation
    return Transform((float(v.x), float(v.y), float(v.z)), _quaternion(t.rotation))


@dataclass
class _Track:
    """Poses as they arrive (any order; sorted and de-duplicated at the end): one by one into
    the lists, or in bulk as arrays (``parts``: stamps (N,), rows (N, 3)), kept in arrival
    order. Arrays, not lists of tuples: a Python tuple of three floats is about 140 bytes a
    pose, 40 MiB for 8 hours of 10 Hz odometry, twice with the ground truth."""

    stamps: list[int] = field(default_factory=list)
    rows: list[tuple[float, float, float]] = field(default_factory=list)
    parts: list[tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.stamps) + sum(len(p[0]) for p in self.parts)

    def add(self, stamp: int, x: float, y: float, theta: float) -> None:
        self.stamps.append(stamp)
        self.rows.append((x, y, theta))

    def extend(self, stamps: npt.NDArray[np.int64], rows: npt.NDArray[np.float64]) -> None:
        """Poses decoded in bulk: ``stamps`` (N,), ``rows`` (N, 3) of x_m, y_m, theta_rad."""
        self._flush()
        self.parts.append((stamps, rows))

    def _flush(self) -> None:
        if self.stamps:
            rows = np.asarray(self.rows, dtype=np.float64).reshape(len(self.rows), 3)
            self.parts.append((np.asarray(self.stamps, dtype=np.int64), rows))
            self.stamps, self.rows = [], []

    def track(self) -> PoseTrack:
        self._flush()
        stamps = np.concatenate([p[0] for p in self.parts]) if self.parts else np.empty(0, np.int64)
        rows = np.concatenate([p[1] for p in self.parts]) if self.parts else np.empty((0, 3))
        order = np.argsort(stamps, kind="stable")
        stamps = stamps[order]
        keep = np.ones(len(stamps), dtype=bool)
        keep[1:] = stamps[1:] != stamps[:-1]  # a repeated stamp: the first message wins
        arr = rows[order[keep]]
        return PoseTrack(
            stamp_ns=stamps[keep],
            x_m=np.ascontiguousarray(arr[:, 0]),
            y_m=np.ascontiguousarray(arr[:, 1]),
            theta_rad=np.ascontiguousarray(arr[:, 2]),
        )


@dataclass
class _Scan:
    """Beam geometry of one laser frame, from its first scan (the messages' float32 values)."""

    angle_min: float
    angle_increment: float
    count: int
    range_min: float
    range_max: float


@dataclass
class _Sonar:
    """One sensor_msgs/Range frame: its first field of view, and the largest ``min_range`` and
    largest ``max_range`` of its messages (the messages' float32 values)."""

    fov: float
    min_range: float
    max_range: float


class MessageAccumulator:
    """Collects decoded messages; :meth:`finish` turns them into a RangeLog."""

    def __init__(
        self, path: str, plan: Plan, robot: RobotDescription | None, refusals: Refusals
    ) -> None:
        self.path = path  # the recording (files joined when several): for errors of the whole
        self.message_path = path  # the file of the message being added: for errors of one
        self.refusals = refusals
        self.plan = plan
        self.robot = robot
        self.odom = _Track()
        self.truth = _Track()
        self.reference = _Track()
        self.tf_series: dict[tuple[str, str], TransformSeries] = {}  # (parent, child) on /tf
        self.tf_pairs: Counter[tuple[str, str]] = Counter()
        self.tree = FrameTree()  # /tf_static, then (by finish) the /tf pairs that never change
        self._buffer: TransformBuffer | None = None
        self.truth_from: str | None = None  # where the reference track came from
        self.mount_from: dict[str, str] = {}  # sensor frame -> "TF", "robot" or "unknown"
        self.odom_children: Counter[str] = Counter()
        self.frame_topic: dict[str, str] = {}  # sensor frame -> topic it arrived on
        self.sonars: dict[str, _Sonar] = {}
        self.scans: dict[str, _Scan] = {}
        self.clouds: list[tuple[int, str, npt.NDArray[np.float64]]] = []
        self.json_sensors: dict[str, RangeSensor] = {}
        # readings in arrival order: stamp, key (sensor name), range (inf = no echo), and whether
        # the range is a message's float32 (converted to its decimal by finish)
        self.keys: dict[str, int] = {}
        self.r_stamp: list[int] = []
        self.r_key: list[int] = []
        self.r_range: list[float] = []
        self.r_f32: list[bool] = []
        # readings decoded in bulk (ros_batches): arrays of the same four, after the lists
        self.r_chunks: list[
            tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.float64], bool]
        ] = []
        self.range_topics = set(plan.range_topics)
        self.topic_types: dict[str, str] = {}

    # ------------------------------------------------------------------ messages
    def add(self, source: str, topic: str, type_name: str, log_time: int, msg: Any) -> None:
        """Take one decoded message of ``topic`` from file ``source``."""
        self.message_path = source
        self.topic_types[topic] = type_name
        try:
            self._dispatch(topic, type_name, log_time, msg)
        except InputFileError:
            raise
        except (AttributeError, KeyError, TypeError, ValueError) as exc:
            raise InputFileError(
                self.message_path,
                f"{topic}: malformed {type_name} message at log time {log_time} "
                f"({type(exc).__name__}: {exc})",
            ) from exc

    def _where(self, topic: str, log_time: int) -> str:
        return f"{topic} at log time {log_time / 1e9:.9f} s"

    def _stamp(self, header_stamp: Any, log_time: int) -> int:
        stamp = _stamp_ns(header_stamp)
        return stamp if stamp != 0 else log_time

    def _dispatch(self, topic: str, type_name: str, log_time: int, msg: Any) -> None:
        if topic in self.plan.static_topics or topic in self.plan.tf_topics:
            self._tf(topic, msg, static=topic in self.plan.static_topics, log_time=log_time)
        if topic == self.plan.odom_topic:
            self._pose(self.odom, topic, type_name, log_time, msg)
        elif topic == self.plan.truth_topic:
            self._pose(self.truth, topic, type_name, log_time, msg)
        elif topic == self.plan.reference_topic:
            self._pose(self.reference, topic, type_name, log_time, msg)
        elif topic == self.plan.sensors_topic:
            self._json_sensor(msg)
        if topic not in self.range_topics:
            return
        if type_name == "sensor_msgs/Range":
            self._range(topic, log_time, msg)
        elif type_name == "sensor_msgs/LaserScan":
            self._scan(topic, log_time, msg)
        elif type_name == "sensor_msgs/PointCloud":
            self._cloud(topic, log_time, msg)
        elif type_name == "gridmap.RangeReading":
            self._json_reading(topic, log_time, msg)

    def _pose(self, track: _Track, topic: str, type_name: str, log_time: int, msg: Any) -> None:
        if type_name == "gridmap.Pose2D":
            stamp = self._stamp(msg["timestamp"], log_time)
            x, y, theta = float(msg["x"]), float(msg["y"]), float(msg["theta"])
            child = str(msg.get("child_frame_id", ""))
        else:
            stamp = self._stamp(msg.header.stamp, log_time)
            # Odometry and PoseWithCovarianceStamped wrap the pose with its covariance
            pose = msg.pose if type_name == "geometry_msgs/PoseStamped" else msg.pose.pose
            x, y = float(pose.position.x), float(pose.position.y)
            theta = yaw_of(_quaternion(pose.orientation))
            child = str(getattr(msg, "child_frame_id", ""))
        if not all(math.isfinite(v) for v in (x, y, theta)):
            raise InputFileError(
                self.message_path,
                f"{self._where(topic, log_time)}: pose is not finite ({x}, {y}, {theta})",
            )
        if child and track is self.odom:
            self.odom_children[frame_name(child)] += 1
        track.add(stamp, x, y, theta)

    def _tf(self, topic: str, msg: Any, static: bool, log_time: int) -> None:
        for t in msg.transforms:
            parent, child = frame_name(t.header.frame_id), frame_name(t.child_frame_id)
            transform = _transform(t.transform)
            if static:
                self.tree.add(parent, child, transform)
                continue
            self.tf_pairs[(parent, child)] += 1
            series = self.tf_series.get((parent, child))
            if series is None:
                series = self.tf_series[(parent, child)] = TransformSeries()
            series.add(self._stamp(t.header.stamp, log_time), transform)

    def _claim(self, frame: str, topic: str) -> None:
        other = self.frame_topic.setdefault(frame, topic)
        if other != topic:
            raise InputFileError(
                self.message_path,
                f"sensor frame '{frame}' publishes on both {other} and {topic}; "
                "choose one with --range-topic",
            )

    def _key(self, name: str) -> int:
        return self.keys.setdefault(name, len(self.keys))

    def _push(self, stamp: int, key: int, value: float, f32: bool) -> None:
        self.r_stamp.append(stamp)
        self.r_key.append(key)
        self.r_range.append(value)
        self.r_f32.append(f32)

    def _extend(self, stamp: int, keys: list[int], values: list[float], f32: bool) -> None:
        self.r_stamp.extend([stamp] * len(keys))
        self.r_key.extend(keys)
        self.r_range.extend(values)
        self.r_f32.extend([f32] * len(keys))

    def _range(self, topic: str, log_time: int, msg: Any) -> None:
        # float32 fields compare as their decimals do (float32_decimal keeps the order), so the
        # conversion waits for finish
        frame = frame_name(msg.header.frame_id)
        self._claim(frame, topic)
        rmin, rmax = msg.min_range, msg.max_range
        if not (0.0 <= rmin < rmax and math.isfinite(rmax)):
            raise InputFileError(
                self.message_path,
                f"{self._where(topic, log_time)}: frame '{frame}': need 0 <= min_range < "
                f"max_range, got {_f32(rmin)} and {_f32(rmax)}",
            )
        sonar = self.sonars.get(frame)
        if sonar is None:
            self.sonars[frame] = _Sonar(msg.field_of_view, rmin, rmax)
        else:
            sonar.min_range = max(sonar.min_range, rmin)
            sonar.max_range = max(sonar.max_range, rmax)
        value = _classify(msg.range, rmax)
        key = self._key(frame)
        if value is not None:
            self._push(self._stamp(msg.header.stamp, log_time), key, value, True)

    def _scan(self, topic: str, log_time: int, msg: Any) -> None:
        frame = frame_name(msg.header.frame_id)
        self._claim(frame, topic)
        ranges = np.asarray(msg.ranges, dtype=np.float64)  # float32 values
        geometry = _Scan(
            msg.angle_min, msg.angle_increment, len(ranges), msg.range_min, msg.range_max
        )
        known = self.scans.setdefault(frame, geometry)
        if (known.angle_min, known.angle_increment, known.count) != (
            geometry.angle_min,
            geometry.angle_increment,
            geometry.count,
        ):
            raise InputFileError(
                self.message_path,
                f"{self._where(topic, log_time)}: laser '{frame}' changed its beams "
                f"({geometry.count} from {_f32(geometry.angle_min):g} rad by "
                f"{_f32(geometry.angle_increment):g}, first scan had {known.count} from "
                f"{_f32(known.angle_min):g} by {_f32(known.angle_increment):g})",
            )
        base = self._key(f"{frame}_0")
        if base + known.count > len(self.keys):
            for i in range(1, known.count):
                self._key(f"{frame}_{i}")
        with np.errstate(invalid="ignore"):
            valid = ~np.isnan(ranges) & (ranges >= 0.0)  # NaN: no reading; -inf: too close
            no_echo = valid & (ranges >= geometry.range_max)
        out = np.where(no_echo, np.inf, ranges)[valid]
        keys = base + np.nonzero(valid)[0]
        self._extend(self._stamp(msg.header.stamp, log_time), keys.tolist(), out.tolist(), True)

    def _cloud(self, topic: str, log_time: int, msg: Any) -> None:
        frame = frame_name(msg.header.frame_id)
        self._claim(frame, topic)
        points = np.asarray([(float(p.x), float(p.y), float(p.z)) for p in msg.points])
        self.clouds.append(
            (self._stamp(msg.header.stamp, log_time), frame, points.reshape(len(msg.points), 3))
        )

    def _json_sensor(self, msg: dict[str, Any]) -> None:
        name = str(msg["name"])
        self.json_sensors[name] = RangeSensor(
            name,
            float(msg["x"]),
            float(msg["y"]),
            float(msg["yaw"]),
            float(msg["beam_width"]),
            float(msg["min_range"]),
            float(msg["max_range"]),
            str(msg.get("kind", "sonar")),
        )

    def _json_reading(self, topic: str, log_time: int, msg: dict[str, Any]) -> None:
        value = float(msg["range"])
        if math.isnan(value):
            return
        if value < 0.0:
            raise InputFileError(
                self.message_path, f"{self._where(topic, log_time)}: negative range {value}"
            )
        self._push(
            self._stamp(msg["timestamp"], log_time), self._key(str(msg["sensor"])), value, False
        )

    # ------------------------------------------------------------------ result
    def buffer(self) -> TransformBuffer:
        """Every transform read: ``/tf`` pairs that never change join the fixed tree (ROS 1
        recordings republish fixed joints on ``/tf``); those that change are never a mounting."""
        if self._buffer is None:
            for (parent, child), series in self.tf_series.items():
                if not series.changes() and child not in self.tree:  # /tf_static wins
                    self.tree.add(parent, child, series.first())
            self._buffer = TransformBuffer(self.tree, self.tf_series)
        return self._buffer

    def base_frame(self) -> str:
        if self.plan.base_frame:
            return frame_name(self.plan.base_frame)
        if self.odom_children:
            return self.odom_children.most_common(1)[0][0]
        if self.plan.odom_topic is None:
            lowest = self.buffer().lowest_moving_child(self.plan.odom_frame, self.frame_topic)
            if lowest is not None:
                return lowest
        return "base_link"

    def finish(self, metadata: dict[str, str]) -> RangeLog:
        self.buffer()  # the fixed tree is complete from here on
        base = self.base_frame()
        poses = self._odometry(base)
        truth = self._truth(base)
        sensors = self._sensors(base)
        if self.clouds:
            self._cloud_readings(base, sensors)
        names = [s.name for s in sensors]
        if self.plan.sensors_topic is not None or not sensors:
            # gridmap JSON: sensor order from /sensors, unknown names left to --robot
            order = list(self.json_sensors) + [k for k in self.keys if k not in self.json_sensors]
            names = order
        index = {name: i for i, name in enumerate(names)}
        remap = np.array([index[k] for k in self.keys], dtype=np.int32)
        stamp = np.concatenate(
            [np.asarray(self.r_stamp, dtype=np.int64), *(c[0] for c in self.r_chunks)]
        )
        key = np.concatenate(
            [np.asarray(self.r_key, dtype=np.intp), *(c[1] for c in self.r_chunks)]
        ).astype(np.intp)
        sensor = remap[key]
        rng = np.concatenate(
            [np.asarray(self.r_range, dtype=np.float64), *(c[2] for c in self.r_chunks)]
        )
        f32 = np.concatenate(
            [
                np.asarray(self.r_f32, dtype=bool),
                *(np.full(len(c[0]), c[3], dtype=bool) for c in self.r_chunks),
            ]
        )
        rng[f32] = float32_decimal(rng[f32])  # at once: one by one was most of the read time
        if sensors and len(rng):
            # no echo is stored at the sensor's maximum range, as in the CSV layout
            max_r = np.array([s.max_range_m for s in sensors], dtype=np.float64)
            rng = np.where(np.isinf(rng), max_r[sensor], rng)
        by_time = np.lexsort((sensor, stamp))  # by stamp, ties in sensor order
        readings = RangeReadings(stamp[by_time], sensor[by_time], rng[by_time])
        described = sensors or tuple(self.json_sensors.values())
        return RangeLog(
            source=self.path,
            poses=poses,
            readings=readings,
            sensor_names=tuple(names),
            sensors=tuple(described) or None,
            truth=truth,
            metadata=dict(metadata),
        )

    def _odometry(self, base: str) -> PoseTrack:
        """The odometry track; refused when there is none (empty when read on)."""
        if self.plan.odom_topic is not None:
            if len(self.odom):
                return self.odom.track()
            self.refusals.refuse(
                InputFileError(self.path, f"{self.plan.odom_topic} holds no messages")
            )
        else:
            found = self.buffer().track(self.plan.odom_frame, base)
            if found is not None and len(found[0]):
                return _tf_track(*found)
            seen = sorted(self.tf_pairs)
            listing = ", ".join(f"{p} -> {c}" for p, c in seen[:12]) or "none"
            self.refusals.refuse(
                InputFileError(
                    self.path,
                    f"no odometry: no pose topic and no '{self.plan.odom_frame}' -> '{base}' "
                    f"transform on {', '.join(self.plan.tf_topics)} (transforms seen: "
                    f"{listing}); choose with --odom-frame / --base-frame",
                )
            )
        return PoseTrack.from_rows(np.empty(0, dtype=np.int64), [])

    def _truth(self, base: str) -> PoseTrack | None:
        """The reference track: a ground-truth or ``--pose-topic`` topic; else the TF chain
        from the map frame (``--map-frame``) down to the base, composed over time; else the one
        PoseWithCovarianceStamped topic (``/amcl_pose``)."""
        if self.plan.truth_topic is not None and len(self.truth):
            self.truth_from = f"{self.plan.truth_topic} ({self._type(self.plan.truth_topic)})"
            return self.truth.track()
        buffer = self.buffer()
        if self.plan.map_frame != self.plan.odom_frame or self.plan.odom_topic is not None:
            found = buffer.track(self.plan.map_frame, base)
            if found is not None and len(found[0]):
                chain = buffer.chain(self.plan.map_frame, base) or []
                frames = [self.plan.map_frame] + [child for _, child, _ in chain]
                self.truth_from = f"TF {' -> '.join(frames)}"
                return _tf_track(*found)
        if self.plan.reference_topic is not None and len(self.reference):
            topic = self.plan.reference_topic
            self.truth_from = f"{topic} ({self._type(topic)})"
            return self.reference.track()
        return None

    def _type(self, topic: str) -> str:
        return self.topic_types.get(topic, "")

    def _mount(self, base: str, frame: str) -> tuple[float, float, float] | None:
        """A frame's mounting (x, y, yaw) from TF, else from the robot's sensor of its name."""
        transform = self.tree.lookup(base, frame)
        if transform is not None:
            self.mount_from[frame] = "TF"
            return transform.planar()
        if self.robot is not None:
            known = self.robot.by_name().get(frame)
            if known is not None:
                self.mount_from[frame] = "robot"
                return known.x_m, known.y_m, known.yaw_rad
        return None

    def _unmounted(self, base: str, frame: str) -> tuple[float, float, float]:
        """A frame with no known mounting: refused; a NaN mounting when read on."""
        self.refusals.refuse(self._unknown_mount(base, frame))
        self.mount_from[frame] = "unknown"
        return math.nan, math.nan, math.nan

    def _unknown_mount(self, base: str, frame: str) -> InputFileError:
        where = ", ".join(dict.fromkeys((*self.plan.static_topics, *self.plan.tf_topics)))
        if self.buffer().moves(base, frame):
            tf_part = (
                f"its transform from '{base}' changes over time (a moving joint), and gridmap "
                "maps sensors with a fixed mounting"
            )
        elif frame in self.tree:
            tf_part = (
                f"its transforms lead to '{self.tree.root_of(frame)}', not to the base frame "
                f"'{base}' (--base-frame)"
            )
        elif where:
            tf_part = f"no transform from '{base}' to it on {where}"
        else:
            tf_part = "the recording has no TF"
        if self.robot is None:
            robot_part = "and no --robot describing it"
        else:
            robot_part = f"and robot '{self.robot.name}' has no sensor named '{frame}'"
        return InputFileError(
            self.path,
            f"sensor frame '{frame}' ({self.frame_topic[frame]}): mounting pose unknown: "
            f"{tf_part}, {robot_part}",
        )

    def _sensors(self, base: str) -> tuple[RangeSensor, ...]:
        """RangeSensors for every Range / LaserScan frame, in a stable order."""
        out: dict[str, list[RangeSensor]] = {}
        for frame, sonar in self.sonars.items():
            mount = self._mount(base, frame) or self._unmounted(base, frame)
            fov, rmin, rmax = float32_decimal(
                [sonar.fov, sonar.min_range, sonar.max_range]
            ).tolist()
            out[frame] = [RangeSensor(frame, *mount, fov, rmin, rmax, "sonar")]
        for frame, scan in self.scans.items():
            out[frame] = self._beams(base, frame, scan)
        if self.clouds and self.robot is not None:
            for s in self._cloud_sonars():
                out[s.name] = [s]
                self.mount_from[s.name] = "robot"
        ranks = {frame: i for i, frame in enumerate(self.tree.order)}
        robot_rank = {n: i for i, n in enumerate(self.robot.names())} if self.robot else {}
        appearance = {name: i for i, name in enumerate(self.keys)}

        def rank(frame: str) -> tuple[int, int]:
            if frame in ranks:
                return 0, ranks[frame]
            for candidate in (frame, f"{frame}_0"):
                if candidate in robot_rank:
                    return 1, robot_rank[candidate]
            return 2, appearance.get(frame, appearance.get(f"{frame}_0", len(appearance)))

        return tuple(s for frame in sorted(out, key=rank) for s in out[frame])

    def _beams(self, base: str, frame: str, scan: _Scan) -> list[RangeSensor]:
        mount = self._mount(base, frame)
        names = [f"{frame}_{i}" for i in range(scan.count)]
        first, step, rmin, rmax = float32_decimal(
            [scan.angle_min, scan.angle_increment, scan.range_min, scan.range_max]
        ).tolist()
        known = self.robot.by_name() if self.robot is not None else {}
        if mount is None and all(n in known for n in names):
            self.mount_from[frame] = "robot"
            return [
                RangeSensor(n, known[n].x_m, known[n].y_m, known[n].yaw_rad, 0.0, rmin, rmax,
                            "laser")
                for n in names
            ]  # fmt: skip
        x, y, yaw = mount or self._unmounted(base, frame)
        yaws = wrap_angle(yaw + first + np.arange(len(names)) * step).tolist()
        return [
            RangeSensor(name, x, y, beam_yaw, 0.0, rmin, rmax, "laser")
            for name, beam_yaw in zip(names, yaws, strict=True)
        ]

    def _cloud_sonars(self) -> list[RangeSensor]:
        assert self.robot is not None
        return [s for s in self.robot.sensors if s.kind == "sonar"]

    def _cloud_readings(self, base: str, sensors: tuple[RangeSensor, ...]) -> None:
        """Ranges from RosAria point clouds: distance from each sonar's mount to its point."""
        topic = self.frame_topic[self.clouds[0][1]]
        if self.robot is None:
            self.refusals.refuse(
                InputFileError(
                    self.path,
                    f"{topic}: sonar point clouds (as RosAria publishes them) need the sonar "
                    "positions: give --robot (a preset, robot YAML or ARIA .p file)",
                )
            )
            return
        sonars = self._cloud_sonars()
        keys = [self._key(s.name) for s in sonars]
        sx = np.array([s.x_m for s in sonars])
        sy = np.array([s.y_m for s in sonars])
        for stamp, frame, points in self.clouds:
            if len(points) > len(sonars):
                raise InputFileError(
                    self.path,
                    f"{topic}: a cloud has {len(points)} points but robot '{self.robot.name}' "
                    f"has {len(sonars)} sonars",
                )
            px, py = points[:, 0], points[:, 1]
            transform = self.tree.lookup(base, frame) if frame != base else None
            if transform is not None:  # RosAria publishes in the robot frame; others may not
                tx, ty, tyaw = transform.planar()
                c, s = math.cos(tyaw), math.sin(tyaw)
                px, py = tx + c * px - s * py, ty + s * px + c * py
            n = len(points)
            self._extend(stamp, keys[:n], np.hypot(px - sx[:n], py - sy[:n]).tolist(), False)


def _tf_track(stamp_ns: npt.NDArray[np.int64], planar: npt.NDArray[np.float64]) -> PoseTrack:
    """A pose track from :meth:`TransformBuffer.track`'s stamps and (N, 3) planar poses."""
    return PoseTrack(
        stamp_ns=stamp_ns,
        x_m=np.ascontiguousarray(planar[:, 0]),
        y_m=np.ascontiguousarray(planar[:, 1]),
        theta_rad=np.ascontiguousarray(planar[:, 2]),
    )


def float32_decimal(values: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """float32 message fields as the shortest decimal (up to 9 places) each float32 stands for.

    ``sensor_msgs/Range`` and ``LaserScan`` carry float32: a range written as 1.234 arrives as
    1.2339999675750732. Reading it back as 1.234 keeps logs that went through ROS messages
    equal to the same run stored as CSV; both doubles round to the same float32.
    """
    v32 = np.atleast_1d(np.asarray(values, dtype=np.float32))
    exact = v32.astype(np.float64)
    out = exact.copy()
    todo = np.flatnonzero(np.isfinite(exact))
    for places in range(10):
        if len(todo) == 0:
            break
        candidate = np.round(exact[todo], places)
        ok = candidate.astype(np.float32) == v32[todo]
        out[todo[ok]] = candidate[ok]
        todo = todo[~ok]
    return out


def _f32(value: float) -> float:
    """One float32 field as its decimal, for error messages. Readings and sensor limits are
    converted together (:meth:`MessageAccumulator.finish`): converting each message's fields one by
    one through numpy took 2.6 s of a 3.6 s read of ``samples/corridor_loop_ros2.mcap``."""
    return float(float32_decimal(value)[0])


def _classify(value: float, max_range: float) -> float | None:
    """A sensor_msgs/Range value as gridmap stores it: None = no reading, inf = no echo.

    NaN is no reading, -inf "too close" (REP 117) and negative values are dropped; +inf and
    anything at or beyond ``max_range`` is no echo. Values below ``min_range`` are kept: the sync
    stage drops and counts them.
    """
    if math.isnan(value) or value < 0.0:
        return None
    if value >= max_range:
        return math.inf
    return value
