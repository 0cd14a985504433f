"""What a reader may be told besides the path: topic and frame choices, and the robot.

One object for every reader so that the registry can call them alike; readers of formats with no
topics or frames (CSV, ARIA) refuse the MCAP-only choices instead of ignoring them silently.
"""

from __future__ import annotations

from dataclasses import dataclass

from gridmap_cli.errors import UsageError
from gridmap_cli.robot import RobotDescription


@dataclass(frozen=True)
class ReadOptions:
    """Choices for reading a log.

    ``odom_topic``: the pose topic to use as odometry (``/tf`` for the odom -> base transforms).
    ``range_topics``: the range topics to map (empty: every supported one).
    ``odom_frame``, ``base_frame``: TF frame names (default ``odom``, and the odometry message's
    child frame or the lowest frame TF moves below the odometry frame, else ``base_link``).
    ``pose_topic``: the reference (corrected) pose topic for ``--pose global``; ``map_frame``:
    the frame of the reference track in TF (default ``map``). ``robot``: the robot description
    (``--robot``), for sensor mounting the log does not carry (and the sonar positions RosAria's
    point clouds need). ``stream``: a long log's readings may be left unheld and read again
    from the file at each pass (:attr:`gridmap_cli.records.RangeLog.stream`): for a caller that
    goes through them by :meth:`~gridmap_cli.records.RangeLog.reading_chunks` and cuts no time
    window. CSV files do it above :data:`gridmap_cli.readers.text.csv_stream.STREAM_FROM_BYTES`.
    ``laser_mount``: ``--laser-mount``, the mounting (x_m, y_m, yaw_rad) of the recording's
    only laser that TF and the robot leave without one, or of its one laser over TF's; its
    beams come from its scans.
    ``poses_only``: the caller wants the tracks alone (``gridmap trajectory --pose odometry`` or
    ``global``), so a recording without range topics is read rather than refused.
    ``odometry_optional``: the caller can make the motion from the laser scans (``--pose
    scan-matched`` or ``slam``), so a recording without odometry is read rather than refused:
    its pose track is empty and :attr:`~gridmap_cli.records.RangeLog.odometry_missing` says why.
    """

    odom_topic: str | None = None
    range_topics: tuple[str, ...] = ()
    odom_frame: str | None = None
    base_frame: str | None = None
    pose_topic: str | None = None
    map_frame: str | None = None
    laser_mount: tuple[float, float, float] | None = None
    robot: RobotDescription | None = None
    stream: bool = False
    poses_only: bool = False
    odometry_optional: bool = False

    def topic_flags(self) -> list[str]:
        """The MCAP-only flags that were given, spelled as on the command line."""
        given = []
        if self.odom_topic is not None:
            given.append("--odom-topic")
        if self.range_topics:
            given.append("--range-topic")
        if self.odom_frame is not None:
            given.append("--odom-frame")
        if self.base_frame is not None:
            given.append("--base-frame")
        if self.pose_topic is not None:
            given.append("--pose-topic")
        if self.map_frame is not None:
            given.append("--map-frame")
        if self.laser_mount is not None:
            given.append("--laser-mount")
        return given

    def refuse_topic_flags(self, format_name: str) -> None:
        """Raise :class:`UsageError` if topic or frame flags were given for a non-ROS log."""
        given = self.topic_flags()
        if given:
            raise UsageError(
                f"{', '.join(given)} only appl{'y' if len(given) > 1 else 'ies'} to ROS recordings "
                f"(MCAP, bag, rosbag2), "
                f"not to {format_name} logs"
            )
