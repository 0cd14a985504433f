"""What the accumulator holds between messages: pose tracks as they arrive, the geometry of
each range frame, the transforms, the readings in arrival order; and the two helpers every
message family uses (a message's stamp, where it is for an error)."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from gridmap_cli.readers.ros.frames import FrameTree, TransformBuffer, TransformSeries
from gridmap_cli.readers.ros.messages.fields import _stamp_ns
from gridmap_cli.readers.ros.topics import Plan, Refusals
from gridmap_cli.records import PoseTrack
from gridmap_cli.robot import BeamBook, RangeSensor, RobotDescription


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
    """One laser frame: the geometry and range limits of its first scan (the messages' float32
    values; each scan's own ``range_max`` decides its no-echo beams), and the beam sensors its
    scans used (``book``; ``keys``: each beam sensor's reading key)."""

    angle_min: float
    angle_increment: float
    count: int
    range_min: float
    range_max: float
    book: BeamBook = field(init=False)
    keys: npt.NDArray[np.int64] = field(init=False)

    def __post_init__(self) -> None:
        self.book = BeamBook(self.angle_min, self.angle_increment, self.count)
        self.keys = np.zeros(0, dtype=np.int64)


def scan_angles_disagree(
    angle_min: npt.NDArray[np.float64],
    angle_max: npt.NDArray[np.float64],
    increment: npt.NDArray[np.float64],
    count: npt.NDArray[np.int64],
) -> npt.NDArray[np.bool_]:
    """Per scan, whether its ranges' number disagrees with its own angles: ``angle_max`` must
    lie at the last beam (``angle_min + (count - 1) * angle_increment``) or one step beyond
    (drivers differ on whether it is the last beam or the end of the sweep), within half a
    step; angles must be finite. A scan of one beam needs only a finite ``angle_min``, an empty
    one nothing."""
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        steps = (angle_max - angle_min) / increment
        fits = (steps >= count - 1.5) & (steps <= count + 0.5)
    finite = np.isfinite(angle_min)
    return (count >= 1) & (~finite | ((count >= 2) & ~fits))


@dataclass
class _Sonar:
    """One sensor_msgs/Range frame: its first field of view, and the largest ``min_range`` and
    largest ``max_range`` of its messages (the messages' float32 values)."""

    fov: float
    min_range: float
    max_range: float


class _State:
    """The accumulator's fields, shared by the message families (:mod:`.mounts`, :mod:`.poses`,
    :mod:`.ranges`) that :class:`~.accumulator.MessageAccumulator` combines."""

    def __init__(
        self, path: str, plan: Plan, robot: RobotDescription | None, refusals: Refusals
    ) -> None:
        self.path = path  # the recording (files joined when several): for errors of the whole
        self.message_path = path  # the file of the message being added: for errors of one
        self.added: dict[tuple[str, str], int] = {}  # messages added by (file, topic): names one
        self.refusals = refusals
        self.plan = plan
        self.robot = robot
        self.laser_mount: tuple[float, float, float] | None = None  # --laser-mount X, Y, yaw
        self.odom = _Track()
        self.truth = _Track()
        self.reference = _Track()
        self.tf_series: dict[tuple[str, str], TransformSeries] = {}  # (parent, child) on /tf
        self.tf_pairs: Counter[tuple[str, str]] = Counter()
        self.tree = FrameTree()  # /tf_static, then (by finish) the /tf pairs that never change
        self._buffer: TransformBuffer | None = None
        self.truth_from: str | None = None  # where the reference track came from
        self.odometry_missing: str | None = None  # why the odometry track is empty (RangeLog)
        self.mount_from: dict[str, str] = {}  # frame -> "TF", "robot" (", upside down"), "unknown"
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
            tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.floating], bool]
        ] = []
        self.range_topics = set(plan.range_topics)
        self.topic_types: dict[str, str] = {}

    def _where(self, topic: str, log_time: int) -> str:
        return f"{topic} at log time {log_time / 1e9:.9f} s"

    def _stamp(self, header_stamp: Any, log_time: int) -> int:
        stamp = _stamp_ns(header_stamp)
        return stamp if stamp != 0 else log_time
