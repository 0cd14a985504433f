"""Quaternions and transform chains (gridmap_cli/readers/ros/frames.py), with hypothesis."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gridmap_cli.geometry import wrap_angle
from gridmap_cli.readers.ros.frames import (
    IDENTITY,
    IDENTITY_ROTATION,
    Transform,
    quaternion_of_yaw,
    yaw_of,
)

ANGLES = st.floats(min_value=-1000.0, max_value=1000.0, allow_nan=False)


@given(ANGLES)
def test_yaw_of_inverts_quaternion_of_yaw(theta: float) -> None:
    back = yaw_of(quaternion_of_yaw(theta))
    # compared as angles: at the seam, -pi and a value just below pi are 1e-16 apart
    assert abs(float(wrap_angle(back - float(wrap_angle(theta))))) <= 1e-12
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


def about(axis: tuple[float, float, float], angle: float) -> Transform:
    s = math.sin(0.5 * angle)
    return Transform(
        (0.0, 0.0, 0.0), (axis[0] * s, axis[1] * s, axis[2] * s, math.cos(0.5 * angle))
    )


@given(st.floats(-3.0, 3.0), st.floats(-1.4, 1.4), st.floats(-3.0, 3.0))
def test_a_tilted_sensor_keeps_the_heading_of_its_x_axis(
    yaw: float, pitch: float, roll: float
) -> None:
    """Yaw, then pitch about the new y axis, then roll about the sensor's own x axis: the x axis
    points at `yaw` in the floor plane whatever the pitch (below 90 deg) and the roll."""
    chain = (
        about((0.0, 0.0, 1.0), yaw)
        .then(about((0.0, 1.0, 0.0), pitch))
        .then(about((1.0, 0.0, 0.0), roll))
    )
    _, _, heading = chain.planar()
    assert abs(float(wrap_angle(heading - yaw))) <= 1e-9


def test_a_chain_composes_translations_in_3d() -> None:
    """base -> mast (1 m up, turned 90 deg) -> sensor 0.5 m along the mast's x: in the base plane
    the sensor stands at (0, 0.5), facing +y."""
    mast = Transform((0.0, 0.0, 1.0), quaternion_of_yaw(math.pi / 2))
    sensor = Transform((0.5, 0.0, 0.0), IDENTITY_ROTATION)
    x, y, heading = mast.then(sensor).planar()
    assert math.isclose(x, 0.0, abs_tol=1e-15) and math.isclose(y, 0.5)
    assert math.isclose(heading, math.pi / 2)


def test_transform_series_gives_its_own_samples_exactly_and_nan_outside() -> None:

    from gridmap_cli.readers.ros.frames import TransformSeries

    series = TransformSeries()
    a = Transform((1.0, 2.0, 0.0), quaternion_of_yaw(0.3))
    b = Transform((3.0, 2.0, 0.0), quaternion_of_yaw(0.5))
    series.add(20, b)
    series.add(10, a)  # out of order: sorted
    series.add(20, a)  # a repeated stamp: the first one wins
    got = series.at(np.array([5, 10, 15, 20, 25], dtype=np.int64))
    assert np.isnan(got[0]).all() and np.isnan(got[4]).all()
    assert got[1].tolist() == [*a.translation, *a.rotation]
    assert got[3].tolist() == [*b.translation, *b.rotation]
    assert got[2, :3].tolist() == [2.0, 2.0, 0.0]
    assert yaw_of(tuple(got[2, 3:].tolist())) == pytest.approx(0.4)  # type: ignore[arg-type]
    assert series.changes()


@given(st.floats(-10, 10), st.floats(-0.3, 0.3), st.floats(-0.3, 0.3))
def test_yaws_of_many_quaternions_are_yaw_of_each(yaw: float, roll: float, pitch: float) -> None:
    from gridmap_cli.readers.ros.frames import _yaws

    flat = quaternion_of_yaw(yaw)
    cr, sr, cp, sp = (
        math.cos(roll / 2),
        math.sin(roll / 2),
        math.cos(pitch / 2),
        math.sin(pitch / 2),
    )
    cy, sy = flat[3], flat[2]
    tilted = (sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
              cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy)  # fmt: skip
    many = _yaws(np.array([flat, tilted]))
    assert many[0] == pytest.approx(yaw_of(flat), abs=1e-12)
    assert many[1] == pytest.approx(yaw_of(tilted), abs=1e-12)


@given(
    st.floats(-math.pi, math.pi),
    st.floats(-1.5, 1.5),
    st.floats(-math.pi, math.pi),
    st.floats(0.1, 10.0),
)
def test_up_is_the_z_axis_height_whatever_the_quaternion_norm(
    yaw: float, pitch: float, roll: float, scale: float
) -> None:
    """Yaw, pitch, roll: the sensor's z axis ends at height cos(pitch) cos(roll), negative
    when the sensor is turned upside down; a recorded quaternion of another norm says the same."""
    chain = (
        about((0.0, 0.0, 1.0), yaw)
        .then(about((0.0, 1.0, 0.0), pitch))
        .then(about((1.0, 0.0, 0.0), roll))
    )
    scaled = Transform(chain.translation, tuple(scale * v for v in chain.rotation))  # type: ignore[arg-type]
    want = math.cos(pitch) * math.cos(roll)
    assert math.isclose(chain.up(), want, abs_tol=1e-12)
    assert math.isclose(scaled.up(), want, abs_tol=1e-12)
