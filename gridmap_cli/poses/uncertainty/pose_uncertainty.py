"""The pose covariance carried along the odometry track, and its projection onto each reading.

The odometry reports increments in the robot frame. Each increment is wrong by a little, and
the errors compose: a heading error made early turns every later step, so it becomes lateral
position error as the robot drives on. This module carries the covariance of (x, y, theta) along
the track (an extended Kalman filter's prediction step with no correction) from per-step noise
in the robot frame, and projects it onto each reading's range and bearing through the sensor's
lever arm. docs/sensor-model.md derives it; docs/odometry-error.md maps the file's coefficients
onto the per-step noise.

The track is cut into *key steps*: a step ends once the odometry has driven
:data:`KEY_STEP_M` or turned :data:`KEY_STEP_RAD` (net, since the step began). The heading noise
grows with a step's net turn, so a heading that wiggles back and forth between odometry samples
adds no more noise than the straight line it averages to.

State: the pose (x, y, theta) and three constant systematic errors, the distance scale ``s``,
the turn scale ``u`` and the heading drift per metre ``c``. A key step of robot-frame increment
(dx, dy, dtheta) and length ds = hypot(dx, dy) moves the true pose by ((1 + s) dx, (1 + s) dy,
(1 + u) dtheta + c ds) plus random noise: along-track variance ``q_a ds``, lateral ``q_l ds``,
heading ``q_t |dtheta| + q_h ds``. The systematic errors start with variances from the file and
never change, so their effect grows linearly with travel, fully correlated along the path, as a
systematic error does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from gridmap_cli.geometry import wrap_angle
from gridmap_cli.poses.odometry_error import OdometryError
from gridmap_cli.records import PoseTrack

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]

#: A key step ends once the odometry has driven this far (metres) ... (calibrate's window: the
#: noise per step is what calibrate measured per window)
KEY_STEP_M = 1.0
#: ... or turned this much net (radians) since the step began.
KEY_STEP_RAD = math.pi / 2


@dataclass(frozen=True)
class StepNoise:
    """Per-step odometry noise in the robot frame; every value finite and >= 0.

    Systematic (standard deviations of constant errors): ``distance_scale`` (m/m),
    ``turn_scale`` (rad/rad), ``heading_drift_rad_per_m``. Random walks (standard deviation
    after one unit): ``along_m_per_sqrt_m``, ``lateral_m_per_sqrt_m``,
    ``heading_rad_per_sqrt_rad`` (with the step's net turn), ``heading_rad_per_sqrt_m`` (with its
    distance).
    """

    distance_scale: float = 0.0
    turn_scale: float = 0.0
    heading_drift_rad_per_m: float = 0.0
    along_m_per_sqrt_m: float = 0.0
    lateral_m_per_sqrt_m: float = 0.0
    heading_rad_per_sqrt_rad: float = 0.0
    heading_rad_per_sqrt_m: float = 0.0

    @classmethod
    def of(cls, model: OdometryError) -> StepNoise:
        """The per-step noise an odometry-error file describes (docs/odometry-error.md)."""
        return cls(
            distance_scale=model.range_m_per_m,
            turn_scale=model.bearing_rad_per_rad,
            heading_drift_rad_per_m=model.heading_drift_rad_per_m,
            along_m_per_sqrt_m=model.range_m_per_sqrt_m,
            lateral_m_per_sqrt_m=model.lateral_m_per_sqrt_m,
            heading_rad_per_sqrt_rad=model.bearing_rad_per_sqrt_rad,
            heading_rad_per_sqrt_m=model.heading_rad_per_sqrt_m,
        )

    @property
    def is_zero(self) -> bool:
        """Perfect odometry: every term 0."""
        return not any(
            (
                self.distance_scale,
                self.turn_scale,
                self.heading_drift_rad_per_m,
                self.along_m_per_sqrt_m,
                self.lateral_m_per_sqrt_m,
                self.heading_rad_per_sqrt_rad,
                self.heading_rad_per_sqrt_m,
            )
        )


def key_steps(track: PoseTrack, step_m: float = KEY_STEP_M, step_rad: float = KEY_STEP_RAD) -> I64:
    """Indices of the key poses of ``track`` (shape (K,), first and last pose included)."""
    n = len(track)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    turn = np.concatenate([[0.0], wrap_angle(np.diff(track.theta_rad))]).tolist()
    step = np.concatenate([[0.0], np.hypot(np.diff(track.x_m), np.diff(track.y_m))]).tolist()
    keys = [0]
    driven = net = 0.0
    for i in range(1, n):
        driven += step[i]
        net += turn[i]
        if driven >= step_m or abs(net) >= step_rad:
            keys.append(i)
            driven = net = 0.0
    if keys[-1] != n - 1:
        keys.append(n - 1)
    return np.asarray(keys, dtype=np.int64)


def key_increments(track: PoseTrack, keys: I64) -> tuple[F64, F64, F64]:
    """Robot-frame increments (dx, dy, dtheta) between consecutive key poses, shape (K-1,) each;
    dtheta is the net turn (the sum of the wrapped increments), so it may exceed pi."""
    x, y, th = track.x_m[keys], track.y_m[keys], track.theta_rad[keys]
    c, s = np.cos(th[:-1]), np.sin(th[:-1])
    ex, ey = np.diff(x), np.diff(y)
    turns = np.concatenate([[0.0], np.cumsum(wrap_angle(np.diff(track.theta_rad)))])
    return c * ex + s * ey, -s * ex + c * ey, np.diff(turns[keys])


@dataclass(frozen=True)
class PoseUncertainty:
    """The pose covariance at the key poses of a track.

    ``stamp_ns`` (K,), ``x_m``, ``y_m`` (K,): the key poses' stamps and positions (odometry
    frame); ``cov`` (K, 3, 3): covariance of (x_m, y_m, theta_rad), zero at the first pose.
    """

    stamp_ns: I64
    x_m: F64
    y_m: F64
    cov: F64

    @property
    def is_zero(self) -> bool:
        return not bool(np.any(self.cov))

    def at(self, stamp_ns: I64) -> F64:
        """Covariance at ``stamp_ns`` (M,), linear in time between key poses: shape (M, 3, 3)."""
        t = (self.stamp_ns - self.stamp_ns[0]).astype(np.float64)
        q = (np.asarray(stamp_ns) - self.stamp_ns[0]).astype(np.float64)
        flat = self.cov.reshape(-1, 9)
        out = np.empty((q.shape[0], 9))
        for j in range(9):
            out[:, j] = np.interp(q, t, flat[:, j])
        return out.reshape(-1, 3, 3)


def propagate(
    track: PoseTrack,
    noise: StepNoise,
    step_m: float = KEY_STEP_M,
    step_rad: float = KEY_STEP_RAD,
) -> PoseUncertainty:
    """Carry the pose covariance along ``track`` (module docstring); zero at its first pose."""
    keys = key_steps(track, step_m, step_rad)
    k = keys.shape[0]
    cov = np.zeros((k, 3, 3))
    if k == 0:
        return PoseUncertainty(np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0), cov)
    dx, dy, dth = key_increments(track, keys)
    th = track.theta_rad[keys]
    x, y = track.x_m[keys], track.y_m[keys]
    p = np.zeros((6, 6))
    p[3, 3] = noise.distance_scale**2
    p[4, 4] = noise.turn_scale**2
    p[5, 5] = noise.heading_drift_rad_per_m**2
    f = np.eye(6)
    for i in range(k - 1):
        ds = math.hypot(dx[i], dy[i])
        ex, ey = x[i + 1] - x[i], y[i + 1] - y[i]  # the step in the odometry frame
        # Jacobian of the next pose w.r.t. the pose and the systematic errors
        f[0, 2], f[1, 2] = -ey, ex
        f[0, 3], f[1, 3] = ex, ey
        f[2, 4], f[2, 5] = dth[i], ds
        p = f @ p @ f.T
        c, s = math.cos(th[i]), math.sin(th[i])
        qa, ql = noise.along_m_per_sqrt_m**2 * ds, noise.lateral_m_per_sqrt_m**2 * ds
        p[0, 0] += c * c * qa + s * s * ql
        p[0, 1] += c * s * (qa - ql)
        p[1, 0] += c * s * (qa - ql)
        p[1, 1] += s * s * qa + c * c * ql
        p[2, 2] += noise.heading_rad_per_sqrt_rad**2 * abs(dth[i])
        p[2, 2] += noise.heading_rad_per_sqrt_m**2 * ds
        cov[i + 1] = p[:3, :3]
    return PoseUncertainty(track.stamp_ns[keys], x, y, cov)


def project(cov: F64, lever_x_m: F64, lever_y_m: F64, beam_rad: F64) -> tuple[F64, F64]:
    """Standard deviations (metres) of a point's position along and across a beam.

    ``cov`` (M, 3, 3): the robot pose covariance; ``lever_*`` (M,): the point minus the robot's
    position (odometry frame), through which a heading error moves it; ``beam_rad`` (M,): the
    beam's direction. The point moves by J (dx, dy, dtheta) with J = [[1, 0, -ly], [0, 1, lx]].
    """
    jx = np.stack([np.ones_like(lever_x_m), np.zeros_like(lever_x_m), -lever_y_m], axis=1)
    jy = np.stack([np.zeros_like(lever_x_m), np.ones_like(lever_x_m), lever_x_m], axis=1)
    u = np.cos(beam_rad)[:, None] * jx + np.sin(beam_rad)[:, None] * jy  # along the beam
    v = -np.sin(beam_rad)[:, None] * jx + np.cos(beam_rad)[:, None] * jy  # across it
    along = np.einsum("mi,mij,mj->m", u, cov, u)
    across = np.einsum("mi,mij,mj->m", v, cov, v)
    return np.sqrt(np.maximum(along, 0.0)), np.sqrt(np.maximum(across, 0.0))


@dataclass(frozen=True)
class SampledOffsets:
    """Tracks drawn from the noise model, as the rigid motion that takes each nominal key
    pose to the sampled one: a pose owned by key pose k (the last key pose at or before it)
    is moved by ``p -> R(rot_rad[s, k]) p + (tx_m[s, k], ty_m[s, k])`` in sample s.

    ``key_stamp_ns`` (K,); ``rot_rad``, ``tx_m``, ``ty_m`` (S, K). Composing a sensor pose
    with the motion is the same as composing the robot pose and then the mounting, so synced
    readings move as their robot does.
    """

    key_stamp_ns: I64
    rot_rad: F64
    tx_m: F64
    ty_m: F64

    @property
    def count(self) -> int:
        return int(self.rot_rad.shape[0])

    def owner(self, stamp_ns: I64) -> I64:
        """Index of the key pose owning each stamp, shape (M,)."""
        at = np.searchsorted(self.key_stamp_ns, stamp_ns, side="right") - 1
        return np.clip(at, 0, self.key_stamp_ns.shape[0] - 1)


def _key_draws(
    track: PoseTrack,
    noise: StepNoise,
    count: int,
    seed: int,
    antithetic: bool,
    step_m: float,
    step_rad: float,
) -> tuple[I64, list[tuple[F64, F64, F64]]]:
    """The key indices and each sample's key poses (x, y, theta), shape (K,) each.

    With ``antithetic`` the samples come in pairs whose standard-normal draws are negatives
    of each other (the last one alone when ``count`` is odd): a pair's errors cancel to first
    order, so the mean over samples converges faster for the same cost."""
    keys = key_steps(track, step_m, step_rad)
    if keys.shape[0] < 2:
        k = track.x_m[keys], track.y_m[keys], track.theta_rad[keys]
        return keys, [k] * count
    rng = np.random.default_rng(seed)
    dx, dy, dth = key_increments(track, keys)
    ds = np.hypot(dx, dy)
    kx, ky, kth = track.x_m[keys], track.y_m[keys], track.theta_rad[keys]
    heading_sd = np.sqrt(
        noise.heading_rad_per_sqrt_rad**2 * np.abs(dth) + noise.heading_rad_per_sqrt_m**2 * ds
    )
    out = []
    draw: tuple[F64, F64] | None = None
    for i in range(count):
        if antithetic and i % 2 == 1 and draw is not None:
            unit, z = -draw[0], -draw[1]
        else:
            unit, z = rng.normal(0.0, 1.0, 3), rng.normal(0.0, 1.0, (3, ds.shape[0]))
            draw = (unit, z)
        scale = unit * (noise.distance_scale, noise.turn_scale, noise.heading_drift_rad_per_m)
        # robot-frame noise: along-track on dx, lateral on dy (as :func:`propagate`)
        sx = dx * (1.0 + scale[0]) + z[0] * noise.along_m_per_sqrt_m * np.sqrt(ds)
        sy = dy * (1.0 + scale[0]) + z[1] * noise.lateral_m_per_sqrt_m * np.sqrt(ds)
        sth = dth * (1.0 + scale[1]) + scale[2] * ds + z[2] * heading_sd
        out.append(_integrate(kx[0], ky[0], kth[0], sx, sy, sth))
    return keys, out


def sample_offsets(
    track: PoseTrack,
    noise: StepNoise,
    count: int,
    seed: int = 0,
    antithetic: bool = False,
    step_m: float = KEY_STEP_M,
    step_rad: float = KEY_STEP_RAD,
) -> SampledOffsets:
    """``count`` tracks drawn as :func:`sample_tracks` draws them (the same draws for the same
    seed), as rigid motions of the nominal key poses (:class:`SampledOffsets`)."""
    keys, draws = _key_draws(track, noise, count, seed, antithetic, step_m, step_rad)
    kx, ky, kth = track.x_m[keys], track.y_m[keys], track.theta_rad[keys]
    rot = np.empty((count, keys.shape[0]))
    tx, ty = np.empty_like(rot), np.empty_like(rot)
    for i, (px, py, pth) in enumerate(draws):
        rot[i] = pth - kth
        c, s = np.cos(rot[i]), np.sin(rot[i])
        tx[i] = px - (c * kx - s * ky)
        ty[i] = py - (s * kx + c * ky)
    return SampledOffsets(track.stamp_ns[keys], rot, tx, ty)


def sample_tracks(
    track: PoseTrack,
    noise: StepNoise,
    count: int,
    seed: int = 0,
    step_m: float = KEY_STEP_M,
    step_rad: float = KEY_STEP_RAD,
) -> list[PoseTrack]:
    """``count`` tracks drawn from the noise model :func:`propagate` carries: each draws its
    systematic errors once and a random error per key step, composes the key steps again, and
    moves every pose between two key poses with the key pose before it. Same stamps as
    ``track``; the first pose is unchanged."""
    keys, draws = _key_draws(track, noise, count, seed, False, step_m, step_rad)
    if keys.shape[0] < 2:
        return [track] * count
    kx, ky, kth = track.x_m[keys], track.y_m[keys], track.theta_rad[keys]
    # every pose relative to the key pose at or before it
    owner = np.searchsorted(keys, np.arange(len(track)), side="right") - 1
    c, s = np.cos(kth[owner]), np.sin(kth[owner])
    ex, ey = track.x_m - kx[owner], track.y_m - ky[owner]
    rx, ry = c * ex + s * ey, -s * ex + c * ey
    rth = track.theta_rad - kth[owner]
    out = []
    for px, py, pth in draws:
        co, so = np.cos(pth[owner]), np.sin(pth[owner])
        out.append(
            PoseTrack(
                stamp_ns=track.stamp_ns,
                x_m=px[owner] + co * rx - so * ry,
                y_m=py[owner] + so * rx + co * ry,
                theta_rad=wrap_angle(pth[owner] + rth),
            )
        )
    return out


def _integrate(
    x0: float, y0: float, th0: float, dx: F64, dy: F64, dth: F64
) -> tuple[F64, F64, F64]:
    """Key poses from a start pose and robot-frame increments, shape (K,) each."""
    th = th0 + np.concatenate([[0.0], np.cumsum(dth)])
    c, s = np.cos(th[:-1]), np.sin(th[:-1])
    x = x0 + np.concatenate([[0.0], np.cumsum(c * dx - s * dy)])
    y = y0 + np.concatenate([[0.0], np.cumsum(s * dx + c * dy)])
    return x, y, th
