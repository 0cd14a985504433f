"""The log's time spans: its odometry and reference tracks (poses) and its range readings.

:func:`track_part` and :func:`readings_part` are the ``log.odometry`` / ``log.truth`` and
``log.readings`` parts of the description; :func:`track_lines` and :func:`readings_lines` their
text.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from gridmap_cli.describe.text import hz, number, pose_text
from gridmap_cli.poses.odometry_error import travelled
from gridmap_cli.poses.sync import interpolate_pose
from gridmap_cli.records import EPOCH_FROM_NS, PoseTrack, RangeLog, RangeReadings, span_text
from gridmap_cli.robot import RangeSensor


def rate_hz(count: int, span_ns: int) -> float | None:
    """The mean rate of ``count`` messages over ``span_ns``, or None when it has none."""
    return round((count - 1) / (span_ns / 1e9), 3) if count > 1 and span_ns > 0 else None


def during_odometry(log: RangeLog) -> npt.NDArray[np.bool_]:
    """Which readings (shape (N,)) fall within the odometry's time span, as sync decides it."""
    if not len(log.poses):
        return np.zeros(len(log.readings), dtype=bool)
    return interpolate_pose(log.poses, log.readings.stamp_ns)[3]


def track_part(track: PoseTrack) -> dict[str, Any] | None:
    """A pose track's count, span, rate, distance and rotation travelled, first and last pose."""
    n = len(track)
    if n == 0:
        return None
    t = track.stamp_ns
    span = int(t[-1] - t[0])
    distance, rotation = travelled(track)
    return {
        "count": n,
        "start_ns": int(t[0]),
        "end_ns": int(t[-1]),
        "duration_s": span / 1e9,
        "rate_hz": rate_hz(n, span),
        "distance_m": round(float(distance[-1]), 3),
        "rotation_deg": round(math.degrees(float(rotation[-1])), 1),
        "start_pose": [float(track.x_m[0]), float(track.y_m[0]), float(track.theta_rad[0])],
        "end_pose": [float(track.x_m[-1]), float(track.y_m[-1]), float(track.theta_rad[-1])],
    }


def readings_part(
    r: RangeReadings,
    valid: npt.NDArray[np.bool_],
    described: list[RangeSensor | None],
    no_echo: int,
) -> dict[str, Any] | None:
    """The readings' count, span and rate, and how many sync would keep.

    ``valid`` (shape (N,)): the readings within the odometry's span; ``described``: each sensor
    as the log or robot describes it (None: unknown); ``no_echo``: the sensors' no-echo total.
    """
    if not len(r):
        return None
    span = int(r.stamp_ns.max() - r.stamp_ns.min())
    inside = int(np.count_nonzero(valid))
    below_min: int | None = None  # as build's sync counts them; None: a sensor is unknown
    if all(s is not None for s in described):
        min_r = np.asarray([s.min_range_m for s in described if s is not None])
        below_min = int(np.count_nonzero(valid & (r.range_m < min_r[r.sensor])))
    return {
        "count": len(r),
        "start_ns": int(r.stamp_ns.min()),
        "end_ns": int(r.stamp_ns.max()),
        "duration_s": span / 1e9,
        "rate_hz": rate_hz(len(r), span),
        "no_echo": no_echo,
        "during_odometry": inside,
        "below_min_range": below_min,
    }


def _clock_note(first_ns: int, mcap: dict[str, Any] | None) -> str:
    """A note when message stamps and log times are on different clocks (simulation time)."""
    if mcap is None or mcap["log_time"] is None:
        return ""
    if (first_ns >= EPOCH_FROM_NS) == (mcap["log_time"]["start_ns"] >= EPOCH_FROM_NS):
        return ""
    return (
        "  (stamps are the messages' header stamps, on another clock than the log time, "
        "e.g. simulation time)"
    )


def track_lines(log: dict[str, Any], mcap: dict[str, Any] | None) -> list[str]:
    """The odometry and the reference track sections; ``mcap``: the recording's part or None."""
    lines: list[str] = []
    for key, title in (("odometry", "Odometry"), ("truth", "Ground truth / reference")):
        track = log[key]
        lines.append("")
        if track is None:
            lines.append(f"{title}: none")
            continue
        lines.append(
            f"{title}: {number(track['count'])} poses, "
            f"{span_text(track['start_ns'], track['end_ns'])}, {hz(track['rate_hz'])}"
        )
        clock = _clock_note(track["start_ns"], mcap)
        if clock:
            lines.append(clock)
        lines.append(
            f"  travelled {track['distance_m']:.2f} m and turned {track['rotation_deg']:.0f} deg, "
            f"from {pose_text(track['start_pose'])} to {pose_text(track['end_pose'])}"
        )
    return lines


def readings_lines(readings: dict[str, Any] | None) -> list[str]:
    """The range readings section."""
    lines = [""]
    if readings is None:
        lines.append("Range readings: none")
        return lines
    lines.append(
        f"Range readings: {number(readings['count'])} ({number(readings['no_echo'])} at maximum "
        "range: no echo), "
        f"{span_text(readings['start_ns'], readings['end_ns'])}, {hz(readings['rate_hz'])}"
    )
    during = f"  {number(readings['during_odometry'])} of them during the odometry's time span"
    below = readings.get("below_min_range")
    if below:
        mapped = readings["during_odometry"] - below
        during += (
            f", {number(below)} of these below their sensor's minimum range: "
            f"build maps {number(mapped)}"
        )
    lines.append(during)
    return lines
