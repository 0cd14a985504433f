"""Range readings: ``sensor_msgs/Range`` (sonar), ``sensor_msgs/LaserScan`` (one sensor per
beam; ``MultiEchoLaserScan`` read as the scan of its first echoes), RosAria's sonar
``sensor_msgs/PointCloud`` and ``gridmap.RangeReading`` /
``gridmap.RangeSensor``, into readings by sensor key; and the RangeSensors of the result, in a
stable order."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import InputFileError
from gridmap_cli.geometry import wrap_angle
from gridmap_cli.limits import MAX_LASER_SAMPLES, too_many_beams
from gridmap_cli.readers.ros.frames import frame_name
from gridmap_cli.readers.ros.messages.fields import (
    _classify,
    _f32,
    float32_decimal,
    scan_limits_problem,
)
from gridmap_cli.readers.ros.messages.mounts import _Mounts
from gridmap_cli.readers.ros.messages.state import _Scan, _Sonar, scan_angles_disagree
from gridmap_cli.robot import RangeSensor, SensorMount


@dataclass(frozen=True)
class FirstEchoes:
    """A ``sensor_msgs/MultiEchoLaserScan`` as the ``LaserScan`` of each beam's first echo: the
    nearest return, as Cartographer reads such scans (a later echo is what the beam met behind
    something it partly passed: glass, a fence, rain). A beam without an echo is NaN, no
    reading, as a ``LaserScan`` beam of NaN."""

    header: Any
    angle_min: float
    angle_max: float
    angle_increment: float
    range_min: float
    range_max: float
    ranges: npt.NDArray[np.float64]

    @classmethod
    def of(cls, msg: Any) -> FirstEchoes:
        first = [e.echoes[0] if len(e.echoes) else math.nan for e in msg.ranges]
        return cls(
            msg.header, msg.angle_min, msg.angle_max, msg.angle_increment, msg.range_min,
            msg.range_max, np.asarray(first, dtype=np.float64),
        )  # fmt: skip


class _Ranges(_Mounts):
    """Range messages in; readings and RangeSensors out."""

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
        amin, ainc, count = float(msg.angle_min), float(msg.angle_increment), len(ranges)
        if count > MAX_LASER_SAMPLES:
            where = f"{self._where(topic, log_time)}: laser '{frame}': "
            raise too_many_beams(self.message_path, count, where=where)
        problem = scan_limits_problem(frame, float(msg.range_min), float(msg.range_max))
        if problem is not None:
            raise InputFileError(self.message_path, f"{self._where(topic, log_time)}: {problem}")
        if scan_angles_disagree(
            np.array([amin]), np.array([float(msg.angle_max)]), np.array([ainc]), np.array([count])
        )[0]:
            raise scan_angles_error(
                self.message_path, self._where(topic, log_time), frame, count, amin,
                float(msg.angle_max), ainc,
            )  # fmt: skip
        known = self.scans.get(frame)
        if known is None:
            known = self.scans[frame] = _Scan(amin, ainc, count, msg.range_min, msg.range_max)
        beams = self._beam_keys(frame, known, known.book.sensors(amin, ainc, count))
        with np.errstate(invalid="ignore"):
            valid = ~np.isnan(ranges) & (ranges > 0.0)  # NaN and 0.0: no reading; -inf: too close
            no_echo = valid & (ranges >= msg.range_max)
        out = np.where(no_echo, np.inf, ranges)[valid]
        keys = beams[valid]
        self._extend(self._stamp(msg.header.stamp, log_time), keys.tolist(), out.tolist(), True)

    def _beam_keys(
        self, frame: str, known: _Scan, sensors: npt.NDArray[np.int64]
    ) -> npt.NDArray[np.int64]:
        """The reading key of each of a scan's beams (``sensors``: their beam sensors), giving
        the beam sensors the scan added keys ``<frame>_<i>`` in order."""
        if len(known.keys) < len(known.book):
            new = [self._key(f"{frame}_{i}") for i in range(len(known.keys), len(known.book))]
            known.keys = np.concatenate((known.keys, np.asarray(new, dtype=np.int64)))
        return known.keys[sensors]

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
        """The beam sensors of a laser frame: the first scan's beams, then those of the
        directions later scans added (:class:`~gridmap_cli.robot.BeamBook`)."""
        mount = self._mount(base, frame)
        book = scan.book
        names = [f"{frame}_{i}" for i in range(len(book))]
        rmin, rmax = float32_decimal([scan.range_min, scan.range_max]).tolist()
        starts = float32_decimal(book.start)
        steps = float32_decimal(book.step)
        known = self.robot.by_name() if self.robot is not None else {}
        first = names[: scan.count]
        robot_names = first
        if mount is None and not all(n in known for n in first):
            robot_names = self._sole_robot_laser(base, scan) or first
        if mount is None and all(n in known for n in robot_names):
            self.mount_from[frame] = "robot"
            beams = [
                RangeSensor(n, known[r].x_m, known[r].y_m, known[r].yaw_rad, 0.0, rmin, rmax,
                            "laser")
                for n, r in zip(first, robot_names, strict=True)
            ]  # fmt: skip
            if len(names) > scan.count:
                # the directions later scans added, about the robot laser's axis
                zero = known[robot_names[0]]
                axis = zero.yaw_rad - float(starts[0])
                more = slice(scan.count, None)
                yaws = wrap_angle(axis + starts[more] + book.local[more] * steps[more]).tolist()
                beams += [
                    RangeSensor(n, zero.x_m, zero.y_m, beam_yaw, 0.0, rmin, rmax, "laser")
                    for n, beam_yaw in zip(names[scan.count :], yaws, strict=True)
                ]
            return beams
        given = None if mount is not None else self._given_mount(base, frame)
        if given is not None:
            mount = given.x_m, given.y_m, given.yaw_rad
        x, y, yaw = mount or self._unmounted(base, frame)
        turn = -1.0 if given is not None and given.upside_down else self._laser_turn(base, frame)
        from_tf = self.mount_from.get(frame, "").startswith("TF")
        if from_tf and self.laser_mount is not None and len(self.scans) == 1:
            # --laser-mount for the recording's one laser wins over its TF: a recorded TF is
            # not the user's to mend, and the odometry may say it is wrong (poses.laser_mount);
            # TF still says which way up the laser is (and refuses one tilted past level)
            x, y, yaw = self.laser_mount
            self.mount_from[frame] = "--laser-mount over TF" + (", upside down" if turn < 0 else "")
        yaws = wrap_angle(yaw + turn * (starts + book.local * steps)).tolist()
        return [
            RangeSensor(name, x, y, beam_yaw, 0.0, rmin, rmax, "laser")
            for name, beam_yaw in zip(names, yaws, strict=True)
        ]

    def _given_mount(self, base: str, frame: str) -> SensorMount | None:
        """A laser's mounting without beams: the robot's of the frame's name; else, for the
        recording's only laser left without one, ``--laser-mount`` or the robot's only such
        mounting (named after no frame of the recording)."""
        mounts = {m.name: m for m in self.robot.mounts} if self.robot is not None else {}
        mount = mounts.get(frame)
        if mount is None:
            if self._beamless(base) != [frame]:
                return None
            if self.laser_mount is not None:
                self.mount_from[frame] = "--laser-mount"
                return SensorMount(frame, *self.laser_mount)
            spare = [m for name, m in mounts.items() if name not in self.scans]
            if len(spare) != 1 or (self.robot is not None and self.robot.lasers()):
                return None
            mount = spare[0]
        self.mount_from[frame] = "robot, upside down" if mount.upside_down else "robot"
        return mount

    def _sole_robot_laser(self, base: str, scan: _Scan) -> list[str] | None:
        """The beam names of the robot's laser when the pairing is unambiguous: the robot
        describes one laser, with ``scan``'s beam count, and one laser frame of the recording
        has no mounting of its own (a Pioneer's ``/scan`` in frame ``laser`` and a robot file
        that calls its SICK ``laser1``). None otherwise (the frame is then refused)."""
        if self.robot is None:
            return None
        lasers = self.robot.lasers()
        unmounted = [
            f for f, sc in self.scans.items()
            if self.tree.lookup(base, f) is None
            and not all(f"{f}_{i}" in self.robot.by_name() for i in range(sc.count))
        ]  # fmt: skip
        if len(lasers) != 1 or len(unmounted) != 1:
            return None
        beams = next(iter(lasers.values()))
        return beams if len(beams) == scan.count else None

    def _cloud_sonars(self) -> list[RangeSensor]:
        assert self.robot is not None
        return [s for s in self.robot.sensors if s.kind == "sonar"]

    def _cloud_readings(self, base: str, sensors: tuple[RangeSensor, ...]) -> None:
        """Ranges from RosAria point clouds: distance from each sonar's mount to its point."""
        topic = self.frame_topic[self.clouds[0][1]]
        if self.robot is None:
            lasers = sorted({self.frame_topic[f] for f in self.scans})
            alone = (
                f", or --range-topic {' --range-topic '.join(lasers)} to map the laser alone"
                if lasers
                else ""
            )
            self.refusals.refuse(
                InputFileError(
                    self.path,
                    f"{topic}: sonar point clouds (as RosAria publishes them) need the sonar "
                    f"positions: give --robot (a preset, robot YAML or ARIA .p file){alone}",
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
                if transform.up() < 0.0:  # a frame upside down: its y axis is the base's -y
                    py = -py
                c, s = math.cos(tyaw), math.sin(tyaw)
                px, py = tx + c * px - s * py, ty + s * px + c * py
            n = len(points)
            self._extend(stamp, keys[:n], np.hypot(px - sx[:n], py - sy[:n]).tolist(), False)


def scan_angles_error(
    path: str, where: str, frame: str, count: int, amin: float, amax: float, inc: float
) -> InputFileError:
    """A LaserScan whose number of ranges disagrees with its own angles
    (:func:`~.state.scan_angles_disagree`)."""
    return InputFileError(
        path,
        f"{where}: laser '{frame}': {count} ranges, but its angles do not fit them (from "
        f"{_f32(amin):g} to {_f32(amax):g} rad by {_f32(inc):g}: angle_max must be angle_min + "
        "(ranges - 1) x angle_increment)",
    )
