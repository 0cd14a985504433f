"""TF: ``/tf`` and ``/tf_static`` messages into the frame tree and the moving series, the base
frame, and each sensor frame's mounting (from TF, else from ``--robot``, else refused with the
reason)."""

from __future__ import annotations

import math
from typing import Any

from gridmap_cli.errors import InputFileError, given, naming_style
from gridmap_cli.readers.ros.frames import (
    TransformBuffer,
    TransformSeries,
    frame_name,
    rotation_problem,
)
from gridmap_cli.readers.ros.messages.fields import _transform
from gridmap_cli.readers.ros.messages.state import _State

#: A laser's scan plane tilted further than this from the base frame's plane (its z axis nearer
#: level than upright or upside down) sees the floor or the ceiling, not the walls at its height.
MAX_LASER_TILT_RAD = math.radians(45.0)


class _Mounts(_State):
    """Transforms in; the base frame and sensor mountings out."""

    def _tf(self, topic: str, msg: Any, static: bool, log_time: int) -> None:
        for t in msg.transforms:
            parent, child = frame_name(t.header.frame_id), frame_name(t.child_frame_id)
            transform = _transform(t.transform)
            problem = rotation_problem(transform.rotation)
            if problem is None and not all(math.isfinite(v) for v in transform.translation):
                problem = f"translation {transform.translation} is not finite"
            if problem is not None:
                raise InputFileError(
                    self.message_path,
                    f"{self._where(topic, log_time)}: transform {parent} -> {child}: {problem}",
                )
            if static:
                self.tree.add(parent, child, transform)
                continue
            self.tf_pairs[(parent, child)] += 1
            series = self.tf_series.get((parent, child))
            if series is None:
                series = self.tf_series[(parent, child)] = TransformSeries()
            series.add(self._stamp(t.header.stamp, log_time), transform)

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

    def _laser_turn(self, base: str, frame: str) -> float:
        """How a TF-mounted laser's beam angles turn in the base frame: 1 as they are, -1
        mirrored for a laser TF mounts upside down (its left the robot's right, as the field
        mounts them under a deck); refused when TF tilts its scan plane past
        :data:`MAX_LASER_TILT_RAD`. 1 for a laser mounted otherwise."""
        transform = self.tree.lookup(base, frame)
        if transform is None or self.mount_from.get(frame) != "TF":
            return 1.0
        up = transform.up()
        if abs(up) < math.cos(MAX_LASER_TILT_RAD):
            tilt = math.degrees(math.acos(min(1.0, abs(up))))
            topic = self.frame_topic[frame]
            # a robot with a level laser beside this one (a backpack's vertical laser) maps
            # with the others: say which
            others = [t for t in self.plan.range_topics if t != topic]
            without = f"; map without it: --range-topic {' --range-topic '.join(others)}"
            self.refusals.refuse(
                InputFileError(
                    self.path,
                    f"laser '{frame}' ({topic}): TF tilts its scan plane {tilt:.0f} degrees "
                    f"from the plane of '{base}': gridmap maps lasers that scan level (upright "
                    f"or upside down){without if others else ''}",
                )
            )
        if up < 0.0:
            self.mount_from[frame] = "TF, upside down"
            return -1.0
        return 1.0

    def _beamless(self, base: str) -> list[str]:
        """The laser frames that neither TF nor a robot laser of their name or beam count
        mounts: those a mounting without beams (a robot file's, ``--laser-mount``) may take."""
        known = self.robot.by_name() if self.robot is not None else {}
        named = {m.name for m in self.robot.mounts} if self.robot is not None else set()
        return [
            f for f, sc in self.scans.items()
            if self.tree.lookup(base, f) is None and f not in named
            and not all(f"{f}_{i}" in known for i in range(sc.count))
        ]  # fmt: skip

    def _unmounted(self, base: str, frame: str) -> tuple[float, float, float]:
        """A frame with no known mounting: refused; a NaN mounting when read on."""
        self.refusals.refuse(self._unknown_mount(base, frame), mount=True)
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
        if frame in self.scans:
            return InputFileError(
                self.path,
                f"sensor frame '{frame}' ({self.frame_topic[frame]}): mounting pose unknown: "
                f"{tf_part}, {self._laser_hint(base, frame)}",
            )
        if self.robot is None:
            robot_part = "and no --robot describing it"
        else:
            robot_part = f"and robot '{self.robot.name}' has no sensor named '{frame}'"
        return InputFileError(
            self.path,
            f"sensor frame '{frame}' ({self.frame_topic[frame]}): mounting pose unknown: "
            f"{tf_part}, {robot_part}",
        )

    def _laser_hint(self, base: str, frame: str) -> str:
        """What the robot lacks for a laser frame, and the two ways to give its mounting (the
        scans give the rest)."""
        count = self.scans[frame].count
        fix = (
            f"give its pose on '{base}' with {_mount_given()}, or "
            f"{given('robot', 'FILE')} holding the two lines 'gridmap-robot: 1' and "
            f"'sensors: [{{name: {frame}, kind: laser, x_m: X, y_m: Y, yaw_deg: YAW_DEG}}]' "
            "(its beams and range come from the scans; docs/robot-format.md)"
        )
        unmounted = self._beamless(base)
        if self.laser_mount is not None and len(unmounted) > 1:
            return (
                f"and {given('laser_mount')} gives one laser's mounting while "
                f"{len(unmounted)} laser frames have none ({', '.join(unmounted)}): give each "
                f"by name in a robot file, "
                f"'{{name: {frame}, kind: laser, x_m: X, y_m: Y, yaw_deg: YAW_DEG}}'"
            )
        if self.robot is None:
            return f"and no {given('robot')} describing it: {fix}"
        lasers = self.robot.lasers()
        same = lasers.get(frame) or (next(iter(lasers.values())) if len(lasers) == 1 else None)
        if same is not None and len(same) != count:
            name = frame if frame in lasers else next(iter(lasers))
            return (
                f"and robot '{self.robot.name}' describes laser '{name}' with {len(same)} "
                f"beams where the scans on {self.frame_topic[frame]} have {count}: leave "
                "first_deg, last_deg and samples out of its entry and the scans give them"
            )
        part = f"and robot '{self.robot.name}' has no laser named '{frame}'"
        if lasers or self.robot.mounts:
            names = [*lasers, *(m.name for m in self.robot.mounts)]
            part += f" (its lasers: {', '.join(names)})"
        return f"{part}: {fix}"


def _mount_given() -> str:
    """How the caller gives a laser's mounting: the flag takes degrees, the Python read
    option radians."""
    if naming_style() == "flags":
        return "--laser-mount X,Y,YAW_DEG (metres, degrees)"
    return "ReadOptions(laser_mount=(X, Y, YAW_RAD)) (metres, radians)"
