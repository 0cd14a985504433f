"""The canonical record stream every reader produces and every later stage consumes.

Columnar (numpy arrays, one entry per record) because a one-hour log holds hundreds of thousands
of readings and every later stage works on them in vectorised batches. Stamps are integer
nanoseconds; everything else is SI (metres, radians). Arrays are time-ordered.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import InputFileError
from gridmap_cli.robot import RangeSensor

#: Where each reader finds a log's ground truth, for the error when a log has none.
TRUTH_SOURCES = (
    "CSV true_x, true_y, true_theta columns, ARIA robotGlobal: lines in every block, a CARMEN "
    "log's TRUEPOS lines or corrected poses, or a ROS recording's reference: --pose-topic, a "
    "ground_truth topic, TF map -> base or /amcl_pose"
)


@dataclass(frozen=True)
class PoseTrack:
    """A time series of planar poses, shape (N,) each.

    ``stamp_ns`` is strictly increasing; ``x_m``, ``y_m`` in metres and ``theta_rad`` in radians
    give the pose of the robot base in the track's frame (odometry frame for odometry, world frame
    for ground truth).
    """

    stamp_ns: npt.NDArray[np.int64]
    x_m: npt.NDArray[np.float64]
    y_m: npt.NDArray[np.float64]
    theta_rad: npt.NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.stamp_ns.shape[0])

    @classmethod
    def from_rows(
        cls, stamp_ns: npt.NDArray[np.int64], rows: Sequence[tuple[float, float, float]]
    ) -> PoseTrack:
        """A track from (x_m, y_m, theta_rad) rows, one per stamp."""
        arr = np.asarray(rows, dtype=np.float64).reshape(len(rows), 3)
        return cls(
            stamp_ns=stamp_ns,
            x_m=np.ascontiguousarray(arr[:, 0]),
            y_m=np.ascontiguousarray(arr[:, 1]),
            theta_rad=np.ascontiguousarray(arr[:, 2]),
        )


@dataclass(frozen=True)
class RangeReadings:
    """Range readings, shape (M,) each, ordered by stamp (ties in sensor order).

    ``sensor`` indexes :attr:`RangeLog.sensor_names`. ``range_m`` is positive and never NaN; a
    range at or beyond the sensor's maximum, ``+inf`` included (a CSV's ``inf``, REP 117's "no
    detection"), means "no echo": sync caps it at the maximum, writers with sensor geometry write
    the maximum. Absent readings (empty or NaN in a log) are not records at all.
    """

    stamp_ns: npt.NDArray[np.int64]
    sensor: npt.NDArray[np.int32]
    range_m: npt.NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.stamp_ns.shape[0])


@dataclass(frozen=True)
class RangeLog:
    """Everything a reader learned from one log file.

    ``sensors`` holds the mounting geometry of those sensors the log itself describes (any
    subset of ``sensor_names``, matched by name); the robot description supplies the rest.
    ``truth`` is a ground-truth (or reference) track in the world frame, when the log has one;
    ``build`` ignores it. ``metadata`` holds the log's own key/value header.
    ``names_are_columns``: the sensor names are free-form table columns (CSV), so a name that
    neither the log nor the robot describes may be some other measurement (a battery voltage):
    :func:`gridmap_cli.selection.ignore_other_columns` leaves it out with a note. Elsewhere a
    sensor is a sensor, and one without mounting geometry is an error.
    """

    source: str
    poses: PoseTrack
    readings: RangeReadings
    sensor_names: tuple[str, ...]
    sensors: tuple[RangeSensor, ...] | None = None
    truth: PoseTrack | None = None
    metadata: dict[str, str] = field(default_factory=dict)
    names_are_columns: bool = False

    def require_truth(self, purpose: str) -> PoseTrack:
        """The ground-truth track; :class:`InputFileError` naming the log if it has none.

        ``purpose`` ends the message, saying what needed the truth ("evaluate needs the true
        path"): ``<source>: the log has no ground truth (<where readers find it>); <purpose>``.
        """
        if self.truth is None:
            raise InputFileError(
                self.source, f"the log has no ground truth ({TRUTH_SOURCES}); {purpose}"
            )
        return self.truth


#: Stamps at or after this (2001-09-09) are taken as Unix epoch times when shown to people;
#: smaller ones are seconds since some start (simulation time, a log's own clock).
EPOCH_FROM_NS = 1_000_000_000 * 1_000_000_000


def stamp_text(stamp_ns: int) -> str:
    """A stamp for people: UTC date and time for epoch stamps, else seconds."""
    if stamp_ns >= EPOCH_FROM_NS:
        when = datetime.fromtimestamp(stamp_ns // 1_000_000_000, tz=UTC)
        frac = (stamp_ns % 1_000_000_000) // 1_000_000
        return f"{when:%Y-%m-%d %H:%M:%S}.{frac:03d} UTC"
    return f"{stamp_ns / 1e9:.3f} s"


def span_text(first_ns: int, last_ns: int) -> str:
    """A time span for people: ``start to end (duration)``."""
    end = stamp_text(last_ns)
    start = stamp_text(first_ns)
    if start[:10] == end[:10] and first_ns >= EPOCH_FROM_NS:
        end = end[11:]  # same day: the date once
    return f"{start} to {end} ({(last_ns - first_ns) / 1e9:.1f} s)"
