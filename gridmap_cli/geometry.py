"""SE(2) helpers on numpy arrays. Angles in radians, positions in metres."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


def wrap_angle(theta_rad: FloatArray | float) -> FloatArray:
    """Wrap angles to [-pi, pi). Accepts scalars or arrays of any shape."""
    return np.asarray((np.asarray(theta_rad) + np.pi) % (2.0 * np.pi) - np.pi, dtype=np.float64)


def compose(
    x_m: FloatArray,
    y_m: FloatArray,
    theta_rad: FloatArray,
    dx_m: FloatArray | float,
    dy_m: FloatArray | float,
    dtheta_rad: FloatArray | float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Compose poses a (x, y, theta) with relative poses b expressed in a's frame: a (+) b.

    All inputs broadcast together; the result has the broadcast shape, theta wrapped.
    """
    c = np.cos(theta_rad)
    s = np.sin(theta_rad)
    x = x_m + c * dx_m - s * dy_m
    y = y_m + s * dx_m + c * dy_m
    return np.asarray(x), np.asarray(y), wrap_angle(theta_rad + dtheta_rad)


def inverse(
    x_m: FloatArray, y_m: FloatArray, theta_rad: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The inverse pose: compose(p, inverse(p)) is the identity."""
    c = np.cos(theta_rad)
    s = np.sin(theta_rad)
    return (
        np.asarray(-c * x_m - s * y_m),
        np.asarray(s * x_m - c * y_m),
        wrap_angle(-np.asarray(theta_rad)),
    )


def relative_poses(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a^-1 b`` row by row: poses ``b`` (R, 3) in the frames of poses ``a`` (R, 3)."""
    ix, iy, ith = inverse(a[:, 0], a[:, 1], a[:, 2])
    return np.column_stack(compose(ix, iy, ith, b[:, 0], b[:, 1], b[:, 2]))


def logmap(
    x_m: FloatArray, y_m: FloatArray, theta_rad: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The logarithm of poses (x, y, theta): their tangent coordinates, the translation taken
    through the inverse of the rotation's left Jacobian ``V`` (as gtsam's ``Pose2.Logmap``);
    theta as given. Inputs broadcast together."""
    theta = np.asarray(theta_rad, dtype=np.float64)
    turning = np.abs(theta) >= 1e-10
    c1, s = np.cos(theta) - 1.0, np.sin(theta)
    # V^-1 t = theta / (s^2 + (1 - c)^2) * (s x + (1 - c) y, -(1 - c) x + s y)
    scale = theta / np.where(turning, c1 * c1 + s * s, 1.0)
    vx = np.where(turning, scale * (s * x_m - c1 * y_m), x_m)
    vy = np.where(turning, scale * (c1 * x_m + s * y_m), y_m)
    return np.asarray(vx), np.asarray(vy), theta
