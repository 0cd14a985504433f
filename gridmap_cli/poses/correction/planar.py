"""Planar poses and scans as small_gicp takes and gives them, and scan points placed by a pose."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


def pose_matrix(x: float, y: float, theta: float) -> FloatArray:
    """The planar pose as the 4 x 4 transform small_gicp takes."""
    m = np.eye(4)
    c, s = math.cos(theta), math.sin(theta)
    m[0, 0], m[0, 1], m[1, 0], m[1, 1] = c, -s, s, c
    m[0, 3], m[1, 3] = x, y
    return m


def planar_pose(m: FloatArray) -> tuple[float, float, float]:
    """The planar pose (x, y, theta) of a 4 x 4 transform."""
    return float(m[0, 3]), float(m[1, 3]), math.atan2(float(m[1, 0]), float(m[0, 0]))


def placed_points(points: FloatArray, pose: tuple[float, float, float]) -> FloatArray:
    """Points (K, 2) of a scan moved to ``pose`` (x, y, theta)."""
    x, y, th = pose
    c, s = math.cos(th), math.sin(th)
    return np.column_stack(
        [x + c * points[:, 0] - s * points[:, 1], y + s * points[:, 0] + c * points[:, 1]]
    )


def planar_sheet(points: FloatArray, voxel_m: float) -> FloatArray:
    """Planar points (K, 2) as three layers one voxel apart in z, shape (3K, 3)."""
    k = len(points)
    sheet = np.empty((3 * k, 3))
    for layer, z in enumerate((-voxel_m, 0.0, voxel_m)):
        # the layers filled in place (this runs for every scan and local map); + 0.0 as a sum
        # with the lift vector has it: a -0.0 coordinate becomes +0.0
        np.add(points, 0.0, out=sheet[layer * k : (layer + 1) * k, :2])
        sheet[layer * k : (layer + 1) * k, 2] = z + 0.5 * voxel_m
    return sheet
