"""The random walks checked on the log's own revisits (poses/calibration/revisit_check.py)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import numpy.typing as npt
from scipy.stats import chi2

from gridmap_cli.geometry import compose, inverse
from gridmap_cli.poses.calibration.revisit_check import revisit_factor, small_sample_factor
from gridmap_cli.poses.correction.loop_closure import Closure
from gridmap_cli.poses.uncertainty.pose_uncertainty import StepNoise
from gridmap_cli.records import PoseTrack

F64 = npt.NDArray[np.float64]
STEP_M = 0.2


def laps(count: int) -> F64:
    """Poses (N, 3) every STEP_M around a 10 x 6 m rectangle, ``count`` times."""
    corners = [(0.0, 0.0), (10.0, 0.0), (10.0, 6.0), (0.0, 6.0), (0.0, 0.0)]
    rows = []
    for _ in range(count):
        for (ax, ay), (bx, by) in itertools.pairwise(corners):
            n = round(math.hypot(bx - ax, by - ay) / STEP_M)
            heading = math.atan2(by - ay, bx - ax)
            rows += [(ax + (bx - ax) * k / n, ay + (by - ay) * k / n, heading) for k in range(n)]
    return np.array(rows)


def odometry_of(truth: F64, heading_error: F64) -> PoseTrack:
    """The truth's steps driven with the heading off by ``heading_error`` (N,) at each pose."""
    ix, iy, ith = inverse(truth[:-1, 0], truth[:-1, 1], truth[:-1, 2])
    dx, dy, _ = compose(ix, iy, ith, truth[1:, 0], truth[1:, 1], truth[1:, 2])
    heading = truth[:, 2] + heading_error
    c, s = np.cos(heading[:-1]), np.sin(heading[:-1])
    x = np.concatenate([[0.0], np.cumsum(c * dx - s * dy)])
    y = np.concatenate([[0.0], np.cumsum(s * dx + c * dy)])
    stamps = np.arange(truth.shape[0], dtype=np.int64) * 400_000_000
    return PoseTrack(stamp_ns=stamps, x_m=x, y_m=y, theta_rad=heading)


def revisits(truth: F64, per_lap: int) -> list[Closure]:
    """Closures as the search gives them (node j, the earlier, in node i's frame) from the
    truth, between each pose of the first lap and the same place on the later laps."""
    out = []
    for j in range(0, per_lap, 10):
        for i in range(j + per_lap, truth.shape[0], per_lap):
            ix, iy, ith = inverse(truth[i, 0], truth[i, 1], truth[i, 2])
            rx, ry, rth = compose(ix, iy, ith, truth[j, 0], truth[j, 1], truth[j, 2])
            out.append(Closure(i, j, float(rx), float(ry), float(rth), 1.0))
    return out


WALK = StepNoise(heading_rad_per_sqrt_m=0.02)


def test_an_error_that_comes_back_is_seen_narrower_than_the_walk_predicts() -> None:
    truth = laps(3)
    per_lap = truth.shape[0] // 3
    # a heading error that wanders 5 degrees and comes back four times a lap: the odometry
    # strays between the revisits, and is where it was a lap later
    wobble = np.radians(5.0) * np.sin(8 * np.pi * np.arange(truth.shape[0]) / per_lap)
    odometry = odometry_of(truth, wobble)
    assert np.hypot(odometry.x_m - truth[:, 0], odometry.y_m - truth[:, 1]).max() > 0.1
    nodes = np.arange(truth.shape[0], dtype=np.intp)
    found = revisit_factor(odometry, nodes, revisits(truth, per_lap), WALK, 0.01, 0.001)
    assert found.revisits == len(revisits(truth, per_lap))
    assert found.factor < 0.5


def test_an_error_that_grows_is_seen_wider_and_the_factor_follows_the_walk() -> None:
    truth = laps(3)
    per_lap = truth.shape[0] // 3
    # a heading drift of 1 degree per metre: the revisits a lap and two later are far apart
    drift = np.radians(1.0) * STEP_M * np.arange(truth.shape[0])
    odometry = odometry_of(truth, drift)
    nodes = np.arange(truth.shape[0], dtype=np.intp)
    closures = revisits(truth, per_lap)
    found = revisit_factor(odometry, nodes, closures, WALK, 0.0, 0.0)
    assert found.factor > 2.0
    # without the registration's jitter the factor is inversely proportional to the walk
    wider = revisit_factor(odometry, nodes, closures, StepNoise(heading_rad_per_sqrt_m=0.04),
                           0.0, 0.0)  # fmt: skip
    assert math.isclose(wider.factor, found.factor / 2.0, rel_tol=1e-9)


def test_no_revisit_says_nothing() -> None:
    truth = laps(2)
    odometry = odometry_of(truth, np.zeros(truth.shape[0]))
    nodes = np.arange(truth.shape[0], dtype=np.intp)
    found = revisit_factor(odometry, nodes, [], WALK, 0.01, 0.001)
    assert math.isnan(found.factor) and found.revisits == 0


def test_a_few_revisits_of_an_error_that_comes_back_cut_the_walk() -> None:
    truth = laps(2)
    per_lap = truth.shape[0] // 2
    wobble = np.radians(5.0) * np.sin(8 * np.pi * np.arange(truth.shape[0]) / per_lap)
    odometry = odometry_of(truth, wobble)
    nodes = np.arange(truth.shape[0], dtype=np.intp)
    found = revisit_factor(odometry, nodes, revisits(truth, per_lap)[:3], WALK, 0.01, 0.001)
    assert found.revisits == 3
    assert found.factor < 0.5


def test_the_few_revisits_factor_is_the_scale_posterior_median() -> None:
    rng = np.random.default_rng(3)
    nees = rng.chisquare(2, size=5) * 0.3**2
    # the sum of n chi-square(2) scaled by f^2: half of the scale's posterior lies below
    expected = math.sqrt(float(nees.sum()) / float(chi2.median(2 * nees.shape[0])))
    assert math.isclose(small_sample_factor(nees), expected, rel_tol=1e-12)
    # one revisit: the median rule of many, on the one there is
    one = nees[:1]
    assert math.isclose(small_sample_factor(one), math.sqrt(one[0] / (2 * math.log(2))))
    # many revisits of one scale: the estimate comes to that scale
    many = rng.chisquare(2, size=4000) * 0.3**2
    assert abs(small_sample_factor(many) - 0.3) < 0.01
