"""The random walks checked at a map's lengths on the log's own revisits.

A random walk fitted over windows of tens of metres, extrapolated over a whole log, predicts a
spread that grows without end; an error that wanders and comes back (a heading error that
reverts) passes the windows and the scan-to-scan check alike, whose own drift is as large.
Where the robot comes back to a place, far along its path, the pose graph's closure search
(:mod:`~gridmap_cli.poses.correction.loop_closure`) registers the second visit's scans on the
first's: the relative pose of the two, as the scans see it, with no drift in between. The
odometry the map uses (the file's biases corrected) is compared with it, against the position
covariance the walks predict for the travel between the two visits
(:class:`~.consistency.SegmentCovariance`, plus the scan registration's jitter at the far end):
the same normalised squared error and the same factor as the check on the positions
(:mod:`.consistency`), at exactly the horizons where the map suffers.

A log that comes back to a place only a few times still says something about the walks: with
fewer revisits than a robust median needs (:data:`~.consistency.MIN_STARTS`), the factor is
the median of the scale's posterior instead, under the Gaussian model the walks themselves
assume (:func:`small_sample_factor`). The two err the same way: the walks are only ever cut,
and a spread cut too far costs a map little where one too wide blurs it (docs/odometry-error.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.special import gammaincinv

from gridmap_cli.geometry import inverse
from gridmap_cli.poses.calibration.consistency import (
    CHI2_2_MEDIAN,
    MIN_STARTS,
    SegmentCovariance,
    nees_and_determinant,
)
from gridmap_cli.poses.correction.loop_closure import Closure
from gridmap_cli.poses.uncertainty.pose_uncertainty import StepNoise
from gridmap_cli.records import PoseTrack

F64 = npt.NDArray[np.float64]


@dataclass(frozen=True)
class RevisitFactor:
    """Actual over predicted standard deviation of the odometry's position error on the
    revisits (NaN: none to check on), and how many it rests on."""

    factor: float
    revisits: int
    #: The sum of the logarithms of the covariances' determinants the revisits were whitened
    #: by (m**4): the part of their likelihood the factor does not hold.
    log_determinant: float = 0.0


def revisit_factor(
    odometry: PoseTrack,
    keyframes: npt.NDArray[np.intp],
    closures: list[Closure],
    noise: StepNoise,
    jitter_m: float,
    jitter_rad: float,
) -> RevisitFactor:
    """The factor on ``closures`` (node ``j``'s pose in node ``i``'s frame, the nodes indices
    into ``keyframes``, these into ``odometry``): ``odometry`` is the corrected odometry at the
    scans' stamps."""
    if not closures or noise.is_zero:
        return RevisitFactor(math.nan, len(closures))
    node_i = keyframes[np.array([c.i for c in closures], dtype=np.intp)]
    node_j = keyframes[np.array([c.j for c in closures], dtype=np.intp)]
    start, end = np.minimum(node_i, node_j), np.maximum(node_i, node_j)
    rel = np.array([(c.dx_m, c.dy_m, c.dtheta_rad) for c in closures])
    # a closure places node j in node i's frame; the end's pose in the start's frame is that,
    # or its inverse when node j is the earlier one
    rx, ry, _ = inverse(rel[:, 0], rel[:, 1], rel[:, 2])
    direct = node_i < node_j
    rx, ry = np.where(direct, rel[:, 0], rx), np.where(direct, rel[:, 1], ry)
    keys = np.arange(len(odometry), dtype=np.int64)
    grown = SegmentCovariance(odometry, keys, noise)
    px, py, th = odometry.x_m, odometry.y_m, odometry.theta_rad
    c, s = np.cos(th[start]), np.sin(th[start])
    ex = (px[end] - px[start]) - (c * rx - s * ry)
    ey = (py[end] - py[start]) - (s * rx + c * ry)
    # the jitter is the registration's own error
    nees, det = nees_and_determinant(
        grown,
        start.astype(np.int64),
        end.astype(np.int64),
        (ex, ey),
        (px[end] - px[start], py[end] - py[start]),
        jitter_m,
        jitter_rad,
    )
    if nees.shape[0] == 0:
        return RevisitFactor(math.nan, 0)
    n, log_det = int(nees.shape[0]), float(np.sum(np.log(det)))
    if n < MIN_STARTS:
        return RevisitFactor(small_sample_factor(nees), n, log_det)
    return RevisitFactor(math.sqrt(float(np.median(nees)) / CHI2_2_MEDIAN), n, log_det)


def small_sample_factor(nees: F64) -> float:
    """The factor from a few revisits' normalised squared errors (shape (n,), n >= 1): if the
    odometry's error is the walks' prediction times a scale ``f``, their sum is ``f^2`` times a
    chi-square with ``2 n`` degrees of freedom; with the scale-free prior (``1 / f^2``) the
    posterior of ``f^2`` is then ``sum / chi2(2 n)``, and the factor is its median,
    ``sqrt(sum / median(chi2(2 n)))``. For many revisits it tends to the mean's estimate."""
    n = int(nees.shape[0])
    chi2_median = 2.0 * float(gammaincinv(n, 0.5))
    return math.sqrt(float(np.sum(nees)) / chi2_median)


def likelihood_ratio(corrected: RevisitFactor, uncorrected: RevisitFactor) -> float:
    """``2 ln`` of the likelihood ratio of the uncorrected track over the corrected one on the
    same revisits: positive when the revisits fit the track better without the correction,
    about a chi-square with one degree of freedom when the two are worth the same; 0 without
    revisits to compare on. Each track is whitened by the covariance its own walks grow along
    it (a track a scale correction shrinks predicts a smaller spread), so the likelihood holds
    the covariances' determinants beside the errors: with ``n`` revisits of two degrees of
    freedom each and the walks' scale unknown (its maximum-likelihood value taken in each),
    ``-2 ln L = 2 n ln S + sum ln det`` up to a constant, ``S`` the sum of normalised squared
    errors, which goes as the factor squared; so the statistic is
    ``4 n ln(f_corrected / f_uncorrected) + sum ln det_corrected - sum ln det_uncorrected``."""
    a, b = corrected.factor, uncorrected.factor
    same = corrected.revisits == uncorrected.revisits
    if not (same and math.isfinite(a) and math.isfinite(b) and a > 0.0 and b > 0.0):
        return 0.0
    return (
        4.0 * corrected.revisits * math.log(a / b)
        + corrected.log_determinant
        - uncorrected.log_determinant
    )
