"""Pose sync: give every range reading the pose of the sensor that took it.

The robot pose at a reading's stamp is interpolated between the two odometry stamps around it
(linear in x and y, along the shorter arc in theta) and composed with the sensor's mounting pose.
Readings outside the odometry's time span or below the sensor's minimum range are counted and
dropped, never silently mapped. A sensor that neither the log nor the robot describes is an error
here: a CSV column that is no range sensor (a battery voltage) is left out before sync, with a
note for the user (:func:`gridmap_cli.mapping.selection.ignore_other_columns`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import GridmapError, given
from gridmap_cli.geometry import compose, wrap_angle
from gridmap_cli.poses.odometry_error import travelled_at
from gridmap_cli.records import PoseTrack, RangeLog, RangeReadings
from gridmap_cli.robot import RangeSensor, RobotDescription


@dataclass(frozen=True)
class SensorReadings:
    """Readings with the pose of their sensor in the odometry frame, shape (M,) each.

    ``x_m``, ``y_m``, ``theta_rad``: sensor position and beam axis direction (odometry frame).
    ``range_m``: the measured range, capped at the sensor's maximum (== maximum: no echo).
    ``sensor``: index into ``sensors``.
    ``distance_m``, ``rotation_rad``: how far the pose track had driven and how much it had turned
    (sum of absolute heading changes) from its start to each reading: what the odometry error
    grows with. None when not computed (hand-made batches in tests); models that need them say so.
    """

    stamp_ns: npt.NDArray[np.int64]
    sensor: npt.NDArray[np.int32]
    range_m: npt.NDArray[np.float64]
    x_m: npt.NDArray[np.float64]
    y_m: npt.NDArray[np.float64]
    theta_rad: npt.NDArray[np.float64]
    sensors: tuple[RangeSensor, ...]
    distance_m: npt.NDArray[np.float64] | None = None
    rotation_rad: npt.NDArray[np.float64] | None = None

    def __len__(self) -> int:
        return int(self.stamp_ns.shape[0])

    def per_sensor(self, attribute: str) -> npt.NDArray[np.float64]:
        """A sensor attribute (e.g. ``"max_range_m"``) looked up for every reading, shape (M,)."""
        table = np.asarray([getattr(s, attribute) for s in self.sensors], dtype=np.float64)
        return table[self.sensor]


def select_readings(
    readings: SensorReadings, sl: slice | npt.NDArray[np.bool_] | npt.NDArray[np.int64]
) -> SensorReadings:
    """The readings picked by ``sl`` (a slice, mask or index array over the M readings)."""
    d, r = readings.distance_m, readings.rotation_rad
    return SensorReadings(
        stamp_ns=readings.stamp_ns[sl],
        sensor=readings.sensor[sl],
        range_m=readings.range_m[sl],
        x_m=readings.x_m[sl],
        y_m=readings.y_m[sl],
        theta_rad=readings.theta_rad[sl],
        sensors=readings.sensors,
        distance_m=None if d is None else d[sl],
        rotation_rad=None if r is None else r[sl],
    )


@dataclass(frozen=True)
class SyncStats:
    """How many readings the sync stage kept and why it dropped the others."""

    total: int
    used: int
    outside_odometry: int
    below_min_range: int


def laser_point(log: RangeLog, robot: RobotDescription | None) -> tuple[float, float] | None:
    """The one point (x, y, robot frame) the log's laser beams start from; None without a
    laser, with lasers at more than one point, or where the log's sensors are not described."""
    try:
        sensors = sensors_for_log(log, robot)
    except GridmapError:
        return None
    points = {(s.x_m, s.y_m) for s in sensors if s.kind == "laser"}
    return points.pop() if len(points) == 1 else None


def sensors_for_log(log: RangeLog, robot: RobotDescription | None) -> tuple[RangeSensor, ...]:
    """Mounting geometry for each of the log's sensor names.

    A sensor the log describes itself (``log.sensors``, matched by name) wins; the robot
    description supplies the rest. A name neither knows is an error.
    """
    own = {s.name: s for s in log.sensors or ()}
    table = {**(robot.by_name() if robot is not None else {}), **own}
    unknown = [n for n in log.sensor_names if n not in table]
    if not unknown:
        return tuple(table[n] for n in log.sensor_names)
    if robot is None:
        raise GridmapError(
            f"{log.source}: the log does not describe sensor"
            f"{'s' if len(unknown) > 1 else ''} {', '.join(repr(u) for u in unknown[:5])}"
            f"{' ...' if len(unknown) > 5 else ''}; give {given('robot')} "
            "(a preset name, a robot YAML file or an ARIA .p file)"
        )
    raise GridmapError(
        f"{log.source}: sensor column{'s' if len(unknown) > 1 else ''} "
        f"{', '.join(repr(u) for u in unknown)} not described by robot '{robot.name}' "
        f"(it has {', '.join(robot.names())})"
    )


def interpolate_pose(
    track: PoseTrack, stamp_ns: npt.NDArray[np.int64]
) -> tuple[
    npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.bool_]
]:
    """Poses of ``track`` at ``stamp_ns`` (shape (M,)): x, y, theta and a mask of valid stamps.

    A stamp is valid when it lies within the track's time span (ends included). Invalid entries
    hold the nearest end pose and must be ignored by the caller.
    """
    t = track.stamp_ns
    hi = np.searchsorted(t, stamp_ns, side="left")
    valid = (stamp_ns >= t[0]) & (stamp_ns <= t[-1])
    hi = np.clip(hi, 1, max(len(track) - 1, 1))
    lo = hi - 1
    if len(track) == 1:
        lo = hi = np.zeros_like(hi)
    span = (t[hi] - t[lo]).astype(np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.where(span > 0, (stamp_ns - t[lo]).astype(np.float64) / span, 0.0)
    frac = np.clip(frac, 0.0, 1.0)
    x = track.x_m[lo] + frac * (track.x_m[hi] - track.x_m[lo])
    y = track.y_m[lo] + frac * (track.y_m[hi] - track.y_m[lo])
    dth = wrap_angle(track.theta_rad[hi] - track.theta_rad[lo])
    theta = wrap_angle(track.theta_rad[lo] + frac * dth)
    return x, y, theta, valid


def stamp_groups(
    stamp_ns: npt.NDArray[np.int64],
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """Runs of equal consecutive stamps: the index of each run's first stamp (R,) and each
    stamp's run (M,), so that ``stamp_ns[first][group] == stamp_ns``."""
    if stamp_ns.shape[0] == 0:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty
    change = stamp_ns[1:] != stamp_ns[:-1]
    first = np.concatenate([[0], np.flatnonzero(change) + 1]).astype(np.int64)
    group = np.concatenate([[0], np.cumsum(change)]).astype(np.int64)
    return first, group


def synchronise(
    log: RangeLog,
    robot: RobotDescription | None,
    chunk: slice | RangeReadings = slice(None),
    travelled: tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]] | None = None,
) -> tuple[SensorReadings, SyncStats]:
    """Attach the sensor pose (odometry frame) to every usable reading of ``log``, or of the
    readings ``chunk`` of it (a slice of its held readings, or readings of it as
    :meth:`RangeLog.reading_chunks` gives them): each reading's pose depends on the pose track
    alone, so chunks synchronised one by one give the whole's readings, bit for bit.
    ``travelled``: :func:`~gridmap_cli.poses.odometry_error.travelled` of ``log.poses``, made once
    by
    a caller that synchronises many chunks."""
    sensors = sensors_for_log(log, robot)
    if isinstance(chunk, RangeReadings):
        r = chunk
    elif log.stream is not None:
        raise GridmapError(f"{log.source}: the readings are streamed; synchronise them by chunk")
    else:
        r = log.readings.part(chunk)
    # the pose (and the distance driven) at each stamp once: a scan's 181 beams or a sonar
    # ring's 16 readings share one stamp; the same arithmetic per stamp, so the same bits
    first, group = stamp_groups(r.stamp_ns)
    xs, ys, ths, valids = interpolate_pose(log.poses, r.stamp_ns[first])
    valid = valids[group]
    min_r = np.asarray([s.min_range_m for s in sensors], dtype=np.float64)[r.sensor]
    max_r = np.asarray([s.max_range_m for s in sensors], dtype=np.float64)[r.sensor]
    too_near = valid & (r.range_m < min_r)
    keep = valid & ~too_near
    idx = r.sensor[keep]
    kept_group = group[keep]  # each kept reading's stamp among the ``first`` ones
    mx = np.asarray([s.x_m for s in sensors], dtype=np.float64)[idx]
    my = np.asarray([s.y_m for s in sensors], dtype=np.float64)[idx]
    myaw = np.asarray([s.yaw_rad for s in sensors], dtype=np.float64)[idx]
    sx, sy, sth = compose(xs[kept_group], ys[kept_group], ths[kept_group], mx, my, myaw)
    distance, rotation = travelled_at(log.poses, r.stamp_ns[first], travelled)
    distance, rotation = distance[kept_group], rotation[kept_group]
    readings = SensorReadings(
        stamp_ns=r.stamp_ns[keep],
        sensor=idx,
        range_m=np.minimum(r.range_m[keep], max_r[keep]),
        x_m=sx,
        y_m=sy,
        theta_rad=sth,
        sensors=sensors,
        distance_m=distance,
        rotation_rad=rotation,
    )
    stats = SyncStats(
        total=len(r),
        used=int(keep.sum()),
        outside_odometry=int((~valid).sum()),
        below_min_range=int(too_near.sum()),
    )
    return readings, stats
