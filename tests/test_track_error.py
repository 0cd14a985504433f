"""Track errors as evo computes them: alignment undoes a rigid motion, RPE sees local error."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gridmap_cli.poses.track_error import align_se2, track_error, transformed
from gridmap_cli.records import PoseTrack


def square(n: int = 200) -> PoseTrack:
    s = np.linspace(0.0, 40.0, n)
    x = np.where(s < 10, s, np.where(s < 20, 10, np.where(s < 30, 30 - s, 0)))
    y = np.where(s < 10, 0, np.where(s < 20, s - 10, np.where(s < 30, 10, 40 - s)))
    th = np.where(s < 10, 0, np.where(s < 20, math.pi / 2, np.where(s < 30, math.pi, -math.pi / 2)))
    return PoseTrack(np.arange(n, dtype=np.int64), x.astype(float), y.astype(float), th)


@given(st.floats(-50, 50), st.floats(-50, 50), st.floats(-math.pi + 1e-6, math.pi - 1e-6))
def test_alignment_undoes_a_rigid_motion(x: float, y: float, theta: float) -> None:
    reference = square()
    moved = transformed(reference, (x, y, theta))
    pose = align_se2(moved, reference)
    back = transformed(moved, pose)
    assert np.allclose(back.x_m, reference.x_m, atol=1e-6)
    assert np.allclose(back.y_m, reference.y_m, atol=1e-6)
    error = track_error(moved, reference)
    assert error.ape_rmse_m == pytest.approx(0.0, abs=1e-6)
    assert error.ape_heading_deg == pytest.approx(0.0, abs=1e-6)
    assert error.rpe_per_m == pytest.approx(0.0, abs=1e-9)


def test_a_scale_error_is_its_relative_error_per_metre() -> None:
    reference = square()
    scaled = PoseTrack(reference.stamp_ns, 1.02 * reference.x_m, 1.02 * reference.y_m,
                       reference.theta_rad)  # fmt: skip
    error = track_error(scaled, reference, delta_m=5.0)
    # 2 % of the chord between the pair, which at a corner is shorter than the path
    assert 0.017 < error.rpe_per_m <= 0.02
    assert error.rpe_heading_deg_per_m == pytest.approx(0.0, abs=1e-9)
    assert error.ape_rmse_m > 0.05
