"""The error-aware models: the standard models' log-odds evidence, faded by the pose spread.

Each reading's pose error comes from the covariance carried along the odometry track
(:mod:`gridmap_cli.poses.uncertainty.pose_uncertainty`), projected through the sensor's lever arm
onto the reading's range and bearing: ``sigma_z = k z + s_along``, ``sigma_theta = beta / 2 +
s_across / z`` (the seed paper's eq. 11 and 12 with f and g replaced by the projections). Eq. 10
is a density normalised by ``1 / (2 pi sigma_z sigma_theta)``: the wider the spread, the less a
reading says about any one cell. The reading's evidence is therefore weighted by the ratio of
that density's peak with and without the pose error,

    w = (Z / (Z + s_along)) * (B / (B + s_across / z)),   Z = max(k z, L),  B = max(beta / 2, L / z)

where L (``trust_length_m``) is the smallest spread a cell can tell apart. With no pose error
w = 1 and the model *is* the standard model: the same evidence, to the bit. Nothing is widened:
a reading too spread to say anything about a cell fades to (nearly) no evidence instead of being
painted over a wide wedge. docs/sensor-model.md derives it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from gridmap_cli.mapping.grid import LogOddsAccumulator
from gridmap_cli.mapping.models.ray import RayModel, RaySegments, accumulate_rays
from gridmap_cli.mapping.models.sector import F64, I64
from gridmap_cli.mapping.models.standard import (
    SectorEvidence,
    StandardSonarModel,
    accumulate_sectors,
)
from gridmap_cli.poses.sync import SensorReadings, select_readings
from gridmap_cli.poses.uncertainty.pose_uncertainty import PoseUncertainty, project
from gridmap_cli.robot import RangeSensor

#: Ray weights are rounded to multiples of 1 / RAY_WEIGHT_LEVELS, so that a batch's rays map in a
#: few groups of one weight each through the standard ray kernel.
RAY_WEIGHT_LEVELS = 64
#: The angular step assumed for a laser beam that belongs to no scan (a lone ray sensor): one
#: degree, the coarsest step of the SICK LMS 200 that the CARMEN logs use.
LONE_BEAM_STEP_RAD = math.radians(1.0)


@dataclass(frozen=True)
class ErrorAwareParams:
    """The error-aware mode's settings beyond the odometry-error model; see docs/sensor-model.md.

    ``trust_length_m``: L of the module docstring (``--trust-length``), the analytic model's.
    ``max_heading_spread_rad``: readings taken after the heading standard deviation passes it
    are left out, in both error-aware maps (``--max-heading-spread``; ``inf`` keeps every
    reading). ``laser_relative_error``: k of eq. 11 for laser rays (the sonar's is in the
    odometry-error file, where the seed paper put it).
    """

    trust_length_m: float = 0.3
    max_heading_spread_rad: float = math.inf
    laser_relative_error: float = 0.005

    def __post_init__(self) -> None:
        if not (self.trust_length_m > 0 and math.isfinite(self.trust_length_m)):
            raise ValueError("the trust length must be a positive number of metres")
        if not self.max_heading_spread_rad > 0:
            raise ValueError("the heading-spread limit must be a positive angle")
        if not (self.laser_relative_error >= 0 and math.isfinite(self.laser_relative_error)):
            raise ValueError("the laser's relative range error must be a finite number >= 0")


def scan_steps(sensors: tuple[RangeSensor, ...], narrow: npt.NDArray[np.bool_]) -> F64:
    """Per sensor, shape (S,): the angular step of the scan its beam belongs to (beta of eq. 12,
    at least the beam's own width), radians; 0 for a sensor that is no narrow beam.

    The narrow-beam sensors ``<laser>_<i>`` at one mounting position are one scan; its step is
    the median gap between their yaws (:data:`LONE_BEAM_STEP_RAD` for a beam alone)."""
    groups: dict[tuple[str, float, float], list[int]] = {}
    for i, s in enumerate(sensors):
        if narrow[i]:
            base, sep, index = s.name.rpartition("_")
            key = (base if sep and index.isdigit() else s.name, s.x_m, s.y_m)
            groups.setdefault(key, []).append(i)
    step = np.zeros(len(sensors), dtype=np.float64)
    for members in groups.values():
        yaw = np.unwrap(np.array([sensors[i].yaw_rad for i in members]))
        gaps = np.diff(yaw[np.argsort(yaw, kind="stable")])
        gaps = gaps[gaps > 1e-9]
        scan_step = float(np.median(gaps)) if gaps.size else LONE_BEAM_STEP_RAD
        for i in members:
            step[i] = max(scan_step, sensors[i].beam_width_rad)
    return step


@dataclass(frozen=True)
class FadeParams:
    """``trust_length_m``: L above; ``sonar_relative_error``, ``laser_relative_error``: k of
    eq. 11 for sonar and laser readings; ``max_heading_spread_rad``: readings whose heading
    standard deviation exceeds it get weight 0 (``inf``: none)."""

    trust_length_m: float = 0.3
    sonar_relative_error: float = 0.01
    laser_relative_error: float = 0.005
    max_heading_spread_rad: float = math.inf


class PoseSpread:
    """The pose uncertainty of a log's track and what it means for each reading."""

    def __init__(self, uncertainty: PoseUncertainty, params: FadeParams) -> None:
        self.uncertainty = uncertainty
        self.params = params

    @property
    def is_zero(self) -> bool:
        return self.uncertainty.is_zero

    def spread(self, readings: SensorReadings) -> tuple[F64, F64, F64]:
        """Pose part of the spread of each reading's echo: (along the beam in metres, across it
        in metres, heading standard deviation in radians), shape (M,) each."""
        u = self.uncertainty
        cov = u.at(readings.stamp_ns)
        t = (u.stamp_ns - u.stamp_ns[0]).astype(np.float64)
        q = (readings.stamp_ns - u.stamp_ns[0]).astype(np.float64)
        rx, ry = np.interp(q, t, u.x_m), np.interp(q, t, u.y_m)
        z = readings.range_m
        ex = readings.x_m + z * np.cos(readings.theta_rad)
        ey = readings.y_m + z * np.sin(readings.theta_rad)
        along, across = project(cov, ex - rx, ey - ry, readings.theta_rad)
        return along, across, np.sqrt(np.maximum(cov[:, 2, 2], 0.0))

    def weight(self, readings: SensorReadings, relative_error: float, half_width: F64) -> F64:
        """w of the module docstring for each reading, shape (M,); exactly 1 without pose error."""
        along, across, heading = self.spread(readings)
        length = self.params.trust_length_m
        z = np.maximum(readings.range_m, 1e-9)
        zs = np.maximum(relative_error * z, length)
        bs = np.maximum(half_width, length / z)
        w = (zs / (zs + along)) * (bs / (bs + across / z))
        # beyond the heading-spread limit: left out (weight -1 marks them for the caller)
        return np.where(heading > self.params.max_heading_spread_rad, -1.0, w)


class FadedSonarModel:
    """The standard sonar model with each reading's evidence weighted by its pose spread."""

    name = "error-aware"

    def __init__(self, standard: StandardSonarModel, spread: PoseSpread) -> None:
        self.standard = standard
        self.spread = spread

    def bounds(self, readings: SensorReadings) -> tuple[float, float, float, float]:
        return self.standard.bounds(readings)

    def accumulate(self, grid: LogOddsAccumulator, readings: SensorReadings) -> int:
        ev = self.standard.evidence(readings)
        if self.spread.is_zero:
            return accumulate_sectors(grid, ev)
        w = self.spread.weight(readings, self.spread.params.sonar_relative_error, ev.half_width_rad)
        if np.any(w < 0.0):
            readings = select_readings(readings, w >= 0.0)
            return self.accumulate(grid, readings) if len(readings) else 0
        echo = ev.outer_value != 0.0
        m = self.standard
        faded = SectorEvidence(
            x_m=ev.x_m,
            y_m=ev.y_m,
            theta_rad=ev.theta_rad,
            half_width_rad=ev.half_width_rad,
            inner_m=ev.inner_m,
            inner_value=np.where(echo, w * m.l_free - w * m.l_occ, w * m.l_free),
            outer_m=ev.outer_m,
            outer_value=np.where(echo, w * m.l_occ, 0.0),
        )
        return accumulate_sectors(grid, faded)


class FadedRayModel:
    """The ray model with each ray's evidence weighted by its pose spread (in a few levels)."""

    name = "error-aware"

    def __init__(self, ray: RayModel, spread: PoseSpread, step_rad: F64) -> None:
        self.ray = ray
        self.spread = spread
        #: per sensor: the angular step of its scan (what a scan cannot tell apart), radians
        self.step_rad = step_rad

    def bounds(self, readings: SensorReadings) -> tuple[float, float, float, float]:
        return self.ray.bounds(readings)

    def accumulate(self, grid: LogOddsAccumulator, readings: SensorReadings) -> int:
        seg = self.ray.segments(readings)
        if self.spread.is_zero:
            return accumulate_rays(grid, seg, self.ray.l_free, self.ray.l_occ)
        half = 0.5 * self.step_rad[readings.sensor]
        w = self.spread.weight(readings, self.spread.params.laser_relative_error, half)
        if np.any(w < 0.0):
            readings = select_readings(readings, w >= 0.0)
            return self.accumulate(grid, readings) if len(readings) else 0
        level = np.rint(w * RAY_WEIGHT_LEVELS).astype(np.int64)
        order = np.argsort(-level, kind="stable")
        cuts = np.flatnonzero(np.diff(level[order])) + 1
        updates = 0
        for group in np.split(order, cuts):
            wq = float(level[group[0]]) / RAY_WEIGHT_LEVELS
            part = _pick(seg, group) if group.shape[0] < level.shape[0] else seg
            updates += accumulate_rays(grid, part, wq * self.ray.l_free, wq * self.ray.l_occ)
        return updates


def _pick(seg: RaySegments, index: I64) -> RaySegments:
    return RaySegments(
        seg.x0_m[index], seg.y0_m[index], seg.x1_m[index], seg.y1_m[index], seg.echo[index]
    )
