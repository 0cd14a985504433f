"""Does a calibration predict its own half's error at the lengths a map uses?

The random walks come from windows of 1 to 50 times the calibration window, compared through
what no frame changes. A map made from the odometry spreads each reading by the pose error
grown from its first pose, over the whole log: hundreds of metres. A heading error of the
reference that wanders (a SLAM track's heading, not its positions) passes for a random walk of
the odometry in the window fit, and extrapolated over a map's lengths it predicts metres of
position error that the odometry's positions never show.

So the fit is checked on the positions: from every key pose of the calibration track, the
corrected odometry is placed at the reference pose and its position error after ``H`` metres
is compared with the covariance the random walks predict (:class:`SegmentCovariance`, exactly
what :func:`~gridmap_cli.poses.uncertainty.pose_uncertainty.propagate` carries with the systematic
terms at 0, plus the reference's jitter at both ends). The normalised squared error (NEES) of a
consistent model has the median of a chi-square with 2 degrees of freedom, ``2 ln 2``; the
square root of the median NEES over the long horizons over that is the factor by which the
random walks mispredict.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from gridmap_cli.geometry import wrap_angle
from gridmap_cli.poses.odometry_error import travelled
from gridmap_cli.poses.uncertainty.pose_uncertainty import StepNoise, key_increments, key_steps
from gridmap_cli.records import PoseTrack

F64 = npt.NDArray[np.float64]

#: Median of a chi-square with 2 degrees of freedom.
CHI2_2_MEDIAN = 2.0 * math.log(2.0)
#: The horizons checked, in calibration windows: long ones, where the random walks (not the
#: reference's jitter) make the error.
HORIZONS = (20.0, 50.0, 100.0, 200.0, 500.0)
#: A horizon counts when this many starts reach it.
MIN_STARTS = 8


def _prefix(values: F64) -> F64:
    """Running sums along the first axis with a leading zero (shape (K,) + rest)."""
    zero = np.zeros((1, *values.shape[1:]))
    return np.concatenate([zero, np.cumsum(values, axis=0)])


class SegmentCovariance:
    """The position covariance the random walks of ``noise`` grow between any two key poses of
    ``track`` (``keys``, :func:`~gridmap_cli.poses.uncertainty.pose_uncertainty.key_steps`), in
    closed form: a step's position noise is added at its end, and its heading noise moves every
    later key pose about that end, so running sums over the steps give any segment's covariance at
    once. The same numbers :func:`~gridmap_cli.poses.uncertainty.pose_uncertainty.propagate`
    carries from the segment's first pose with the systematic terms at 0."""

    def __init__(self, track: PoseTrack, keys: npt.NDArray[np.int64], noise: StepNoise) -> None:
        dx, dy, dth = key_increments(track, keys)
        ds = np.hypot(dx, dy)
        th = track.theta_rad[keys]
        self.x, self.y = track.x_m[keys], track.y_m[keys]
        c, s = np.cos(th[:-1]), np.sin(th[:-1])
        qa = noise.along_m_per_sqrt_m**2 * ds
        ql = noise.lateral_m_per_sqrt_m**2 * ds
        pos = np.stack(
            [c * c * qa + s * s * ql, c * s * (qa - ql), s * s * qa + c * c * ql], axis=1
        )
        w = noise.heading_rad_per_sqrt_rad**2 * np.abs(dth) + noise.heading_rad_per_sqrt_m**2 * ds
        x1, y1 = self.x[1:], self.y[1:]
        self._pos = _prefix(pos)
        self._w = _prefix(w)
        self._wx, self._wy = _prefix(w * x1), _prefix(w * y1)
        self._wxx, self._wxy = _prefix(w * x1 * x1), _prefix(w * x1 * y1)
        self._wyy = _prefix(w * y1 * y1)

    def between(
        self, start: npt.NDArray[np.int64], end: npt.NDArray[np.int64]
    ) -> tuple[F64, F64, F64]:
        """Covariance (xx, xy, yy), shape (M,) each, of key pose ``end`` given key pose
        ``start`` (key indices, ``start <= end``), odometry frame."""
        xe, ye = self.x[end], self.y[end]
        a = self._w[end] - self._w[start]
        bx, by = self._wx[end] - self._wx[start], self._wy[end] - self._wy[start]
        cxx, cxy = self._wxx[end] - self._wxx[start], self._wxy[end] - self._wxy[start]
        cyy = self._wyy[end] - self._wyy[start]
        # the sum of w (p_e - p) (p_e - p)^T, then turned by 90 degrees (a heading error moves
        # a point across its lever): [[yy, -xy], [-xy, xx]]
        mxx = a * xe * xe - 2 * xe * bx + cxx
        mxy = a * xe * ye - xe * by - ye * bx + cxy
        myy = a * ye * ye - 2 * ye * by + cyy
        pp = self._pos[end] - self._pos[start]
        return pp[:, 0] + myy, pp[:, 1] - mxy, pp[:, 2] + mxx


def nees_and_determinant(
    grown: SegmentCovariance,
    start: npt.NDArray[np.int64],
    end: npt.NDArray[np.int64],
    error: tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]],
    length: tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]],
    jitter_m: float,
    jitter_rad: float,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """The position ``error`` of each segment ``start`` -> ``end`` (vector ``length``) whitened
    by the covariance the walks grow along it plus the jitter of what it is compared with (its
    heading turns the far end about the near one; its position is off at both ends), and that
    covariance's determinant, which a likelihood of the errors needs beside their normalised
    squares; segments whose covariance is singular are left out of both."""
    ex, ey = error
    lx, ly = length
    sxx, sxy, syy = grown.between(start, end)
    jr, jm = jitter_rad**2, 2.0 * jitter_m**2
    sxx, sxy, syy = sxx + jr * ly * ly + jm, sxy - jr * lx * ly, syy + jr * lx * lx + jm
    det = sxx * syy - sxy * sxy
    ok = det > 0.0
    quad = syy * ex * ex - 2 * sxy * ex * ey + sxx * ey * ey
    nees: npt.NDArray[np.float64] = quad[ok] / det[ok]
    return nees, det[ok]


def consistency(
    odometry: PoseTrack,
    truth: PoseTrack,
    noise: StepNoise,
    jitter_m: float,
    jitter_rad: float,
    step_m: float,
    step_rad: float,
) -> tuple[float, int]:
    """The factor (actual / predicted standard deviation of the position error, the median
    over the long horizons) and how many (start, horizon) pairs it rests on; (nan, 0) when no
    horizon is reached from :data:`MIN_STARTS` starts. ``odometry`` is corrected already; both
    tracks at the same stamps (N,)."""
    keys = key_steps(odometry, step_m, step_rad)
    if keys.shape[0] < 3 or noise.is_zero:
        return math.nan, 0
    grown = SegmentCovariance(odometry, keys, noise)
    px, py = grown.x, grown.y
    dist, _ = travelled(truth)
    kd = dist[keys]
    # the reference's motion from each key pose, turned into the odometry's frame there
    rot = wrap_angle(odometry.theta_rad[keys] - truth.theta_rad[keys])
    tx, ty = truth.x_m[keys], truth.y_m[keys]
    ratios: list[float] = []
    pairs = 0
    for h in HORIZONS:
        end = np.searchsorted(kd, kd + h * step_m, side="left")
        start = np.flatnonzero(end < keys.shape[0])
        if start.shape[0] < MIN_STARTS:
            continue
        e = end[start]
        cr, sr = np.cos(rot[start]), np.sin(rot[start])
        rx, ry = tx[e] - tx[start], ty[e] - ty[start]
        ex = (px[e] - px[start]) - (cr * rx - sr * ry)
        ey = (py[e] - py[start]) - (sr * rx + cr * ry)
        # the reference's jitter: its heading at the start turns the whole segment about it,
        # its position is off at both ends
        nees, _ = nees_and_determinant(
            grown, start, e, (ex, ey), (px[e] - px[start], py[e] - py[start]), jitter_m, jitter_rad
        )
        if nees.shape[0] < MIN_STARTS:
            continue
        ratios.append(math.sqrt(float(np.median(nees)) / CHI2_2_MEDIAN))
        pairs += int(nees.shape[0])
    if not ratios:
        return math.nan, 0
    return float(np.median(ratios)), pairs
