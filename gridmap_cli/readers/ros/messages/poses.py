"""Poses: ``nav_msgs/Odometry``, ``geometry_msgs/PoseStamped`` /
``PoseWithCovarianceStamped`` and ``gridmap.Pose2D`` messages into tracks, and the odometry
and reference tracks of the result (a pose topic, else a TF chain over time)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import InputFileError
from gridmap_cli.readers.ros.frames import frame_name, rotation_problem, yaw_of
from gridmap_cli.readers.ros.messages.fields import _quaternion
from gridmap_cli.readers.ros.messages.mounts import _Mounts
from gridmap_cli.readers.ros.messages.state import _Track
from gridmap_cli.records import PoseTrack


class _Poses(_Mounts):
    """Pose messages in; the odometry and reference tracks out."""

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
            q = _quaternion(pose.orientation)
            problem = rotation_problem(q)
            if problem is not None:
                raise InputFileError(
                    self.message_path, f"{self._where(topic, log_time)}: orientation {problem}"
                )
            theta = yaw_of(q)
            child = str(getattr(msg, "child_frame_id", ""))
        if not all(math.isfinite(v) for v in (x, y, theta)):
            raise InputFileError(
                self.message_path,
                f"{self._where(topic, log_time)}: pose is not finite ({x}, {y}, {theta})",
            )
        if child and track is self.odom:
            self.odom_children[frame_name(child)] += 1
        track.add(stamp, x, y, theta)

    def _odometry(self, base: str) -> PoseTrack:
        """The odometry track; refused when there is none (empty when read on, or when the
        recording has none and the plan can do without: :attr:`odometry_missing` says so)."""
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
            self._no_odometry(
                InputFileError(
                    self.path,
                    f"no odometry: no pose topic and no '{self.plan.odom_frame}' -> '{base}' "
                    f"transform on {', '.join(self.plan.tf_topics)} (transforms seen: "
                    f"{listing}); choose with --odom-frame / --base-frame",
                )
            )
        return PoseTrack.from_rows(np.empty(0, dtype=np.int64), [])

    def _no_odometry(self, error: InputFileError) -> None:
        if self.plan.odometry_optional:
            self.odometry_missing = f"missing: {self.plan.odometry_reason or error.detail}"
        else:
            self.refusals.refuse(error)

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


def _tf_track(stamp_ns: npt.NDArray[np.int64], planar: npt.NDArray[np.float64]) -> PoseTrack:
    """A pose track from :meth:`TransformBuffer.track`'s stamps and (N, 3) planar poses."""
    return PoseTrack(
        stamp_ns=stamp_ns,
        x_m=np.ascontiguousarray(planar[:, 0]),
        y_m=np.ascontiguousarray(planar[:, 1]),
        theta_rad=np.ascontiguousarray(planar[:, 2]),
    )
