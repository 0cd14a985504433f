"""Quaternions about z and back (gridmap_cli/readers/ros_frames.py), with hypothesis."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from gridmap_cli.geometry import wrap_angle
from gridmap_cli.readers.ros_frames import (
    IDENTITY,
    IDENTITY_ROTATION,
    quaternion_of_yaw,
    wrapped,
    yaw_of,
)

ANGLES = st.floats(min_value=-1000.0, max_value=1000.0, allow_nan=False)


@given(ANGLES)
def test_yaw_of_inverts_quaternion_of_yaw(theta: float) -> None:
    back = yaw_of(quaternion_of_yaw(theta))
    # compared as angles: at the seam, -pi and a value just below pi are 1e-16 apart
    assert abs(wrapped(back - float(wrap_angle(theta)))) <= 1e-12
    assert -math.pi <= back < math.pi


@given(ANGLES)
def test_quaternion_of_yaw_is_a_unit_rotation_about_z(theta: float) -> None:
    x, y, z, w = quaternion_of_yaw(theta)
    assert (x, y) == (0.0, 0.0)
    assert math.isclose(z * z + w * w, 1.0, rel_tol=1e-15)


def test_by_hand() -> None:
    assert quaternion_of_yaw(0.0) == IDENTITY_ROTATION == IDENTITY.rotation
    x, y, z, w = quaternion_of_yaw(math.pi / 2)
    assert (x, y) == (0.0, 0.0)
    assert math.isclose(z, math.sqrt(0.5)) and math.isclose(w, math.sqrt(0.5))
    assert yaw_of(quaternion_of_yaw(math.pi / 2)) == math.pi / 2
