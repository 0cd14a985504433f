"""Wheel odometry with drift, from a true trajectory.

Odometry is integrated from the true motion between consecutive samples, corrupted by systematic
and random errors (:class:`OdometryErrorModel`). It starts at (0, 0, 0): **the odometry frame is
the frame of the first true pose**. With no error the odometry equals the truth expressed relative
to its first pose, ``inverse(truth[0]) (+) truth[k]``; that is the comparison to make when
evaluating drift.

Per step, the true relative motion (dx, dy, dtheta) in the robot frame at the step's start has
length ``s = hypot(dx, dy)`` and rotation ``dtheta``. Odometry reports

* the translation (dx, dy) scaled by ``1 + scale_error + sigma_dist_per_sqrt_m * n1 / sqrt(s)``,
  i.e. a distance error of ``scale_error * s`` plus ``N(0, sigma_dist_per_sqrt_m**2 * s)``;
* a rotation ``dtheta * (1 + turn_scale_error) + heading_drift_rad_per_m * s
  + N(0, sigma_turn_per_sqrt_rad**2 * |dtheta|)``.

Random variances grow with distance and angle travelled, not with the number of steps, so the
error of a log does not depend on the sampling rate. Heading drift is a bias per metre driven:
a Pioneer with slightly unequal wheel diameters curves the same way on every straight.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

from gridmap_cli.geometry import compose, inverse, wrap_angle
from gridmap_cli.poses.odometry_error import OdometryError
from gridmap_cli.records import PoseTrack


@dataclass(frozen=True)
class OdometryErrorModel:
    """Systematic and random odometry errors; the defaults are "drift 1".

    Attributes
    ----------
    scale_error
        Relative error of measured distance (0.01: odometry reports 1.01 m per true metre).
        Tyre pressure and wear on a Pioneer leave an uncalibrated distance scale off by 1-2 %.
    turn_scale_error
        Relative error of measured rotation (0.02: reports 1.02 rad per true radian). Rotation
        is worse than distance on any Pioneer (effective wheel base depends on the floor and on
        the tyres' contact patch) and worst on the skid-steered P3-AT: 2-3 % uncalibrated.
    heading_drift_rad_per_m
        Heading error per metre driven (radians per metre; 0.2 deg/m): unequal wheel diameters.
        A diameter ratio off by 0.15 % on a 0.4 m wheel base turns 0.0015 / 0.4 rad per metre.
        (0.75 deg/m, tried first, bent a 56 m loop by 40 degrees: not "typical".)
    sigma_dist_per_sqrt_m
        Standard deviation of the random distance error after one metre (m / sqrt(m)): 1 cm, the
        size of the systematic error over a metre, as wheel slip on a hard floor gives.
    sigma_turn_per_sqrt_rad
        Standard deviation of the random rotation error after one radian (rad / sqrt(rad)): 0.02,
        again the size of the systematic term over a radian.
    """

    scale_error: float = 0.01
    turn_scale_error: float = 0.02
    heading_drift_rad_per_m: float = math.radians(0.2)
    sigma_dist_per_sqrt_m: float = 0.01
    sigma_turn_per_sqrt_rad: float = 0.02

    def scaled(self, drift: float) -> OdometryErrorModel:
        """Every term multiplied by ``drift`` (0: perfect odometry; 2: twice these errors)."""
        if not (drift >= 0.0 and math.isfinite(drift)):
            raise ValueError(f"drift must be a finite number >= 0, got {drift}")
        return replace(self, **{f.name: getattr(self, f.name) * drift for f in fields(self)})

    def as_odometry_error(self) -> OdometryError:
        """The f and g coefficients (:mod:`gridmap_cli.poses.odometry_error`) these errors give.

        Each term maps onto one coefficient: the systematic ones as magnitudes (a spread has no
        sign), the random walks as they are. The sonar's own error keeps its default.
        """
        return OdometryError(
            range_m_per_m=abs(self.scale_error),
            range_m_per_sqrt_m=self.sigma_dist_per_sqrt_m,
            bearing_rad_per_rad=abs(self.turn_scale_error),
            bearing_rad_per_sqrt_rad=self.sigma_turn_per_sqrt_rad,
            heading_drift_rad_per_m=abs(self.heading_drift_rad_per_m),
        )


def odometry_from_truth(
    truth: PoseTrack, model: OdometryErrorModel, rng: np.random.Generator
) -> PoseTrack:
    """Odometry a robot driving ``truth`` would report.

    Parameters
    ----------
    truth
        True poses, shape (N,), world frame.
    model
        Errors to apply (use ``model.scaled(0)`` for perfect odometry).
    rng
        Source of the random terms: exactly two arrays of N - 1 standard normals are drawn
        (distance noise, then rotation noise), whatever the model, so that a seed fixes the log.

    Returns
    -------
    PoseTrack
        Shape (N,), same stamps; poses in the odometry frame (the frame of ``truth``'s first
        pose), starting at (0, 0, 0), theta wrapped to [-pi, pi).
    """
    n = len(truth)
    noise_dist = rng.standard_normal(max(n - 1, 0))
    noise_turn = rng.standard_normal(max(n - 1, 0))
    if n == 0:
        return truth
    # true motion of each step in the robot frame at its start
    ix, iy, ith = inverse(truth.x_m[:-1], truth.y_m[:-1], truth.theta_rad[:-1])
    dx, dy, dth = compose(ix, iy, ith, truth.x_m[1:], truth.y_m[1:], truth.theta_rad[1:])
    dist = np.hypot(dx, dy)
    with np.errstate(invalid="ignore", divide="ignore"):
        # random distance error as a relative one, so that it scales (dx, dy) together
        rel = np.where(dist > 0.0, model.sigma_dist_per_sqrt_m * noise_dist / np.sqrt(dist), 0.0)
    k = 1.0 + model.scale_error + rel
    rot = (
        dth * (1.0 + model.turn_scale_error)
        + model.heading_drift_rad_per_m * dist
        + model.sigma_turn_per_sqrt_rad * np.sqrt(np.abs(dth)) * noise_turn
    )
    # Heading before each step is the running sum of reported rotations; positions follow by
    # rotating each step's translation into the odometry frame and summing.
    theta = np.concatenate([[0.0], np.cumsum(rot)])
    c = np.cos(theta[:-1])
    s = np.sin(theta[:-1])
    ox = np.concatenate([[0.0], np.cumsum(k * (c * dx - s * dy))])
    oy = np.concatenate([[0.0], np.cumsum(k * (s * dx + c * dy))])
    return PoseTrack(stamp_ns=truth.stamp_ns.copy(), x_m=ox, y_m=oy, theta_rad=wrap_angle(theta))
