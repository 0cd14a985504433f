"""The topics of a ROS recording (MCAP, ROS 1 bag, rosbag2) and which of them gridmap uses.

A :class:`Survey` lists a recording's topics with their message types and counts, whatever the
container; the plan picks the odometry, reference, TF and range topics by message type, or as
``--odom-topic`` / ``--range-topic`` / ``--pose-topic`` say; an ambiguous or missing choice is an
error that lists the topics with their types and message counts.
"""

from __future__ import annotations

from dataclasses import dataclass

from gridmap_cli.errors import GridmapError, InputFileError, UsageError
from gridmap_cli.readers.options import ReadOptions

#: Message types gridmap reads, by role (ROS 2 names with ``/msg/`` removed).
POSE_TYPES = ("nav_msgs/Odometry", "geometry_msgs/PoseStamped", "gridmap.Pose2D")
TF_TYPES = ("tf/tfMessage", "tf2_msgs/TFMessage")
RANGE_TYPES = (
    "sensor_msgs/Range",
    "sensor_msgs/LaserScan",
    "sensor_msgs/MultiEchoLaserScan",
    "sensor_msgs/PointCloud",
    "gridmap.RangeReading",
)
#: The range types that are a laser's scans.
LASER_TYPES = ("sensor_msgs/LaserScan", "sensor_msgs/MultiEchoLaserScan")
SENSOR_TYPES = ("gridmap.RangeSensor",)
#: Pose types that are a corrected (localised) pose, never odometry: AMCL's /amcl_pose.
REFERENCE_TYPES = ("geometry_msgs/PoseWithCovarianceStamped",)
#: Topic names holding TF that never changes.
STATIC_TF_TOPICS = ("/tf_static", "tf_static")


def qos_text(profiles: list[dict[str, object]]) -> str:
    """The QoS rosbag2 recorded for a topic, as ``ros2 bag info`` readers want it: reliability,
    durability and history depth of the first offered profile ('' when none was recorded)."""
    if not profiles or not isinstance(profiles[0], dict):
        return ""
    first = profiles[0]
    parts = [str(first[k]) for k in ("reliability", "durability") if first.get(k)]
    if first.get("depth") not in (None, ""):
        parts.append(f"depth {first['depth']}")
    more = f" (+{len(profiles) - 1} publishers)" if len(profiles) > 1 else ""
    return ", ".join(parts) + more


def fold_type(name: str) -> str:
    """A type name, ROS 2 style folded: ``nav_msgs/msg/Odometry`` -> ``nav_msgs/Odometry``."""
    return name.replace("/msg/", "/")


def is_truth_topic(topic: str) -> bool:
    """Pose topics named like ground truth are the reference track, not odometry."""
    return "ground_truth" in topic


@dataclass(frozen=True)
class ChannelInfo:
    """One channel of an MCAP file. ``count`` is the number of messages on it."""

    topic: str
    type_name: str
    schema_encoding: str
    message_encoding: str
    count: int
    qos: str = ""  # the recorded QoS, shortened ("reliable, transient_local, depth 1", "latched")

    @property
    def role(self) -> str:
        """What gridmap uses it for: odometry, truth, reference, tf, tf_static, range, sensors
        or ''."""
        if self.type_name in POSE_TYPES:
            return "truth" if is_truth_topic(self.topic) else "odometry"
        if self.type_name in REFERENCE_TYPES:
            return "reference"
        if self.type_name in TF_TYPES:
            return "tf_static" if self.topic in STATIC_TF_TOPICS else "tf"
        if self.type_name == "sensor_msgs/PointCloud":
            # PointCloud carries anything; RosAria's sonar topic is the one gridmap knows
            return "range" if "sonar" in self.topic else ""
        if self.type_name in RANGE_TYPES:
            return "range"
        if self.type_name in SENSOR_TYPES:
            return "sensors"
        return ""

    def describe(self) -> str:
        return f"{self.topic} ({self.type_name or 'no schema'}, {self.count} messages)"


@dataclass(frozen=True)
class Survey:
    """An MCAP file's header, channels and time span (log times, ns)."""

    path: str
    profile: str
    library: str
    channels: tuple[ChannelInfo, ...]
    start_ns: int | None
    end_ns: int | None
    message_count: int
    metadata: dict[str, dict[str, str]]
    indexed: bool
    storage: str = ""  # "mcap", "rosbag 2.0", "sqlite3"
    compression: str = ""  # "zstd", "lz4", "bz2", "none", or a mix ("none, lz4")
    files: tuple[tuple[str, int], ...] = ()  # (file, bytes) of each file read

    def topic(self, name: str) -> ChannelInfo | None:
        """The channel of topic ``name``; a name without its leading ``/`` (``sonar``) is the
        root namespace's topic (``/sonar``), as ROS resolves it, when no topic is spelled so."""
        for channel in self.channels:
            if channel.topic == name:
                return channel
        for channel in self.channels:
            if channel.topic.lstrip("/") == name.lstrip("/"):
                return channel
        return None

    def listing(self) -> str:
        """All topics with their types and counts, for error messages."""
        if not self.channels:
            return "the file has no channels"
        return "topics: " + "; ".join(c.describe() for c in self.channels)


class Refusals:
    """Errors that stop a build: a strict read (``build``) raises the first one at once; a lenient
    read (``inspect``) keeps them all in :attr:`errors` and reads on to show what the file
    holds (and every problem build would meet, not only the first)."""

    def __init__(self, strict: bool = True) -> None:
        self.strict = strict
        self.errors: list[GridmapError] = []
        self.mounts_only = True  # every error kept is a sensor's unknown mounting

    @property
    def first(self) -> GridmapError | None:
        return self.errors[0] if self.errors else None

    def refuse(self, error: GridmapError, mount: bool = False) -> None:
        """``mount``: the error is a sensor's unknown mounting, which leaves the rest of the
        log as build reads it (its later checks still say something new)."""
        if self.strict:
            raise error
        if any(_subject(error) == _subject(e) for e in self.errors):
            return  # the same thing missing, seen again at a later stage of the read
        self.errors.append(error)
        self.mounts_only = self.mounts_only and mount


def _subject(error: GridmapError) -> str:
    """What an error is about: its detail up to the first colon ("no odometry")."""
    detail = error.detail if isinstance(error, InputFileError) else str(error)
    return detail.partition(":")[0]


@dataclass(frozen=True)
class Plan:
    """The topics a read uses.

    ``odom_topic`` is a pose topic, or None when odometry comes from TF (``tf_topics``,
    ``odom_frame`` -> base frame). ``static_topics`` hold the sensor mounting (and ``/tf`` pairs
    that never change, as ROS 1 recordings publish fixed joints). The reference track is
    ``truth_topic`` (``--pose-topic``, or a topic named ground_truth), else the TF chain from
    ``map_frame`` to the base, else ``reference_topic`` (the one PoseWithCovarianceStamped).
    """

    odom_topic: str | None
    truth_topic: str | None
    range_topics: tuple[str, ...]
    tf_topics: tuple[str, ...]
    static_topics: tuple[str, ...]
    sensors_topic: str | None
    odom_frame: str
    base_frame: str | None
    reference_topic: str | None = None
    map_frame: str = "map"
    #: a recording without odometry is read (its track empty) rather than refused
    odometry_optional: bool = False
    #: why the recording has no odometry, when the plan found none (for a caller that can do
    #: without: the scans make the motion)
    odometry_reason: str | None = None

    def topics(self) -> list[str]:
        """Every topic the read decodes: /tf unless a pose topic gives both the odometry and
        the reference and /tf_static the mounting."""
        out = [t for t in (self.odom_topic, self.truth_topic, self.sensors_topic) if t]
        out += [*self.range_topics, *self.static_topics]
        if self.reference_topic:
            out.append(self.reference_topic)
        if self.odom_topic is None or not self.static_topics or self.truth_topic is None:
            out += self.tf_topics
        return list(dict.fromkeys(out))


def plan_topics(survey: Survey, options: ReadOptions, refusals: Refusals | None = None) -> Plan:
    """Choose the topics to read. Raises InputFileError / UsageError listing the topics.

    No odometry or no range topic goes to ``refusals`` (default: strict, raise), so that a
    lenient read (``inspect``) plans a file that has none.
    """
    refuse = (refusals or Refusals()).refuse
    path = survey.path
    by_role: dict[str, list[ChannelInfo]] = {}
    for channel in survey.channels:
        if channel.count > 0:
            by_role.setdefault(channel.role, []).append(channel)
    tf_topics = tuple(c.topic for c in by_role.get("tf", []))
    static_topics = tuple(c.topic for c in by_role.get("tf_static", []))
    # the scans can make the motion where there is no odometry, for a caller that asks; a
    # recording without laser scans still needs its odometry
    scans = any(c.type_name in LASER_TYPES for c in survey.channels if c.count > 0)
    odometry_optional = options.odometry_optional and scans

    odom_topic: str | None
    no_odometry: str | None = None
    if options.odom_topic is not None:
        chosen = survey.topic(options.odom_topic)
        if chosen is None:
            raise UsageError(
                f"{path}: --odom-topic {options.odom_topic}: no such topic; {survey.listing()}"
            )
        if chosen.type_name in TF_TYPES:
            odom_topic = None
            tf_topics = (chosen.topic,)
        elif chosen.type_name in POSE_TYPES:
            odom_topic = chosen.topic
        else:
            raise UsageError(
                f"{path}: --odom-topic {chosen.topic} is {chosen.type_name or 'untyped'}, not a "
                f"pose type ({', '.join(POSE_TYPES)}) or TF"
            )
    else:
        candidates = by_role.get("odometry", [])
        if len(candidates) > 1:
            raise InputFileError(
                path,
                "more than one odometry topic: "
                + "; ".join(c.describe() for c in candidates)
                + "; choose one with --odom-topic",
            )
        odom_topic = candidates[0].topic if candidates else None
        if not candidates and not tf_topics:
            no_odometry = (
                "no odometry: no nav_msgs/Odometry, geometry_msgs/PoseStamped or "
                f"gridmap.Pose2D topic and no TF; {survey.listing()}"
            )
            if not odometry_optional:
                refuse(InputFileError(path, no_odometry))
    truths = [c.topic for c in by_role.get("truth", []) if c.topic != odom_topic]
    truth_topic = truths[0] if len(truths) == 1 else None
    references = [c.topic for c in by_role.get("reference", [])]
    reference_topic = references[0] if len(references) == 1 else None
    if options.pose_topic is not None:
        chosen = survey.topic(options.pose_topic)
        if chosen is None:
            raise UsageError(
                f"{path}: --pose-topic {options.pose_topic}: no such topic; {survey.listing()}"
            )
        if chosen.type_name not in POSE_TYPES + REFERENCE_TYPES:
            raise UsageError(
                f"{path}: --pose-topic {chosen.topic} is {chosen.type_name or 'untyped'}, not a "
                f"pose type ({', '.join(POSE_TYPES + REFERENCE_TYPES)})"
            )
        if chosen.topic == odom_topic:
            raise UsageError(
                f"{path}: --pose-topic {chosen.topic} is the odometry; the reference track must "
                "come from another topic"
            )
        truth_topic, reference_topic = chosen.topic, None

    if options.range_topics:
        ranges = []
        for name in options.range_topics:
            chosen = survey.topic(name)
            if chosen is None:
                raise UsageError(f"{path}: --range-topic {name}: no such topic; {survey.listing()}")
            if chosen.type_name not in RANGE_TYPES:
                raise UsageError(
                    f"{path}: --range-topic {name} is {chosen.type_name or 'untyped'}, not a "
                    f"range type ({', '.join(RANGE_TYPES)})"
                )
            ranges.append(chosen.topic)
        range_topics = tuple(dict.fromkeys(ranges))
    else:
        range_topics = tuple(c.topic for c in by_role.get("range", []))
        if not range_topics and not options.poses_only:
            refuse(
                InputFileError(
                    path,
                    "no range readings: no sensor_msgs/Range, LaserScan, MultiEchoLaserScan, "
                    "PointCloud (sonar) or "
                    f"gridmap.RangeReading topic; {survey.listing()}",
                )
            )
    sensors = by_role.get("sensors", [])
    return Plan(
        odom_topic=odom_topic,
        truth_topic=truth_topic,
        range_topics=range_topics,
        tf_topics=tf_topics,
        static_topics=static_topics,
        sensors_topic=sensors[0].topic if sensors else None,
        odom_frame=options.odom_frame or "odom",
        base_frame=options.base_frame,
        reference_topic=reference_topic,
        map_frame=options.map_frame or "map",
        odometry_optional=odometry_optional,
        odometry_reason=no_odometry,
    )
