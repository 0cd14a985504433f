"""Simulated sonar readings: a fan of rays per beam, specular walls, Gaussian range noise.

A Polaroid-style sonar hears the first echo that comes back to it. A smooth wall reflects sound
like a mirror, so it only echoes back to the transducer where the sound meets it close to
head-on; at grazing incidence the sound bounces away and the sonar hears nothing (or something far
behind). Each beam is modelled as ``rays_per_beam`` rays spread evenly across its opening angle;
a ray echoes when it hits something at an incidence below ``critical_incidence_deg``, and the
reading is the nearest echo. Because the fan spans the beam, a wall still echoes while some part
of the beam meets it steeply enough: with the p3at's 25 deg beam and the default 35 deg critical
angle, up to about 47 deg between the beam axis and the wall normal.

The default critical angle, 35 deg, sits in the 30-40 deg range usual in sonar simulators and
reported for Polaroid transducers on painted walls and doors: beyond the purely specular limit
(half the beam width), because real surfaces are rough at the scale of the 7 mm wavelength and the
transducer has side lobes, but well short of the grazing angles at which only rough surfaces
echo. Concave corners echo from any direction (the smoothed surface normal there points along the
corner's bisector), as corner reflectors do.

Multiple reflections (the long phantom readings of real sonars) and crosstalk are not simulated:
a beam without an echo reads exactly its maximum range.

Laser beams (sensor kind ``laser``, beam width 0) are simulated in the same pass with what differs
for light: surfaces scatter it diffusely, so any hit short of exactly grazing echoes, and the
range noise is absolute (``laser_noise_m``, 1 cm as for a SICK LMS200) rather than relative.
"""

from __future__ import annotations

import math

import numpy as np

from gridmap_cli.geometry import compose
from gridmap_cli.records import PoseTrack, RangeReadings
from gridmap_cli.robot import RobotDescription
from gridmap_cli.sim.world import World

#: Rays per beam. Nine rays across a 25 deg beam are ~3 deg apart (22 cm at the p3at's 4.3 m
#: maximum range), enough for the edges of doorways and furniture to show; more cost time linearly.
DEFAULT_RAYS_PER_BEAM = 9

#: Incidence (degrees from the surface normal) beyond which a surface sends no echo back.
DEFAULT_CRITICAL_INCIDENCE_DEG = 35.0

#: Smallest range reported for an echo (metres): a sensor inside an obstacle reads this, since a
#: range reading must be positive.
MIN_REPORTED_RANGE_M = 1e-3

#: Rays cast per batch (poses x sensors x rays): bounds memory to some tens of megabytes.
_RAYS_PER_CHUNK = 1 << 20


def simulate_ranges(
    world: World,
    truth: PoseTrack,
    robot: RobotDescription,
    rng: np.random.Generator,
    *,
    rays_per_beam: int = DEFAULT_RAYS_PER_BEAM,
    range_noise: float = 0.01,
    critical_incidence_deg: float = DEFAULT_CRITICAL_INCIDENCE_DEG,
    laser_noise_m: float = 0.01,
) -> RangeReadings:
    """One reading per sensor of ``robot`` at every pose of ``truth``.

    Parameters
    ----------
    world
        What the sonars see.
    truth
        True robot base poses, shape (N,), in the world's frame.
    robot
        Sensors and their mounting poses (base frame); reading ``sensor`` indices are positions in
        ``robot.sensors``.
    rng
        Source of range noise: exactly N * len(robot.sensors) standard normals are drawn, one per
        reading in output order, echo or not, so that a seed fixes the log.
    rays_per_beam
        Rays spread evenly across each beam's opening angle (edges included); a sensor with
        beam width 0 casts them all along its axis.
    range_noise
        Standard deviation of the range noise relative to the range (0.01: 1 cm at 1 m).
    critical_incidence_deg
        Rays meeting a surface further than this from its normal give no echo (sonar only).
    laser_noise_m
        Standard deviation of a laser's range noise, metres.

    Returns
    -------
    RangeReadings
        Shape (N * S,) for S sensors, ordered by stamp then sensor index. An echo reads its
        distance plus noise, clipped into [min_range_m, max_range_m) (an echo nearer than the
        sensor's minimum range keeps its true value, floored at 1 mm: such readings are reported
        and the mapper discards them). No echo reads exactly ``max_range_m``.
    """
    if rays_per_beam < 1:
        raise ValueError(f"rays_per_beam must be >= 1, got {rays_per_beam}")
    if range_noise < 0.0:
        raise ValueError(f"range_noise must be >= 0, got {range_noise}")
    sensors = robot.sensors
    n_poses, n_sensors = len(truth), len(sensors)
    noise = rng.standard_normal(n_poses * n_sensors).reshape(n_poses, n_sensors)
    mount_x = np.asarray([s.x_m for s in sensors], dtype=np.float64)
    mount_y = np.asarray([s.y_m for s in sensors], dtype=np.float64)
    mount_yaw = np.asarray([s.yaw_rad for s in sensors], dtype=np.float64)
    rmin = np.asarray([s.min_range_m for s in sensors], dtype=np.float64)
    rmax = np.asarray([s.max_range_m for s in sensors], dtype=np.float64)
    width = np.asarray([s.beam_width_rad for s in sensors], dtype=np.float64)
    # ray directions relative to each beam axis, shape (S, R)
    fan = np.linspace(-0.5, 0.5, rays_per_beam) if rays_per_beam > 1 else np.zeros(1)
    offsets = width[:, None] * fan[None, :]
    laser = np.asarray([s.kind == "laser" for s in sensors], dtype=bool)
    # light scatters diffusely: a laser hears any hit that is not exactly grazing
    critical = np.where(laser, math.pi / 2, math.radians(critical_incidence_deg))

    range_m = np.empty((n_poses, n_sensors), dtype=np.float64)
    per_chunk = max(_RAYS_PER_CHUNK // max(n_sensors * rays_per_beam, 1), 1)
    for lo in range(0, n_poses, per_chunk):
        hi = min(lo + per_chunk, n_poses)
        # sensor poses in the world frame, shape (P, S)
        sx, sy, sth = compose(
            truth.x_m[lo:hi, None],
            truth.y_m[lo:hi, None],
            truth.theta_rad[lo:hi, None],
            mount_x[None, :],
            mount_y[None, :],
            mount_yaw[None, :],
        )
        # rays, shape (P, S, R)
        ray_range, incidence = world.cast(
            sx[:, :, None], sy[:, :, None], sth[:, :, None] + offsets[None], rmax[None, :, None]
        )
        # NaN incidence (no hit) compares False: no echo
        echo = incidence < critical[None, :, None]
        nearest = np.min(np.where(echo, ray_range, np.inf), axis=2)
        range_m[lo:hi] = nearest

    heard = np.isfinite(range_m)
    sigma = np.where(laser[None, :], laser_noise_m, range_noise * np.where(heard, range_m, 0.0))
    noisy = range_m + np.where(heard, sigma, 0.0) * noise
    # Noise must neither turn an echo into "no echo" (>= max) nor push an echo from the usable
    # interval below the minimum range; echoes truly below the minimum stay below it.
    below_max = np.nextafter(rmax, 0.0)[None, :]
    floor = np.where(range_m >= rmin[None, :], rmin[None, :], MIN_REPORTED_RANGE_M)
    noisy = np.minimum(np.maximum(noisy, floor), below_max)
    out = np.where(heard, noisy, rmax[None, :])
    stamps = np.repeat(truth.stamp_ns, n_sensors)
    sensor = np.tile(np.arange(n_sensors, dtype=np.int32), n_poses)
    return RangeReadings(stamp_ns=stamps, sensor=sensor, range_m=out.ravel())
