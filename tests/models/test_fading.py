"""The error-aware mode's settings and the scan steps its laser fade uses (fading.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gridmap_cli.mapping.models.fading import LONE_BEAM_STEP_RAD, ErrorAwareParams, scan_steps
from gridmap_cli.robot import RangeSensor

BEAMS = 181
LASER = tuple(
    RangeSensor(f"laser_{i}", 0.0, 0.0, math.radians(-90 + i), 0.0, 0.0, 8.0, "laser")
    for i in range(BEAMS)
)
SONAR = RangeSensor("sonar", 0.1, 0.0, 0.0, math.radians(25.0), 0.1, 5.0, "sonar")


def test_a_scan_step_is_its_beams_yaw_gap_whatever_their_order() -> None:
    sensors = (*LASER[::-1], SONAR)
    narrow = np.array([True] * BEAMS + [False])
    step = scan_steps(sensors, narrow)
    assert step.shape == (BEAMS + 1,)
    assert np.allclose(step[:BEAMS], math.radians(1.0))
    assert step[BEAMS] == 0.0  # a sonar has no scan


def test_a_lone_beam_or_a_wide_one_keeps_at_least_its_width() -> None:
    lone = RangeSensor("ray", 0.0, 0.0, 0.0, 0.0, 0.0, 8.0, "laser")
    wide = tuple(
        RangeSensor(f"fan_{i}", 0.0, 0.0, math.radians(i), math.radians(3.0), 0.0, 8.0, "laser")
        for i in range(3)
    )
    step = scan_steps((lone, *wide), np.ones(4, dtype=bool))
    assert step[0] == LONE_BEAM_STEP_RAD
    assert np.allclose(step[1:], math.radians(3.0))  # the 1-degree gap, widened to the beam


def test_two_lasers_at_different_mountings_are_two_scans() -> None:
    front = tuple(
        RangeSensor(f"laser_{i}", 0.2, 0.0, math.radians(2 * i), 0.0, 0.0, 8.0, "laser")
        for i in range(5)
    )
    back = tuple(
        RangeSensor(f"laser_{i}", -0.2, 0.0, math.radians(180 + 0.5 * i), 0.0, 0.0, 8.0, "laser")
        for i in range(5)
    )
    step = scan_steps((*front, *back), np.ones(10, dtype=bool))
    assert np.allclose(step[:5], math.radians(2.0))
    assert np.allclose(step[5:], math.radians(0.5))


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("trust_length_m", 0.0, "trust length"),
        ("trust_length_m", math.inf, "trust length"),
        ("max_heading_spread_rad", 0.0, "heading-spread"),
        ("laser_relative_error", -0.1, "relative range error"),
        ("laser_relative_error", math.nan, "relative range error"),
    ],
)
def test_error_aware_params_refuse_what_means_nothing(
    field: str, value: float, message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        ErrorAwareParams(**{field: value})
