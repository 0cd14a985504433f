"""calibrate's check of the random walks on the positions, at a map's lengths."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from gridmap_cli.poses.calibration.calibrate import calibrate_tracks, checked
from gridmap_cli.poses.calibration.consistency import SegmentCovariance, consistency
from gridmap_cli.poses.calibration.windows import truth_at_odometry
from gridmap_cli.poses.odometry_error import correct_track
from gridmap_cli.poses.uncertainty.pose_uncertainty import StepNoise, key_steps, propagate
from gridmap_cli.readers import read_log
from gridmap_cli.records import PoseTrack

SAMPLE = Path(__file__).resolve().parents[1] / "samples" / "corridor_loop.csv"


@pytest.fixture(scope="module")
def tracks():  # type: ignore[no-untyped-def]
    return truth_at_odometry(read_log(SAMPLE))


def test_factor_is_inverse_to_the_noise(tracks) -> None:  # type: ignore[no-untyped-def]
    """Without jitter the predicted covariance scales with the walks' variances, so a model
    twice as noisy reads half the factor: the check compares errors with the covariance."""
    odometry, truth = tracks
    noise = StepNoise(along_m_per_sqrt_m=0.01, heading_rad_per_sqrt_rad=0.02)
    twice = StepNoise(along_m_per_sqrt_m=0.02, heading_rad_per_sqrt_rad=0.04)
    f1, n1 = consistency(odometry, truth, noise, 0.0, 0.0, 1.0, math.pi / 2)
    f2, n2 = consistency(odometry, truth, twice, 0.0, 0.0, 1.0, math.pi / 2)
    assert n1 == n2 > 0
    assert f2 == pytest.approx(f1 / 2, rel=1e-9)


def test_no_noise_no_check(tracks) -> None:  # type: ignore[no-untyped-def]
    odometry, truth = tracks
    factor, pairs = consistency(odometry, truth, StepNoise(), 0.0, 0.0, 1.0, math.pi / 2)
    assert math.isnan(factor) and pairs == 0


def test_a_weak_walk_that_overpredicts_is_cut(tracks) -> None:  # type: ignore[no-untyped-def]
    """Walks ten times the fitted ones over-predict the track's own error: the windows could
    not show them (standard errors as large as they are), so they come down by the factor;
    the same walks shown by the windows (tiny standard errors) stand."""
    odometry, truth = tracks
    cal = calibrate_tracks(odometry, truth)
    assert cal is not None
    m = cal.model
    loud = dataclasses.replace(
        m,
        range_m_per_sqrt_m=10 * m.range_m_per_sqrt_m,
        bearing_rad_per_sqrt_rad=10 * max(m.bearing_rad_per_sqrt_rad, 0.01),
    )
    weak = dataclasses.replace(cal, model=loud, walk_variance_se=(1.0, 1.0, 1.0))
    cut = checked(weak, odometry, truth)
    assert cut.consistency < 0.5
    assert cut.walk_checked[:2] == (True, True)
    assert cut.model.range_m_per_sqrt_m == pytest.approx(loud.range_m_per_sqrt_m * cut.consistency)
    assert cut.model.distance_scale_bias == loud.distance_scale_bias  # biases untouched
    strong = dataclasses.replace(cal, model=loud, walk_variance_se=(0.0, 0.0, 0.0))
    kept = checked(strong, odometry, truth)
    assert kept.model == loud and kept.walk_checked == (False, False, False)
    # the factor is measured on the corrected track
    again, _ = consistency(
        correct_track(odometry, loud), truth, StepNoise.of(loud.random_part()),
        cal.jitter_m, cal.jitter_rad, cal.window_m, cal.window_rad,
    )  # fmt: skip
    assert cut.consistency == pytest.approx(again)


def test_never_raised(tracks) -> None:  # type: ignore[no-untyped-def]
    """Walks a hundredth of the fitted ones under-predict: nothing is raised."""
    odometry, truth = tracks
    cal = calibrate_tracks(odometry, truth)
    assert cal is not None
    quiet = dataclasses.replace(
        cal.model,
        range_m_per_sqrt_m=cal.model.range_m_per_sqrt_m / 100,
        bearing_rad_per_sqrt_rad=0.0001,
    )
    out = checked(dataclasses.replace(cal, model=quiet, walk_variance_se=(1.0, 1.0, 1.0)),
                  odometry, truth)  # fmt: skip
    assert out.consistency > 1.0
    assert out.model == quiet and out.random_walk_scale == 1.0


def test_closed_form_is_propagate(tracks) -> None:  # type: ignore[no-untyped-def]
    """The running sums give the covariance the pose uncertainty carries step by step, from the
    first key pose and from one further on."""
    odometry, _ = tracks
    noise = StepNoise(
        along_m_per_sqrt_m=0.02,
        lateral_m_per_sqrt_m=0.01,
        heading_rad_per_sqrt_rad=0.015,
        heading_rad_per_sqrt_m=0.004,
    )
    keys = key_steps(odometry)
    grown = SegmentCovariance(odometry, keys, noise)
    last = keys.shape[0] - 1
    for first in (0, last // 3):
        k = int(keys[first])
        part = PoseTrack(
            odometry.stamp_ns[k:], odometry.x_m[k:], odometry.y_m[k:], odometry.theta_rad[k:]
        )
        expected = propagate(part, noise).cov[-1]
        sxx, sxy, syy = grown.between(np.array([first]), np.array([last]))
        assert float(sxx[0]) == pytest.approx(expected[0, 0], rel=1e-9)
        assert float(sxy[0]) == pytest.approx(expected[0, 1], rel=1e-9, abs=1e-12)
        assert float(syy[0]) == pytest.approx(expected[1, 1], rel=1e-9)
