"""A whole simulated log: true trajectory, drifting odometry and sonar readings.

The glue between the simulator's parts, returning the same :class:`~gridmap_cli.records.RangeLog`
a reader would, so a simulated log can be written by any writer and mapped like a real one.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from gridmap_cli.errors import InputFileError
from gridmap_cli.records import PoseTrack, RangeLog, RangeReadings
from gridmap_cli.robot import RobotDescription
from gridmap_cli.sim.odometry import OdometryErrorModel, odometry_from_truth
from gridmap_cli.sim.path import MAX_SIM_POSES, WaypointPath, trajectory
from gridmap_cli.sim.sonar import simulate_ranges
from gridmap_cli.sim.world import World

#: The most range readings one simulation makes (at 40 bytes or so each in memory, ~2 GB).
MAX_SIM_READINGS = 50_000_000


def simulate(
    world: World,
    path: WaypointPath,
    robot: RobotDescription,
    *,
    rate_hz: float = 10.0,
    seed: int = 0,
    drift: float = 1.0,
    duration_s: float | None = None,
    error_model: OdometryErrorModel | None = None,
) -> RangeLog:
    """Drive ``robot`` along ``path`` through ``world`` and record what it would log.

    Parameters
    ----------
    world
        The world the sonars see; the path's coordinates are in its frame.
    path
        Where the robot drives (see :func:`~gridmap_cli.sim.path.trajectory`).
    robot
        Its range sensors; every sensor reads at every pose.
    rate_hz
        Pose and reading rate.
    seed
        Seeds the one random generator; the same arguments and seed give the same log, bit for bit.
    drift
        Multiplies every term of the odometry error model (0: perfect odometry).
    duration_s
        None: drive the path's laps once. A number: keep lapping and stop at this duration.
    error_model
        Odometry errors at drift 1; default :class:`OdometryErrorModel` (a Pioneer on a hard
        floor). The model applied is ``error_model.scaled(drift)``.

    Returns
    -------
    RangeLog
        ``poses``: odometry (frame of the first true pose, see
        :mod:`gridmap_cli.sim.odometry`); ``truth``: the true poses in the world frame;
        ``readings``: one per pose and sensor, ordered by stamp then sensor; ``sensor_names``: the
        robot's, in order; ``sensors`` None (the robot description supplies the geometry);
        ``metadata``: ``robot``, ``seed`` and ``drift``.
    """
    model = (error_model if error_model is not None else OdometryErrorModel()).scaled(drift)
    rng = np.random.default_rng(seed)
    # every sensor reads at every pose: the readings bound the poses
    max_poses = min(MAX_SIM_POSES, MAX_SIM_READINGS // max(len(robot.sensors), 1))
    what = "MAX_SIM_POSES" if max_poses == MAX_SIM_POSES else (
        f"MAX_SIM_READINGS, {MAX_SIM_READINGS:,} readings of {len(robot.sensors)} sensors"
    )  # fmt: skip
    truth = trajectory(path, rate_hz, duration_s, max_poses, what)
    _check_clear(world, truth, path.source)
    # Draw order is fixed: odometry noise first, then range noise.
    odometry = odometry_from_truth(truth, model, rng)
    readings = simulate_ranges(world, truth, robot, rng)
    return RangeLog(
        source=f"simulation of {path.source}",
        poses=quantize_track(odometry),
        readings=quantize_readings(readings),
        sensor_names=robot.names(),
        sensors=None,
        truth=quantize_track(truth),
        metadata={
            "robot": robot.name,
            "seed": str(seed),
            "drift": str(drift),
        },
    )


def _check_clear(world: World, truth: PoseTrack, source: str) -> None:
    """Refuse a path that drives the robot's centre through an occupied cell.

    Sonars fired from inside an obstacle would log nonsense that no real robot can produce.
    """
    inside = world.occupied_at(truth.x_m, truth.y_m)
    if inside.any():
        k = int(np.argmax(inside))
        raise InputFileError(
            source,
            f"the path drives through an obstacle of the world at x={truth.x_m[k]:.2f} m, "
            f"y={truth.y_m[k]:.2f} m (t={truth.stamp_ns[k] / 1e9:.1f} s)",
        )


def _to_mm(values_m: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    # mm / 1000 is correctly rounded, so it is the same double as parsing the decimal "x.xxx"
    return np.round(values_m * 1000.0) / 1000.0


def quantize_track(track: PoseTrack) -> PoseTrack:
    """Poses at the resolution a Pioneer reports and ARIA logs hold: 1 mm and 0.01 degree.

    Every log format gridmap writes then holds the same numbers exactly, so the same run stored
    as CSV or ARIA reads back bit-identical. Headings are radians(round(degrees, 2)), computed
    the way a reader converts the logged degrees.
    """
    degrees = np.round(np.degrees(track.theta_rad), 2)
    theta = np.asarray([math.radians(float(f"{d:.2f}")) for d in degrees], dtype=np.float64)
    return PoseTrack(track.stamp_ns, _to_mm(track.x_m), _to_mm(track.y_m), theta)


def quantize_readings(readings: RangeReadings) -> RangeReadings:
    """Ranges at 1 mm, as the Pioneer's sonar reports them."""
    return RangeReadings(readings.stamp_ns, readings.sensor, _to_mm(readings.range_m))
