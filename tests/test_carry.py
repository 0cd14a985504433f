"""Carrying anchor corrections along a denser track (gridmap_cli/poses/correction/carry.py)."""

from __future__ import annotations

import math

import numpy as np

from gridmap_cli.geometry import compose, wrap_angle
from gridmap_cli.poses.correction.carry import carry


def _line(n: int, far_m: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A straight drive along x, ``far_m`` from the frame's origin in y."""
    x = np.linspace(0.0, 4.0, n)
    return x, np.full(n, far_m), np.zeros(n)


def test_passes_through_the_anchors_and_keeps_the_base_between_equal_corrections() -> None:
    stamps = np.arange(41, dtype=np.int64) * 100_000_000
    base = _line(41, far_m=50.0)
    anchors = np.array([0, 10, 20, 40])
    # the same rigid frame change at every anchor: every pose gets exactly that change
    frame = (1.0, -2.0, math.radians(30.0))
    fixed = compose(*frame, *(b[anchors] for b in base))
    x, y, th = carry(stamps, base, stamps[anchors], tuple(b[anchors] for b in base), fixed)
    ex, ey, eth = compose(*frame, *base)
    np.testing.assert_allclose(x, ex, atol=1e-9)
    np.testing.assert_allclose(y, ey, atol=1e-9)
    np.testing.assert_allclose(wrap_angle(th - eth), 0.0, atol=1e-12)


def test_spreads_the_correction_by_motion_not_time() -> None:
    # the base stands still for the first half of the gap, then drives 1 m
    stamps = np.arange(11, dtype=np.int64) * 100_000_000
    bx = np.concatenate([np.zeros(6), np.linspace(0.2, 1.0, 5)])
    base = (bx, np.zeros(11), np.zeros(11))
    anchors = np.array([0, 10])
    fixed = (np.array([0.0, 1.2]), np.array([0.0, 0.0]), np.array([0.0, 0.0]))
    x, _, _ = carry(stamps, base, stamps[anchors], (bx[anchors], *(np.zeros(2),) * 2), fixed)
    # standing still: no share of the 0.2 m the odometry missed yet
    np.testing.assert_allclose(x[:6], 0.0, atol=1e-12)
    assert x[-1] == 1.2
    # driving: the missed 0.2 m comes in step with the motion
    np.testing.assert_allclose(x[6:], bx[6:] * 1.2, atol=1e-9)


def test_a_heading_correction_far_from_the_origin_does_not_swing_the_pose() -> None:
    # 50 m from the frame's origin, the second anchor's heading is corrected by 10 degrees
    stamps = np.arange(21, dtype=np.int64) * 100_000_000
    base = _line(21, far_m=50.0)
    anchors = np.array([0, 20])
    ab = tuple(b[anchors] for b in base)
    fixed = (ab[0], ab[1], np.array([0.0, math.radians(10.0)]))
    x, y, _ = carry(stamps, base, stamps[anchors], ab, fixed)
    # both predictions lie near the line; the blend never leaves it by more than the arm
    # of the turn over the 4 m driven (a frame-change blend swings ~50 m * 10 deg^2 / 8 off)
    assert np.abs(y - 50.0).max() < 4.0 * math.radians(10.0)
    assert np.all(np.diff(x) > 0)


def test_before_the_first_and_after_the_last_anchor_the_nearest_carries_rigidly() -> None:
    stamps = np.arange(30, dtype=np.int64) * 100_000_000
    base = _line(30)
    anchors = np.array([10, 20])
    ab = tuple(b[anchors] for b in base)
    fixed = (ab[0] + np.array([0.5, -0.5]), ab[1] + np.array([0.1, 0.3]), ab[2])
    x, y, _ = carry(stamps, base, stamps[anchors], ab, fixed)
    np.testing.assert_allclose(x[:10] - base[0][:10], 0.5)
    np.testing.assert_allclose(y[:10], 0.1)
    np.testing.assert_allclose(x[21:] - base[0][21:], -0.5)
    np.testing.assert_allclose(y[21:], 0.3)


def test_one_anchor_carries_everything_rigidly() -> None:
    stamps = np.arange(5, dtype=np.int64)
    base = _line(5)
    fixed = (np.array([1.0]), np.array([1.0]), np.array([math.pi / 2]))
    x, y, th = carry(stamps, base, stamps[:1], tuple(b[:1] for b in base), fixed)
    np.testing.assert_allclose(x, 1.0, atol=1e-12)
    np.testing.assert_allclose(y, 1.0 + base[0], atol=1e-12)
    np.testing.assert_allclose(wrap_angle(th - math.pi / 2), 0.0, atol=1e-12)
