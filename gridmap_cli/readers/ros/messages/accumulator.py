"""The :class:`MessageAccumulator`: each message to its family by topic and type, and
:meth:`MessageAccumulator.finish`, which puts the families' results into one RangeLog."""

from __future__ import annotations

from typing import Any

import numpy as np

from gridmap_cli.errors import InputFileError
from gridmap_cli.readers.ros.bulk import lexsort_order
from gridmap_cli.readers.ros.messages.fields import float32_decimal
from gridmap_cli.readers.ros.messages.poses import _Poses
from gridmap_cli.readers.ros.messages.ranges import FirstEchoes, _Ranges
from gridmap_cli.records import RangeLog, RangeReadings


class MessageAccumulator(_Poses, _Ranges):
    """Collects decoded messages; :meth:`finish` turns them into a RangeLog."""

    def add(self, source: str, topic: str, type_name: str, log_time: int, msg: Any) -> None:
        """Take one decoded message of ``topic`` from file ``source``."""
        self.message_path = source
        self.topic_types[topic] = type_name
        index = self.added[(source, topic)] = self.added.get((source, topic), 0) + 1
        try:
            self._dispatch(topic, type_name, log_time, msg)
        except InputFileError:
            raise
        except (AttributeError, KeyError, TypeError, ValueError, IndexError) as exc:
            # a schema that does not match its type decodes to messages without its fields
            what = (
                f"its schema does not match {type_name} ({exc})"
                if isinstance(exc, AttributeError)
                else f"malformed {type_name} message ({type(exc).__name__}: {exc})"
            )
            raise InputFileError(
                self.message_path,
                f"message {index} of {topic} ({type_name}, log time {log_time / 1e9:.9f} s): "
                f"{what}",
            ) from exc

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
        elif type_name == "sensor_msgs/MultiEchoLaserScan":
            self._scan(topic, log_time, FirstEchoes.of(msg))
        elif type_name == "sensor_msgs/PointCloud":
            self._cloud(topic, log_time, msg)
        elif type_name == "gridmap.RangeReading":
            self._json_reading(topic, log_time, msg)

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
        ).astype(np.intp, copy=False)
        sensor = remap[key]
        # float32 fields as their decimals, a chunk at once: one by one was most of the read time
        listed = np.asarray(self.r_range, dtype=np.float64)
        f32 = np.asarray(self.r_f32, dtype=bool)
        listed[f32] = float32_decimal(listed[f32])
        rng = np.concatenate(
            [listed, *(float32_decimal(c[2]) if c[3] else c[2] for c in self.r_chunks)],
            dtype=np.float64,
        )
        if sensors and len(rng):
            # no echo is stored at the sensor's maximum range, as in the CSV layout
            max_r = np.array([s.max_range_m for s in sensors], dtype=np.float64)
            rng = np.where(np.isinf(rng), max_r[sensor], rng)
        by_time = lexsort_order((sensor, stamp))  # by stamp, ties in sensor order
        if by_time is not None:
            stamp, sensor, rng = stamp[by_time], sensor[by_time], rng[by_time]
        readings = RangeReadings(stamp, sensor, rng)
        described = sensors or tuple(self.json_sensors.values())
        return RangeLog(
            source=self.path,
            poses=poses,
            readings=readings,
            sensor_names=tuple(names),
            sensors=tuple(described) or None,
            truth=truth,
            metadata=dict(metadata),
            odometry_missing=self.odometry_missing,
        )
