"""The pose covariance carried along a track, its projection, and tracks sampled from it."""

from __future__ import annotations

import math

import numpy as np

from gridmap_cli.geometry import wrap_angle
from gridmap_cli.poses.odometry_error import OdometryError
from gridmap_cli.poses.uncertainty.pose_uncertainty import (
    StepNoise,
    key_steps,
    project,
    propagate,
    sample_offsets,
    sample_tracks,
)
from gridmap_cli.records import PoseTrack


def straight(n: int = 201, length_m: float = 20.0, wiggle_rad: float = 0.0) -> PoseTrack:
    x = np.linspace(0.0, length_m, n)
    theta = wiggle_rad * (-1.0) ** np.arange(n)
    stamps = (np.arange(n) * 100_000_000).astype(np.int64)
    return PoseTrack(stamps, x, np.zeros(n), theta)


def test_perfect_odometry_has_no_spread() -> None:
    u = propagate(straight(), StepNoise.of(OdometryError()))
    assert u.is_zero


def test_heading_drift_becomes_lateral_error_quadratic_in_distance() -> None:
    c = 0.01  # rad/m, systematic: lateral error c d^2 / 2
    u = propagate(straight(), StepNoise(heading_drift_rad_per_m=c))
    final = u.cov[-1]
    assert math.isclose(math.sqrt(final[2, 2]), c * 20.0, rel_tol=1e-9)
    # to the key steps (1 m): the heading error of a step turns the steps after it
    assert math.isclose(math.sqrt(final[1, 1]), c * 20.0 * 19.0 / 2, rel_tol=1e-6)
    assert final[0, 0] < 1e-12  # along-track: nothing


def test_heading_noise_grows_with_the_net_turn_not_the_wiggle() -> None:
    noise = StepNoise(heading_rad_per_sqrt_rad=0.1)
    wiggly = propagate(straight(wiggle_rad=0.05), noise)
    # 200 steps of 0.1 rad each would sum to 20 rad of turning; the net turn is nil
    assert wiggly.cov[-1, 2, 2] < 0.1**2 * 0.5
    assert len(key_steps(straight(wiggle_rad=0.05))) < 100


def test_projection_through_the_lever_arm() -> None:
    cov = np.zeros((1, 3, 3))
    cov[0, 2, 2] = 0.01**2  # heading only
    # a point 10 m ahead along the beam moves across it by 10 m * 0.01 rad
    along, across = project(cov, np.array([10.0]), np.array([0.0]), np.array([0.0]))
    assert along[0] < 1e-12 and math.isclose(across[0], 0.1, rel_tol=1e-12)


def test_sampled_tracks_scatter_as_the_covariance_says() -> None:
    noise = StepNoise(
        distance_scale=0.02, heading_drift_rad_per_m=0.005, along_m_per_sqrt_m=0.05,
        heading_rad_per_sqrt_m=0.01,
    )  # fmt: skip
    track = straight()
    u = propagate(track, noise)
    tracks = sample_tracks(track, noise, 2000, seed=3)
    end = np.array([[t.x_m[-1], t.y_m[-1], t.theta_rad[-1]] for t in tracks])
    empirical = np.cov(end.T)
    for i in range(3):
        assert math.isclose(empirical[i, i], u.cov[-1, i, i], rel_tol=0.15), i
    assert all(t.x_m[0] == track.x_m[0] for t in tracks)


def test_sampled_offsets_move_the_track_as_the_sampled_tracks() -> None:
    noise = StepNoise(
        distance_scale=0.02, heading_drift_rad_per_m=0.005, along_m_per_sqrt_m=0.05,
        lateral_m_per_sqrt_m=0.03, heading_rad_per_sqrt_m=0.01,
    )  # fmt: skip
    track = straight(wiggle_rad=0.01)
    tracks = sample_tracks(track, noise, 5, seed=4)
    offsets = sample_offsets(track, noise, 5, seed=4)
    k = offsets.owner(track.stamp_ns)
    for s, sampled in enumerate(tracks):
        c, sn = np.cos(offsets.rot_rad[s][k]), np.sin(offsets.rot_rad[s][k])
        x = c * track.x_m - sn * track.y_m + offsets.tx_m[s][k]
        y = sn * track.x_m + c * track.y_m + offsets.ty_m[s][k]
        assert np.allclose(x, sampled.x_m, atol=1e-9) and np.allclose(y, sampled.y_m, atol=1e-9)
        turned = wrap_angle(track.theta_rad + offsets.rot_rad[s][k] - sampled.theta_rad)
        assert np.allclose(turned, 0.0, atol=1e-9)


def test_antithetic_pairs_mirror_their_errors() -> None:
    # with a distance scale error only, a track is the nominal one stretched by (1 + s); the
    # pair's partner is stretched by (1 - s): their end points straddle the nominal one
    track = straight()
    offsets = sample_offsets(track, StepNoise(distance_scale=0.05), 4, seed=1, antithetic=True)
    ends = offsets.tx_m[:, -1] + track.x_m[-1] * np.cos(offsets.rot_rad[:, -1])
    assert np.all(np.abs(ends - track.x_m[-1]) > 1e-6)
    assert np.allclose(ends[0::2] - track.x_m[-1], -(ends[1::2] - track.x_m[-1]), atol=1e-9)
